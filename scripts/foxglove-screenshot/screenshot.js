// A screenshot of a limot MCAP recording as Foxglove Studio shows it, taken
// headless: serves Foxglove Studio 1.48 (@foxglove/studio-base's prebuilt
// bundle) and the file on 127.0.0.1, opens the file at a time with a layout
// in Debian's Chromium (software WebGL) and saves the window as a PNG.
//
//   cd scripts/foxglove-screenshot && npm ci
//   node screenshot.js RECORDING.mcap OUT.png [TIME_S] [LAYOUT.json]
//
// TIME_S: the data time to show (default 0); LAYOUT: default
// docs/foxglove-layout.json. CHROMIUM (default /usr/bin/chromium), WIDTH and
// HEIGHT (default 1400 x 800) and SETTLE_MS (the wait after the file's topics
// are listed, default 20000) come from the environment.
const fs = require("fs");
const http = require("http");
const path = require("path");
const { chromium } = require("playwright-core");

const [recording, out, timeArg, layoutArg] = process.argv.slice(2);
if (!recording || !out) {
  console.error("usage: node screenshot.js RECORDING.mcap OUT.png [TIME_S] [LAYOUT.json]");
  process.exit(2);
}
const layoutPath = layoutArg || path.join(__dirname, "..", "..", "docs", "foxglove-layout.json");
const timeS = Number(timeArg || 0);
const modules = path.join(__dirname, "node_modules");
for (const file of [recording, layoutPath, path.join(modules, "@foxglove/studio-base/assets/index.js")]) {
  if (!fs.existsSync(file)) {
    console.error(`${file}: not found${file.includes("node_modules") ? " (run `npm ci` here first)" : ""}`);
    process.exit(1);
  }
}

/** URL path -> file served. */
function resolve(urlPath) {
  if (urlPath === "/" || urlPath === "/index.html") return path.join(__dirname, "index.html");
  if (urlPath === "/host.js") return path.join(__dirname, "host.js");
  if (urlPath === "/layout.json") return layoutPath;
  if (urlPath === "/recording.mcap") return recording;
  if (urlPath.startsWith("/studio/")) {
    return path.join(modules, "@foxglove/studio-base/assets", path.basename(urlPath));
  }
  for (const pkg of ["react", "react-dom"]) {
    if (urlPath.startsWith(`/${pkg}/umd/`)) return path.join(modules, pkg, "umd", path.basename(urlPath));
  }
  return undefined;
}

const types = { ".html": "text/html", ".js": "application/javascript", ".json": "application/json",
  ".wasm": "application/wasm", ".png": "image/png", ".ttf": "font/ttf" };

/** Static files with HTTP range requests (Foxglove reads an MCAP file by ranges). */
const server = http.createServer((req, res) => {
  const file = resolve(decodeURIComponent(req.url.split("?")[0]));
  fs.stat(file || "", (err, stat) => {
    if (!file || err || !stat.isFile()) {
      res.writeHead(404);
      res.end();
      return;
    }
    const headers = { "Content-Type": types[path.extname(file)] || "application/octet-stream", "Accept-Ranges": "bytes" };
    const range = req.headers.range && /bytes=(\d*)-(\d*)/.exec(req.headers.range);
    let start = 0;
    let end = stat.size - 1;
    if (range) {
      start = range[1] ? Number(range[1]) : stat.size - Number(range[2]);
      end = range[1] && range[2] ? Math.min(Number(range[2]), stat.size - 1) : stat.size - 1;
      res.writeHead(206, { ...headers, "Content-Range": `bytes ${start}-${end}/${stat.size}`, "Content-Length": end - start + 1 });
    } else {
      res.writeHead(200, { ...headers, "Content-Length": stat.size });
    }
    if (req.method === "HEAD") {
      res.end();
      return;
    }
    fs.createReadStream(file, { start, end }).pipe(res);
  });
});

async function main() {
  await new Promise((ready) => server.listen(0, "127.0.0.1", ready));
  const origin = `http://127.0.0.1:${server.address().port}`;
  const time = new Date(Math.round(timeS * 1000)).toISOString().replace(/\.(\d{3})Z$/, (_, ms) => `.${ms}000000Z`);
  const url = `${origin}/?ds=remote-file&ds.url=${encodeURIComponent(`${origin}/recording.mcap`)}`
    + `&layoutId=limot&time=${encodeURIComponent(time)}`;
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
    headless: true,
    args: ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
      "--disable-component-update", "--disable-sync", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
  });
  try {
    const page = await browser.newPage({
      viewport: { width: Number(process.env.WIDTH || 1400), height: Number(process.env.HEIGHT || 800) },
    });
    page.on("pageerror", (e) => console.error("page error:", String(e)));
    await page.goto(url, { waitUntil: "load", timeout: 120000 });
    // the file is open once its topics are listed; then the panels draw the frame
    await page.getByText("/lidar/points", { exact: true }).first().waitFor({ timeout: 120000 });
    await page.waitForTimeout(Number(process.env.SETTLE_MS || 20000));
    await page.addStyleTag({ content: "[role=tooltip] { display: none !important; }" });
    await page.waitForTimeout(500);
    await page.screenshot({ path: out });
    console.log(`${out}: ${recording} at t = ${timeS} s in Foxglove Studio 1.48`);
  } finally {
    await browser.close();
    server.close();
  }
}

main().catch((e) => {
  console.error(e);
  process.exit(1);
});
