//! The scenario spec's tables: family, ego, ground, `[highway]` and `[urban]`
//! parameters, with their defaults.

use crate::traffic::{JamFront, LaneChange};
use serde::{Deserialize, Serialize};

/// Scenario family: which generator builds the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Family {
    /// Multi-lane highway with trucks, guard rails and roadside structures.
    Highway,
    /// City street with intersections, parked cars, cyclists and pedestrians.
    Urban,
    /// A surface car park: rows of bays either side of its aisles, the ego
    /// at walking pace round a row's end and into a free bay.
    Parking,
    /// A digital twin of a KITTI tracking sequence: the ego and the labelled
    /// objects replayed, a static scene generated along the driven corridor
    /// (see [`crate::replay`]; the `[kitti]` table names the sequence).
    Kitti,
}

impl Family {
    /// The family's name, as scenario files and datasets' `meta.toml` spell it.
    pub fn name(self) -> &'static str {
        match self {
            Family::Highway => "highway",
            Family::Urban => "urban",
            Family::Parking => "parking",
            Family::Kitti => "kitti",
        }
    }
}

/// The `[kitti]` table of a `kitti` scenario: which KITTI tracking sequence
/// it replays. The simulator reads no KITTI files itself: the caller (the
/// `limot` CLI) reads them into a [`crate::replay::ReplayInput`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KittiParams {
    /// KITTI tracking `training` directory (with `calib/`, `oxts/`, `label_02/`).
    pub training: String,
    /// Sequence number, 0..=9999 (`0000.txt`, ...).
    pub sequence: u32,
    /// First KITTI frame of the twin (its t = 0).
    #[serde(default)]
    pub first_frame: usize,
    /// Frames replayed, at least 2; unset = to the end of the sequence
    /// (`duration_s` caps the twin as well).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<usize>,
    /// Static scene along the corridor; unset = chosen from the sequence
    /// (see [`crate::replay::Corridor::choose`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub corridor: Option<crate::replay::Corridor>,
    /// An AB3DMOT-format CSV of real detections of this sequence (camera
    /// frame, logit scores as PointRCNN's) put into the dataset instead of
    /// the detector model's boxes; unset = the detector model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detections: Option<String>,
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
    /// Upper end of the slope range, per cent.
    pub slope_max_percent: f64,
    /// Number of sinusoidal undulations.
    pub undulations: usize,
    /// Smallest undulation amplitude, m.
    pub amplitude_min_m: f64,
    /// Largest undulation amplitude, m.
    pub amplitude_max_m: f64,
    /// Shortest undulation wavelength, m.
    pub wavelength_min_m: f64,
    /// Longest undulation wavelength, m.
    pub wavelength_max_m: f64,
    /// Each undulation's amplitude is capped so that its own grade stays below
    /// this (keeps roads driveable for short wavelengths), per cent.
    pub undulation_grade_max_percent: f64,
    /// Road roughness: ISO 8608 displacement PSD at 0.1 cycles/m, m³
    /// (class A 16e-6, B 64e-6, C 256e-6); 0 = a smooth road.
    pub roughness_psd_m3: f64,
    /// Wavelength band of the roughness, m (0.25..=64).
    pub roughness_wavelength_min_m: f64,
    /// Longest roughness wavelength, m.
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
    /// Lane width, m.
    pub lane_width_m: f64,
    /// Other vehicles (cars and trucks).
    pub vehicles: usize,
    /// Desired speeds are drawn uniformly from [speed_min_mps, speed_max_mps].
    pub speed_min_mps: f64,
    /// Upper end of the desired-speed range, m/s.
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
    /// Largest curve radius, m.
    pub curve_radius_max_m: f64,
    /// Vehicles start between this far behind and `spawn_ahead_m` ahead of the ego.
    pub spawn_behind_m: f64,
    /// How far ahead of the ego vehicles may start, m.
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
    /// Share of the right roadside in a cutting.
    pub cutting_fraction: f64,
    /// Mean spacing of bushes and trees on the verges and in the median; 0 = none.
    pub vegetation_spacing_m: f64,
    /// Distance between the posts of the right-of-way fence beyond open
    /// verges; 0 = no fence.
    pub fence_post_spacing_m: f64,
    /// Mean distance between overpasses, between sign gantries and between
    /// roadside sign boards (distance and speed signs); 0 = none.
    pub overpass_spacing_m: f64,
    /// Mean distance between sign gantries, m; 0 = none.
    pub gantry_spacing_m: f64,
    /// Mean distance between roadside sign boards, m; 0 = none.
    pub sign_spacing_m: f64,
    /// The ego's lane changes, in time order: each is requested at `t_s` and
    /// starts at the first moment after it (and after the previous change has
    /// ended) when the traffic model finds the gap in the target lane safe,
    /// the ego and the target lane's traffic making room meanwhile (braking
    /// at most comfortably; see [`crate::traffic::LaneChange::cooperative`]);
    /// `to_lane` (0 = rightmost) is one lane left or right of where the
    /// previous change left the ego. Requests the run ends before are not
    /// executed. Empty = the ego keeps its lane.
    pub ego_lane_changes: Vec<LaneChange>,
    /// The ego starts on an on-ramp's acceleration lane and merges
    /// (`[highway.on_ramp]`); unset = it starts in `ego.lane`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub on_ramp: Option<OnRampParams>,
    /// The ego leaves the highway by an off-ramp (`[highway.off_ramp]`);
    /// unset = it stays on the highway.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub off_ramp: Option<OffRampParams>,
    /// A stop-and-go jam the ego drives into (`[highway.jam]`); unset =
    /// free-flowing traffic.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jam: Option<JamParams>,
}

/// An on-ramp for the ego (`[highway.on_ramp]`): an acceleration lane to
/// the right of lane 0, from the start of the road to `length_m` ahead of
/// the ego's start, paved beside the carriageway (the right shoulder, rail
/// and roadside move out by one lane width along the whole road). The ego
/// starts on it and asks to merge into lane 0 at `merge_request_s`; the
/// traffic in lane 0 makes room (a cooperative lane change, see
/// [`crate::traffic::LaneChange::cooperative`]) and the ego's
/// `ego_lane_changes` follow from lane 0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OnRampParams {
    /// Where the acceleration lane ends, ahead of the ego's start, m.
    pub length_m: f64,
    /// When the ego asks to merge, s.
    pub merge_request_s: f64,
}

impl Default for OnRampParams {
    fn default() -> Self {
        OnRampParams {
            length_m: 250.0,
            merge_request_s: 5.0,
        }
    }
}

/// An off-ramp for the ego (`[highway.off_ramp]`): the ego asks at
/// `exit_request_s` to change from lane 0 into the deceleration lane right
/// of it (paved beside the carriageway like an on-ramp's acceleration lane:
/// the right shoulder, rail and roadside move out by one lane width along
/// the whole road); `diverge_ahead_m` ahead of the ego's start the ramp
/// leaves the carriageway in a right curve of `curve_radius_m` through 30
/// degrees and runs straight on. The roadside in its way is cleared (the
/// gore) and a guard rail lines its right side. The ego must be in lane 0
/// after its `ego_lane_changes` and change into the deceleration lane
/// before the diverge point (the build reports it if it does not).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OffRampParams {
    /// Where the ramp leaves the carriageway, ahead of the ego's start, m.
    pub diverge_ahead_m: f64,
    /// When the ego asks to change into the deceleration lane, s.
    pub exit_request_s: f64,
    /// Radius of the ramp's curve (its lane's centre line), m.
    pub curve_radius_m: f64,
}

impl Default for OffRampParams {
    fn default() -> Self {
        OffRampParams {
            diverge_ahead_m: 450.0,
            exit_request_s: 14.0,
            curve_radius_m: 150.0,
        }
    }
}

/// A stop-and-go jam ahead of the ego (`[highway.jam]`): in every lane, an
/// invisible jam head starts `front_ahead_m` ahead of the ego and drives a
/// stop-and-go cycle (see [`crate::traffic::JamFront`]): cruising at
/// `peak_speed_mps`, braking at `accel_mps2` to a stand of `stopped_s`,
/// pulling away again, every `period_s`, each lane running its cycle
/// `lane_offset_s` after the lane to its right. The traffic behind it, the ego's
/// with it, queues and moves off in waves: the case where moving cars look
/// most like the static world. Vehicles that would start within a safe gap
/// of a head are not placed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct JamParams {
    /// Where the heads start, ahead of the ego, m.
    pub front_ahead_m: f64,
    /// Length of one stop-and-go cycle, s.
    pub period_s: f64,
    /// Standing part of each cycle, s.
    pub stopped_s: f64,
    /// The heads' speed between stands, m/s.
    pub peak_speed_mps: f64,
    /// The heads' braking and pulling-away rate, m/s².
    pub accel_mps2: f64,
    /// Each lane runs its cycle this much after the lane to its right, s.
    pub lane_offset_s: f64,
}

impl Default for JamParams {
    fn default() -> Self {
        JamParams {
            front_ahead_m: 60.0,
            period_s: 30.0,
            stopped_s: 10.0,
            peak_speed_mps: 14.0,
            accel_mps2: 1.5,
            lane_offset_s: 4.0,
        }
    }
}

impl JamParams {
    /// The head in `lane` of a road whose ego starts at `ego_s_m`: at the
    /// start of its cruise at t = 0 in lane 0, each lane to the left
    /// `lane_offset_s` more short of a cycle's start.
    pub(crate) fn front(&self, lane: usize, ego_s_m: f64) -> JamFront {
        JamFront {
            lane,
            start_s_m: ego_s_m + self.front_ahead_m,
            period_s: self.period_s,
            stopped_s: self.stopped_s,
            peak_speed_mps: self.peak_speed_mps,
            accel_mps2: self.accel_mps2,
            phase_s: (-(lane as f64) * self.lane_offset_s).rem_euclid(self.period_s),
        }
    }
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
            // overtake on the left, then back to the ego's lane
            ego_lane_changes: vec![
                LaneChange {
                    t_s: 8.0,
                    to_lane: 2,
                    cooperative: false,
                },
                LaneChange {
                    t_s: 24.0,
                    to_lane: 1,
                    cooperative: false,
                },
            ],
            on_ramp: None,
            off_ramp: None,
            jam: None,
        }
    }
}

/// The urban ego's route (`urban.ego_route`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EgoRoute {
    /// Along the main street, from any lane.
    Straight,
    /// From the kerb lane (`ego.lane = 0`) right into the cross street on
    /// the main street's green; the pedestrians and cyclists on the ego's
    /// side of the main street wait until it has turned.
    TurnRight,
    /// From the inner lane (`ego.lane = lanes_per_direction - 1`) left across
    /// the oncoming lanes into the cross street, in a protected phase: the
    /// oncoming traffic and the pedestrians and cyclists on the far side of
    /// the main street wait until it has turned.
    TurnLeft,
    /// From the kerb lane (`ego.lane = 0`) round through half a circle across
    /// the inner and the oncoming lanes into the oncoming kerb lane, inside the
    /// intersection, then back along the main street; in a protected phase:
    /// the ego's other lanes and the oncoming lanes wait until it has turned.
    /// Its radius is (lanes_per_direction - 0.5) x lane_width_m, which must
    /// be a car's (two lanes per direction).
    UTurn,
}

/// The `[urban]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UrbanParams {
    /// Lanes per direction on the main street, 1..=2.
    pub lanes_per_direction: usize,
    /// Lane width, m.
    pub lane_width_m: f64,
    /// Bike lane between the traffic lanes and the parking strip, each side.
    pub bike_lane_width_m: f64,
    /// Parking strip along each kerb.
    pub parking_width_m: f64,
    /// Sidewalk width, each side, m.
    pub sidewalk_width_m: f64,
    /// Distance between cross streets, drawn uniformly.
    pub block_length_min_m: f64,
    /// Longest block, m.
    pub block_length_max_m: f64,
    /// Width of a cross street, m.
    pub cross_street_width_m: f64,
    /// Moving cars, both directions together.
    pub moving_cars: usize,
    /// Slowest desired car speed, m/s.
    pub car_speed_min_mps: f64,
    /// Fastest desired car speed, m/s.
    pub car_speed_max_mps: f64,
    /// Cyclists in the bike lanes, both directions together.
    pub cyclists: usize,
    /// Slowest desired cyclist speed, m/s.
    pub cyclist_speed_min_mps: f64,
    /// Fastest desired cyclist speed, m/s.
    pub cyclist_speed_max_mps: f64,
    /// Pedestrians on the sidewalks, both directions together.
    pub pedestrians: usize,
    /// Slowest desired walking speed, m/s.
    pub pedestrian_speed_min_mps: f64,
    /// Fastest desired walking speed, m/s.
    pub pedestrian_speed_max_mps: f64,
    /// Fraction of the parking places that hold a car.
    pub parking_occupancy: f64,
    /// Traffic signal period and the red part of it, at every intersection.
    pub signal_cycle_s: f64,
    /// Red part of the signal cycle for the main street, s.
    pub red_s: f64,
    /// Cars on the cross streets of every intersection the ego's LiDAR can
    /// see (both directions together); they cross while the main street is red.
    pub cross_cars_per_intersection: usize,
    /// Mean spacing of trees and of light poles along each sidewalk.
    pub tree_spacing_m: f64,
    /// Mean spacing of light poles along each sidewalk, m.
    pub pole_spacing_m: f64,
    /// Probability that a building lot holds a building, in [0, 1]; each lot
    /// decides independently. Below 1 the parked cars become the main
    /// structure along the street. 1 = a building on every lot.
    pub building_fraction: f64,
    /// Street furniture on the sidewalks: traffic signs, bollards, bins,
    /// benches and bus shelters (the sidewalks and their kerbs are always there).
    pub street_furniture: bool,
    /// The ego's route: straight along the main street, or a turn at its
    /// first traffic light (where it always waits at red) into the cross
    /// street, which it then follows.
    pub ego_route: EgoRoute,
    /// Share of the intersections without traffic lights, in [0, 1] (each
    /// decides independently; the ego's first intersection has them unless
    /// `ego_turn_give_way`):
    /// there the main street has priority and drives on, and the cross
    /// street's cars give way to every road user on it, pedestrians on its
    /// sidewalks included, taking a gap long enough to cross. 0 = every
    /// intersection signalled.
    pub give_way_fraction: f64,
    /// The intersection where the ego turns (`ego_route` = `turn-right` or
    /// `turn-left`) has no traffic lights either: the ego, on the main
    /// street, has right of way over the cross street, whose cars give way
    /// to it, and waits at a yield line before its turn until the road
    /// users its path crosses leave a gap long enough to turn through: the
    /// pedestrians and cyclists going straight across the cross street's
    /// mouth on the side it turns to and, turning left, the oncoming cars.
    /// There the cross street's cars all come towards the main street.
    pub ego_turn_give_way: bool,
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
            ego_route: EgoRoute::TurnRight,
            give_way_fraction: 0.0,
            ego_turn_give_way: false,
        }
    }
}

/// The `[parking]` table: a surface car park of two one-way aisles along x.
/// Across it (y up): a building's front, a walkway, a row of bays, aisle 1
/// (driven towards +x), a double row of bays (head to head), aisle 2
/// (driven towards -x), a row of bays, a walkway and trees. The ego drives
/// down aisle 1, turns round the double row's end through two tight left
/// corners into aisle 2 and parks forwards in a free bay of the far row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ParkingParams {
    /// Bays in each row, side by side along x.
    pub bays_per_row: usize,
    /// Width of a bay (along the row), m.
    pub bay_width_m: f64,
    /// Depth of a bay (across the row), m.
    pub bay_depth_m: f64,
    /// Width of an aisle, m.
    pub aisle_width_m: f64,
    /// Fraction of the bays that hold a parked car (the ego's bay and its
    /// two neighbours are always free).
    pub occupancy: f64,
    /// Pedestrians on the two walkways, both directions together.
    pub pedestrians: usize,
    /// The bay of the far row the ego parks in, counted from the aisle's
    /// start (its east end, where the ego enters it), 1 = the first.
    pub ego_bay: usize,
    /// How far before the end of aisle 1 the ego starts, m.
    pub ego_start_before_end_m: f64,
}

impl Default for ParkingParams {
    fn default() -> Self {
        ParkingParams {
            bays_per_row: 24,
            bay_width_m: 2.6,
            bay_depth_m: 5.3,
            aisle_width_m: 6.5,
            occupancy: 0.75,
            pedestrians: 8,
            ego_bay: 4,
            ego_start_before_end_m: 15.0,
        }
    }
}
