#!/usr/bin/env python3
"""Ego accuracy on a real KITTI tracking sequence: KISS-ICP beside limot.

Runs the peer KISS-ICP (Python package, pinned in scripts/requirements.txt,
one thread) on the sequence's Velodyne scans, writes its poses as TUM, and
scores it and any number of TUM files (limot's `poses_tum.txt`, one per
variant) against the OXTS ground truth in the LiDAR frame with evo's Python
API. Prints one side-by-side table: ATE_T and ATE_R (SE(3) alignment), ATE_T
with Sim(3) alignment and its scale, RPE translation over 1 frame and over
10 m of (reference) path, the number of poses scored and the time per frame
(KISS-ICP measured here; limot from `timings.csv` beside its poses,
`total_ms`).

Usage (see docs/kitti-real-data.md):

    python3 -m venv /tmp/peervenv && /tmp/peervenv/bin/pip install -r scripts/requirements.txt
    for v in lio allfilt dynafilt limot; do
      target/release/limot run /work/kitti_training --sequence 0 --variant $v --out /tmp/scale/$v \
        --detections ../shared/data/kitti_tracking/detections/pointrcnn_Car_val --score-map sigmoid
    done
    /tmp/peervenv/bin/python scripts/kitti_peer_eval.py --training /work/kitti_training --sequence 0 \
        --out /tmp/scale/kiss --kiss 0:nodeskew --kiss 0.22 \
        lio=/tmp/scale/lio/poses_tum.txt limot=/tmp/scale/limot/poses_tum.txt

Options worth knowing:
  --kiss A[:nodeskew]       one KISS-ICP run (repeatable; default `--kiss 0`):
                            every point raised by A degrees of elevation first
                            (KISS-ICP's own KITTI readers use 0.205,
                            IMLS-SLAM/CT-ICP 0.22; 0 = the scans as stored);
                            `:nodeskew` gives no per-point times, as KISS-ICP's
                            generic .bin reader (`kiss_icp_pipeline
                            velodyne/0000`, the issue's 0.858 m) runs.
  --no-kiss                 score the given files only.
  --all-frames              score each file on all frames it covers (default:
                            the frames every file covers, so rows compare).
  --association frame       the naive convention: frame i of every file is
                            compared with OXTS line i (all at t = 0.1 s * i).
                            Default `interp`: every estimate is interpolated
                            (SE(3)) to the time of its OXTS record (below).
                            In `frame` mode LABEL=FILE@DELAY says when in
                            sweep i a file's pose holds (stamp 0.1 i + DELAY).
  --rpe-split               after the table, split each file's 10 m RPE into
                            its along-track, lateral and vertical parts and
                            the yaw of the relative rotation (RMS, mean),
                            in the frame of each segment's start.
  --truth velocity          a diagnostic truth: the OXTS attitude with the
                            OXTS velocity integrated over the record spacing
                            that its heading and yaw rate imply (0.1036 s on
                            0000); see docs/kitti-real-data.md.

Conventions (the same as limot, src/io/kitti/oxts.rs, src/experiments/track_kitti.rs):
- OXTS -> pose exactly as the KITTI devkit's convertOxtsToPose: Mercator with
  scale cos(lat of the first record), rotation Rz(yaw) Ry(pitch) Rx(roll),
  relative to the first record (T_w_imu); then
  t_world_lidar = T_w_imu * inv(Tr_imu_velo), Tr_imu_velo from calib/NNNN.txt.
- Time: sweep i starts at 0.1 s * i (the tracking set has no timestamps).
  KITTI synchronises OXTS record i with the camera trigger, when the laser
  faces forward: half a sweep after the sweep start, t = 0.1 i + 0.05 s
  (limot's open_tracking_sequence uses the same). limot's poses_tum.txt holds
  the pose at the sweep start (stamp 0.1 i); KISS-ICP 1.3 de-skews every
  sweep to its END (checked: a point at normalized time 1 is left in place),
  so its pose i is written with stamp 0.1 i + 0.1.
- pos_accuracy (OXTS field 24, 1-based; index 23): records above
  --max-pos-accuracy (default: keep all) are dropped from the ground truth;
  the script prints the range of the field so the choice is visible.
  Sequence 0000 has 0.30-0.52 m on every record (no RTK-fixed solution).
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np

EARTH_RADIUS_M = 6378137.0
FRAME_PERIOD_S = 0.1
OXTS_DELAY_S = 0.05  # OXTS record i: camera trigger, half a sweep after the start
KISS_POSE_DELAY_S = 0.1  # KISS-ICP 1.3 de-skews to the sweep end
PAPER_LIMOT_ATE_T = 0.846  # LIMOT paper, Table I, sequence 0000


# --------------------------------------------------------------------------
# Ground truth
# --------------------------------------------------------------------------


def read_oxts(path: Path) -> np.ndarray:
    rows = [list(map(float, line.split())) for line in path.read_text().splitlines() if line.strip()]
    arr = np.array(rows)
    if arr.ndim != 2 or arr.shape[1] != 30:
        sys.exit(f"{path}: expected 30 columns per line")
    return arr


def read_tr_imu_velo(path: Path) -> np.ndarray:
    for line in path.read_text().splitlines():
        key, *values = line.replace(":", " ").split()
        if key == "Tr_imu_velo":
            t = np.eye(4)
            t[:3, :4] = np.array(list(map(float, values))).reshape(3, 4)
            return t
    sys.exit(f"{path}: no Tr_imu_velo")


def rot_enu_imu(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def oxts_to_poses(oxts: np.ndarray) -> list[np.ndarray]:
    """Devkit convertOxtsToPose: T_w_imu relative to the first record."""
    scale = math.cos(math.radians(oxts[0, 0]))
    poses = []
    for r in oxts:
        t = np.eye(4)
        t[0, 3] = scale * math.radians(r[1]) * EARTH_RADIUS_M
        t[1, 3] = scale * EARTH_RADIUS_M * math.log(math.tan(math.radians(90.0 + r[0]) / 2.0))
        t[2, 3] = r[2]
        t[:3, :3] = rot_enu_imu(r[3], r[4], r[5])
        poses.append(t)
    t0_inv = np.linalg.inv(poses[0])
    return [t0_inv @ p for p in poses]


def record_period_s(oxts: np.ndarray) -> float:
    """Spacing of the OXTS records implied by their own heading and yaw rate:
    least squares of the heading steps against the mean rate wu (field 23)."""
    dyaw = np.diff(np.unwrap(oxts[:, 5]))
    rate = 0.5 * (oxts[1:, 22] + oxts[:-1, 22])
    return float(dyaw @ rate / (rate @ rate))


def oxts_velocity_poses(oxts: np.ndarray, period_s: float) -> list[np.ndarray]:
    """Dead-reckoned T_w_imu: the OXTS attitude, and positions integrated from
    the OXTS velocity (vf, vl, vu: level frame that follows the heading) with
    records `period_s` apart (trapezoid); relative to the first record."""
    v_enu = []
    for r in oxts:
        c, s = math.cos(r[5]), math.sin(r[5])
        v_enu.append(np.array([c * r[8] - s * r[9], s * r[8] + c * r[9], r[10]]))
    poses, p = [], np.zeros(3)
    for i, r in enumerate(oxts):
        if i > 0:
            p = p + 0.5 * period_s * (v_enu[i - 1] + v_enu[i])
        t = np.eye(4)
        t[:3, :3] = rot_enu_imu(r[3], r[4], r[5])
        t[:3, 3] = p
        poses.append(t)
    t0_inv = np.linalg.inv(poses[0])
    return [t0_inv @ q for q in poses]


def ground_truth(training: Path, sequence: int, max_pos_accuracy: float | None, truth: str = "positions"):
    name = f"{sequence:04d}"
    oxts = read_oxts(training / "oxts" / f"{name}.txt")
    tr_imu_velo = read_tr_imu_velo(training / "calib" / f"{name}.txt")
    t_imu_velo = np.linalg.inv(tr_imu_velo)
    if truth == "positions":
        imu_poses = oxts_to_poses(oxts)
    else:
        period = record_period_s(oxts) if truth == "velocity" else FRAME_PERIOD_S
        print(f"truth: OXTS velocity integrated over {period:.4f} s per record")
        imu_poses = oxts_velocity_poses(oxts, period)
    poses = [p @ t_imu_velo for p in imu_poses]
    keep = np.ones(len(oxts), dtype=bool)
    if max_pos_accuracy is not None:
        keep = oxts[:, 23] <= max_pos_accuracy
    return oxts, poses, keep


# --------------------------------------------------------------------------
# KISS-ICP
# --------------------------------------------------------------------------


def correct_elevation(points: np.ndarray, angle_deg: float) -> np.ndarray:
    """Rotate each point up by angle_deg of elevation about z x p (range and
    azimuth kept): the IMLS-SLAM / CT-ICP / KISS-ICP KITTI correction."""
    if angle_deg == 0.0:
        return points
    rho = np.hypot(points[:, 0], points[:, 1])
    r = np.linalg.norm(points, axis=1)
    elev = np.arctan2(points[:, 2], rho) + math.radians(angle_deg)
    az = np.arctan2(points[:, 1], points[:, 0])
    out = np.empty_like(points)
    out[:, 0] = r * np.cos(elev) * np.cos(az)
    out[:, 1] = r * np.cos(elev) * np.sin(az)
    out[:, 2] = r * np.sin(elev)
    # points on the z axis have no azimuth plane: leave them
    on_axis = rho < 1e-9
    out[on_axis] = points[on_axis]
    return out


def run_kiss(training: Path, sequence: int, correction_deg: float, out_dir: Path, deskew: bool):
    from kiss_icp.config import KISSConfig
    from kiss_icp.kiss_icp import KissICP

    config = KISSConfig()
    config.registration.max_num_threads = 1
    config.mapping.voxel_size = config.data.max_range / 100.0  # as load_config does
    odometry = KissICP(config=config)
    scans = sorted((training / "velodyne" / f"{sequence:04d}").glob("*.bin"))
    poses, times_ms = [], []
    for path in scans:
        pts = np.fromfile(path, dtype=np.float32).reshape(-1, 4)[:, :3].astype(np.float64)
        start = time.perf_counter()
        pts = correct_elevation(pts, correction_deg)
        # normalized sweep time: 0 rear-left, 0.5 ahead, 1 rear-right (KITTI raw loader)
        stamps = 0.5 * (-np.arctan2(pts[:, 1], pts[:, 0]) / np.pi + 1.0) if deskew else np.array([])
        odometry.register_frame(pts, stamps)
        times_ms.append(1e3 * (time.perf_counter() - start))
        poses.append(odometry.last_pose.copy())
    out_dir.mkdir(parents=True, exist_ok=True)
    tum = out_dir / f"kiss_icp_{correction_deg:g}deg{'' if deskew else '_nodeskew'}_tum.txt"
    # without de-skewing the sweep is taken as a snapshot: its middle is the best guess
    delay = KISS_POSE_DELAY_S if deskew else 0.5 * FRAME_PERIOD_S
    stamps = [FRAME_PERIOD_S * i + delay for i in range(len(poses))]
    write_tum(tum, stamps, poses)
    return tum, delay, float(np.mean(times_ms))


# --------------------------------------------------------------------------
# Trajectories and metrics
# --------------------------------------------------------------------------


def write_tum(path: Path, stamps, poses):
    from scipy.spatial.transform import Rotation

    with open(path, "w") as f:
        for t, p in zip(stamps, poses):
            qx, qy, qz, qw = Rotation.from_matrix(p[:3, :3]).as_quat()
            f.write(f"{t:.6f} {p[0,3]:.9f} {p[1,3]:.9f} {p[2,3]:.9f} {qx:.12f} {qy:.12f} {qz:.12f} {qw:.12f}\n")


def read_tum(path: Path):
    data = np.loadtxt(path, comments="#", ndmin=2)
    from scipy.spatial.transform import Rotation

    poses = []
    for row in data:
        t = np.eye(4)
        t[:3, 3] = row[1:4]
        t[:3, :3] = Rotation.from_quat(row[4:8]).as_matrix()
        poses.append(t)
    return data[:, 0], poses


def interpolate(stamps, poses, at):
    """SE(3) poses at times `at` (slerp + linear); None outside the span."""
    from scipy.spatial.transform import Rotation, Slerp

    stamps = np.asarray(stamps)
    slerp = Slerp(stamps, Rotation.from_matrix([p[:3, :3] for p in poses]))
    xyz = np.array([p[:3, 3] for p in poses])
    out = []
    for t in at:
        if t < stamps[0] - 1e-9 or t > stamps[-1] + 1e-9:
            out.append(None)
            continue
        p = np.eye(4)
        p[:3, :3] = slerp([min(max(t, stamps[0]), stamps[-1])]).as_matrix()[0]
        p[:3, 3] = [np.interp(t, stamps, xyz[:, k]) for k in range(3)]
        out.append(p)
    return out


def estimate_at_frames(n_frames, stamps, poses, pose_delay_s, association):
    """{frame index: estimated pose at the time of that frame's OXTS record}."""
    out = {}
    if association == "interp":
        gt_times = [FRAME_PERIOD_S * i + OXTS_DELAY_S for i in range(n_frames)]
        for i, p in enumerate(interpolate(stamps, poses, gt_times)):
            if p is not None:
                out[i] = p
    else:
        for t, p in zip(stamps, poses):
            i = int(round((t - pose_delay_s) / FRAME_PERIOD_S))
            if 0 <= i < n_frames:
                out[i] = p
    return out


def paired(gt_poses, frames, at_frames):
    """(reference, estimate, times) at the given frames."""
    ref = [gt_poses[i] for i in frames]
    est = [at_frames[i] for i in frames]
    return ref, est, np.array([FRAME_PERIOD_S * i + OXTS_DELAY_S for i in frames])


def score(ref_poses, est_poses, times):
    import copy

    from evo.core import metrics
    from evo.core.trajectory import PoseTrajectory3D
    from evo.core.units import Unit

    ref = PoseTrajectory3D(poses_se3=ref_poses, timestamps=times)
    est = PoseTrajectory3D(poses_se3=est_poses, timestamps=times)
    out = {"n": len(times), "path_m": ref.path_length, "est_path_m": est.path_length}

    se3 = copy.deepcopy(est)
    se3.align(ref, correct_scale=False)
    for key, rel in [("ate_t", metrics.PoseRelation.translation_part), ("ate_r", metrics.PoseRelation.rotation_angle_rad)]:
        ape = metrics.APE(rel)
        ape.process_data((ref, se3))
        out[key] = ape.get_statistic(metrics.StatisticsType.rmse)

    sim3 = copy.deepcopy(est)
    _, _, s = sim3.align(ref, correct_scale=True)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, sim3))
    out["ate_t_sim3"] = ape.get_statistic(metrics.StatisticsType.rmse)
    out["scale"] = s

    rpe = metrics.RPE(metrics.PoseRelation.translation_part, delta=1, delta_unit=Unit.frames, all_pairs=False)
    rpe.process_data((ref, est))
    out["rpe1"] = rpe.get_statistic(metrics.StatisticsType.rmse)
    rpe = metrics.RPE(
        metrics.PoseRelation.translation_part,
        delta=10.0,
        delta_unit=Unit.meters,
        rel_delta_tol=0.1,
        all_pairs=True,
        pairs_from_reference=True,
    )
    rpe.process_data((ref, est))
    out["rpe10m"] = rpe.get_statistic(metrics.StatisticsType.rmse)
    return out


def rpe10_split(ref_poses, est_poses):
    """RMS and mean of the 10 m relative error split into along-track,
    lateral and vertical parts (m) and the relative yaw error (deg), each
    segment from pose i to the first pose at least 10 m of reference path
    later (evo's `pairs_from_reference`, without its 10 % tolerance)."""
    xyz = np.array([p[:3, 3] for p in ref_poses])
    path = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))])
    parts = {"along": [], "lateral": [], "vertical": [], "yaw_deg": []}
    for i in range(len(ref_poses)):
        later = np.flatnonzero(path - path[i] >= 10.0)
        if len(later) == 0:
            break
        j = later[0]
        d_ref = np.linalg.inv(ref_poses[i]) @ ref_poses[j]
        d_est = np.linalg.inv(est_poses[i]) @ est_poses[j]
        err = d_est[:3, 3] - d_ref[:3, 3]  # in frame i
        ahead = d_ref[:3, 3] / np.linalg.norm(d_ref[:3, 3])
        up = np.array([0.0, 0.0, 1.0])
        left = np.cross(up, ahead)
        left /= np.linalg.norm(left)
        parts["along"].append(err @ ahead)
        parts["lateral"].append(err @ left)
        parts["vertical"].append(err @ np.cross(ahead, left))
        r_err = d_ref[:3, :3].T @ d_est[:3, :3]
        parts["yaw_deg"].append(math.degrees(math.atan2(r_err[1, 0], r_err[0, 0])))
    return {k: (float(np.sqrt(np.mean(np.square(v)))), float(np.mean(v))) for k, v in parts.items()}


def limot_ms_per_frame(tum: Path):
    path = tum.parent / "timings.csv"
    if not path.is_file():
        return None
    with open(path) as f:
        rows = list(csv.DictReader(f))
    if not rows or "total_ms" not in rows[0]:
        return None
    return float(np.mean([float(r["total_ms"]) for r in rows]))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--training", type=Path, required=True)
    ap.add_argument("--sequence", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("/tmp/kitti_peer_eval"))
    ap.add_argument("--no-kiss", action="store_true")
    ap.add_argument(
        "--kiss",
        action="append",
        metavar="ANGLE[:nodeskew]",
        help="one KISS-ICP run: elevation correction in degrees, `:nodeskew` for no per-point times",
    )
    ap.add_argument("--association", choices=["interp", "frame"], default="interp")
    ap.add_argument("--max-pos-accuracy", type=float, default=None)
    ap.add_argument(
        "--truth",
        choices=["positions", "velocity", "velocity10hz"],
        default="positions",
        help="positions: the devkit poses (default); velocity: a diagnostic truth, the OXTS attitude with "
        "the OXTS velocity integrated over the record spacing its heading and yaw rate imply; "
        "velocity10hz: the same over 0.1 s",
    )
    ap.add_argument(
        "--all-frames",
        action="store_true",
        help="score each estimate on every frame it covers (default: only the frames all cover, "
        "e.g. limot starts after its 10 initialisation frames, KISS-ICP at frame 0)",
    )
    ap.add_argument("--rpe-split", action="store_true", help="split the 10 m RPE (see the module doc)")
    ap.add_argument(
        "estimates",
        nargs="*",
        help="LABEL=poses_tum.txt[@DELAY]: DELAY (s) = when in sweep i (stamp 0.1 i + DELAY) the pose "
        "holds; 0 (default) for limot (sweep start), 0.1 for KISS-ICP 1.3 files",
    )
    args = ap.parse_args()

    oxts, gt, keep = ground_truth(args.training, args.sequence, args.max_pos_accuracy, args.truth)
    acc = oxts[:, 23]
    print(
        f"sequence {args.sequence:04d}: {len(gt)} OXTS records, pos_accuracy {acc.min():.2f}-{acc.max():.2f} m "
        f"(median {np.median(acc):.2f}), {int(keep.sum())} kept; association: {args.association}"
    )

    runs = []  # (label, tum path, pose delay, ms/frame)
    if not args.no_kiss:
        for config in args.kiss or ["0"]:
            angle_text, _, mode = config.partition(":")
            if mode not in ("", "nodeskew"):
                sys.exit(f"--kiss {config}: expected ANGLE or ANGLE:nodeskew")
            angle, deskew = float(angle_text), mode != "nodeskew"
            tum, delay, ms = run_kiss(args.training, args.sequence, angle, args.out, deskew)
            note = "" if deskew else ", no deskew"
            runs.append((f"KISS-ICP 1.3.0 ({angle:g} deg{note})", tum, delay, ms))
    for spec in args.estimates:
        label, _, path = spec.partition("=")
        if not path:
            label, path = Path(spec).parent.name, spec
        path, _, delay = path.partition("@")
        runs.append((label, Path(path), float(delay or 0.0), limot_ms_per_frame(Path(path))))


    at = []
    for label, tum, delay, ms in runs:
        stamps, poses = read_tum(tum)
        at.append(estimate_at_frames(len(gt), stamps, poses, delay, args.association))
    common = set(np.flatnonzero(keep))
    for a in at:
        common &= set(a)
    common = sorted(common)
    if args.all_frames:
        print("every estimate scored on all the frames it covers (n differs between rows)")
    else:
        print(f"scored on the {len(common)} frames every estimate covers ({common[0]}-{common[-1]})")
    header = f"| {'estimate':<28} | ATE_T SE3 [m] | ATE_R [rad] | ATE_T Sim3 [m] | scale | RPE 1 fr [m] | RPE 10 m [m] | n | path [m] est/ref | ms/frame |"
    print(header)
    print("|" + "|".join("-" * (len(c)) for c in header.split("|")[1:-1]) + "|")
    for (label, tum, delay, ms), a in zip(runs, at):
        frames = sorted(set(a) & set(np.flatnonzero(keep))) if args.all_frames else common
        ref, est, times = paired(gt, frames, a)
        m = score(ref, est, times)
        ms_text = f"{ms:.1f}" if ms is not None else "-"
        print(
            f"| {label:<28} | {m['ate_t']:13.3f} | {m['ate_r']:11.4f} | {m['ate_t_sim3']:14.3f} | {m['scale']:.3f} "
            f"| {m['rpe1']:12.4f} | {m['rpe10m']:12.3f} | {m['n']} | {m['est_path_m']:.2f}/{m['path_m']:.2f} | {ms_text:>8} |"
        )
    print(f"| paper LIMOT (Table I)        | {PAPER_LIMOT_ATE_T:13.3f} |")
    if args.rpe_split:
        print()
        print("10 m RPE split, RMS (mean) per part, in the frame of each segment's start:")
        print(f"| {'estimate':<28} | along [m] | lateral [m] | vertical [m] | yaw [deg] |")
        print("|---|---|---|---|---|")
        for (label, tum, delay, ms), a in zip(runs, at):
            frames = sorted(set(a) & set(np.flatnonzero(keep))) if args.all_frames else common
            ref, est, _ = paired(gt, frames, a)
            cells = " | ".join(f"{rms:.3f} ({mean:+.3f})" for rms, mean in rpe10_split(ref, est).values())
            print(f"| {label:<28} | {cells} |")


if __name__ == "__main__":
    main()
