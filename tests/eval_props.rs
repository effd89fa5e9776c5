//! Property tests of the evaluation metrics (src/metrics).

use limot::metrics::{
    ClearMotConfig, EvalError, IouKind, MotFrame, RpeDelta, TrackedBox, ate, clear_mot, iou_3d,
    iou_bev, min_cost_assignment, rpe,
};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::input::ObjectClass;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};
use proptest::prelude::*;

use limot_test_support::SplitMix64 as Rng;

/// Box–Muller normals with the radius drawn from (0, 1], exactly as the Python
/// script that regenerated the evo reference pair draws them.
trait OpenNormal {
    fn open_normal(&mut self) -> f64;
    fn open_normal3(&mut self, sigma: f64) -> Vector3<f64>;
}

impl OpenNormal for Rng {
    fn open_normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // (0, 1]
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
    fn open_normal3(&mut self, sigma: f64) -> Vector3<f64> {
        Vector3::new(self.open_normal(), self.open_normal(), self.open_normal()) * sigma
    }
}

/// Timestamped poses.
type Trajectory = Vec<(f64, Isometry3<f64>)>;

/// A 3D, non-degenerate ego trajectory (helix with varying attitude).
fn trajectory(n: usize) -> Trajectory {
    (0..n)
        .map(|i| {
            let s = i as f64 * 0.05;
            let pose = Isometry3::from_parts(
                Translation3::new(20.0 * s.cos(), 15.0 * s.sin(), 2.0 * (0.7 * s).sin()),
                UnitQuaternion::from_euler_angles(0.05 * s.sin(), 0.03 * s.cos(), s + 1.57),
            );
            (i as f64 * 0.1, pose)
        })
        .collect()
}

fn se3_strategy() -> impl Strategy<Value = Isometry3<f64>> {
    (
        prop::array::uniform3(-100.0..100.0f64),
        prop::array::uniform3(-1.0..1.0f64),
        0.0..std::f64::consts::PI,
    )
        .prop_filter("axis must be non-zero", |(_, a, _)| {
            Vector3::from(*a).norm() > 1e-3
        })
        .prop_map(|(t, axis, angle)| {
            Isometry3::new(Vector3::from(t), Vector3::from(axis).normalize() * angle)
        })
}

fn box_strategy() -> impl Strategy<Value = OrientedBox> {
    (
        prop::array::uniform3(-3.0..3.0f64),
        prop::array::uniform3(0.2..5.0f64),
        -4.0..4.0f64,
    )
        .prop_map(|(c, s, yaw)| OrientedBox::new(Vector3::from(c), Vector3::from(s), yaw))
}

/// Brute force: the maximum number of allowed pairs, then the minimum cost.
fn brute_force(rows: usize, cols: usize, cost: &[f64]) -> (usize, f64) {
    fn go(r: usize, rows: usize, cols: usize, cost: &[f64], used: &mut [bool]) -> (usize, f64) {
        if r == rows {
            return (0, 0.0);
        }
        let mut best = go(r + 1, rows, cols, cost, used); // row r unassigned
        for c in 0..cols {
            let v = cost[r * cols + c];
            if used[c] || !v.is_finite() {
                continue;
            }
            used[c] = true;
            let (n, s) = go(r + 1, rows, cols, cost, used);
            used[c] = false;
            let cand = (n + 1, s + v);
            if cand.0 > best.0 || (cand.0 == best.0 && cand.1 < best.1) {
                best = cand;
            }
        }
        best
    }
    go(0, rows, cols, cost, &mut vec![false; cols])
}

fn cost_matrix_strategy() -> impl Strategy<Value = (usize, usize, Vec<f64>)> {
    (0usize..=5, 0usize..=5).prop_flat_map(|(rows, cols)| {
        let entry = prop_oneof![1 => Just(f64::INFINITY), 3 => -10.0..10.0f64];
        (
            Just(rows),
            Just(cols),
            prop::collection::vec(entry, rows * cols),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn hungarian_equals_brute_force((rows, cols, cost) in cost_matrix_strategy()) {
        let a = min_cost_assignment(rows, cols, &cost).unwrap();
        let (n, best) = brute_force(rows, cols, &cost);
        prop_assert_eq!(a.pairs.len(), n);
        prop_assert!((a.total_cost - best).abs() < 1e-9, "{} vs {}", a.total_cost, best);
        // The pairs are a valid matching of allowed entries with that cost.
        let mut rows_seen = vec![false; rows];
        let mut cols_seen = vec![false; cols];
        let mut sum = 0.0;
        for &(r, c) in &a.pairs {
            prop_assert!(!rows_seen[r] && !cols_seen[c]);
            rows_seen[r] = true;
            cols_seen[c] = true;
            prop_assert!(cost[r * cols + c].is_finite());
            sum += cost[r * cols + c];
        }
        prop_assert!((sum - a.total_cost).abs() < 1e-12);
    }

    #[test]
    fn ate_removes_any_rigid_offset(offset in se3_strategy()) {
        let truth = trajectory(100);
        let est: Vec<_> = truth.iter().map(|(t, p)| (*t, offset * p)).collect();
        let r = ate(&est, &truth, 1e-6).unwrap();
        prop_assert_eq!(r.n, 100);
        prop_assert!(r.ate_t_rmse_m < 1e-9, "ATE_T {}", r.ate_t_rmse_m);
        prop_assert!(r.ate_r_rmse_rad < 1e-9, "ATE_R {}", r.ate_r_rmse_rad);
        prop_assert!(!r.alignment.degenerate);
    }

    #[test]
    fn iou_properties(a in box_strategy(), b in box_strategy(), shift in prop::array::uniform3(-50.0..50.0f64), turn in -3.0..3.0f64) {
        let (i3, ib) = (iou_3d(&a, &b), iou_bev(&a, &b));
        prop_assert!((0.0..=1.0).contains(&i3) && (0.0..=1.0).contains(&ib));
        prop_assert!((i3 - iou_3d(&b, &a)).abs() < 1e-12);
        prop_assert!((ib - iou_bev(&b, &a)).abs() < 1e-12);
        prop_assert!(i3 <= ib + 1e-12);
        prop_assert!((iou_3d(&a, &a) - 1.0).abs() < 1e-12);
        // Invariant under a common yaw rotation and translation of both boxes.
        let motion = Isometry3::new(Vector3::from(shift), Vector3::z() * turn);
        let moved = |x: &OrientedBox| OrientedBox::new((motion * nalgebra::Point3::from(x.center)).coords, x.size_lwh, x.yaw_rad + turn);
        let (ma, mb) = (moved(&a), moved(&b));
        prop_assert!((iou_3d(&ma, &mb) - i3).abs() < 1e-9);
        prop_assert!((iou_bev(&ma, &mb) - ib).abs() < 1e-9);
    }

    #[test]
    fn perfect_tracker_scores_one(
        seed in any::<u64>(),
        n_frames in 1usize..30,
        kind in prop_oneof![Just(IouKind::ThreeD), Just(IouKind::Bev)],
        threshold in prop_oneof![Just(0.25), Just(0.5)],
    ) {
        let mut rng = Rng(seed);
        // Up to 6 objects on a grid (no two identical), each present at random.
        let frames: Vec<MotFrame> = (0..n_frames)
            .map(|f| {
                let present: Vec<u64> = (0..6u64).filter(|_| rng.uniform() < 0.7).collect();
                let gt: Vec<TrackedBox> = present
                    .into_iter()
                    .map(|id| TrackedBox {
                        id,
                        class: ObjectClass::Car,
                        bbox: OrientedBox::new(
                            Vector3::new(3.0 * id as f64 + 0.1 * f as f64, rng.range(-1.0, 1.0), 0.8),
                            Vector3::new(rng.range(3.0, 5.0), rng.range(1.6, 2.2), 1.6),
                            rng.range(-0.5, 0.5),
                        ),
                    })
                    .collect();
                let tracks = gt.iter().rev().map(|g| TrackedBox { id: g.id + 100, ..*g }).collect();
                MotFrame { gt, tracks, dont_care: vec![] }
            })
            .collect();
        let cfg = ClearMotConfig { iou_threshold: threshold, iou_kind: kind, ..ClearMotConfig::default() };
        let r = clear_mot(&frames, &cfg).unwrap();
        prop_assert_eq!(r.false_positives, 0);
        prop_assert_eq!(r.false_negatives, 0);
        prop_assert_eq!(r.id_switches, 0);
        prop_assert_eq!(r.fragmentations, 0);
        if r.gt_count > 0 {
            prop_assert_eq!(r.mota, Some(1.0));
            prop_assert!((r.motp.unwrap() - 1.0).abs() < 1e-12);
            for (frame, matches) in frames.iter().zip(&r.per_frame) {
                for m in matches {
                    prop_assert_eq!(m.track_id, m.gt_id + 100);
                    prop_assert_eq!(frame.gt[m.gt_index].id, m.gt_id);
                }
            }
        }
    }
}

/// Position noise of known sigma per axis: ATE_T ≈ σ·√3; rotation noise of
/// σ_r per axis: ATE_R ≈ σ_r·√3 (small angles).
#[test]
fn ate_of_gaussian_noise_matches_sigma() {
    let sigma_m = 0.2;
    let sigma_rad = 0.01;
    let n = 4000;
    let truth = trajectory(n);
    for seed in 0..4u64 {
        let mut rng = Rng(seed);
        let est: Vec<_> = truth
            .iter()
            .map(|(t, p)| {
                let noisy = Isometry3::from_parts(
                    Translation3::from(p.translation.vector + rng.open_normal3(sigma_m)),
                    p.rotation * UnitQuaternion::from_scaled_axis(rng.open_normal3(sigma_rad)),
                );
                (*t, noisy)
            })
            .collect();
        let r = ate(&est, &truth, 1e-6).unwrap();
        eprintln!(
            "seed {seed}: ATE_T {:.5} m (σ√3 = {:.5}), ATE_R {:.6} rad (σ√3 = {:.6})",
            r.ate_t_rmse_m,
            sigma_m * 3f64.sqrt(),
            r.ate_r_rmse_rad,
            sigma_rad * 3f64.sqrt()
        );
        // Relative standard deviation of the RMSE is about sqrt(6/n)/6 ≈ 0.6 %.
        let expected_t = sigma_m * 3f64.sqrt();
        let expected_r = sigma_rad * 3f64.sqrt();
        assert!(
            (r.ate_t_rmse_m / expected_t - 1.0).abs() < 0.03,
            "seed {seed}: ATE_T {} vs {expected_t}",
            r.ate_t_rmse_m
        );
        assert!(
            (r.ate_r_rmse_rad / expected_r - 1.0).abs() < 0.03,
            "seed {seed}: ATE_R {} vs {expected_r}",
            r.ate_r_rmse_rad
        );
    }
}

/// The exact BEV intersection agrees with a dense grid count.
#[test]
fn bev_intersection_matches_grid_count() {
    let inside = |b: &OrientedBox, p: Vector2<f64>| {
        let d = p - b.center.xy();
        let (s, c) = b.yaw_rad.sin_cos();
        let along = d.x * c + d.y * s;
        let across = -d.x * s + d.y * c;
        along.abs() <= 0.5 * b.size_lwh.x && across.abs() <= 0.5 * b.size_lwh.y
    };
    let mut rng = Rng(7);
    let mut checked = 0;
    while checked < 5 {
        let mk = |rng: &mut Rng| {
            OrientedBox::new(
                Vector3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0),
                Vector3::new(rng.range(1.0, 4.0), rng.range(1.0, 3.0), 1.0),
                rng.range(-3.0, 3.0),
            )
        };
        let (a, b) = (mk(&mut rng), mk(&mut rng));
        let steps = 800;
        let (lo, hi) = (-4.0, 4.0);
        let cell = (hi - lo) / steps as f64;
        let mut count = 0usize;
        for i in 0..steps {
            for j in 0..steps {
                let p = Vector2::new(lo + (i as f64 + 0.5) * cell, lo + (j as f64 + 0.5) * cell);
                if inside(&a, p) && inside(&b, p) {
                    count += 1;
                }
            }
        }
        let grid_inter = count as f64 * cell * cell;
        if grid_inter < 0.5 {
            continue;
        }
        let grid_iou = grid_inter / (a.bev_area() + b.bev_area() - grid_inter);
        assert!(
            (iou_bev(&a, &b) - grid_iou).abs() < 5e-3,
            "{} vs grid {}",
            iou_bev(&a, &b),
            grid_iou
        );
        checked += 1;
    }
}

#[test]
fn errors_not_panics_on_bad_input() {
    let truth = trajectory(10);
    let mut est = truth.clone();
    est[4].1.translation.vector.z = f64::INFINITY;
    assert!(matches!(
        ate(&est, &truth, 0.01),
        Err(EvalError::NotFinite { index: 4, .. })
    ));
    assert!(matches!(
        min_cost_assignment(2, 2, &[0.0, 1.0, f64::NAN, 0.0]),
        Err(EvalError::Invalid { index: 2, .. })
    ));
}

/// Cross-check against evo 1.38.1: the same 200-pose pair (helix + Gaussian
/// noise σ = 0.2 m / 0.01 rad per axis from `Rng(42)`) was regenerated in
/// Python, written as TUM files and scored with `evo_ape tum ref est -a`
/// (translation_part and rotation_angle_rad). The reference figures below are
/// evo's output.
/// The reference pair for the evo cross-checks: 200 helix poses and the same
/// poses with Gaussian noise σ = 0.2 m / 0.01 rad per axis from `Rng(42)`
/// (position noise first, then rotation noise, right-multiplied).
fn evo_reference_pair() -> (Trajectory, Trajectory) {
    let truth = trajectory(200);
    let mut rng = Rng(42);
    let est: Vec<_> = truth
        .iter()
        .map(|(t, p)| {
            let position = p.translation.vector + rng.open_normal3(0.2);
            let rotation = p.rotation * UnitQuaternion::from_scaled_axis(rng.open_normal3(0.01));
            (
                *t,
                Isometry3::from_parts(Translation3::from(position), rotation),
            )
        })
        .collect();
    (est, truth)
}

fn close_to_evo(ours: f64, evo: f64) -> bool {
    (ours - evo).abs() < 1e-9 * evo.max(1.0)
}

#[test]
fn ate_matches_evo_on_reference_pair() {
    let (est, truth) = evo_reference_pair();
    let r = ate(&est, &truth, 0.01).unwrap();
    let close = close_to_evo;
    assert_eq!(r.n, 200);
    assert!(
        close(r.ate_t_rmse_m, 0.357_670_491_522_869_84),
        "{}",
        r.ate_t_rmse_m
    );
    assert!(close(r.mean_m, 0.330_682_732_626_217_3), "{}", r.mean_m);
    assert!(close(r.median_m, 0.324_818_988_673_401_3), "{}", r.median_m);
    assert!(close(r.max_m, 0.800_938_483_818_175_6), "{}", r.max_m);
    assert!(
        close(r.ate_r_rmse_rad, 0.016_893_000_323_628_37),
        "{}",
        r.ate_r_rmse_rad
    );
}

/// evo 1.38.1 `metrics.RPE(relation, delta, unit, rel_delta_tol=0.02, all_pairs,
/// pairs_from_reference=True)` on the same pair (0.02 · 5 m = 0.1 m tolerance).
#[test]
fn rpe_matches_evo_on_reference_pair() {
    let (est, truth) = evo_reference_pair();
    // (delta, all_pairs, pairs, trans rmse, trans max, rot rmse, rot max)
    let cases = [
        (
            RpeDelta::Frames(1),
            false,
            199,
            0.520_303_703_248_619_2,
            1.004_956_370_166_744_6,
            0.023_855_997_234_898_334,
            0.045_853_761_563_352_66,
        ),
        (
            RpeDelta::Frames(5),
            true,
            195,
            0.512_443_744_118_264_8,
            1.118_428_453_582_391_6,
            0.023_757_284_789_017_67,
            0.056_459_846_691_538_18,
        ),
        (
            RpeDelta::Meters {
                delta_m: 10.0,
                path_tolerance_m: 0.0,
            },
            false,
            16,
            0.509_544_399_553_648_3,
            0.813_871_903_787_567,
            0.021_937_788_003_214_057,
            0.036_626_479_420_318_9,
        ),
        (
            RpeDelta::Meters {
                delta_m: 5.0,
                path_tolerance_m: 0.1,
            },
            true,
            55,
            0.532_121_889_256_563_9,
            0.928_254_701_306_757_6,
            0.022_677_684_316_961_887,
            0.036_787_017_475_373_72,
        ),
    ];
    for (delta, all_pairs, n, t_rmse, t_max, r_rmse, r_max) in cases {
        let r = rpe(&est, &truth, 0.01, delta, all_pairs).unwrap();
        assert_eq!(r.n_pairs, n, "{delta:?}");
        assert!(
            close_to_evo(r.trans_rmse_m, t_rmse),
            "{delta:?}: {}",
            r.trans_rmse_m
        );
        assert!(
            close_to_evo(r.trans_max_m, t_max),
            "{delta:?}: {}",
            r.trans_max_m
        );
        assert!(
            close_to_evo(r.rot_rmse_rad, r_rmse),
            "{delta:?}: {}",
            r.rot_rmse_rad
        );
        assert!(
            close_to_evo(r.rot_max_rad, r_max),
            "{delta:?}: {}",
            r.rot_max_rad
        );
    }
}
