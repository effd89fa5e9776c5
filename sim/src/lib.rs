//! LIMOT simulation testbed: scenario generation, traffic, a rolling 64-beam
//! LiDAR ray-cast against a rapier3d world, a noisy IMU, a detector model and
//! exact ground truth. Knows nothing about estimation.
//!
//! The entry points are at the crate root: a [`ScenarioSpec`] (a TOML file or
//! a built-in scenario) becomes a [`Simulation`], which renders frames or
//! writes a dataset directory; a [`Dataset`] reads one back. The concept
//! modules hold the rest:
//!
//! - [`scenario`]: the spec and its tables, with validation;
//! - [`scene`]: what a generated scenario contains (ground, statics, agents,
//!   ego) and the trajectories they follow;
//! - [`traffic`]: the vehicle model that moves the agents;
//! - [`sensors`]: LiDAR, IMU and detector models;
//! - [`record`]: the dataset format (writer, reader, scan codec);
//! - [`replay`]: digital twins of recorded drives (a replay input and the
//!   builder of its scene).

#![warn(missing_docs)]

mod fast_trig;
pub mod record;
pub mod replay;
mod roughness;
pub mod scenario;
pub mod scene;
pub mod sensors;
mod simulation;
pub mod traffic;
mod trajectory;
mod world;

pub use record::{Dataset, DatasetWriter, RecordError};
pub use scenario::{Family, ScenarioError, ScenarioSpec};
pub use simulation::{SimulatedFrame, Simulation, SimulationError};
