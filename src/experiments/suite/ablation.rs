//! Ablations of the suite: one variant run again on every sequence with one
//! estimator setting changed, saved and reported beside the variant it changes
//! (`limot eval suite --ablation joint`).

use limot_estimator::Variant;
use limot_estimator::pipeline::EstimatorConfig;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// A suite-level run of [`Ablation::variant`] with one configuration override.
///
/// Not a [`Variant`]: the variants are the systems compared, an ablation is
/// one of them with one setting changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Ablation {
    /// `limot` in the fully joint form: dynamic objects inform the ego
    /// (`ObjectGraphConfig::dynamic_objects_inform_ego = true`) instead of
    /// being conditioned on the optimised ego.
    Joint,
}

impl Ablation {
    /// Every ablation, in report order.
    pub const ALL: [Ablation; 1] = [Ablation::Joint];

    /// Machine name, as `--ablation` takes it (`joint`).
    pub fn name(self) -> &'static str {
        match self {
            Ablation::Joint => "joint",
        }
    }

    /// The variant this ablation changes.
    pub fn variant(self) -> Variant {
        match self {
            Ablation::Joint => Variant::Limot,
        }
    }

    /// The run's name in results and its run directory: `<variant>-<name>`
    /// (`limot-joint`), which no variant name can take.
    pub fn run_name(self) -> String {
        format!("{}-{}", self.variant().name(), self.name())
    }

    /// Label in report tables (`LIMOT (joint)`).
    pub fn label(self) -> String {
        format!("{} ({})", self.variant().label(), self.name())
    }

    /// Applies the override to a configuration of [`Ablation::variant`].
    pub fn apply(self, config: &mut EstimatorConfig) {
        match self {
            Ablation::Joint => config.objects.dynamic_objects_inform_ego = true,
        }
    }
}

impl fmt::Display for Ablation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Ablation {
    type Err = String;

    fn from_str(s: &str) -> Result<Ablation, String> {
        Ablation::ALL
            .into_iter()
            .find(|a| a.name() == s || a.run_name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Ablation::ALL.iter().map(|a| a.name()).collect();
                format!("unknown ablation (expected one of: {})", names.join(", "))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiments::parse_list;

    #[test]
    fn names_parse_and_key_the_run() {
        let list = parse_list("ablation", " joint ,", str::parse::<Ablation>).unwrap();
        assert_eq!(list, vec![Ablation::Joint]);
        assert_eq!("limot-joint".parse::<Ablation>(), Ok(Ablation::Joint));
        let e = parse_list("ablation", "jointly", str::parse::<Ablation>)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--ablation `jointly`") && e.contains("joint"),
            "{e}"
        );
        let joint = Ablation::Joint;
        assert_eq!(joint.variant(), Variant::Limot);
        assert_eq!(joint.run_name(), "limot-joint");
        assert_eq!(joint.label(), "LIMOT (joint)");
        assert!("limot-joint".parse::<Variant>().is_err(), "not a variant");
        assert_eq!(serde_json::to_string(&joint).unwrap(), "\"joint\"");
    }

    #[test]
    fn joint_lets_dynamic_objects_inform_the_ego() {
        let mut config = EstimatorConfig::default();
        assert!(
            !config.objects.dynamic_objects_inform_ego,
            "conditioned by default"
        );
        Ablation::Joint.apply(&mut config);
        assert!(config.objects.dynamic_objects_inform_ego);
    }
}
