//! Factor graph: typed variable keys, values on their manifolds, factors
//! (residual + Jacobians, GTSAM style), kept separate from the solver.
//!
//! Conventions shared by every factor:
//! * Poses are [`Isometry3`](nalgebra::Isometry3) with the right perturbation
//!   `T ⊕ ξ = T·Exp(ξ)`, tangent `ξ = (ρ, φ)` (see [`crate::lie`]).
//! * Velocities and biases are Euclidean: `x ⊕ δ = x + δ`.
//! * A factor returns its *unwhitened* residual and Jacobians (one per key,
//!   with respect to that key's tangent); the [`NoiseModel`] whitens them and
//!   applies the robust kernel, so factors never do.

pub mod between_factor;
pub mod conditioned_factor;
pub mod factor;
pub mod imu_factor;
pub mod key;
pub mod marginalization;
pub mod noise;
pub mod object_factors;
pub mod prior_factor;
pub mod sliding_window;
pub mod solver;
pub mod values;

pub use between_factor::BetweenFactor;
pub use conditioned_factor::ConditionedFactor;
pub use factor::{Factor, FactorError, Linearization, check_factor_jacobians};
pub use key::Key;
pub use marginalization::{MarginalPriorFactor, MarginalizationConfig, MarginalizationError};
pub use noise::{NoiseModel, RobustKernel};
pub use object_factors::{ObjectMotionFactor, ObjectObservationFactor, SmoothMotionFactor};
pub use prior_factor::PriorFactor;
pub use sliding_window::{SlidingWindowSmoother, WindowError};
pub use solver::{
    FactorGraph, SolverConfig, SolverError, SolverReport, SolverWorkspace, VariableIndex,
};
pub use values::{Values, Variable};
