// Mounts Foxglove Studio's App with one layout (/layout.json, id `limot`),
// in-memory settings and the MCAP data sources; the page's deep link
// (?ds=remote-file&ds.url=...&layoutId=limot&time=...) opens the file.
(async () => {
  const data = await (await fetch("/layout.json")).json();
  const savedAt = "2000-01-01T00:00:00.000Z";
  const layout = {
    id: "limot",
    name: "limot",
    permission: "CREATOR_WRITE",
    baseline: { data, savedAt },
    working: undefined,
    syncInfo: undefined,
  };
  const layoutStorage = {
    async list() { return [layout]; },
    async get(_namespace, id) { return id === layout.id ? layout : undefined; },
    async put(_namespace, l) { return l; },
    async delete() {},
    async importLayouts() {},
    async migrateUnnamespacedLayouts() {},
  };
  const settings = new Map();
  const appConfiguration = {
    get: (key) => settings.get(key),
    set: async (key, value) => { settings.set(key, value); },
    addChangeListener() {},
    removeChangeListener() {},
  };
  await window.initI18n();
  window.ReactDOM.render(
    window.React.createElement(window.App, {
      deepLinks: [window.location.href],
      appConfiguration,
      dataSources: [new window.McapLocalDataSourceFactory(), new window.RemoteDataSourceFactory()],
      layoutStorage,
      extensionLoaders: [],
      enableGlobalCss: true,
      enableLaunchPreferenceScreen: false,
    }),
    document.getElementById("root"),
  );
})().catch((e) => console.error("host:", e && e.stack ? e.stack : e));
