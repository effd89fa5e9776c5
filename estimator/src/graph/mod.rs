//! Factor graph: typed variable keys, values on their manifolds, factors
//! (residual + Jacobians, GTSAM style), and the sparse solver built on them,
//! one concept per file as in GTSAM:
//! * variables: [`Key`], [`Values`]/[`Variable`], [`VariableIndex`] (the
//!   column layout of the stacked tangent);
//! * factors: [`Factor`] and [`NoiseModel`], the ego factors ([`PriorFactor`],
//!   [`BetweenFactor`], [`ImuFactor`], [`BiasRandomWalkFactor`]), the object
//!   factors ([`ObjectObservationFactor`], [`ObjectMotionFactor`],
//!   [`SmoothMotionFactor`]) and [`ConditionedFactor`];
//! * linearization: whitened factors accumulated into the block-sparse
//!   [`NormalEquations`] ([`linearize_normal_equations`], [`total_cost`]);
//! * elimination: block-AMD ordering and supernodal sparse Cholesky, with
//!   symbolic analyses kept in a [`SolverWorkspace`];
//! * optimizer: Levenberg–Marquardt ([`optimize`], [`SolverConfig`],
//!   [`SolverReport`], [`FactorGraph`]);
//! * marginals: [`marginal_covariance`]; marginalization by Schur complement
//!   ([`marginalize`], [`MarginalPriorFactor`]); the fixed-lag
//!   [`SlidingWindowSmoother`].
//!
//! Conventions shared by every factor:
//! * Poses are [`Isometry3`](nalgebra::Isometry3) with the right perturbation
//!   `T ⊕ ξ = T·Exp(ξ)`, tangent `ξ = (ρ, φ)` (see [`crate::lie`]).
//! * Velocities and biases are Euclidean: `x ⊕ δ = x + δ`.
//! * A factor writes its *unwhitened* residual and Jacobians (one per key,
//!   with respect to that key's tangent) into the caller's buffers; the [`NoiseModel`] whitens them and
//!   applies the robust kernel, so factors never do.

mod between_factor;
mod conditioned_factor;
mod elimination;
mod factor;
mod imu_factor;
mod key;
mod linearization;
mod marginalization;
mod marginals;
mod noise;
mod object_factors;
mod optimizer;
mod prior_factor;
mod sliding_window;
mod values;
mod variable_index;

pub use between_factor::BetweenFactor;
pub use conditioned_factor::ConditionedFactor;
pub use elimination::SolverWorkspace;
pub use factor::{Factor, FactorError, JacobiansMut, Linearization, check_factor_jacobians};
pub use imu_factor::{BiasRandomWalkFactor, ImuFactor, ImuFactorJacobians, Vector9};
pub use key::Key;
pub use linearization::{NormalEquations, linearize_normal_equations, total_cost};
pub use marginalization::{
    MarginalPriorFactor, MarginalizationConfig, MarginalizationError, marginalize,
};
pub use marginals::marginal_covariance;
pub use noise::{NoiseModel, RobustKernel};
pub use object_factors::{ObjectMotionFactor, ObjectObservationFactor, SmoothMotionFactor};
pub use optimizer::{
    FactorGraph, SolverConfig, SolverError, SolverReport, gauss_newton_step, optimize,
    optimize_with,
};
pub use prior_factor::PriorFactor;
pub use sliding_window::{SlidingWindowSmoother, WindowError};
pub use values::{Values, Variable};
pub use variable_index::VariableIndex;
