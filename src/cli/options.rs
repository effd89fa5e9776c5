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
