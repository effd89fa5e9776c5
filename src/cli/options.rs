//! Argument parsers shared by several subcommands.

pub(super) fn parse_score_map(
    name: &str,
) -> Result<crate::io::kitti::detections::ScoreMap, String> {
    use crate::io::kitti::detections::ScoreMap;
    match name {
        "sigmoid" => Ok(ScoreMap::Sigmoid),
        "clamp01" => Ok(ScoreMap::Clamp01),
        other => Err(format!("unknown --score-map `{other}` (sigmoid, clamp01)")),
    }
}

/// The KITTI tracking settings (tracker and result-file rules) named `paper`
/// (the paper's tracker; every matched confirmed track written), `tuned`
/// (online, chosen on the KITTI val split with PointRCNN boxes) or `offline`
/// (tuned, with AB3DMOT's whole-track score gate; not causal).
pub(super) fn kitti_tracking_options(
    name: &str,
    score_map: crate::io::kitti::detections::ScoreMap,
) -> Result<crate::experiments::TrackKittiOptions, String> {
    use crate::experiments::{TrackKittiOptions, kitti_val_offline_options};
    let options = match name {
        "paper" => TrackKittiOptions::default(),
        "tuned" => crate::experiments::kitti_val_tuned_options(),
        "offline" => kitti_val_offline_options(),
        other => {
            return Err(format!(
                "tracker settings `{other}`: expected paper, tuned or offline"
            ));
        }
    };
    Ok(crate::experiments::TrackKittiOptions {
        score_map,
        ..options
    })
}

/// `--mcap-points N|all` of the commands that record MCAP files: the cloud
/// points a recorded sweep keeps at most (`None`: all).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub(super) struct McapPoints {
    /// Cloud points per sweep in the MCAP recording: at most N (every
    /// k-th point, the filter's removed points besides) or `all`. The
    /// default keeps a 64-beam sweep's shape at a fifth of its size.
    #[arg(long = "mcap-points", value_name = "N|all", default_value = "25000", value_parser = parse_mcap_points)]
    max_cloud_points: PointCap,
}

/// The parsed value of `--mcap-points` (a newtype: clap takes a bare
/// `Option` field for an optional flag).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PointCap(Option<usize>);

impl McapPoints {
    /// The recording of `path` at this density.
    pub(super) fn request(self, path: std::path::PathBuf) -> crate::io::mcap::McapRequest {
        crate::io::mcap::McapRequest {
            path,
            max_cloud_points: self.max_cloud_points.0,
        }
    }
}

/// Parses `--mcap-points`: a positive count, or `all` (no cap).
fn parse_mcap_points(s: &str) -> Result<PointCap, String> {
    if s == "all" {
        return Ok(PointCap(None));
    }
    match s.parse::<usize>() {
        Ok(n) if n > 0 => Ok(PointCap(Some(n))),
        _ => Err(format!("`{s}` is neither a positive point count nor `all`")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_recording_command_takes_mcap_points() {
        use clap::Parser as _;
        for command in [
            &["simulate", "urban", "--out", "d"][..],
            &["run", "data/urban"],
            &["demo"],
        ] {
            for (flag, cap) in [
                (None, Some(25_000)),
                (Some("all"), None),
                (Some("7"), Some(7)),
            ] {
                let mut args = vec!["limot"];
                args.extend(command);
                args.extend(["--mcap", "x.mcap"]);
                if let Some(flag) = flag {
                    args.extend(["--mcap-points", flag]);
                }
                let cli = super::super::Cli::try_parse_from(&args).unwrap();
                let points = match cli.command {
                    super::super::Command::Simulate { mcap_points, .. }
                    | super::super::Command::Run { mcap_points, .. }
                    | super::super::Command::Demo { mcap_points, .. } => mcap_points,
                    _ => unreachable!("{args:?}"),
                };
                let request = points.request("x.mcap".into());
                assert_eq!(request.max_cloud_points, cap, "{args:?}");
            }
        }
    }

    #[test]
    fn mcap_points_are_a_positive_count_or_all() {
        assert_eq!(parse_mcap_points("all"), Ok(PointCap(None)));
        assert_eq!(parse_mcap_points("25000"), Ok(PointCap(Some(25_000))));
        for bad in ["0", "-3", "many", ""] {
            let e = parse_mcap_points(bad).unwrap_err();
            assert!(e.contains(&format!("`{bad}`")), "{e}");
        }
    }
}
