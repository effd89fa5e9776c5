//! Noise models: whitening by a square-root information matrix, and robust
//! kernels applied by iterative reweighting.

use nalgebra::{DMatrix, DVector};

/// Robust loss on the whitened residual norm `s = ‖r‖`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RobustKernel {
    /// Quadratic within `k`, linear beyond.
    Huber {
        /// Threshold on the whitened residual norm.
        k: f64,
    },
    /// `ρ(s) = k²/2·ln(1 + s²/k²)`.
    Cauchy {
        /// Scale on the whitened residual norm.
        k: f64,
    },
}

impl RobustKernel {
    /// IRLS weight `w(s) = ρ'(s)/s` for a whitened residual of norm `s`.
    pub fn weight(&self, s: f64) -> f64 {
        match *self {
            RobustKernel::Huber { k } => {
                if s <= k {
                    1.0
                } else {
                    k / s
                }
            }
            RobustKernel::Cauchy { k } => 1.0 / (1.0 + (s / k).powi(2)),
        }
    }

    /// The loss `ρ(s)` (equals `s²/2` near zero).
    pub fn loss(&self, s: f64) -> f64 {
        match *self {
            RobustKernel::Huber { k } => {
                if s <= k {
                    0.5 * s * s
                } else {
                    k * (s - 0.5 * k)
                }
            }
            RobustKernel::Cauchy { k } => 0.5 * k * k * (1.0 + (s / k).powi(2)).ln(),
        }
    }
}

/// Gaussian noise given by its square-root information `L` (`Lᵀ·L = Σ⁻¹`),
/// optionally with a robust kernel on the whitened residual.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseModel {
    /// `L` with `LᵀL` the information matrix: the whitened residual is `L·r`.
    pub sqrt_information: DMatrix<f64>,
    /// Robust kernel on the whitened residual norm, if any.
    pub robust: Option<RobustKernel>,
}

impl NoiseModel {
    /// Independent components with the given standard deviations.
    pub fn diagonal_sigmas(sigmas: &[f64]) -> NoiseModel {
        NoiseModel {
            sqrt_information: DMatrix::from_diagonal(&DVector::from_iterator(
                sigmas.len(),
                sigmas.iter().map(|s| 1.0 / s),
            )),
            robust: None,
        }
    }

    /// From a covariance (symmetric positive definite); `None` if it is not.
    pub fn from_covariance(covariance: &DMatrix<f64>) -> Option<NoiseModel> {
        let information = covariance.clone().try_inverse()?;
        NoiseModel::from_information(&information)
    }

    /// From an information matrix (symmetric positive definite); `None` if it is not.
    pub fn from_information(information: &DMatrix<f64>) -> Option<NoiseModel> {
        let sym = (information + information.transpose()) * 0.5;
        let chol = nalgebra::linalg::Cholesky::new(sym)?;
        Some(NoiseModel {
            sqrt_information: chol.l().transpose(),
            robust: None,
        })
    }

    /// The same model with `kernel` on the whitened residual norm.
    pub fn with_robust(mut self, kernel: RobustKernel) -> NoiseModel {
        self.robust = Some(kernel);
        self
    }

    /// Dimension of the residual it whitens.
    pub fn dim(&self) -> usize {
        self.sqrt_information.nrows()
    }

    /// `L·r`.
    pub fn whiten(&self, residual: &DVector<f64>) -> DVector<f64> {
        &self.sqrt_information * residual
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sqrt_information_reproduces_information() {
        let cov = DMatrix::from_row_slice(2, 2, &[4.0, 1.0, 1.0, 2.0]);
        let noise = NoiseModel::from_covariance(&cov).unwrap();
        let info = noise.sqrt_information.transpose() * &noise.sqrt_information;
        let expected = cov.try_inverse().unwrap();
        assert!((info - expected).norm() < 1e-12);
        assert!(NoiseModel::from_covariance(&DMatrix::from_row_slice(1, 1, &[-1.0])).is_none());
    }

    #[test]
    fn kernel_weights_are_derivatives_of_the_loss_over_s() {
        for kernel in [
            RobustKernel::Huber { k: 1.3 },
            RobustKernel::Cauchy { k: 0.7 },
        ] {
            for s in [0.1, 0.9, 2.0, 10.0] {
                let h = 1e-6;
                let d = (kernel.loss(s + h) - kernel.loss(s - h)) / (2.0 * h);
                assert!((d / s - kernel.weight(s)).abs() < 1e-6, "{kernel:?} at {s}");
            }
        }
    }
}
