//! `limot eval`: ego and track scores of result files, the simulated suite and the KITTI suite.

use super::options::{kitti_tracking_options, parse_score_map};
use super::report::{print_kitti_report, print_suite_report};
use super::{EvalCommand, SuiteArgs};
use crate::experiments::EvaluateError;
use crate::experiments::{EgoEvalOptions, evaluate_ego, parse_rpe_delta};
use crate::experiments::{TrackEvalOptions, evaluate_tracks};
use std::path::PathBuf;

pub(super) fn parse_align(s: &str) -> Result<crate::metrics::AlignMode, EvaluateError> {
    use crate::metrics::AlignMode;
    match s.to_ascii_lowercase().as_str() {
        "se3" => Ok(AlignMode::Se3),
        "sim3" => Ok(AlignMode::Sim3),
        "none" => Ok(AlignMode::None),
        _ => Err(EvaluateError::Argument(format!(
            "--align `{s}`: expected se3, sim3 or none"
        ))),
    }
}

pub(super) fn write_output(path: &std::path::Path, text: &str) -> Result<(), EvaluateError> {
    std::fs::write(path, text).map_err(|source| EvaluateError::Io {
        path: path.to_path_buf(),
        source,
    })
}

pub(super) fn run_eval(what: EvalCommand) -> Result<(), Box<dyn std::error::Error>> {
    match what {
        EvalCommand::Ego {
            truth,
            estimate,
            format,
            times,
            truth_format,
            truth_times,
            sequence,
            align,
            max_dt,
            rpe_delta,
            rpe_all_pairs,
            json,
            markdown,
        } => {
            let opts = EgoEvalOptions {
                estimate_format: format.as_deref().map(str::parse).transpose()?,
                estimate_times: times,
                truth_format: truth_format.as_deref().map(str::parse).transpose()?,
                truth_times,
                sequence,
                align: parse_align(&align)?,
                max_dt_s: max_dt,
                rpe_delta: parse_rpe_delta(&rpe_delta)?,
                rpe_all_pairs,
            };
            let r = evaluate_ego(&truth, &estimate, &opts)?;
            println!("{}", r.summary_line());
            println!();
            print!("{}", r.table()?.to_markdown()?);
            if let Some(note) = r.alignment_note() {
                println!("note: {note}");
            }
            if let Some(path) = json {
                write_output(&path, &r.to_json().render())?;
            }
            if let Some(path) = markdown {
                write_output(&path, &r.to_markdown()?)?;
            }
        }
        EvalCommand::Tracks {
            truth,
            results,
            gt_filter,
            sequence,
            json,
            markdown,
        } => {
            let opts = TrackEvalOptions {
                gt_filter: gt_filter.parse()?,
                sequence,
                ..TrackEvalOptions::default()
            };
            let r = evaluate_tracks(&truth, &results, &opts)?;
            for line in r.summary_lines() {
                println!("{line}");
            }
            println!();
            print!("{}", r.clear_mot_table()?.to_markdown()?);
            println!();
            print!("{}", r.object_table()?.to_markdown()?);
            if let Some(path) = json {
                write_output(&path, &r.to_json().render())?;
            }
            if let Some(path) = markdown {
                write_output(&path, &r.to_markdown()?)?;
            }
        }
        EvalCommand::Suite(args) => run_eval_suite(args)?,
        EvalCommand::Kitti {
            training,
            detections,
            score_map,
            sequences,
            variants,
            tracker,
            tracking_peer,
            ego_peer,
            out,
        } => run_eval_kitti(
            training,
            detections,
            &score_map,
            sequences,
            &variants,
            &tracker,
            tracking_peer,
            ego_peer,
            out,
        )?,
    }
    Ok(())
}

/// `limot eval suite`: runs the suite, writes OUT/report and prints the ego table.
pub(super) fn run_eval_suite(args: SuiteArgs) -> Result<(), Box<dyn std::error::Error>> {
    use crate::experiments::{Ablation, KittiTwins, Shard, SuiteSpec, TWIN_FAMILY};
    use crate::experiments::{parse_list, parse_sequences, run_suite};
    use limot_estimator::Variant;
    let families = match &args.families {
        Some(list) => parse_list("families", list, |s| Ok(s.to_string()))?,
        None => limot_sim::scenario::ScenarioSpec::builtin_names()
            .iter()
            .map(|name| name.to_string())
            .collect(),
    };
    let twins_only = families.iter().all(|f| f == TWIN_FAMILY);
    let twins = match (args.training, args.sequences) {
        (Some(training), Some(sequences)) => Some(KittiTwins {
            training,
            sequences: parse_sequences("sequences", &sequences)?,
            detections: args.detections,
        }),
        (Some(training), None) => {
            if !training.is_dir() {
                return Err(format!("--training {}: not a directory", training.display()).into());
            }
            Some(KittiTwins::every_sequence(&training, args.detections)?)
        }
        (None, Some(_)) => return Err("--sequences needs --training DIR".into()),
        (None, None) if args.detections.is_some() => {
            return Err("--detections needs --training DIR and --families kitti".into());
        }
        (None, None) => None,
    };
    // A twin is as long as its KITTI sequence and one seed of its corridor is
    // the natural default; generated scenes default to 30 s and two seeds.
    let seeds = args
        .seeds
        .unwrap_or_else(|| if twins_only { "1" } else { "1,2" }.to_string());
    let duration_s = args.duration.unwrap_or(if twins_only {
        limot_sim::scenario::MAX_DURATION_S
    } else {
        30.0
    });
    let spec = SuiteSpec {
        families,
        seeds: parse_list("seeds", &seeds, |s| {
            s.parse::<u64>().map_err(|e| e.to_string())
        })?,
        duration_s,
        variants: parse_list("variants", &args.variants, |s| {
            s.parse::<Variant>().map_err(|e| e.to_string())
        })?,
        ablations: match &args.ablation {
            Some(list) => parse_list("ablation", list, str::parse::<Ablation>)?,
            None => Vec::new(),
        },
        out_dir: args.out,
        shard: args.shard.as_deref().map(Shard::parse).transpose()?,
        jobs: args.jobs,
        twins,
    };
    let sequences = spec.sequence_families()?.len() * spec.seeds.len();
    let runs = sequences * spec.runs_per_sequence();
    let ablations = if spec.ablations.is_empty() {
        String::new()
    } else {
        format!(" + {} ablation(s)", spec.ablations.len())
    };
    println!(
        "limot eval suite: {sequences} sequence(s) x ({} variant(s){ablations}) = {runs} runs of up to {} s into {}",
        spec.variants.len(),
        spec.duration_s,
        spec.out_dir.display()
    );
    if let Some(twins) = &spec.twins {
        let missing: Vec<String> = twins
            .sequences
            .iter()
            .filter_map(|&n| twins.missing_files(n))
            .collect();
        println!(
            "KITTI twins of {} sequence(s) in {}, detections: {}",
            twins.sequences.len(),
            twins.training.display(),
            twins.detections.as_ref().map_or_else(
                || "the simulator's detector model".to_string(),
                |d| d.display().to_string()
            )
        );
        for why in missing {
            println!("  not available: {why}");
        }
    }
    let results = run_suite(&spec, true)?;
    if let Some(shard) = spec.shard {
        println!(
            "shard {}/{}: {} sequence(s) in {}; join all shards with `limot report --merge {}`",
            shard.index,
            shard.count,
            results.sequences.len(),
            spec.out_dir.join(shard.results_file_name()).display(),
            spec.out_dir.join("results-shard-*.json").display()
        );
        return Ok(());
    }
    print_suite_report(&results, &spec.out_dir, &spec.out_dir.join("report"))
}

/// `NAME=DIR` of a peer option.
pub(super) fn parse_peer(option: &str, text: &str) -> Result<(String, PathBuf), String> {
    match text.split_once('=') {
        Some((name, dir)) if !name.trim().is_empty() && !dir.is_empty() => {
            Ok((name.trim().to_string(), PathBuf::from(dir)))
        }
        _ => Err(format!("--{option} `{text}`: expected NAME=DIR")),
    }
}

#[allow(clippy::too_many_arguments)]
pub(super) fn run_eval_kitti(
    training: PathBuf,
    detections: Option<PathBuf>,
    score_map: &str,
    sequences: Option<String>,
    variants: &str,
    tracker: &str,
    tracking_peer: Option<String>,
    ego_peer: Vec<String>,
    out: PathBuf,
) -> Result<(), Box<dyn std::error::Error>> {
    use crate::experiments::parse_list;
    use crate::experiments::{KittiSuiteSpec, run_kitti_suite};
    use limot_estimator::Variant;
    let spec = KittiSuiteSpec {
        training,
        detections,
        tracking: kitti_tracking_options(tracker, parse_score_map(score_map)?)?,
        variants: parse_list("variants", variants, |s| {
            s.parse::<Variant>().map_err(|e| e.to_string())
        })?,
        sequences: sequences
            .map(|s| crate::experiments::parse_sequences("sequences", &s))
            .transpose()?,
        tracking_peer: tracking_peer
            .map(|p| parse_peer("tracking-peer", &p))
            .transpose()?,
        ego_peers: ego_peer
            .iter()
            .map(|p| parse_peer("ego-peer", p))
            .collect::<Result<_, _>>()?,
        out_dir: out,
    };
    println!(
        "limot eval kitti: {} into {}",
        spec.training.display(),
        spec.out_dir.display()
    );
    let results = run_kitti_suite(&spec, true)?;
    let file = spec.out_dir.join(crate::experiments::RESULTS_FILE);
    print_kitti_report(&results, &file, &spec.out_dir.join("report"))
}
