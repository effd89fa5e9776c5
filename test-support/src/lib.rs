//! Dev-only helpers shared by the workspace's tests and benchmarks.
//!
//! Nothing here is part of limot's API; the crate exists so that tests do not
//! each carry their own copy of the same generator.
#![warn(missing_docs)]

use nalgebra::Vector3;
use std::ops::Deref;
use std::path::Path;

/// A fresh directory under the system's temp dir for one test, removed with
/// everything in it when dropped, also when the test panics. Derefs to its
/// [`Path`] (and is `AsRef<Path>`), so `&dir` goes wherever a path does.
///
/// ```
/// use limot_test_support::ScratchDir;
/// let kept;
/// {
///     let dir = ScratchDir::new("doc");
///     std::fs::write(dir.join("a.txt"), "x").unwrap();
///     kept = dir.to_path_buf();
///     assert!(kept.join("a.txt").exists());
/// }
/// assert!(!kept.exists());
/// ```
#[derive(Debug)]
pub struct ScratchDir(tempfile::TempDir);

impl ScratchDir {
    /// Creates `limot-<tag>-XXXXXX` under the temp dir.
    ///
    /// # Panics
    /// When the directory cannot be created (a test cannot run without it).
    pub fn new(tag: &str) -> ScratchDir {
        let dir = tempfile::Builder::new()
            .prefix(&format!("limot-{tag}-"))
            .tempdir()
            .unwrap_or_else(|e| panic!("cannot create a scratch dir for {tag}: {e}"));
        ScratchDir(dir)
    }
}

impl AsRef<Path> for ScratchDir {
    fn as_ref(&self) -> &Path {
        self.0.path()
    }
}

impl Deref for ScratchDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

/// SplitMix64 (Steele, Lea and Flood 2014): a tiny deterministic generator,
/// fixed forever, so a test's seed always gives the same data.
///
/// ```
/// use limot_test_support::SplitMix64;
/// let mut a = SplitMix64(7);
/// let mut b = SplitMix64(7);
/// assert_eq!(a.next_u64(), b.next_u64());
/// let u = a.uniform();
/// assert!((0.0..1.0).contains(&u));
/// ```
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1), on the grid of 2⁻⁵³.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Uniform index in 0..n (n > 0; the modulo bias is negligible for test sizes).
    pub fn index(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Standard normal by Box–Muller (the radius draw is kept away from 0).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Three independent normals scaled by `sigma`.
    pub fn normal3(&mut self, sigma: f64) -> Vector3<f64> {
        Vector3::new(self.normal(), self.normal(), self.normal()) * sigma
    }

    /// Uniform in the cube [-scale, scale)³.
    pub fn vector3(&mut self, scale: f64) -> Vector3<f64> {
        Vector3::new(
            self.range(-scale, scale),
            self.range(-scale, scale),
            self.range(-scale, scale),
        )
    }
}

/// What the workspace's benchmarks share: their arguments, a hash to tell
/// whether a change kept their outputs bit for bit, and the mean and 95th
/// percentile they report.
pub mod bench {
    /// The benchmark's own arguments: the process arguments without the
    /// program name and the `--bench` that `cargo bench` appends.
    pub fn args() -> Vec<String> {
        std::env::args()
            .skip(1)
            .filter(|a| a != "--bench")
            .collect()
    }

    /// 64-bit FNV-1a over 64-bit words.
    ///
    /// ```
    /// use limot_test_support::bench::Fnv1a;
    /// let mut a = Fnv1a::new();
    /// a.write([1, 2]);
    /// let mut b = Fnv1a::new();
    /// b.write([2, 1]);
    /// assert_ne!(a.finish(), b.finish());
    /// ```
    #[derive(Debug, Clone, Copy)]
    pub struct Fnv1a(u64);

    impl Default for Fnv1a {
        fn default() -> Self {
            Self::new()
        }
    }

    impl Fnv1a {
        /// The hash of nothing (FNV's offset basis).
        pub fn new() -> Self {
            Fnv1a(0xcbf2_9ce4_8422_2325)
        }

        /// Hashes `words` in order.
        pub fn write(&mut self, words: impl IntoIterator<Item = u64>) {
            for word in words {
                self.0 = (self.0 ^ word).wrapping_mul(0x0100_0000_01b3);
            }
        }

        /// The hash so far.
        pub fn finish(&self) -> u64 {
            self.0
        }
    }

    /// Mean and 95th percentile (nearest rank) of `values` (0 and NaN for
    /// none).
    ///
    /// ```
    /// let (mean, p95) = limot_test_support::bench::mean_p95((1..=20).map(f64::from).collect());
    /// assert_eq!((mean, p95), (10.5, 19.0));
    /// ```
    pub fn mean_p95(mut values: Vec<f64>) -> (f64, f64) {
        values.sort_by(f64::total_cmp);
        let mean = values.iter().sum::<f64>() / values.len().max(1) as f64;
        let p95 = values
            .get(((values.len().max(1) - 1) as f64 * 0.95).round() as usize)
            .copied()
            .unwrap_or(f64::NAN);
        (mean, p95)
    }
}
