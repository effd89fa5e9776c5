//! `limot report`: re-render (or merge, then render) a suite report from its results.

use std::path::PathBuf;

/// `limot report`: re-renders a suite report from its results.json, or
/// joins the shards' results files first (`--merge`).
pub(super) fn run_report(
    results: &[PathBuf],
    merge: bool,
    out: Option<PathBuf>,
) -> Result<(), Box<dyn std::error::Error>> {
    if merge {
        let (merged, suite_dir) = crate::experiments::merge_shards(results)?;
        let file = merged.save(&suite_dir)?;
        println!(
            "merged {} shard(s), {} sequence(s): {}",
            results.len(),
            merged.sequences.len(),
            file.display()
        );
        let out = out.unwrap_or_else(|| suite_dir.join("report"));
        return print_suite_report(&merged, &suite_dir, &out);
    }
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
    let text = std::fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
    if crate::experiments::is_kitti_results(&text) {
        let kitti = crate::experiments::KittiSuiteResults::parse(&text, &file)?;
        let dir = file
            .parent()
            .map_or_else(|| PathBuf::from("."), PathBuf::from);
        let out = out.unwrap_or_else(|| dir.join("report"));
        return print_kitti_report(&kitti, &file, &out);
    }
    let (results, suite_dir) = crate::experiments::SuiteResults::load(results)?;
    let out = out.unwrap_or_else(|| suite_dir.join("report"));
    print_suite_report(&results, &suite_dir, &out)
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
