//! Road roughness: a seeded, world-fixed height texture whose longitudinal
//! profile has the ISO 8608 displacement spectrum `Gd(n) = Gd(n0) (n / n0)^-2`
//! (n in cycles/m, n0 = 0.1 cycles/m) between two wavelengths.
//!
//! The texture is one periodic tile of `TILE_CELLS`² heights, synthesised in
//! the frequency domain (random phases, amplitudes from the isotropic 2-D
//! spectrum that has the ISO profile spectrum along every line), and read by
//! bilinear interpolation, so a height costs four loads. The tile repeats
//! every `TILE_CELLS * CELL_M` = 64 m, far beyond the ~3 m a vehicle moves
//! between two sweeps. The synthesis uses rustfft's scalar radix-4 transform
//! only, so a tile is bit-identical on every machine.
//!
//! ISO 8608 classes by `Gd(n0)` (geometric mean, m³): A 16e-6, B 64e-6,
//! C 256e-6, D 1024e-6.

use limot_estimator::geometry::floor_to_i64;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftDirection, algorithm::Radix4};
use std::f64::consts::TAU;
use std::sync::Arc;

/// Cells along each side of the tile (a power of two, for the radix-4 FFT).
const TILE_CELLS: usize = 512;
/// Cell size, m: a quarter of the default shortest wavelength (0.3 m) and more.
const CELL_M: f64 = 0.125;
/// Reference spatial frequency of ISO 8608, cycles/m.
pub const ISO_N0_CYCLES_PER_M: f64 = 0.1;

/// The isotropic 2-D spectrum (m⁴, two-sided, k in cycles/m) whose line
/// profiles have the one-sided ISO spectrum `Gd(n) = psd (n0 / n)^2`:
/// a profile's two-sided spectrum is `∫ G2(√(n² + m²)) dm = 2A / n²` for
/// `G2 = A k⁻³`, and one-sided is twice that, so `A = psd n0² / 4`.
fn iso_2d_spectrum(psd_at_n0_m3: f64, k: f64) -> f64 {
    psd_at_n0_m3 * ISO_N0_CYCLES_PER_M * ISO_N0_CYCLES_PER_M / (4.0 * k * k * k)
}

/// A periodic height texture over the plane; [`Roughness::height`] is
/// continuous and piecewise bilinear.
#[derive(Debug, Clone, PartialEq)]
pub struct Roughness {
    /// Row-major, `heights[iy * TILE_CELLS + ix] * scale_m`: 16-bit
    /// heights keep the tile (512 KiB) in a core's L2 cache, which the ray
    /// caster's scattered lookups need, at a resolution of bound / 32767.
    heights: Arc<[i16; TILE_CELLS * TILE_CELLS]>,
    scale_m: f64,
    /// max |height| over the texture, m.
    bound_m: f64,
    /// max |gradient| over the texture (largest cell-edge slope x sqrt 2).
    slope_bound: f64,
}

impl Roughness {
    /// A texture with profile spectrum `Gd(n) = psd_at_n0_m3 (n / n0)^-2`
    /// for wavelengths in `[wavelength_min_m, wavelength_max_m]` (clamped to
    /// what the tile resolves: 2 cells to the tile size), zero elsewhere.
    pub fn iso8608(
        rng: &mut ChaCha8Rng,
        psd_at_n0_m3: f64,
        wavelength_min_m: f64,
        wavelength_max_m: f64,
    ) -> Roughness {
        let n = TILE_CELLS;
        let period_m = n as f64 * CELL_M;
        let dk = 1.0 / period_m;
        let k_lo = 1.0 / wavelength_max_m.min(period_m);
        let k_hi = 1.0 / wavelength_min_m.max(2.0 * CELL_M);
        let g2 = |k: f64| iso_2d_spectrum(psd_at_n0_m3, k);
        let mut spectrum = vec![Complex::new(0.0, 0.0); n * n];
        let signed = |i: usize| {
            if i <= n / 2 {
                i as f64
            } else {
                i as f64 - n as f64
            }
        };
        // draw every bin in a fixed order (the stream layout does not depend
        // on the band), then keep the band
        for iy in 0..n {
            for ix in 0..n {
                let phase = TAU * rng.random::<f64>();
                let k = dk * (signed(ix).powi(2) + signed(iy).powi(2)).sqrt();
                if k < k_lo || k > k_hi || psd_at_n0_m3 <= 0.0 {
                    continue;
                }
                // a real field from complex bins: each bin carries half the
                // variance of its +-k pair; E|c|^2 = G2 dk^2
                let amplitude = (g2(k) * dk * dk).sqrt();
                spectrum[iy * n + ix] = Complex::from_polar(amplitude, phase);
            }
        }
        // 2-D inverse transform: rows, then columns
        let fft = Radix4::new(n, FftDirection::Inverse);
        for row in spectrum.chunks_mut(n) {
            fft.process(row);
        }
        let mut column = vec![Complex::new(0.0, 0.0); n];
        for ix in 0..n {
            for iy in 0..n {
                column[iy] = spectrum[iy * n + ix];
            }
            fft.process(&mut column);
            for iy in 0..n {
                spectrum[iy * n + ix] = column[iy];
            }
        }
        // the real part of a sum of random-phase bins: sqrt 2 restores the
        // variance the imaginary part took
        let real: Vec<f64> = spectrum
            .iter()
            .map(|c| c.re * std::f64::consts::SQRT_2)
            .collect();
        let peak = real.iter().map(|h| h.abs()).fold(0.0, f64::max);
        let scale_m = if peak > 0.0 {
            peak / i16::MAX as f64
        } else {
            1.0
        };
        let heights: Vec<i16> = real.iter().map(|h| (h / scale_m).round() as i16).collect();
        let bound_m = heights
            .iter()
            .map(|&h| (h as f64 * scale_m).abs())
            .fold(0.0, f64::max);
        let mut max_step = 0.0_f64;
        for iy in 0..n {
            for ix in 0..n {
                let h = heights[iy * n + ix] as f64;
                let right = heights[iy * n + (ix + 1) % n] as f64;
                let up = heights[((iy + 1) % n) * n + ix] as f64;
                max_step = max_step.max((right - h).abs()).max((up - h).abs());
            }
        }
        let heights: Box<[i16; TILE_CELLS * TILE_CELLS]> = heights
            .into_boxed_slice()
            .try_into()
            .expect("one height per cell of the tile");
        Roughness {
            heights: heights.into(),
            scale_m,
            bound_m,
            slope_bound: std::f64::consts::SQRT_2 * max_step * scale_m / CELL_M,
        }
    }

    /// Upper bound of |height|, m.
    pub fn bound_m(&self) -> f64 {
        self.bound_m
    }

    /// Upper bound of the gradient's norm.
    pub fn slope_bound(&self) -> f64 {
        self.slope_bound
    }

    /// Height at world (x, y), m.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        self.height_and_gradient(x, y).0
    }

    /// Height and (dh/dx, dh/dy) at world (x, y); on a cell edge the
    /// gradient is that of the cell above/right of it.
    #[inline]
    pub fn height_and_gradient(&self, x: f64, y: f64) -> (f64, f64, f64) {
        let n = TILE_CELLS;
        let (u, v) = (x / CELL_M, y / CELL_M);
        let (iu, iv) = (floor_to_i64(u), floor_to_i64(v));
        let (tx, ty) = (u - iu as f64, v - iv as f64);
        // n is a power of two: the mask is the Euclidean remainder
        let ix = (iu & (n as i64 - 1)) as usize;
        let iy = (iv & (n as i64 - 1)) as usize;
        let (ix1, iy1) = ((ix + 1) % n, (iy + 1) % n);
        let h = |i: usize, j: usize| self.heights[j * n + i] as f64 * self.scale_m;
        let (h00, h10, h01, h11) = (h(ix, iy), h(ix1, iy), h(ix, iy1), h(ix1, iy1));
        let bottom = h00 + (h10 - h00) * tx;
        let top = h01 + (h11 - h01) * tx;
        let height = bottom + (top - bottom) * ty;
        let dhdx = ((h10 - h00) * (1.0 - ty) + (h11 - h01) * ty) / CELL_M;
        let dhdy = (top - bottom) / CELL_M;
        (height, dhdx, dhdy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn texture(psd: f64, seed: u64) -> Roughness {
        Roughness::iso8608(&mut ChaCha8Rng::seed_from_u64(seed), psd, 0.3, 20.0)
    }

    /// Variance the synthesis promises: the sum of its bins' power.
    fn bin_variance(psd: f64, wavelength_min_m: f64, wavelength_max_m: f64) -> f64 {
        let n = TILE_CELLS as f64;
        let dk = 1.0 / (n * CELL_M);
        let mut sum = 0.0;
        for i in 0..TILE_CELLS {
            for j in 0..TILE_CELLS {
                let s = |i: usize| {
                    if i as f64 <= n / 2.0 {
                        i as f64
                    } else {
                        i as f64 - n
                    }
                };
                let k = dk * (s(i).powi(2) + s(j).powi(2)).sqrt();
                if k >= 1.0 / wavelength_max_m && k <= 1.0 / wavelength_min_m {
                    sum += iso_2d_spectrum(psd, k) * dk * dk;
                }
            }
        }
        sum
    }

    #[test]
    fn bins_approximate_the_continuous_spectrum() {
        // int G2 d2k over the band annulus = (pi / 2) psd n0^2 (1/k_lo - 1/k_hi)
        let psd = 64e-6;
        let continuous =
            0.5 * std::f64::consts::PI * psd * ISO_N0_CYCLES_PER_M.powi(2) * (20.0 - 1.0 / 0.3);
        let discrete = bin_variance(psd, 0.3, 20.0);
        assert!(
            (discrete / continuous - 1.0).abs() < 0.15,
            "{discrete} vs {continuous}"
        );
    }

    #[test]
    fn texture_variance_is_the_bins_power() {
        let psd = 64e-6;
        let want = bin_variance(psd, 0.3, 20.0);
        let mut sum = 0.0;
        let mut count = 0usize;
        for seed in 0..4 {
            let r = texture(psd, seed);
            for i in 0..TILE_CELLS {
                for j in (0..TILE_CELLS).step_by(4) {
                    let h = r.height(i as f64 * CELL_M, j as f64 * CELL_M);
                    sum += h * h;
                    count += 1;
                }
            }
        }
        let got = sum / count as f64;
        // the few lowest-frequency bins dominate: allow for their scatter
        assert!((got / want - 1.0).abs() < 0.25, "variance {got} vs {want}");
    }

    #[test]
    fn profile_spectrum_falls_as_n_to_the_minus_two() {
        // mean square of first differences at lag L ~ int Gd (2 sin(pi n L))^2 dn:
        // for Gd ~ n^-2 and L well inside the band it grows linearly with L
        let r = texture(64e-6, 7);
        let structure = |lag_cells: usize| {
            let mut s = 0.0;
            let mut c = 0;
            for j in (0..TILE_CELLS).step_by(2) {
                for i in 0..TILE_CELLS {
                    let a = r.height(i as f64 * CELL_M, j as f64 * CELL_M);
                    let b = r.height((i + lag_cells) as f64 * CELL_M, j as f64 * CELL_M);
                    s += (a - b).powi(2);
                    c += 1;
                }
            }
            s / c as f64
        };
        let (d1, d4) = (structure(8), structure(32));
        let ratio = d4 / d1;
        assert!((2.8..5.2).contains(&ratio), "structure ratio {ratio}");
    }

    #[test]
    fn texture_is_continuous_periodic_bounded_and_its_gradient_is_right() {
        let r = texture(256e-6, 3);
        let period = TILE_CELLS as f64 * CELL_M;
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for _ in 0..2000 {
            let x = rng.random_range(-5000.0..5000.0);
            let y = rng.random_range(-5000.0..5000.0);
            let (h, gx, gy) = r.height_and_gradient(x, y);
            assert!(h.abs() <= r.bound_m() + 1e-12);
            assert!((gx * gx + gy * gy).sqrt() <= r.slope_bound() + 1e-9);
            assert!((r.height(x + period, y - 3.0 * period) - h).abs() < 1e-6);
            // continuity across cell edges and finite-difference gradient inside a cell
            let e = 1e-7;
            assert!((r.height(x + e, y) - h).abs() < 1e-5);
            let cx = (x / CELL_M).fract().abs();
            let cy = (y / CELL_M).fract().abs();
            if (0.01..0.99).contains(&cx) && (0.01..0.99).contains(&cy) {
                let d = 1e-5;
                let fx = (r.height(x + d, y) - r.height(x - d, y)) / (2.0 * d);
                let fy = (r.height(x, y + d) - r.height(x, y - d)) / (2.0 * d);
                assert!((fx - gx).abs() < 1e-4 && (fy - gy).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn same_seed_same_texture_zero_psd_flat() {
        assert_eq!(texture(64e-6, 5), texture(64e-6, 5));
        assert_ne!(texture(64e-6, 5), texture(64e-6, 6));
        let flat = texture(0.0, 5);
        assert_eq!(flat.bound_m(), 0.0);
        assert_eq!(flat.height(3.3, -7.1), 0.0);
    }
}
