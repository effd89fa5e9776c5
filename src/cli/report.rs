//! `limot report`: re-render (or merge, then render) a suite report from its results.

use std::path::PathBuf;

/// `limot report --baseline`: the suite to compare with and whether a
/// regression is an error.
pub(super) struct Baseline {
    pub(super) path: PathBuf,
    pub(super) fail_on_regression: bool,
}

/// `limot report`: re-renders a suite report from its results.json, or
/// joins the shards' results files first (`--merge`); with a baseline, adds
/// the comparison with it.
pub(super) fn run_report(
    results: &[PathBuf],
    merge: bool,
    out: Option<PathBuf>,
    baseline: Option<Baseline>,
) -> Result<(), Box<dyn std::error::Error>> {
    let (suite, suite_dir) = if merge {
        let (merged, suite_dir) = crate::experiments::merge_shards(results)?;
        let file = merged.save(&suite_dir)?;
        println!(
            "merged {} shard(s), {} sequence(s): {}",
            results.len(),
            merged.sequences.len(),
            file.display()
        );
        (merged, suite_dir)
    } else {
        let [results] = results else {
            return Err(
                "one results file or suite directory (or --merge with the shards' files)".into(),
            );
        };
        let results = results.as_path();
        let file = if results.is_dir() {
            results.join(crate::experiments::RESULTS_FILE)
        } else {
            results.to_path_buf()
        };
        let text =
            std::fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
        if crate::experiments::is_kitti_results(&text) {
            if baseline.is_some() {
                return Err(format!(
                    "{}: --baseline compares suite results (limot eval suite), this is a \
                     real-KITTI results file (limot eval kitti)",
                    file.display()
                )
                .into());
            }
            let kitti = crate::experiments::KittiSuiteResults::parse(&text, &file)?;
            let dir = file
                .parent()
                .map_or_else(|| PathBuf::from("."), PathBuf::from);
            let out = out.unwrap_or_else(|| dir.join("report"));
            return print_kitti_report(&kitti, &file, &out);
        }
        crate::experiments::SuiteResults::load(results)?
    };
    let out = out.unwrap_or_else(|| suite_dir.join("report"));
    print_suite_report(&suite, &suite_dir, &out)?;
    match baseline {
        Some(baseline) => compare_with_baseline(&suite, &baseline, &out),
        None => Ok(()),
    }
}

/// Writes `report_dir/baseline.md`, prints the per-variant summary and the
/// regressions; an error when there are any and the caller asked for a gate.
fn compare_with_baseline(
    suite: &crate::experiments::SuiteResults,
    baseline: &Baseline,
    report_dir: &std::path::Path,
) -> Result<(), Box<dyn std::error::Error>> {
    use crate::report::{Tolerance, baseline_markdown, baseline_summary_table, regressions};
    let (before, _) = crate::experiments::SuiteResults::load(&baseline.path)?;
    let tolerance = Tolerance::default();
    let found = regressions(suite, &before, &tolerance);
    let page = baseline_markdown(
        suite,
        &before,
        &baseline.path.display().to_string(),
        &tolerance,
        &found,
    )?;
    let file = report_dir.join("baseline.md");
    std::fs::write(&file, page).map_err(|e| format!("{}: {e}", file.display()))?;
    println!();
    print!(
        "{}",
        baseline_summary_table(suite, &before, &found)?.to_markdown()?
    );
    for r in &found {
        println!("regression: {r}");
    }
    println!("against the baseline: {}", file.display());
    if baseline.fail_on_regression && !found.is_empty() {
        return Err(format!(
            "{} regression(s) against {} (see {})",
            found.len(),
            baseline.path.display(),
            file.display()
        )
        .into());
    }
    Ok(())
}

pub(super) fn print_kitti_report(
    results: &crate::experiments::KittiSuiteResults,
    results_file: &std::path::Path,
    report_dir: &std::path::Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let readme = crate::report::write_kitti_report(report_dir, results)?;
    println!();
    print!(
        "{}",
        crate::report::kitti_ego_table(results)?.to_markdown()?
    );
    println!();
    print!(
        "{}",
        crate::report::kitti_tracking_table(results)?.to_markdown()?
    );
    println!("results: {}", results_file.display());
    println!("report: {}", readme.display());
    Ok(())
}

pub(super) fn print_suite_report(
    results: &crate::experiments::SuiteResults,
    suite_dir: &std::path::Path,
    report_dir: &std::path::Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let readme = crate::report::write_suite_report(report_dir, results, suite_dir)?;
    println!();
    print!(
        "{}",
        crate::report::suite_ego_table(results)?.to_markdown()?
    );
    if let Some(table) = crate::report::suite_ablation_table(results)? {
        println!();
        print!("{}", table.to_markdown()?);
    }
    for s in &results.sequences {
        if let Some(e) = &s.error {
            println!("{}: not available: {e}", s.name);
        }
        for r in s.variants.iter().filter(|r| r.error.is_some()) {
            println!(
                "{} / {}: not available: {}",
                s.name,
                r.variant.label(),
                r.error.as_deref().unwrap_or_default()
            );
        }
        for r in s.ablations.iter().filter(|r| r.error.is_some()) {
            println!(
                "{} / {}: not available: {}",
                s.name,
                r.ablation.label(),
                r.error.as_deref().unwrap_or_default()
            );
        }
    }
    println!(
        "results: {}",
        suite_dir.join(crate::experiments::RESULTS_FILE).display()
    );
    println!("report: {}", readme.display());
    Ok(())
}
