//! Validation of a scenario spec's tables, and the limits the generators
//! rely on (capacities, spacings, signal timing).

use super::{
    EgoSpec, GroundParams, HighwayParams, JamParams, KittiParams, MAX_DURATION_S, ParkingParams,
    ScenarioError, UrbanParams, invalid,
};
use crate::sensors::LidarConfig;
use crate::traffic::LaneChange;

pub(super) fn positive_finite(field: &str, value: f64) -> Result<(), ScenarioError> {
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
pub(super) fn in_range(field: &str, value: f64, min: f64, max: f64) -> Result<(), ScenarioError> {
    if value.is_finite() && (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("= {value}: must be in [{min}, {max}]"),
        ))
    }
}

pub(super) fn count_in_range(
    field: &str,
    value: usize,
    min: usize,
    max: usize,
) -> Result<(), ScenarioError> {
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

pub(super) fn validate_lidar(l: &LidarConfig) -> Result<(), ScenarioError> {
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

pub(super) fn validate_ground(g: &GroundParams) -> Result<(), ScenarioError> {
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

pub(super) fn validate_ego(e: &EgoSpec, duration_s: f64) -> Result<(), ScenarioError> {
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

pub(super) fn validate_highway(h: &HighwayParams) -> Result<(), ScenarioError> {
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
    if let Some(jam) = &h.jam {
        validate_jam(jam)?;
    }
    if let Some(ramp) = &h.on_ramp {
        in_range("highway.on_ramp.length_m", ramp.length_m, 100.0, 5000.0)?;
        in_range(
            "highway.on_ramp.merge_request_s",
            ramp.merge_request_s,
            0.0,
            MAX_DURATION_S,
        )?;
    }
    if let Some(ramp) = &h.off_ramp {
        in_range(
            "highway.off_ramp.diverge_ahead_m",
            ramp.diverge_ahead_m,
            100.0,
            5000.0,
        )?;
        in_range(
            "highway.off_ramp.exit_request_s",
            ramp.exit_request_s,
            0.0,
            MAX_DURATION_S,
        )?;
        in_range(
            "highway.off_ramp.curve_radius_m",
            ramp.curve_radius_m,
            50.0,
            2000.0,
        )?;
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

/// Checks `[highway.jam]`: every field in a sensible range, and a cycle
/// long enough to stand, brake, pull away and cruise.
fn validate_jam(jam: &JamParams) -> Result<(), ScenarioError> {
    in_range(
        "highway.jam.front_ahead_m",
        jam.front_ahead_m,
        20.0,
        100_000.0,
    )?;
    in_range("highway.jam.period_s", jam.period_s, 5.0, MAX_DURATION_S)?;
    in_range("highway.jam.stopped_s", jam.stopped_s, 0.5, MAX_DURATION_S)?;
    in_range("highway.jam.peak_speed_mps", jam.peak_speed_mps, 1.0, 40.0)?;
    in_range("highway.jam.accel_mps2", jam.accel_mps2, 0.3, 4.0)?;
    in_range(
        "highway.jam.lane_offset_s",
        jam.lane_offset_s,
        0.0,
        MAX_DURATION_S,
    )?;
    // the traffic model's own test of a head's cycle
    let cruise_s = jam.front(0, 0.0).cruise_s();
    if cruise_s < 0.0 {
        let busy_s = jam.period_s - cruise_s;
        return Err(invalid(
            "highway.jam.period_s",
            format!(
                "= {}: shorter than standing {} s plus braking and pulling away to and from \
                 {} m/s at {} m/s^2 ({busy_s:.1} s in all)",
                jam.period_s, jam.stopped_s, jam.peak_speed_mps, jam.accel_mps2
            ),
        ));
    }
    Ok(())
}

/// Checks the ego's lane changes against the road: times finite, in
/// [0, MAX_DURATION_S] and in order (a request after the end of a shortened
/// run is valid and not executed), each target an existing lane next to the
/// lane the previous change (or `ego_lane`) left the ego in. Fields are named
/// `highway.ego_lane_changes[i].t_s` / `.to_lane`.
pub(super) fn validate_ego_lane_changes(
    changes: &[LaneChange],
    ego_lane: usize,
    lanes: usize,
) -> Result<(), ScenarioError> {
    let mut lane = ego_lane;
    let mut last_t_s = 0.0;
    for (i, change) in changes.iter().enumerate() {
        let field = |name: &str| format!("highway.ego_lane_changes[{i}].{name}");
        in_range(&field("t_s"), change.t_s, 0.0, MAX_DURATION_S)?;
        if change.t_s < last_t_s {
            return Err(invalid(
                field("t_s"),
                format!(
                    "= {}: before the previous change's {last_t_s} s (list them in time order)",
                    change.t_s
                ),
            ));
        }
        if change.to_lane >= lanes {
            return Err(invalid(
                field("to_lane"),
                format!(
                    "= {}: must be below highway.lanes = {lanes}",
                    change.to_lane
                ),
            ));
        }
        if change.to_lane.abs_diff(lane) != 1 {
            return Err(invalid(
                field("to_lane"),
                format!(
                    "= {}: must be next to lane {lane}, where the ego is before this change",
                    change.to_lane
                ),
            ));
        }
        lane = change.to_lane;
        last_t_s = change.t_s;
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

pub(super) fn validate_urban(u: &UrbanParams, duration_s: f64) -> Result<(), ScenarioError> {
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
    in_range("urban.give_way_fraction", u.give_way_fraction, 0.0, 1.0)?;
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

/// Checks the `[kitti]` table (the files themselves are read by the caller).
pub(super) fn validate_parking(p: &ParkingParams, ego: &EgoSpec) -> Result<(), ScenarioError> {
    count_in_range("parking.bays_per_row", p.bays_per_row, 4, 400)?;
    in_range("parking.bay_width_m", p.bay_width_m, 2.2, 4.0)?;
    in_range("parking.bay_depth_m", p.bay_depth_m, 4.5, 7.0)?;
    in_range("parking.aisle_width_m", p.aisle_width_m, 5.5, 10.0)?;
    in_range("parking.occupancy", p.occupancy, 0.0, 1.0)?;
    count_in_range(
        "parking.pedestrians",
        p.pedestrians,
        0,
        super::parking::max_pedestrians(p),
    )?;
    count_in_range("parking.ego_bay", p.ego_bay, 1, p.bays_per_row)?;
    in_range(
        "parking.ego_start_before_end_m",
        p.ego_start_before_end_m,
        0.0,
        2000.0,
    )?;
    let [length, width, _] = ego.size_lwh_m;
    if length > p.bay_depth_m - 0.2 || width > p.bay_width_m - 0.4 {
        return Err(invalid(
            "parking.bay_depth_m",
            format!(
                "bays of {} x {} m do not take the ego ({length} x {width} m) with 0.2 m to \
                 spare in depth and 0.4 m in width",
                p.bay_width_m, p.bay_depth_m
            ),
        ));
    }
    super::parking::checked_ego_route(p, ego).map(|_| ())
}

pub(super) fn validate_kitti(k: &KittiParams) -> Result<(), ScenarioError> {
    if k.training.trim().is_empty() {
        return Err(invalid("kitti.training", "must name a directory"));
    }
    if k.sequence > 9999 {
        return Err(invalid(
            "kitti.sequence",
            format!("= {}: must be in 0..=9999", k.sequence),
        ));
    }
    if let Some(frames) = k.frames {
        count_in_range("kitti.frames", frames, 2, 100_000)?;
    }
    if k.first_frame > 100_000 {
        return Err(invalid(
            "kitti.first_frame",
            format!("= {}: must be at most 100000", k.first_frame),
        ));
    }
    if k.detections.as_deref().is_some_and(|d| d.trim().is_empty()) {
        return Err(invalid("kitti.detections", "must name a file when given"));
    }
    Ok(())
}
