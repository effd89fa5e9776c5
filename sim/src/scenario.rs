//! Scenario specifications (TOML files in `scenarios/`), their validation
//! with file/line/field error reporting, and the seeded generators that turn
//! a spec into a [`Scene`].
//!
//! A spec names a family (highway or urban), a seed and the sensor settings;
//! the family table (`[highway]` or `[urban]`) holds the road and traffic
//! parameters. Building is deterministic: all randomness comes from a
//! `ChaCha8Rng` seeded with `seed`, so the same spec always gives the same
//! scene.

mod common;
mod highway;
mod roadside;
mod streetscape;
mod urban;

use crate::detector::DetectorConfig;
use crate::imu::ImuConfig;
use crate::lidar::LidarConfig;
use crate::scene::Scene;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Scenario family: which generator builds the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Family {
    Highway,
    Urban,
}

/// The ego vehicle: where it drives and how its sensors are mounted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EgoSpec {
    /// Lane counted from the right edge of the ego's carriageway, 0 = rightmost.
    pub lane: usize,
    /// Desired cruising speed; unset = the family's typical speed (highway:
    /// middle of the speed range, urban: middle of the car speed range).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub speed_mps: Option<f64>,
    /// The ego stands still until this time so an estimator can initialise.
    pub depart_s: f64,
    /// Car body length, width, height.
    pub size_lwh_m: [f64; 3],
    /// LiDAR height above the ground (KITTI: 1.73 m).
    pub lidar_height_m: f64,
    /// How far the LiDAR sits ahead of the body box centre (KITTI: ~0.27 m).
    pub lidar_ahead_of_center_m: f64,
    /// Translation of T_lidar_imu: the IMU origin in the LiDAR frame (KITTI's
    /// Tr_imu_velo: the OXTS unit is 0.81 m behind, 0.32 m left of and 0.80 m
    /// below the Velodyne). The rotation is identity.
    pub imu_in_lidar_m: [f64; 3],
}

impl Default for EgoSpec {
    fn default() -> Self {
        EgoSpec {
            lane: 1,
            speed_mps: None,
            depart_s: 1.0,
            size_lwh_m: [4.8, 1.8, 1.5],
            lidar_height_m: 1.73,
            lidar_ahead_of_center_m: 0.27,
            imu_in_lidar_m: [-0.81, 0.32, -0.80],
        }
    }
}

/// Ground height field: a plane with a small slope plus a few gentle waves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroundParams {
    /// Slope of the plane, per cent (1 % = 1 m rise per 100 m), drawn uniformly.
    pub slope_min_percent: f64,
    pub slope_max_percent: f64,
    /// Number of sinusoidal undulations.
    pub undulations: usize,
    pub amplitude_min_m: f64,
    pub amplitude_max_m: f64,
    pub wavelength_min_m: f64,
    pub wavelength_max_m: f64,
    /// Each undulation's amplitude is capped so that its own grade stays below
    /// this (keeps roads driveable for short wavelengths), per cent.
    pub undulation_grade_max_percent: f64,
    /// Road roughness: ISO 8608 displacement PSD at 0.1 cycles/m, m³
    /// (class A 16e-6, B 64e-6, C 256e-6); 0 = a smooth road.
    pub roughness_psd_m3: f64,
    /// Wavelength band of the roughness, m (0.25..=64).
    pub roughness_wavelength_min_m: f64,
    pub roughness_wavelength_max_m: f64,
    /// Camber: the road's centre line is this much above the terrain far
    /// to its sides (a Gaussian ridge); 0 = none.
    pub crown_height_m: f64,
    /// Standard deviation of the crown's ridge, m: the steepest cross slope
    /// (0.61 height / width) is this far from the centre line.
    pub crown_width_m: f64,
}

impl Default for GroundParams {
    fn default() -> Self {
        GroundParams {
            slope_min_percent: 1.0,
            slope_max_percent: 2.0,
            undulations: 3,
            amplitude_min_m: 0.2,
            amplitude_max_m: 1.0,
            wavelength_min_m: 100.0,
            wavelength_max_m: 400.0,
            undulation_grade_max_percent: 2.0,
            roughness_psd_m3: 96e-6,
            roughness_wavelength_min_m: 0.3,
            roughness_wavelength_max_m: 20.0,
            crown_height_m: 0.25,
            crown_width_m: 7.0,
        }
    }
}

/// The `[highway]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HighwayParams {
    /// Lanes in the ego's direction, 3..=5.
    pub lanes: usize,
    pub lane_width_m: f64,
    /// Other vehicles (cars and trucks).
    pub vehicles: usize,
    /// Desired speeds are drawn uniformly from [speed_min_mps, speed_max_mps].
    pub speed_min_mps: f64,
    pub speed_max_mps: f64,
    /// Fraction of the vehicles that are trucks.
    pub truck_fraction: f64,
    /// Trucks' desired speeds are capped at this.
    pub truck_speed_max_mps: f64,
    /// Number of lane-change requests spread over the run.
    pub lane_changes: usize,
    /// Length of the initial straight (the LiDAR-degenerate stretch).
    pub straight_length_m: f64,
    /// Radii of the gentle curves that follow, drawn uniformly.
    pub curve_radius_min_m: f64,
    pub curve_radius_max_m: f64,
    /// Vehicles start between this far behind and `spawn_ahead_m` ahead of the ego.
    pub spawn_behind_m: f64,
    pub spawn_ahead_m: f64,
    /// Length of one straight guard rail segment.
    pub guard_rail_segment_m: f64,
    /// Distance between light poles along the road.
    pub pole_spacing_m: f64,
    /// Distance between the posts under the rails' beams; 0 = solid rails
    /// down to the ground, no posts.
    pub rail_post_spacing_m: f64,
    /// Distance between the reflector posts on the right shoulder's edge; 0 = none.
    pub delineator_spacing_m: f64,
    /// Shares of the right roadside (in stretches of 80-300 m) with a noise
    /// wall and with a cutting (an earth slope rising 2-6 m); the rest is
    /// open verge. Their sum is at most 1.
    pub noise_wall_fraction: f64,
    pub cutting_fraction: f64,
    /// Mean spacing of bushes and trees on the verges and in the median; 0 = none.
    pub vegetation_spacing_m: f64,
    /// Distance between the posts of the right-of-way fence beyond open
    /// verges; 0 = no fence.
    pub fence_post_spacing_m: f64,
    /// Mean distance between overpasses, between sign gantries and between
    /// roadside sign boards (distance and speed signs); 0 = none.
    pub overpass_spacing_m: f64,
    pub gantry_spacing_m: f64,
    pub sign_spacing_m: f64,
}

impl Default for HighwayParams {
    fn default() -> Self {
        HighwayParams {
            lanes: 4,
            lane_width_m: 3.7,
            vehicles: 40,
            speed_min_mps: 20.0,
            speed_max_mps: 33.0,
            truck_fraction: 0.2,
            truck_speed_max_mps: 25.0,
            lane_changes: 10,
            straight_length_m: 800.0,
            curve_radius_min_m: 800.0,
            curve_radius_max_m: 2500.0,
            spawn_behind_m: 300.0,
            spawn_ahead_m: 600.0,
            guard_rail_segment_m: 12.0,
            pole_spacing_m: 60.0,
            rail_post_spacing_m: 2.0,
            delineator_spacing_m: 50.0,
            noise_wall_fraction: 0.3,
            cutting_fraction: 0.3,
            vegetation_spacing_m: 8.0,
            fence_post_spacing_m: 3.0,
            overpass_spacing_m: 800.0,
            gantry_spacing_m: 1000.0,
            sign_spacing_m: 200.0,
        }
    }
}

/// The `[urban]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UrbanParams {
    /// Lanes per direction on the main street, 1..=2.
    pub lanes_per_direction: usize,
    pub lane_width_m: f64,
    /// Bike lane between the traffic lanes and the parking strip, each side.
    pub bike_lane_width_m: f64,
    /// Parking strip along each kerb.
    pub parking_width_m: f64,
    pub sidewalk_width_m: f64,
    /// Distance between cross streets, drawn uniformly.
    pub block_length_min_m: f64,
    pub block_length_max_m: f64,
    pub cross_street_width_m: f64,
    /// Moving cars, both directions together.
    pub moving_cars: usize,
    pub car_speed_min_mps: f64,
    pub car_speed_max_mps: f64,
    pub cyclists: usize,
    pub cyclist_speed_min_mps: f64,
    pub cyclist_speed_max_mps: f64,
    pub pedestrians: usize,
    pub pedestrian_speed_min_mps: f64,
    pub pedestrian_speed_max_mps: f64,
    /// Fraction of the parking places that hold a car.
    pub parking_occupancy: f64,
    /// Traffic signal period and the red part of it, at every intersection.
    pub signal_cycle_s: f64,
    pub red_s: f64,
    /// Cars on the cross streets of every intersection the ego's LiDAR can
    /// see (both directions together); they cross while the main street is red.
    pub cross_cars_per_intersection: usize,
    /// Mean spacing of trees and of light poles along each sidewalk.
    pub tree_spacing_m: f64,
    pub pole_spacing_m: f64,
    /// Probability that a building lot holds a building, in [0, 1]; each lot
    /// decides independently. Below 1 the parked cars become the main
    /// structure along the street. 1 = a building on every lot.
    pub building_fraction: f64,
    /// Street furniture on the sidewalks: traffic signs, bollards, bins,
    /// benches and bus shelters (the sidewalks and their kerbs are always there).
    pub street_furniture: bool,
}

impl Default for UrbanParams {
    fn default() -> Self {
        UrbanParams {
            lanes_per_direction: 2,
            lane_width_m: 3.3,
            bike_lane_width_m: 1.6,
            parking_width_m: 2.4,
            sidewalk_width_m: 4.0,
            block_length_min_m: 80.0,
            block_length_max_m: 120.0,
            cross_street_width_m: 14.0,
            moving_cars: 14,
            car_speed_min_mps: 8.0,
            car_speed_max_mps: 15.0,
            cyclists: 4,
            cyclist_speed_min_mps: 4.0,
            cyclist_speed_max_mps: 6.0,
            pedestrians: 12,
            pedestrian_speed_min_mps: 1.2,
            pedestrian_speed_max_mps: 1.5,
            parking_occupancy: 0.6,
            signal_cycle_s: 40.0,
            red_s: 15.0,
            cross_cars_per_intersection: 2,
            tree_spacing_m: 15.0,
            pole_spacing_m: 30.0,
            building_fraction: 1.0,
            street_furniture: true,
        }
    }
}

/// A complete scenario description, the contents of one scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    pub name: String,
    pub family: Family,
    pub seed: u64,
    pub duration_s: f64,
    #[serde(default)]
    pub lidar: LidarConfig,
    #[serde(default)]
    pub imu: ImuConfig,
    #[serde(default)]
    pub detector: DetectorConfig,
    #[serde(default)]
    pub ego: EgoSpec,
    #[serde(default)]
    pub ground: GroundParams,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub highway: Option<HighwayParams>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub urban: Option<UrbanParams>,
}

/// Why a scenario could not be loaded or built.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("{}: cannot read scenario file: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}:{line}:{column}: TOML syntax error: {message}", path.display())]
    Syntax {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    #[error("{}field `{field}`: {message}", location(path.as_deref(), *line))]
    Invalid {
        path: Option<PathBuf>,
        line: Option<usize>,
        /// Dotted path of the offending field, e.g. `highway.speed_max_mps`.
        field: String,
        message: String,
    },
    /// The generated road or traffic was rejected by the traffic model.
    #[error("scenario `{scenario}`: traffic: {source}")]
    Traffic {
        scenario: String,
        #[source]
        source: crate::traffic::TrafficError,
    },
    /// A generator invariant failed (a bug, not bad input).
    #[error("scenario `{scenario}`: {message}")]
    Build { scenario: String, message: String },
}

fn location(path: Option<&Path>, line: Option<usize>) -> String {
    match (path, line) {
        (Some(p), Some(l)) => format!("{}:{l}: ", p.display()),
        (Some(p), None) => format!("{}: ", p.display()),
        (None, Some(l)) => format!("line {l}: "),
        (None, None) => String::new(),
    }
}

fn invalid(field: impl Into<String>, message: impl Into<String>) -> ScenarioError {
    ScenarioError::Invalid {
        path: None,
        line: None,
        field: field.into(),
        message: message.into(),
    }
}

/// The built-in urban streets: rougher than the default (highway) road,
/// between ISO 8608 classes B and C.
fn urban_ground() -> GroundParams {
    GroundParams {
        roughness_psd_m3: 128e-6,
        ..GroundParams::default()
    }
}

const BUILTIN_NAMES: &[&str] = &["highway", "urban", "highway-dense", "urban-parked"];

impl ScenarioSpec {
    /// The default scenarios, equal to `scenarios/<name>.toml`.
    pub fn builtin(name: &str) -> Option<ScenarioSpec> {
        let base = |family, seed| ScenarioSpec {
            name: name.to_string(),
            family,
            seed,
            duration_s: 60.0,
            lidar: LidarConfig::default(),
            imu: ImuConfig::default(),
            detector: DetectorConfig::default(),
            ego: EgoSpec::default(),
            ground: GroundParams::default(),
            highway: None,
            urban: None,
        };
        match name {
            "highway" => Some(ScenarioSpec {
                highway: Some(HighwayParams::default()),
                ..base(Family::Highway, 1)
            }),
            "urban" => Some(ScenarioSpec {
                ground: urban_ground(),
                urban: Some(UrbanParams::default()),
                ..base(Family::Urban, 2)
            }),
            // Congested highway: the ego drives at 12 m/s among cars and many
            // trucks at 9-14 m/s, as densely as the safe gaps allow, so that
            // vehicles pacing the ego fill much of the view (the case where
            // moving objects corrupt LiDAR odometry, KITTI tracking 0020).
            "highway-dense" => Some(ScenarioSpec {
                ego: EgoSpec {
                    speed_mps: Some(12.0),
                    ..EgoSpec::default()
                },
                highway: Some(HighwayParams {
                    vehicles: 32,
                    speed_min_mps: 9.0,
                    speed_max_mps: 14.0,
                    truck_fraction: 0.4,
                    truck_speed_max_mps: 13.0,
                    spawn_behind_m: 150.0,
                    spawn_ahead_m: 250.0,
                    // a bare roadside, so that pacing traffic is much of
                    // what the LiDAR sees: concrete barriers (no posts),
                    // empty verges, only the light poles and their signs
                    rail_post_spacing_m: 0.0,
                    delineator_spacing_m: 0.0,
                    noise_wall_fraction: 0.0,
                    cutting_fraction: 0.0,
                    vegetation_spacing_m: 0.0,
                    fence_post_spacing_m: 0.0,
                    overpass_spacing_m: 0.0,
                    gantry_spacing_m: 0.0,
                    sign_spacing_m: 0.0,
                    ..HighwayParams::default()
                }),
                ..base(Family::Highway, 1)
            }),
            // A street without buildings, every parking place taken, few
            // trees and poles and no street furniture: parked cars are the
            // main structure, so dropping every detected box (allfilt)
            // throws most of the map away.
            "urban-parked" => Some(ScenarioSpec {
                urban: Some(UrbanParams {
                    building_fraction: 0.0,
                    street_furniture: false,
                    parking_occupancy: 1.0,
                    tree_spacing_m: 60.0,
                    pole_spacing_m: 60.0,
                    ..UrbanParams::default()
                }),
                ground: urban_ground(),
                ..base(Family::Urban, 1)
            }),
            _ => None,
        }
    }

    pub fn builtin_names() -> &'static [&'static str] {
        BUILTIN_NAMES
    }

    /// Parses and validates a scenario; `origin` names the file in errors.
    pub fn parse(text: &str, origin: &Path) -> Result<ScenarioSpec, ScenarioError> {
        let spec: ScenarioSpec = match toml::from_str(text) {
            Ok(spec) => spec,
            Err(e) => return Err(toml_error(text, origin, &e)),
        };
        spec.validate().map_err(|e| match e {
            ScenarioError::Invalid { field, message, .. } => ScenarioError::Invalid {
                path: Some(origin.to_path_buf()),
                line: line_of_field(text, &field),
                field,
                message,
            },
            other => other,
        })?;
        Ok(spec)
    }

    pub fn load(path: &Path) -> Result<ScenarioSpec, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        ScenarioSpec::parse(&text, path)
    }

    /// The spec as TOML; `parse(&to_toml(s))` gives `s` back for valid specs.
    /// Serialising plain numbers, strings, arrays and tables does not fail;
    /// should toml ever refuse, the text is a TOML comment saying why.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_else(|e| format!("# cannot write this scenario: {e}\n"))
    }

    /// Builds the scene: validates, then runs the family's generator with a
    /// `ChaCha8Rng` seeded by `seed` (same spec, same scene).
    pub fn build(&self) -> Result<Scene, ScenarioError> {
        self.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        match self.family {
            Family::Highway => highway::build(self, &mut rng),
            Family::Urban => urban::build(self, &mut rng),
        }
    }

    /// The family parameters in effect (the table, or its defaults).
    pub fn highway_params(&self) -> HighwayParams {
        self.highway.clone().unwrap_or_default()
    }

    pub fn urban_params(&self) -> UrbanParams {
        self.urban.clone().unwrap_or_default()
    }

    /// Desired ego speed in effect.
    pub fn ego_speed_mps(&self) -> f64 {
        self.ego.speed_mps.unwrap_or_else(|| match self.family {
            Family::Highway => {
                let h = self.highway_params();
                0.5 * (h.speed_min_mps + h.speed_max_mps)
            }
            Family::Urban => {
                let u = self.urban_params();
                0.5 * (u.car_speed_min_mps + u.car_speed_max_mps)
            }
        })
    }

    /// Checks every field; errors name the dotted field (no line: `parse`
    /// adds file and line).
    pub fn validate(&self) -> Result<(), ScenarioError> {
        if self.name.trim().is_empty() {
            return Err(invalid("name", "must not be empty"));
        }
        positive_finite("duration_s", self.duration_s)?;
        if self.duration_s > 3600.0 {
            return Err(invalid("duration_s", "must be at most 3600 s"));
        }
        validate_lidar(&self.lidar)?;
        self.imu.validate().map_err(|e| match e {
            crate::imu::ImuError::BadConfig { field, .. } => {
                invalid(format!("imu.{field}"), e.to_string())
            }
            other => invalid("imu", other.to_string()),
        })?;
        self.detector.validate().map_err(|e| match &e {
            crate::detector::DetectorError::BadConfig { field, .. } => {
                invalid(format!("detector.{field}"), e.to_string())
            }
            _ => invalid("detector", e.to_string()),
        })?;
        validate_ground(&self.ground)?;
        match self.family {
            Family::Highway => {
                if self.urban.is_some() {
                    return Err(invalid("urban", "given for a highway scenario"));
                }
                let h = self.highway_params();
                validate_highway(&h)?;
                if self.ego.lane >= h.lanes {
                    return Err(invalid(
                        "ego.lane",
                        format!("must be below highway.lanes = {}", h.lanes),
                    ));
                }
            }
            Family::Urban => {
                if self.highway.is_some() {
                    return Err(invalid("highway", "given for an urban scenario"));
                }
                let u = self.urban_params();
                validate_urban(&u, self.duration_s)?;
                if self.ego.lane >= u.lanes_per_direction {
                    return Err(invalid(
                        "ego.lane",
                        format!(
                            "must be below urban.lanes_per_direction = {}",
                            u.lanes_per_direction
                        ),
                    ));
                }
            }
        }
        validate_ego(&self.ego, self.duration_s)?;
        let ego_speed = self.ego_speed_mps();
        if !(ego_speed.is_finite() && ego_speed > 0.0 && ego_speed <= 60.0) {
            return Err(invalid("ego.speed_mps", "must be in (0, 60] m/s"));
        }
        Ok(())
    }
}

fn positive_finite(field: &str, value: f64) -> Result<(), ScenarioError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("= {value}: must be finite and positive"),
        ))
    }
}

/// Checks `min <= value <= max` (and finiteness).
fn in_range(field: &str, value: f64, min: f64, max: f64) -> Result<(), ScenarioError> {
    if value.is_finite() && (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("= {value}: must be in [{min}, {max}]"),
        ))
    }
}

fn count_in_range(field: &str, value: usize, min: usize, max: usize) -> Result<(), ScenarioError> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("= {value}: must be in {min}..={max}"),
        ))
    }
}

/// Checks a `[min, max]` pair: both in range and `min <= max`.
fn range_pair(
    table: &str,
    (min_name, min): (&str, f64),
    (max_name, max): (&str, f64),
    bounds: (f64, f64),
) -> Result<(), ScenarioError> {
    in_range(&format!("{table}.{min_name}"), min, bounds.0, bounds.1)?;
    in_range(&format!("{table}.{max_name}"), max, bounds.0, bounds.1)?;
    if min > max {
        return Err(invalid(
            format!("{table}.{min_name}"),
            format!("= {min} is greater than {max_name} = {max}"),
        ));
    }
    Ok(())
}

fn validate_lidar(l: &LidarConfig) -> Result<(), ScenarioError> {
    in_range("lidar.rotation_hz", l.rotation_hz, 1.0, 50.0)?;
    count_in_range("lidar.azimuth_steps", l.azimuth_steps, 16, 20_000)?;
    range_pair(
        "lidar",
        ("min_range_m", l.min_range_m),
        ("max_range_m", l.max_range_m),
        (0.0, 1000.0),
    )?;
    positive_finite("lidar.max_range_m", l.max_range_m)?;
    in_range("lidar.range_noise_sigma_m", l.range_noise_sigma_m, 0.0, 1.0)?;
    in_range("lidar.dropout_probability", l.dropout_probability, 0.0, 1.0)
}

fn validate_ground(g: &GroundParams) -> Result<(), ScenarioError> {
    range_pair(
        "ground",
        ("slope_min_percent", g.slope_min_percent),
        ("slope_max_percent", g.slope_max_percent),
        (0.0, 8.0),
    )?;
    count_in_range("ground.undulations", g.undulations, 0, 8)?;
    range_pair(
        "ground",
        ("amplitude_min_m", g.amplitude_min_m),
        ("amplitude_max_m", g.amplitude_max_m),
        (0.0, 5.0),
    )?;
    range_pair(
        "ground",
        ("wavelength_min_m", g.wavelength_min_m),
        ("wavelength_max_m", g.wavelength_max_m),
        (20.0, 10_000.0),
    )?;
    in_range(
        "ground.undulation_grade_max_percent",
        g.undulation_grade_max_percent,
        0.0,
        8.0,
    )?;
    in_range("ground.roughness_psd_m3", g.roughness_psd_m3, 0.0, 0.01)?;
    range_pair(
        "ground",
        ("roughness_wavelength_min_m", g.roughness_wavelength_min_m),
        ("roughness_wavelength_max_m", g.roughness_wavelength_max_m),
        (0.25, 64.0),
    )?;
    in_range("ground.crown_height_m", g.crown_height_m, 0.0, 2.0)?;
    in_range("ground.crown_width_m", g.crown_width_m, 1.0, 100.0)
}

fn validate_ego(e: &EgoSpec, duration_s: f64) -> Result<(), ScenarioError> {
    in_range("ego.depart_s", e.depart_s, 0.0, duration_s)?;
    for (i, axis) in ["length", "width", "height"].iter().enumerate() {
        let v = e.size_lwh_m[i];
        if !(v.is_finite() && v > 0.5 && v <= 20.0) {
            return Err(invalid(
                "ego.size_lwh_m",
                format!("{axis} = {v}: must be in (0.5, 20] m"),
            ));
        }
    }
    in_range("ego.lidar_height_m", e.lidar_height_m, 0.3, 5.0)?;
    if e.lidar_height_m <= 0.5 * e.size_lwh_m[2] {
        return Err(invalid(
            "ego.lidar_height_m",
            "must be above the centre of the car body",
        ));
    }
    let half_length = 0.5 * e.size_lwh_m[0];
    in_range(
        "ego.lidar_ahead_of_center_m",
        e.lidar_ahead_of_center_m,
        -half_length,
        half_length,
    )?;
    for v in e.imu_in_lidar_m {
        if !(v.is_finite() && v.abs() <= 5.0) {
            return Err(invalid(
                "ego.imu_in_lidar_m",
                format!("component {v}: must be finite and within 5 m"),
            ));
        }
    }
    Ok(())
}

fn validate_highway(h: &HighwayParams) -> Result<(), ScenarioError> {
    count_in_range("highway.lanes", h.lanes, 3, 5)?;
    in_range("highway.lane_width_m", h.lane_width_m, 2.5, 5.0)?;
    count_in_range("highway.vehicles", h.vehicles, 0, 200)?;
    range_pair(
        "highway",
        ("speed_min_mps", h.speed_min_mps),
        ("speed_max_mps", h.speed_max_mps),
        (0.0, 60.0),
    )?;
    positive_finite("highway.speed_min_mps", h.speed_min_mps)?;
    in_range("highway.truck_fraction", h.truck_fraction, 0.0, 1.0)?;
    in_range(
        "highway.truck_speed_max_mps",
        h.truck_speed_max_mps,
        h.speed_min_mps,
        60.0,
    )?;
    count_in_range("highway.lane_changes", h.lane_changes, 0, 1000)?;
    in_range(
        "highway.straight_length_m",
        h.straight_length_m,
        0.0,
        20_000.0,
    )?;
    range_pair(
        "highway",
        ("curve_radius_min_m", h.curve_radius_min_m),
        ("curve_radius_max_m", h.curve_radius_max_m),
        (300.0, 1e6),
    )?;
    in_range("highway.spawn_behind_m", h.spawn_behind_m, 0.0, 5000.0)?;
    in_range("highway.spawn_ahead_m", h.spawn_ahead_m, 0.0, 20_000.0)?;
    in_range(
        "highway.guard_rail_segment_m",
        h.guard_rail_segment_m,
        2.0,
        50.0,
    )?;
    in_range("highway.pole_spacing_m", h.pole_spacing_m, 10.0, 10_000.0)?;
    for (field, value) in [
        ("highway.rail_post_spacing_m", h.rail_post_spacing_m),
        ("highway.delineator_spacing_m", h.delineator_spacing_m),
        ("highway.vegetation_spacing_m", h.vegetation_spacing_m),
        ("highway.fence_post_spacing_m", h.fence_post_spacing_m),
    ] {
        if value != 0.0 {
            in_range(field, value, 1.0, 1000.0)?;
        }
    }
    for (field, value) in [
        ("highway.overpass_spacing_m", h.overpass_spacing_m),
        ("highway.gantry_spacing_m", h.gantry_spacing_m),
        ("highway.sign_spacing_m", h.sign_spacing_m),
    ] {
        if value != 0.0 {
            in_range(field, value, 100.0, 100_000.0)?;
        }
    }
    in_range(
        "highway.noise_wall_fraction",
        h.noise_wall_fraction,
        0.0,
        1.0,
    )?;
    in_range("highway.cutting_fraction", h.cutting_fraction, 0.0, 1.0)?;
    if h.noise_wall_fraction + h.cutting_fraction > 1.0 {
        return Err(invalid(
            "highway.cutting_fraction",
            "noise_wall_fraction + cutting_fraction must be at most 1",
        ));
    }
    // impossible geometry: the vehicles must fit into the spawn zone with
    // safe gaps (the zone around the ego stays free in its lane)
    let capacity = highway_capacity(h);
    if h.vehicles > capacity {
        return Err(invalid(
            "highway.vehicles",
            format!(
                "= {}: at most {capacity} vehicles fit with safe gaps into {} lanes x {} m \
                 (raise spawn_behind_m/spawn_ahead_m or lanes)",
                h.vehicles,
                h.lanes,
                h.spawn_behind_m + h.spawn_ahead_m
            ),
        ));
    }
    Ok(())
}

/// Safe spacing between the centres of two vehicles in one lane at spawn:
/// a truck length plus a 1.5 s headway at the top speed.
pub(crate) fn highway_min_spacing_m(h: &HighwayParams) -> f64 {
    HIGHWAY_TRUCK_LENGTH_M + 1.5 * h.speed_max_mps + 5.0
}

pub(crate) const HIGHWAY_TRUCK_LENGTH_M: f64 = 16.5;

/// How many vehicles fit into the spawn zone: per lane, the zone divided by
/// the minimum spacing, less the slots the ego's free zone takes in its lane.
pub(crate) fn highway_capacity(h: &HighwayParams) -> usize {
    let span = h.spawn_behind_m + h.spawn_ahead_m;
    let per_lane = (span / highway_min_spacing_m(h)).floor() as usize;
    (per_lane * h.lanes).saturating_sub(HIGHWAY_EGO_FREE_SLOTS)
}

/// Slots kept free around the ego in its own lane.
pub(crate) const HIGHWAY_EGO_FREE_SLOTS: usize = 4;

fn validate_urban(u: &UrbanParams, duration_s: f64) -> Result<(), ScenarioError> {
    count_in_range("urban.lanes_per_direction", u.lanes_per_direction, 1, 2)?;
    in_range("urban.lane_width_m", u.lane_width_m, 2.5, 5.0)?;
    in_range("urban.bike_lane_width_m", u.bike_lane_width_m, 1.0, 4.0)?;
    in_range("urban.parking_width_m", u.parking_width_m, 2.2, 5.0)?;
    in_range("urban.sidewalk_width_m", u.sidewalk_width_m, 3.0, 10.0)?;
    range_pair(
        "urban",
        ("block_length_min_m", u.block_length_min_m),
        ("block_length_max_m", u.block_length_max_m),
        (40.0, 1000.0),
    )?;
    in_range(
        "urban.cross_street_width_m",
        u.cross_street_width_m,
        6.0,
        40.0,
    )?;
    if u.cross_street_width_m + 20.0 > u.block_length_min_m {
        return Err(invalid(
            "urban.cross_street_width_m",
            "cross streets leave no room between intersections (need block_length_min_m >= \
             cross_street_width_m + 20)",
        ));
    }
    count_in_range("urban.moving_cars", u.moving_cars, 0, 200)?;
    range_pair(
        "urban",
        ("car_speed_min_mps", u.car_speed_min_mps),
        ("car_speed_max_mps", u.car_speed_max_mps),
        (0.5, 25.0),
    )?;
    count_in_range("urban.cyclists", u.cyclists, 0, 100)?;
    range_pair(
        "urban",
        ("cyclist_speed_min_mps", u.cyclist_speed_min_mps),
        ("cyclist_speed_max_mps", u.cyclist_speed_max_mps),
        (0.5, 12.0),
    )?;
    count_in_range("urban.pedestrians", u.pedestrians, 0, 400)?;
    range_pair(
        "urban",
        ("pedestrian_speed_min_mps", u.pedestrian_speed_min_mps),
        ("pedestrian_speed_max_mps", u.pedestrian_speed_max_mps),
        (0.2, 3.0),
    )?;
    in_range("urban.parking_occupancy", u.parking_occupancy, 0.0, 1.0)?;
    in_range("urban.building_fraction", u.building_fraction, 0.0, 1.0)?;
    in_range("urban.signal_cycle_s", u.signal_cycle_s, 10.0, 600.0)?;
    in_range("urban.red_s", u.red_s, 0.0, u.signal_cycle_s * 0.8)?;
    count_in_range(
        "urban.cross_cars_per_intersection",
        u.cross_cars_per_intersection,
        0,
        URBAN_CROSS_CARS_MAX,
    )?;
    if u.cross_cars_per_intersection > 0 {
        // a cross street holds one lane per direction between two sidewalks
        let needed = 2.0 * u.lane_width_m + 2.0 * URBAN_CROSS_SIDEWALK_MIN_M;
        if u.cross_street_width_m < needed {
            return Err(invalid(
                "urban.cross_street_width_m",
                format!(
                    "= {}: cross traffic needs at least {needed} m (2 x lane_width_m + 2 x \
                     {URBAN_CROSS_SIDEWALK_MIN_M} m sidewalk); or set \
                     cross_cars_per_intersection = 0",
                    u.cross_street_width_m
                ),
            ));
        }
        // the cross street's green is the main street's red less an all-red
        // clearance at each end
        let needed = 2.0 * URBAN_ALL_RED_S + URBAN_CROSS_GREEN_MIN_S;
        if u.red_s < needed {
            return Err(invalid(
                "urban.red_s",
                format!(
                    "= {}: cross traffic needs a red of at least {needed} s (two {} s all-red \
                     clearances and {} s of cross-street green); or set \
                     cross_cars_per_intersection = 0",
                    u.red_s, URBAN_ALL_RED_S, URBAN_CROSS_GREEN_MIN_S
                ),
            ));
        }
    }
    in_range("urban.tree_spacing_m", u.tree_spacing_m, 5.0, 10_000.0)?;
    in_range("urban.pole_spacing_m", u.pole_spacing_m, 5.0, 10_000.0)?;
    // impossible geometry: the agents must fit into their spawn zones
    let spawn = urban_spawn_length_m(u, duration_s);
    // (field, count, lanes per direction, spacing); half of each kind drives
    // each way, the odd one in the ego's direction
    let checks = [
        (
            "urban.moving_cars",
            u.moving_cars,
            u.lanes_per_direction,
            URBAN_CAR_SPACING_M,
        ),
        ("urban.cyclists", u.cyclists, 1, URBAN_CYCLIST_SPACING_M),
        (
            "urban.pedestrians",
            u.pedestrians,
            2,
            URBAN_PEDESTRIAN_SPACING_M,
        ),
    ];
    for (field, count, lanes, spacing) in checks {
        let per_lane = (spawn / spacing).floor() as usize;
        // moving cars leave the slots around the ego in its lane free
        let reserved = if field == "urban.moving_cars" {
            URBAN_EGO_FREE_SLOTS
        } else {
            0
        };
        let capacity = (lanes * per_lane).saturating_sub(reserved);
        if count.div_ceil(2) > capacity {
            return Err(invalid(
                field,
                format!(
                    "= {count}: at most {} fit with safe gaps into {lanes} lanes per direction x \
                     {spawn:.0} m",
                    2 * capacity
                ),
            ));
        }
    }
    Ok(())
}

/// Cross traffic: at most this many cars per intersection.
pub(crate) const URBAN_CROSS_CARS_MAX: usize = 8;
/// Narrowest sidewalk beside a cross street's two lanes, m.
pub(crate) const URBAN_CROSS_SIDEWALK_MIN_M: f64 = 1.0;
/// All-red clearance between the main street's and the cross street's green,
/// s. A red stop line makes only the vehicles stop that still can comfortably
/// (it acts as yellow + red), so the few that run it clear the intersection
/// in this interval plus the time the other street's first car needs to
/// reach the conflict zone from its stop line (2-3 s).
pub(crate) const URBAN_ALL_RED_S: f64 = 3.0;
/// Shortest useful cross-street green, s.
pub(crate) const URBAN_CROSS_GREEN_MIN_S: f64 = 4.0;

/// Car slots kept free around the ego in its lane (50 m behind, 25 m ahead).
pub(crate) const URBAN_EGO_FREE_SLOTS: usize = 4;

/// Minimum centre spacing of urban agents at spawn, per lane.
pub(crate) const URBAN_CAR_SPACING_M: f64 = 25.0;
pub(crate) const URBAN_CYCLIST_SPACING_M: f64 = 12.0;
pub(crate) const URBAN_PEDESTRIAN_SPACING_M: f64 = 6.0;

/// Length of street along which urban agents start: a few blocks.
pub(crate) fn urban_spawn_length_m(u: &UrbanParams, _duration_s: f64) -> f64 {
    4.0 * u.block_length_min_m
}

/// Wraps a traffic-model error with the scenario's name.
fn traffic_error(spec: &ScenarioSpec, source: crate::traffic::TrafficError) -> ScenarioError {
    ScenarioError::Traffic {
        scenario: spec.name.clone(),
        source,
    }
}

/// Converts a toml deserialisation error into a located error: pure syntax
/// errors become `Syntax`, unknown keys and wrong types become `Invalid`
/// with the dotted field the error span falls into.
fn toml_error(text: &str, origin: &Path, e: &toml::de::Error) -> ScenarioError {
    let message = e.message().trim().to_string();
    let (line, column) = match e.span() {
        Some(span) => line_column(text, span.start),
        None => (1, 1),
    };
    match toml::de::DeTable::parse(text) {
        // the document parses, so this is a schema error: name the field
        Ok(doc) => {
            let field = e
                .span()
                .and_then(|span| field_at(doc.get_ref(), span.start, ""))
                .unwrap_or_else(|| "(document)".to_string());
            ScenarioError::Invalid {
                path: Some(origin.to_path_buf()),
                line: Some(line),
                field,
                message,
            }
        }
        Err(_) => ScenarioError::Syntax {
            path: origin.to_path_buf(),
            line,
            column,
            message,
        },
    }
}

/// 1-based line and column of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let line_start = before
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    (line, offset - line_start + 1)
}

/// The dotted path of the innermost key whose key or value span contains
/// `offset` (a `[table]`'s value span need not cover its body, so every
/// sub-table is searched).
fn field_at(table: &toml::de::DeTable<'_>, offset: usize, prefix: &str) -> Option<String> {
    let inside = |s: std::ops::Range<usize>| s.start <= offset && offset < s.end.max(s.start + 1);
    for (key, value) in table.iter() {
        let path = if prefix.is_empty() {
            key.get_ref().to_string()
        } else {
            format!("{prefix}.{}", key.get_ref())
        };
        if let Some(sub) = value.get_ref().as_table()
            && let Some(inner) = field_at(sub, offset, &path)
        {
            return Some(inner);
        }
        if inside(key.span()) || inside(value.span()) {
            return Some(path);
        }
    }
    None
}

/// The line of a dotted field in the source (or of its nearest enclosing
/// table present in the file when the field itself is absent).
fn line_of_field(text: &str, field: &str) -> Option<usize> {
    let doc = toml::de::DeTable::parse(text).ok()?;
    let mut table = Some(doc.get_ref());
    let mut line = None;
    for segment in field.split('.') {
        let Some((key, value)) = table.and_then(|t| t.iter().find(|(k, _)| k.get_ref() == segment))
        else {
            break;
        };
        line = Some(line_column(text, key.span().start).0);
        table = value.get_ref().as_table();
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_validate_and_round_trip() {
        for name in ScenarioSpec::builtin_names() {
            let spec = ScenarioSpec::builtin(name).unwrap();
            spec.validate().unwrap();
            let text = spec.to_toml();
            let back = ScenarioSpec::parse(&text, Path::new("x.toml")).unwrap();
            assert_eq!(back, spec, "{text}");
        }
        assert!(ScenarioSpec::builtin("nowhere").is_none());
    }

    fn error_of(text: &str) -> String {
        ScenarioSpec::parse(text, Path::new("bad.toml"))
            .unwrap_err()
            .to_string()
    }

    const HEAD: &str = "name = \"t\"\nfamily = \"highway\"\nseed = 3\nduration_s = 20.0\n";

    #[test]
    fn errors_name_file_line_and_field() {
        let unknown = format!("{HEAD}[highway]\nlanes = 4\nwheels = 5\n");
        let msg = error_of(&unknown);
        assert!(msg.contains("bad.toml:7"), "{msg}");
        assert!(msg.contains("highway.wheels"), "{msg}");

        let nan = format!("{HEAD}[highway]\nlanes = 4\nspeed_max_mps = nan\n");
        let msg = error_of(&nan);
        assert!(msg.contains("bad.toml:7"), "{msg}");
        assert!(msg.contains("highway.speed_max_mps"), "{msg}");

        let negative = format!("{HEAD}[highway]\n\nspeed_min_mps = -3.0\n");
        let msg = error_of(&negative);
        assert!(msg.contains("bad.toml:7"), "{msg}");
        assert!(msg.contains("highway.speed_min_mps"), "{msg}");

        let swapped = format!("{HEAD}[highway]\nspeed_min_mps = 30.0\nspeed_max_mps = 21.0\n");
        let msg = error_of(&swapped);
        assert!(msg.contains("bad.toml:6"), "{msg}");
        assert!(msg.contains("highway.speed_min_mps"), "{msg}");

        let lanes = format!("{HEAD}[highway]\nlanes = 7\n");
        let msg = error_of(&lanes);
        assert!(msg.contains("bad.toml:6"), "{msg}");
        assert!(msg.contains("highway.lanes"), "{msg}");

        let wrong_type = format!("{HEAD}[highway]\nlanes = \"four\"\n");
        let msg = error_of(&wrong_type);
        assert!(msg.contains("bad.toml:6"), "{msg}");
        assert!(msg.contains("highway.lanes"), "{msg}");

        let crowded = format!("{HEAD}[highway]\nlanes = 3\nvehicles = 120\n");
        let msg = error_of(&crowded);
        assert!(msg.contains("bad.toml:7"), "{msg}");
        assert!(msg.contains("highway.vehicles"), "{msg}");

        let duration = "name = \"t\"\nfamily = \"urban\"\nseed = 3\nduration_s = -1.0\n";
        let msg = error_of(duration);
        assert!(msg.contains("bad.toml:4"), "{msg}");
        assert!(msg.contains("duration_s"), "{msg}");

        let imu = format!("{HEAD}[imu]\nrate_hz = inf\n");
        let msg = error_of(&imu);
        assert!(msg.contains("bad.toml:6"), "{msg}");
        assert!(msg.contains("imu.rate_hz"), "{msg}");

        let detector = format!("{HEAD}[detector.car]\nposition_sigma_m = -1.0\n");
        let msg = error_of(&detector);
        assert!(msg.contains("bad.toml:6"), "{msg}");
        assert!(msg.contains("detector.car.position_sigma_m"), "{msg}");
    }

    #[test]
    fn full_range_seeds_round_trip() {
        // toml 1 writes and reads u64 beyond i64::MAX
        let mut spec = ScenarioSpec::builtin("urban").unwrap();
        spec.seed = u64::MAX;
        let back = ScenarioSpec::parse(&spec.to_toml(), Path::new("s.toml")).unwrap();
        assert_eq!(back, spec);
    }

    #[test]
    fn syntax_errors_and_missing_files_are_errors() {
        let msg = error_of("name = \"t\"\nfamily = [\n");
        assert!(msg.contains("bad.toml:"), "{msg}");
        let err = ScenarioSpec::load(Path::new("/nonexistent/none.toml")).unwrap_err();
        assert!(matches!(err, ScenarioError::Io { .. }));
        let msg = error_of("family = \"highway\"\nseed = 1\nduration_s = 1.0\n");
        assert!(msg.contains("name"), "{msg}");
    }
}
