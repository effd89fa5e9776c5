//! The paper's published figures that the KITTI report sets beside ours
//! (Tables I-III of the LIMOT paper, copied by hand).

use crate::report::Cell;
use limot_estimator::Variant;

/// A row of the paper's Table I: sequence, then (ATE_T m, ATE_R rad) for
/// LIO-SAM, DL-SLOT, LIO-SEGMOT, LIO-Allfilt, LIO-Dynafilt, LIMOT.
pub(super) type PaperEgoRow = (u32, [(f64, f64); 6]);

/// The paper's Table I (ego ATE on KITTI tracking, CenterPoint detections).
pub(super) const PAPER_TABLE_I: [PaperEgoRow; 18] = [
    (
        0,
        [
            (0.856, 0.024),
            (0.984, 0.031),
            (0.867, 0.020),
            (0.854, 0.024),
            (0.852, 0.024),
            (0.846, 0.024),
        ],
    ),
    (
        1,
        [
            (1.683, 0.044),
            (1.764, 0.193),
            (1.704, 0.043),
            (1.824, 0.043),
            (1.686, 0.044),
            (1.681, 0.045),
        ],
    ),
    (
        2,
        [
            (0.274, 0.013),
            (0.362, 0.023),
            (0.253, 0.016),
            (0.280, 0.014),
            (0.274, 0.012),
            (0.269, 0.013),
        ],
    ),
    (
        3,
        [
            (0.245, 0.031),
            (1.920, 0.050),
            (0.269, 0.038),
            (0.247, 0.028),
            (0.246, 0.028),
            (0.245, 0.030),
        ],
    ),
    (
        4,
        [
            (0.660, 0.104),
            (1.050, 0.276),
            (0.657, 0.114),
            (0.659, 0.116),
            (0.634, 0.099),
            (0.629, 0.107),
        ],
    ),
    (
        5,
        [
            (0.347, 0.134),
            (1.209, 0.100),
            (0.313, 0.124),
            (0.346, 0.127),
            (0.342, 0.122),
            (0.355, 0.112),
        ],
    ),
    (
        6,
        [
            (0.266, 0.013),
            (1.925, 0.081),
            (0.202, 0.012),
            (0.199, 0.012),
            (0.206, 0.012),
            (0.190, 0.012),
        ],
    ),
    (
        7,
        [
            (1.319, 0.025),
            (1.759, 0.272),
            (1.376, 0.032),
            (1.331, 0.025),
            (1.308, 0.024),
            (1.278, 0.024),
        ],
    ),
    (
        8,
        [
            (1.274, 0.307),
            (2.807, 0.284),
            (1.120, 0.284),
            (1.253, 0.328),
            (1.257, 0.310),
            (1.237, 0.311),
        ],
    ),
    (
        9,
        [
            (1.201, 0.024),
            (1.597, 1.123),
            (1.135, 0.025),
            (1.181, 0.024),
            (1.220, 0.025),
            (1.175, 0.030),
        ],
    ),
    (
        10,
        [
            (0.438, 0.108),
            (0.860, 0.137),
            (0.495, 0.106),
            (0.447, 0.118),
            (0.438, 0.106),
            (0.425, 0.106),
        ],
    ),
    (
        11,
        [
            (0.262, 0.202),
            (0.303, 0.214),
            (0.282, 0.283),
            (0.260, 0.182),
            (0.262, 0.150),
            (0.266, 0.181),
        ],
    ),
    (
        13,
        [
            (0.260, 0.044),
            (0.331, 0.051),
            (0.258, 0.040),
            (0.263, 0.043),
            (0.262, 0.043),
            (0.256, 0.045),
        ],
    ),
    (
        14,
        [
            (0.105, 0.013),
            (0.151, 0.197),
            (0.095, 0.013),
            (0.111, 0.014),
            (0.107, 0.013),
            (0.108, 0.012),
        ],
    ),
    (
        15,
        [
            (0.275, 0.066),
            (0.385, 0.012),
            (0.291, 0.076),
            (0.274, 0.065),
            (0.273, 0.066),
            (0.274, 0.066),
        ],
    ),
    (
        18,
        [
            (0.385, 0.141),
            (0.851, 0.166),
            (0.371, 0.168),
            (0.374, 0.157),
            (0.376, 0.159),
            (0.373, 0.160),
        ],
    ),
    (
        19,
        [
            (0.916, 0.122),
            (1.006, 0.358),
            (0.955, 0.136),
            (0.916, 0.131),
            (0.916, 0.135),
            (0.915, 0.120),
        ],
    ),
    (
        20,
        [
            (9.488, 0.021),
            (22.349, 0.043),
            (9.313, 0.023),
            (1.863, 0.027),
            (1.834, 0.025),
            (1.710, 0.027),
        ],
    ),
];

/// Table I's methods; the last four correspond to our variants.
pub(super) const PAPER_EGO_METHODS: [(&str, Option<Variant>); 6] = [
    ("LIO-SAM", Some(Variant::Lio)),
    ("DL-SLOT", None),
    ("LIO-SEGMOT", None),
    ("LIO-Allfilt", Some(Variant::Allfilt)),
    ("LIO-Dynafilt", Some(Variant::Dynafilt)),
    ("LIMOT", Some(Variant::Limot)),
];

/// The paper's Table II: MOTP [%] at 3D IoU 0.25 and 0.5 over its sequences.
pub(super) const PAPER_TABLE_II: [(&str, f64, f64); 5] = [
    ("AB3DMOT", 61.37, 64.17),
    ("PC3T", 61.26, 64.07),
    ("DL-SLOT", 60.13, 63.60),
    ("LIO-SEGMOT", 61.45, 64.22),
    ("LIMOT", 62.25, 64.26),
];

/// The paper's Table II as rows of our Table II layouts: method, `source`,
/// "all" sequences, then (MOTA, MOTP) at IoU 0.25 and 0.5 (the paper gives
/// MOTP only) and four empty count columns (IDSW, FP, FN, GT). With
/// `with_2d_mota` an empty 2D MOTA column comes before the 3D ones.
pub(super) fn paper_table_ii_rows(source: &str, with_2d_mota: bool) -> Vec<Vec<Cell>> {
    PAPER_TABLE_II
        .iter()
        .map(|&(name, motp25, motp50)| {
            let mut cells = vec![Cell::from(name), Cell::from(source), Cell::from("all")];
            if with_2d_mota {
                cells.push(Cell::Missing);
            }
            cells.extend([Cell::Missing, motp25.into(), Cell::Missing, motp50.into()]);
            cells.extend(vec![Cell::Missing; 4]);
            cells
        })
        .collect()
}

/// The paper's Table III: sequence, object id, then (TP %, ATE_T m, ATE_R rad)
/// for DL-SLOT, LIO-SEGMOT and LIMOT.
pub(super) type PaperObjectRow = (u32, u64, [(f64, f64, f64); 3]);

/// The paper's Table III rows.
pub(super) const PAPER_TABLE_III: [PaperObjectRow; 10] = [
    (
        4,
        2,
        [
            (27.07, 2.799, 1.760),
            (27.71, 0.711, 0.241),
            (27.07, 0.697, 0.233),
        ],
    ),
    (
        5,
        31,
        [
            (40.40, 0.924, 0.223),
            (40.07, 0.304, 0.175),
            (40.40, 0.302, 0.163),
        ],
    ),
    (
        8,
        8,
        [
            (23.33, 0.661, 0.346),
            (24.36, 0.430, 0.122),
            (23.08, 0.384, 0.130),
        ],
    ),
    (
        8,
        13,
        [
            (48.85, 0.827, 0.116),
            (50.76, 0.656, 0.104),
            (48.85, 0.641, 0.105),
        ],
    ),
    (
        10,
        0,
        [
            (93.88, 0.943, 0.168),
            (88.44, 0.439, 0.156),
            (93.88, 0.368, 0.156),
        ],
    ),
    (
        11,
        0,
        [
            (51.21, 0.445, 0.129),
            (50.40, 0.292, 0.186),
            (51.21, 0.277, 0.189),
        ],
    ),
    (
        18,
        2,
        [
            (29.17, 0.566, 0.878),
            (31.44, 0.246, 0.580),
            (30.68, 0.261, 0.602),
        ],
    ),
    (
        18,
        3,
        [
            (46.67, 0.493, 0.456),
            (45.61, 0.386, 0.560),
            (47.02, 0.372, 0.459),
        ],
    ),
    (
        20,
        12,
        [
            (37.79, 10.342, 0.106),
            (45.10, 1.701, 0.105),
            (46.66, 0.826, 0.102),
        ],
    ),
    (
        20,
        122,
        [
            (30.20, 1.005, 0.117),
            (29.41, 0.258, 0.127),
            (30.20, 0.292, 0.131),
        ],
    ),
];

/// Table III's methods; the last is ours.
pub(super) const PAPER_OBJECT_METHODS: [&str; 3] = ["DL-SLOT", "LIO-SEGMOT", "LIMOT"];

/// The paper's Table I figures (ATE_T m, ATE_R rad) of `variant`'s
/// counterpart on `sequence`, when the table has that sequence.
pub(super) fn paper_ego(sequence: u32, variant: Variant) -> Option<(f64, f64)> {
    let column = PAPER_EGO_METHODS
        .iter()
        .position(|(_, v)| *v == Some(variant))?;
    PAPER_TABLE_I
        .iter()
        .find(|(s, _)| *s == sequence)
        .map(|(_, row)| row[column])
}

/// The paper's name of `variant`'s counterpart in Table I.
pub(super) fn paper_name(variant: Variant) -> &'static str {
    PAPER_EGO_METHODS
        .iter()
        .find(|(_, v)| *v == Some(variant))
        .map_or("?", |(name, _)| name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_ii_rows_put_the_motp_under_their_columns() {
        let twins = paper_table_ii_rows("paper", false);
        let real = paper_table_ii_rows("paper", true);
        assert_eq!((twins.len(), real.len()), (5, 5));
        let limot_twins = &twins[4];
        let limot_real = &real[4];
        // method, source, sequences, MOTA/MOTP@0.25, MOTA/MOTP@0.5, 4 counts
        assert_eq!((limot_twins.len(), limot_real.len()), (11, 12));
        assert_eq!(limot_twins[0], Cell::from("LIMOT"));
        assert_eq!(limot_twins[4], Cell::from(62.25));
        assert_eq!(limot_twins[6], Cell::from(64.26));
        // the 2D MOTA column shifts the 3D ones by one
        assert_eq!(limot_real[3], Cell::Missing);
        assert_eq!(limot_real[5], Cell::from(62.25));
        assert_eq!(limot_real[7], Cell::from(64.26));
    }
}
