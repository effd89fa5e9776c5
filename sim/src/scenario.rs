//! Scenario specifications (TOML files in `scenarios/`), their validation
//! with file/line/field error reporting, and the seeded generators that turn
//! a spec into a [`Scene`].
//!
//! A spec names a family (highway, urban, parking or a KITTI twin), a seed
//! and the sensor settings; the family table (`[highway]`, `[urban]`,
//! `[parking]`, `[kitti]`) holds the road and traffic parameters. Building is deterministic: all randomness comes from a
//! `ChaCha8Rng` seeded with `seed`, so the same spec always gives the same
//! scene.

pub(crate) mod common;
mod highway;
mod parking;
pub(crate) mod roadside;
mod streetscape;
mod urban;

use crate::scene::Scene;
use crate::sensors::DetectorConfig;
use crate::sensors::ImuConfig;
use crate::sensors::LidarConfig;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

mod params;
mod validate;

pub use params::{
    EgoRoute, EgoSpec, Family, GroundParams, HighwayParams, JamParams, KittiParams, OffRampParams,
    OnRampParams, ParkingParams, UrbanParams,
};

/// The ego's desired speed in a car park unless `ego.speed_mps` says
/// otherwise: a brisk walk, m/s.
pub const PARKING_EGO_SPEED_MPS: f64 = 2.0;

/// The tightest half circle the urban ego's U-turn may take (its path's
/// radius; a car's turning circle), m.
pub const U_TURN_MIN_RADIUS_M: f64 = 4.5;

/// Longest simulated time span a scenario may have, s.
pub const MAX_DURATION_S: f64 = 3600.0;
pub(crate) use validate::{
    HIGHWAY_EGO_FREE_SLOTS, HIGHWAY_TRUCK_LENGTH_M, URBAN_ALL_RED_S, URBAN_CAR_SPACING_M,
    URBAN_CYCLIST_SPACING_M, URBAN_PEDESTRIAN_SPACING_M, highway_min_spacing_m,
    urban_spawn_length_m,
};
use validate::{
    positive_finite, validate_ego, validate_ego_lane_changes, validate_ground, validate_highway,
    validate_kitti, validate_lidar, validate_parking, validate_urban,
};

/// A complete scenario description, the contents of one scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    /// Scenario name (written to the dataset's `meta.toml`).
    pub name: String,
    /// Which generator builds the scene.
    pub family: Family,
    /// Seed of every random draw (generator and sensors).
    pub seed: u64,
    /// Simulated time span, s (at most [`MAX_DURATION_S`]).
    pub duration_s: f64,
    #[serde(default)]
    /// The `[lidar]` table.
    pub lidar: LidarConfig,
    #[serde(default)]
    /// The `[imu]` table.
    pub imu: ImuConfig,
    #[serde(default)]
    /// The `[detector]` table.
    pub detector: DetectorConfig,
    #[serde(default)]
    /// The `[ego]` table.
    pub ego: EgoSpec,
    #[serde(default)]
    /// The `[ground]` table.
    pub ground: GroundParams,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    /// The `[highway]` table (highway family only; defaults if absent).
    pub highway: Option<HighwayParams>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    /// The `[urban]` table (urban family only; defaults if absent).
    pub urban: Option<UrbanParams>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    /// The `[parking]` table (parking family only; defaults if absent).
    pub parking: Option<ParkingParams>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    /// The `[kitti]` table (kitti family only, required there).
    pub kitti: Option<KittiParams>,
}

/// Why a scenario could not be loaded or built.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("{}: cannot read scenario file: {source}", path.display())]
    /// The scenario file could not be read.
    Io {
        /// The file.
        path: PathBuf,
        #[source]
        /// The I/O error.
        source: std::io::Error,
    },
    #[error("{}:{line}:{column}: TOML syntax error: {message}", path.display())]
    /// The file is not valid TOML.
    Syntax {
        /// The file.
        path: PathBuf,
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
        /// The parser's message.
        message: String,
    },
    #[error("{}field `{field}`: {message}", location(path.as_deref(), *line))]
    /// A field is unknown, of the wrong type or out of range.
    Invalid {
        /// The file, when the spec came from one.
        path: Option<PathBuf>,
        /// 1-based line of the field, when known.
        line: Option<usize>,
        /// Dotted path of the offending field, e.g. `highway.speed_max_mps`.
        field: String,
        /// What is wrong with the field.
        message: String,
    },
    /// The generated road or traffic was rejected by the traffic model.
    #[error("scenario `{scenario}`: traffic: {source}")]
    Traffic {
        /// Scenario name.
        scenario: String,
        #[source]
        /// The traffic model's error.
        source: crate::traffic::TrafficError,
    },
    /// A generator invariant failed (a bug, not bad input).
    #[error("scenario `{scenario}`: {message}")]
    Build {
        /// Scenario name.
        scenario: String,
        /// The failed invariant.
        message: String,
    },
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

/// A car park's paving: the urban street's texture, no road crown.
fn parking_ground() -> GroundParams {
    GroundParams {
        crown_height_m: 0.0,
        ..urban_ground()
    }
}

const BUILTIN_NAMES: &[&str] = &[
    "highway",
    "highway-dense",
    "highway-jam",
    "highway-exit",
    "urban",
    "urban-parked",
    "urban-left",
    "urban-uturn",
    "urban-give-way",
    "parking-lot",
];

impl ScenarioSpec {
    /// The default scenarios, equal to `scenarios/<name>.toml`.
    pub fn builtin(name: &str) -> Option<ScenarioSpec> {
        let base = |family, seed| ScenarioSpec::with_defaults(name.to_string(), family, seed, 60.0);
        match name {
            // The ego starts on an on-ramp's acceleration lane, merges into
            // the right lane, overtakes on the left and returns.
            "highway" => Some(ScenarioSpec {
                ego: EgoSpec {
                    lane: 0,
                    ..EgoSpec::default()
                },
                highway: Some(HighwayParams {
                    on_ramp: Some(OnRampParams::default()),
                    ego_lane_changes: vec![
                        crate::traffic::LaneChange {
                            t_s: 14.0,
                            to_lane: 1,
                            cooperative: false,
                        },
                        crate::traffic::LaneChange {
                            t_s: 28.0,
                            to_lane: 0,
                            cooperative: false,
                        },
                    ],
                    ..HighwayParams::default()
                }),
                ..base(Family::Highway, 1)
            }),
            // the ego turns right at its first crossing, from the kerb lane
            "urban" => Some(ScenarioSpec {
                ground: urban_ground(),
                urban: Some(UrbanParams::default()),
                ego: EgoSpec {
                    lane: 0,
                    ..EgoSpec::default()
                },
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
                    // the ego keeps its lane among the pacing traffic
                    ego_lane_changes: Vec::new(),
                    ..HighwayParams::default()
                }),
                ..base(Family::Highway, 1)
            }),
            // Stop-and-go: a jam head in every lane stands and pulls away
            // each cycle, and the ego moves with the queue behind it in
            // waves among traffic that stands as often as it moves.
            "highway-jam" => Some(ScenarioSpec {
                highway: Some(HighwayParams {
                    jam: Some(JamParams::default()),
                    // the ego keeps its lane through the waves
                    ego_lane_changes: Vec::new(),
                    ..HighwayParams::default()
                }),
                ..base(Family::Highway, 1)
            }),
            // An off-ramp: the ego keeps the right lane, changes into the
            // deceleration lane and leaves the highway on the ramp's curve.
            "highway-exit" => Some(ScenarioSpec {
                ego: EgoSpec {
                    lane: 0,
                    ..EgoSpec::default()
                },
                highway: Some(HighwayParams {
                    off_ramp: Some(OffRampParams::default()),
                    ego_lane_changes: Vec::new(),
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
                    ego_route: EgoRoute::Straight,
                    ..UrbanParams::default()
                }),
                ground: urban_ground(),
                ..base(Family::Urban, 1)
            }),
            // The default street and seed, the ego turning left at its first
            // crossing from the inner lane, across the oncoming lanes.
            "urban-left" => Some(ScenarioSpec {
                ground: urban_ground(),
                urban: Some(UrbanParams {
                    ego_route: EgoRoute::TurnLeft,
                    ..UrbanParams::default()
                }),
                ego: EgoSpec {
                    lane: UrbanParams::default().lanes_per_direction - 1,
                    ..EgoSpec::default()
                },
                ..base(Family::Urban, 2)
            }),
            // The default street and seed, the ego turning round at its
            // first crossing from the kerb lane into the oncoming kerb lane
            // and driving back along the main street.
            "urban-uturn" => Some(ScenarioSpec {
                ground: urban_ground(),
                urban: Some(UrbanParams {
                    ego_route: EgoRoute::UTurn,
                    ..UrbanParams::default()
                }),
                ego: EgoSpec {
                    lane: 0,
                    ..EgoSpec::default()
                },
                ..base(Family::Urban, 2)
            }),
            // The default street and seed, the ego turning left at its first
            // crossing, which has no lights (nor has every other one, a
            // draw): it yields to the oncoming traffic and the far side's
            // cyclists and pedestrians.
            "urban-give-way" => Some(ScenarioSpec {
                ground: urban_ground(),
                urban: Some(UrbanParams {
                    ego_route: EgoRoute::TurnLeft,
                    ego_turn_give_way: true,
                    give_way_fraction: 0.5,
                    ..UrbanParams::default()
                }),
                ego: EgoSpec {
                    lane: UrbanParams::default().lanes_per_direction - 1,
                    ..EgoSpec::default()
                },
                ..base(Family::Urban, 2)
            }),
            // The default car park: the ego from aisle 1 round the double
            // row into aisle 2 and forwards into a free bay, at walking pace.
            "parking-lot" => Some(ScenarioSpec {
                ground: parking_ground(),
                parking: Some(ParkingParams::default()),
                ego: EgoSpec {
                    lane: 0,
                    ..EgoSpec::default()
                },
                duration_s: 40.0,
                ..base(Family::Parking, 1)
            }),
            _ => None,
        }
    }

    /// The digital twin of a KITTI tracking sequence: default sensors, ego
    /// and ground, seed 1, as long as the sequence (up to [`MAX_DURATION_S`]).
    pub fn kitti(params: KittiParams) -> ScenarioSpec {
        let name = format!("kitti-{:04}", params.sequence);
        ScenarioSpec {
            kitti: Some(params),
            ..ScenarioSpec::with_defaults(name, Family::Kitti, 1, MAX_DURATION_S)
        }
    }

    /// A spec with default sensors, ego and ground and no family table.
    fn with_defaults(name: String, family: Family, seed: u64, duration_s: f64) -> ScenarioSpec {
        ScenarioSpec {
            name,
            family,
            seed,
            duration_s,
            lidar: LidarConfig::default(),
            imu: ImuConfig::default(),
            detector: DetectorConfig::default(),
            ego: EgoSpec::default(),
            ground: GroundParams::default(),
            highway: None,
            urban: None,
            parking: None,
            kitti: None,
        }
    }

    /// Names accepted by [`ScenarioSpec::builtin`].
    pub fn builtin_names() -> &'static [&'static str] {
        BUILTIN_NAMES
    }

    /// Parses and validates a scenario; `origin` names the file in errors.
    ///
    /// # Errors
    /// [`ScenarioError::Syntax`] for invalid TOML; [`ScenarioError::Invalid`]
    /// with file, line and dotted field for unknown, mistyped or out-of-range
    /// fields.
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

    /// Reads, parses and validates the scenario file at `path`.
    ///
    /// # Errors
    /// [`ScenarioError::Io`] if the file cannot be read; otherwise as
    /// [`ScenarioSpec::parse`].
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
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] for an invalid spec, and for a `kitti`
    /// spec (its scene comes from its replay input:
    /// [`crate::replay::build_scene`]); [`ScenarioError::Traffic`] or
    /// [`ScenarioError::Build`] if the generated traffic is rejected.
    pub fn build(&self) -> Result<Scene, ScenarioError> {
        self.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        match self.family {
            Family::Highway => highway::build(self, &mut rng),
            Family::Urban => urban::build(self, &mut rng),
            Family::Parking => parking::build(self, &mut rng),
            Family::Kitti => Err(invalid(
                "family",
                "a kitti scenario is built from its KITTI files (limot simulate reads them)",
            )),
        }
    }

    /// The family parameters in effect (the table, or its defaults).
    pub fn highway_params(&self) -> HighwayParams {
        self.highway.clone().unwrap_or_default()
    }

    /// The urban parameters in effect (the table, or its defaults).
    pub fn urban_params(&self) -> UrbanParams {
        self.urban.clone().unwrap_or_default()
    }

    /// The parking parameters in effect (the table, or its defaults).
    pub fn parking_params(&self) -> ParkingParams {
        self.parking.clone().unwrap_or_default()
    }

    /// Desired ego speed in effect (a kitti twin's ego follows its OXTS
    /// record instead; this is then `ego.speed_mps` or 10 m/s).
    pub fn ego_speed_mps(&self) -> f64 {
        self.ego.speed_mps.unwrap_or_else(|| match self.family {
            Family::Kitti => 10.0,
            Family::Highway => {
                let h = self.highway_params();
                0.5 * (h.speed_min_mps + h.speed_max_mps)
            }
            Family::Urban => {
                let u = self.urban_params();
                0.5 * (u.car_speed_min_mps + u.car_speed_max_mps)
            }
            Family::Parking => PARKING_EGO_SPEED_MPS,
        })
    }

    /// Checks every field; errors name the dotted field (no line: `parse`
    /// adds file and line).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] for the first invalid field.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        if self.name.trim().is_empty() {
            return Err(invalid("name", "must not be empty"));
        }
        positive_finite("duration_s", self.duration_s)?;
        if self.duration_s > MAX_DURATION_S {
            return Err(invalid(
                "duration_s",
                format!("must be at most {MAX_DURATION_S} s"),
            ));
        }
        validate_lidar(&self.lidar)?;
        self.imu.validate().map_err(|e| match e {
            crate::sensors::ImuError::BadConfig { field, .. } => {
                invalid(format!("imu.{field}"), e.to_string())
            }
            other => invalid("imu", other.to_string()),
        })?;
        self.detector.validate().map_err(|e| match &e {
            crate::sensors::DetectorError::BadConfig { field, .. } => {
                invalid(format!("detector.{field}"), e.to_string())
            }
            _ => invalid("detector", e.to_string()),
        })?;
        validate_ground(&self.ground)?;
        for (table, given, family) in [
            ("highway", self.highway.is_some(), Family::Highway),
            ("urban", self.urban.is_some(), Family::Urban),
            ("parking", self.parking.is_some(), Family::Parking),
            ("kitti", self.kitti.is_some(), Family::Kitti),
        ] {
            if given && self.family != family {
                return Err(invalid(
                    table,
                    format!("given for a {} scenario", self.family.name()),
                ));
            }
        }
        match self.family {
            Family::Kitti => {
                let Some(k) = &self.kitti else {
                    return Err(invalid("kitti", "a kitti scenario needs a [kitti] table"));
                };
                validate_kitti(k)?;
            }
            Family::Highway => {
                let h = self.highway_params();
                validate_highway(&h)?;
                if self.ego.lane >= h.lanes {
                    return Err(invalid(
                        "ego.lane",
                        format!("must be below highway.lanes = {}", h.lanes),
                    ));
                }
                if h.on_ramp.is_some() && self.ego.lane != 0 {
                    return Err(invalid(
                        "ego.lane",
                        "must be 0 with highway.on_ramp (the lane the ego merges into)",
                    ));
                }
                validate_ego_lane_changes(&h.ego_lane_changes, self.ego.lane, h.lanes)?;
                if let Some(exit) = &h.off_ramp {
                    let last = h.ego_lane_changes.last();
                    let final_lane = last.map_or(self.ego.lane, |c| c.to_lane);
                    if final_lane != 0 {
                        return Err(invalid(
                            "highway.ego_lane_changes",
                            format!(
                                "end in lane {final_lane}, but the off-ramp \
                                 (highway.off_ramp) leaves from lane 0"
                            ),
                        ));
                    }
                    let after_s = last
                        .map(|c| c.t_s)
                        .into_iter()
                        .chain(h.on_ramp.as_ref().map(|r| r.merge_request_s))
                        .fold(0.0, f64::max);
                    if exit.exit_request_s < after_s {
                        return Err(invalid(
                            "highway.off_ramp.exit_request_s",
                            format!(
                                "= {}: must not come before the ego's last lane change or \
                                 merge request ({after_s} s)",
                                exit.exit_request_s
                            ),
                        ));
                    }
                }
            }
            Family::Parking => {
                let p = self.parking_params();
                validate_parking(&p, &self.ego)?;
                if self.ego.lane != 0 {
                    return Err(invalid(
                        "ego.lane",
                        format!(
                            "= {}: a car park's aisle has one lane: set ego.lane = 0",
                            self.ego.lane
                        ),
                    ));
                }
            }
            Family::Urban => {
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
                let (needed, route, lane_name) = match u.ego_route {
                    EgoRoute::Straight => (self.ego.lane, "", ""),
                    EgoRoute::TurnRight => (0, "turn-right", "kerb lane"),
                    EgoRoute::TurnLeft => (u.lanes_per_direction - 1, "turn-left", "inner lane"),
                    EgoRoute::UTurn => (0, "u-turn", "kerb lane"),
                };
                let u_turn_radius_m = (u.lanes_per_direction as f64 - 0.5) * u.lane_width_m;
                if u.ego_route == EgoRoute::UTurn && u_turn_radius_m < U_TURN_MIN_RADIUS_M {
                    return Err(invalid(
                        "urban.ego_route",
                        format!(
                            "= \"u-turn\": from the kerb lane into the oncoming one is a half \
                             circle of {u_turn_radius_m} m radius, tighter than a car turns \
                             ({U_TURN_MIN_RADIUS_M} m): it needs lanes_per_direction = 2"
                        ),
                    ));
                }
                if self.ego.lane != needed {
                    return Err(invalid(
                        "ego.lane",
                        format!(
                            "= {}: the ego's route (urban.ego_route = \"{route}\") starts \
                             from the {lane_name}: set ego.lane = {needed}, or \
                             urban.ego_route = \"straight\"",
                            self.ego.lane
                        ),
                    ));
                }
                if u.ego_turn_give_way
                    && !matches!(u.ego_route, EgoRoute::TurnRight | EgoRoute::TurnLeft)
                {
                    let route = match u.ego_route {
                        EgoRoute::Straight => "straight",
                        _ => "u-turn",
                    };
                    return Err(invalid(
                        "urban.ego_turn_give_way",
                        format!(
                            "= true needs a turn into the cross street (urban.ego_route = \
                             \"turn-right\" or \"turn-left\"), not \"{route}\""
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
/// table present in the file when the field itself is absent); a segment
/// `name[i]` is element i of the array `name` (an inline table's keys are
/// found on the element's line or below).
fn line_of_field(text: &str, field: &str) -> Option<usize> {
    let doc = toml::de::DeTable::parse(text).ok()?;
    let mut table = Some(doc.get_ref());
    let mut line = None;
    for segment in field.split('.') {
        // `name[i]`: element i of the array `name`
        let (name, index) = match segment.split_once('[') {
            Some((name, rest)) => (name, rest.trim_end_matches(']').parse::<usize>().ok()),
            None => (segment, None),
        };
        let Some((key, value)) = table.and_then(|t| t.iter().find(|(k, _)| k.get_ref() == name))
        else {
            break;
        };
        line = Some(line_column(text, key.span().start).0);
        let element = index.and_then(|i| value.get_ref().as_array()?.get(i));
        if let Some(element) = element {
            line = Some(line_column(text, element.span().start).0);
            table = element.get_ref().as_table();
        } else {
            table = value.get_ref().as_table();
        }
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

        // an on-ramp needs the ego to merge into lane 0
        let ramp = format!("{HEAD}[ego]\nlane = 1\n[highway.on_ramp]\nlength_m = 200.0\n");
        let msg = error_of(&ramp);
        assert!(msg.contains("ego.lane"), "{msg}");
        let ramp = format!("{HEAD}[ego]\nlane = 0\n[highway.on_ramp]\nlength_m = 20.0\n");
        let msg = error_of(&ramp);
        assert!(msg.contains("bad.toml:8"), "{msg}");
        assert!(msg.contains("highway.on_ramp.length_m"), "{msg}");

        // a jam whose cycle is too short to stand, brake and pull away
        let jam = format!("{HEAD}[highway.jam]\nstopped_s = 10.0\nperiod_s = 20.0\n");
        let msg = error_of(&jam);
        assert!(msg.contains("bad.toml:7"), "{msg}");
        assert!(msg.contains("highway.jam.period_s"), "{msg}");
        let jam = format!("{HEAD}[highway.jam]\nfront_ahead_m = 5.0\n");
        let msg = error_of(&jam);
        assert!(msg.contains("bad.toml:6"), "{msg}");
        assert!(msg.contains("highway.jam.front_ahead_m"), "{msg}");

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
    fn kitti_specs_round_trip_and_their_table_is_validated() {
        let spec = ScenarioSpec::kitti(KittiParams {
            training: "/data/training".into(),
            sequence: 20,
            first_frame: 5,
            frames: Some(100),
            corridor: Some(crate::replay::Corridor::Highway),
            detections: Some("/data/det/0020.txt".into()),
        });
        spec.validate().unwrap();
        let back = ScenarioSpec::parse(&spec.to_toml(), Path::new("k.toml")).unwrap();
        assert_eq!(back, spec);
        // the scene comes from the KITTI files, not from `build`
        assert!(spec.build().is_err());
        let head = "name = \"k\"\nfamily = \"kitti\"\nseed = 1\nduration_s = 30.0\n";
        let msg = error_of(head);
        assert!(msg.contains("kitti") && msg.contains("[kitti]"), "{msg}");
        let frames = format!("{head}[kitti]\ntraining = \"t\"\nsequence = 1\nframes = 1\n");
        let msg = error_of(&frames);
        assert!(
            msg.contains("bad.toml:8") && msg.contains("kitti.frames"),
            "{msg}"
        );
        let corridor =
            format!("{head}[kitti]\ntraining = \"t\"\nsequence = 1\ncorridor = \"forest\"\n");
        let msg = error_of(&corridor);
        assert!(
            msg.contains("bad.toml:8") && msg.contains("kitti.corridor"),
            "{msg}"
        );
        let sequence = format!("{head}[kitti]\ntraining = \"t\"\nsequence = 12345\n");
        let msg = error_of(&sequence);
        assert!(
            msg.contains("bad.toml:7") && msg.contains("kitti.sequence"),
            "{msg}"
        );
        let stray = format!("{HEAD}[kitti]\ntraining = \"t\"\nsequence = 1\n");
        let msg = error_of(&stray);
        assert!(msg.contains("bad.toml:5") && msg.contains("kitti"), "{msg}");
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
