//! Conformance of our KITTI 2D CLEAR-MOT (`eval::kitti_mot`) with TrackEval
//! 1.3.0's `Kitti2DBox` + `CLEAR` on real KITTI ground truth.
//!
//! A tracker result is made from the ground truth of sequences 0001 and 0006
//! by a deterministic perturbation (fixed seed, SplitMix64): 10 % of the boxes
//! dropped, every corner jittered by up to ±3 px, the ids of the two longest
//! car tracks alive at mid-sequence swapped from there on, vans reported as
//! cars, random false boxes (some under 25 px tall) and a three-frame outage
//! without any output. The expected figures were produced by
//! running TrackEval on exactly these files (set `LIMOT_KITTI_MOT_DUMP=<dir>`
//! to write them as `<dir>/00NN.txt`; see docs/metrics.md for the command).
//!
//! The test reads `CARGO_MANIFEST_DIR/../shared/data/kitti_tracking`; without
//! it, it prints a note and passes.

use limot::io::kitti::labels::{TrackingLabel, read_labels};
use limot::io::kitti::results::write_results;
use limot::io::kitti::seqmap::read_seqmap;
use limot::metrics::{ClearMotConfig, ClearMotResult, MatchingRule, clear_mot, combine_sequences};
use limot::metrics::{KittiEvalClass, KittiPreprocessConfig, kitti_2d_clear_mot, kitti_2d_frames};
use std::collections::BTreeMap;
use std::path::PathBuf;

use limot_test_support::SplitMix64;

const SEED: u64 = 0x6b69_7474_695f_6d6f;
const SEQUENCES: [u32; 2] = [1, 6];

/// Two decimals, as result files usually carry.
fn round2(x: f64) -> f64 {
    (x * 100.0).round() / 100.0
}

/// The perturbed tracker result of one sequence (see the module docs).
fn perturb(gt: &[TrackingLabel], num_frames: u32, seed: u64) -> Vec<TrackingLabel> {
    let mut rng = SplitMix64(seed);
    // The two longest Car tracks present at mid-sequence (ties: smaller id)
    // swap ids from there on.
    let swap_from = num_frames / 2;
    let at_mid: Vec<i64> = gt
        .iter()
        .filter(|l| l.frame == swap_from && l.type_name == "Car" && l.track_id >= 0)
        .map(|l| l.track_id)
        .collect();
    let mut car_lengths: BTreeMap<i64, usize> = BTreeMap::new();
    for l in gt.iter().filter(|l| at_mid.contains(&l.track_id)) {
        *car_lengths.entry(l.track_id).or_default() += 1;
    }
    let mut longest: Vec<(i64, usize)> = car_lengths.into_iter().collect();
    longest.sort_by_key(|&(id, n)| (std::cmp::Reverse(n), id));
    let (swap_a, swap_b) = (longest[0].0, longest[1].0);
    // A tracker outage: three frames without any output (TrackEval carries
    // correspondences over such frames and counts no fragmentation there).
    let outage = num_frames / 3..num_frames / 3 + 3;

    let mut out = Vec::new();
    for l in gt {
        let type_name = match l.type_name.as_str() {
            "Car" | "Van" => "Car",
            "Pedestrian" => "Pedestrian",
            _ => continue,
        };
        if l.track_id < 0 {
            continue;
        }
        let drop = rng.uniform() < 0.1;
        let jitter: [f64; 4] = std::array::from_fn(|_| rng.range(-3.0, 3.0));
        if drop || outage.contains(&l.frame) {
            continue;
        }
        let mut b: [f64; 4] = std::array::from_fn(|k| round2(l.bbox_2d[k] + jitter[k]));
        b[2] = b[2].max(b[0] + 1.0);
        b[3] = b[3].max(b[1] + 1.0);
        let mut track_id = l.track_id;
        if l.frame >= swap_from {
            if track_id == swap_a {
                track_id = swap_b;
            } else if track_id == swap_b {
                track_id = swap_a;
            }
        }
        out.push(TrackingLabel {
            track_id,
            type_name: type_name.to_string(),
            truncated: -1.0,
            occluded: -1,
            bbox_2d: b,
            score: Some(1.0),
            ..l.clone()
        });
    }
    // False boxes: a quarter of the frames get one, some under 25 px tall.
    for frame in 0..num_frames {
        if rng.uniform() >= 0.25 {
            continue;
        }
        let left = round2(rng.range(0.0, 1100.0));
        let top = round2(rng.range(100.0, 250.0));
        let width = round2(rng.range(30.0, 150.0));
        let height = round2(rng.range(15.0, 105.0));
        let pedestrian = rng.uniform() < 0.3;
        if outage.contains(&frame) {
            continue;
        }
        let template = &gt[0];
        out.push(TrackingLabel {
            frame,
            track_id: 1000 + i64::from(frame),
            type_name: if pedestrian { "Pedestrian" } else { "Car" }.to_string(),
            truncated: -1.0,
            occluded: -1,
            bbox_2d: [left, top, left + width, top + height],
            score: Some(0.5),
            ..template.clone()
        });
    }
    out
}

/// TrackEval 1.3.0 (`Kitti2DBox`, `CLEAR`, THRESHOLD 0.5; numpy 2.4.6, scipy
/// 1.17.1) on the perturbed files, printed with 12 decimals. `sequence: None`
/// is TrackEval's COMBINED_SEQ. TrackEval reports MOTA = MOTP = 0 where we
/// report `None` (no ground truth, no matches).
struct Expected {
    sequence: Option<u32>,
    class: KittiEvalClass,
    tp: usize,
    fp: usize,
    fn_: usize,
    idsw: usize,
    frag: usize,
    mt: usize,
    pt: usize,
    ml: usize,
    mota: f64,
    motp: f64,
}

const EXPECTED: [Expected; 6] = [
    Expected {
        sequence: Some(1),
        class: KittiEvalClass::Car,
        tp: 2021,
        fp: 56,
        fn_: 251,
        idsw: 2,
        frag: 209,
        mt: 76,
        pt: 10,
        ml: 0,
        mota: 0.863996478873,
        motp: 0.903897458688,
    },
    Expected {
        sequence: Some(1),
        class: KittiEvalClass::Pedestrian,
        tp: 91,
        fp: 31,
        fn_: 15,
        idsw: 0,
        frag: 8,
        mt: 2,
        pt: 1,
        ml: 0,
        mota: 0.566037735849,
        motp: 0.857389756729,
    },
    Expected {
        sequence: Some(6),
        class: KittiEvalClass::Car,
        tp: 446,
        fp: 46,
        fn_: 54,
        idsw: 2,
        frag: 29,
        mt: 10,
        pt: 1,
        ml: 0,
        mota: 0.796000000000,
        motp: 0.866630718568,
    },
    Expected {
        sequence: Some(6),
        class: KittiEvalClass::Pedestrian,
        tp: 0,
        fp: 12,
        fn_: 0,
        idsw: 0,
        frag: 0,
        mt: 0,
        pt: 0,
        ml: 0,
        mota: 0.000000000000,
        motp: 0.000000000000,
    },
    Expected {
        sequence: None,
        class: KittiEvalClass::Car,
        tp: 2467,
        fp: 102,
        fn_: 305,
        idsw: 4,
        frag: 238,
        mt: 86,
        pt: 11,
        ml: 0,
        mota: 0.851731601732,
        motp: 0.897160139639,
    },
    Expected {
        sequence: None,
        class: KittiEvalClass::Pedestrian,
        tp: 91,
        fp: 43,
        fn_: 15,
        idsw: 0,
        frag: 8,
        mt: 2,
        pt: 1,
        ml: 0,
        mota: 0.452830188679,
        motp: 0.857389756729,
    },
];

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti_tracking/training")
}

#[test]
fn clear_mot_matches_trackeval_kitti_2d_box() {
    let dir = data_dir();
    if !dir.join("label_02").is_dir() {
        eprintln!(
            "\n!!!!! NOTE: {} is absent; the TrackEval conformance test did not run !!!!!\n",
            dir.display()
        );
        return;
    }
    let seqmap = read_seqmap(&dir.join("evaluate_tracking.seqmap.val")).unwrap();
    let dump = std::env::var_os("LIMOT_KITTI_MOT_DUMP").map(PathBuf::from);
    let mut per_class: BTreeMap<KittiEvalClass, Vec<ClearMotResult>> = BTreeMap::new();
    let mut ours: Vec<(Option<u32>, KittiEvalClass, ClearMotResult)> = Vec::new();
    for sequence in SEQUENCES {
        let entry = seqmap
            .iter()
            .find(|e| e.sequence == sequence)
            .expect("sequence in the seqmap");
        let num_frames = entry.num_frames();
        let gt = read_labels(&dir.join(format!("label_02/{sequence:04}.txt"))).unwrap();
        let results = perturb(&gt, num_frames, SEED ^ u64::from(sequence));
        if let Some(d) = &dump {
            std::fs::create_dir_all(d).unwrap();
            std::fs::write(
                d.join(format!("{sequence:04}.txt")),
                write_results(&results),
            )
            .unwrap();
        }
        for class in KittiEvalClass::ALL {
            let r = kitti_2d_clear_mot(&gt, &results, num_frames, class).unwrap();
            per_class.entry(class).or_default().push(r.clone());
            ours.push((Some(sequence), class, r));
        }
    }
    for (class, results) in per_class {
        ours.push((None, class, combine_sequences(&results)));
    }
    for (sequence, class, r) in &ours {
        eprintln!(
            "{sequence:?} {class:?}: TP {} FP {} FN {} IDSW {} Frag {} MT {} PT {} ML {} MOTA {:.12} MOTP {:.12}",
            r.matches,
            r.false_positives,
            r.false_negatives,
            r.id_switches,
            r.fragmentations,
            r.mostly_tracked,
            r.partially_tracked,
            r.mostly_lost,
            r.mota.unwrap_or(f64::NAN),
            r.motp.unwrap_or(f64::NAN),
        );
    }
    assert_eq!(ours.len(), EXPECTED.len());
    for e in &EXPECTED {
        let (_, _, r) = ours
            .iter()
            .find(|(s, c, _)| *s == e.sequence && *c == e.class)
            .unwrap();
        let what = format!("{:?} {:?}", e.sequence, e.class);
        assert_eq!(r.matches, e.tp, "{what} TP");
        assert_eq!(r.false_positives, e.fp, "{what} FP");
        assert_eq!(r.false_negatives, e.fn_, "{what} FN");
        assert_eq!(r.id_switches, e.idsw, "{what} IDSW");
        assert_eq!(r.fragmentations, e.frag, "{what} Frag");
        assert_eq!(
            (r.mostly_tracked, r.partially_tracked, r.mostly_lost),
            (e.mt, e.pt, e.ml),
            "{what} MT/PT/ML"
        );
        // TrackEval divides by max(1, ·): 0 where our ratios are undefined.
        assert!((r.mota.unwrap_or(0.0) - e.mota).abs() < 1e-6, "{what} MOTA");
        assert!((r.motp.unwrap_or(0.0) - e.motp).abs() < 1e-6, "{what} MOTP");
        assert_eq!(r.mota.is_none(), e.tp + e.fn_ == 0, "{what} MOTA defined");
        assert_eq!(r.motp.is_none(), e.tp == 0, "{what} MOTP defined");
    }
}

/// The conformance above is not vacuous: the KITTI-devkit-style matching
/// (continuity broken by the outage) changes the fragmentation count on the
/// same frames, and the devkit's consecutive-match ID-switch rule would too.
#[test]
fn devkit_matching_differs_on_the_same_data() {
    let dir = data_dir();
    if !dir.join("label_02").is_dir() {
        eprintln!(
            "\n!!!!! NOTE: {} is absent; test skipped !!!!!\n",
            dir.display()
        );
        return;
    }
    let seqmap = read_seqmap(&dir.join("evaluate_tracking.seqmap.val")).unwrap();
    let (mut frag_trackeval, mut frag_devkit) = (0, 0);
    let (mut per_seq_trackeval, mut per_seq_devkit) = (Vec::new(), Vec::new());
    for sequence in SEQUENCES {
        let num_frames = seqmap
            .iter()
            .find(|e| e.sequence == sequence)
            .unwrap()
            .num_frames();
        let gt = read_labels(&dir.join(format!("label_02/{sequence:04}.txt"))).unwrap();
        let results = perturb(&gt, num_frames, SEED ^ u64::from(sequence));
        let prepared =
            kitti_2d_frames(&gt, &results, num_frames, &KittiPreprocessConfig::default()).unwrap();
        let te = clear_mot(&prepared.frames, &ClearMotConfig::trackeval()).unwrap();
        let devkit_cfg = ClearMotConfig {
            matching: MatchingRule::MaxMatches,
            ..ClearMotConfig::trackeval()
        };
        let dk = clear_mot(&prepared.frames, &devkit_cfg).unwrap();
        eprintln!(
            "{sequence:04} car: TrackEval rule Frag {} IDSW {} | devkit rule Frag {} IDSW {}",
            te.fragmentations, te.id_switches, dk.fragmentations, dk.id_switches
        );
        frag_trackeval += te.fragmentations;
        frag_devkit += dk.fragmentations;
        per_seq_trackeval.push(te);
        per_seq_devkit.push(dk);
    }
    assert!(
        frag_devkit > frag_trackeval,
        "{frag_devkit} vs {frag_trackeval}"
    );
    // Matching itself (TP/FP/FN/MOTP) agrees on this data: no competing pairs.
    let (a, b) = (
        combine_sequences(&per_seq_trackeval),
        combine_sequences(&per_seq_devkit),
    );
    assert_eq!(
        (a.matches, a.false_positives),
        (b.matches, b.false_positives)
    );
}
