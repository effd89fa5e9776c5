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

/// `--mcap-points N|all`: the cloud points a recorded sweep keeps at most
/// (`None`: all).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct McapPoints(Option<usize>);

impl McapPoints {
    /// The recording of `path` at this density.
    pub(super) fn request(self, path: std::path::PathBuf) -> crate::io::mcap::McapRequest {
        crate::io::mcap::McapRequest {
            path,
            max_cloud_points: self.0,
        }
    }
}

/// Parses `--mcap-points`: a positive count or `all`.
pub(super) fn parse_mcap_points(s: &str) -> Result<McapPoints, String> {
    if s == "all" {
        return Ok(McapPoints(None));
    }
    match s.parse::<usize>() {
        Ok(n) if n > 0 => Ok(McapPoints(Some(n))),
        _ => Err(format!("`{s}` is neither a positive point count nor `all`")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mcap_points_are_a_positive_count_or_all() {
        assert_eq!(parse_mcap_points("all"), Ok(McapPoints(None)));
        assert_eq!(parse_mcap_points("25000"), Ok(McapPoints(Some(25_000))));
        for bad in ["0", "-3", "many", ""] {
            let e = parse_mcap_points(bad).unwrap_err();
            assert!(e.contains(&format!("`{bad}`")), "{e}");
        }
    }
}
