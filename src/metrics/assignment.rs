//! Rectangular linear assignment with forbidden entries (Kuhn–Munkres /
//! Hungarian algorithm with potentials, O(n²·m) for n ≤ m).
//!
//! Semantics (as the KITTI devkit's Munkres with a huge cost for forbidden
//! pairs, but exact): among all matchings that use only allowed pairs, pick one
//! with the largest number of pairs, and among those one with the smallest
//! total cost. Instead of a big-M constant (which loses the small costs to
//! rounding) the costs are lexicographic pairs (forbidden count, cost); the
//! Hungarian algorithm works unchanged over this ordered group.

use super::EvalError;
use std::cmp::Ordering;
use std::ops::{Add, Sub};

/// The chosen pairs `(row, col)`, sorted by row, and their summed cost.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// Matched `(row, column)` pairs, by increasing row.
    pub pairs: Vec<(usize, usize)>,
    /// Sum of the matched pairs' costs.
    pub total_cost: f64,
}

/// Lexicographic cost: number of forbidden pairs first, then the real cost.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Lex {
    forbidden: i64,
    cost: f64,
}

impl Lex {
    const ZERO: Lex = Lex {
        forbidden: 0,
        cost: 0.0,
    };
    const INF: Lex = Lex {
        forbidden: i64::MAX / 4,
        cost: 0.0,
    };
}

impl Add for Lex {
    type Output = Lex;
    fn add(self, o: Lex) -> Lex {
        Lex {
            forbidden: self.forbidden + o.forbidden,
            cost: self.cost + o.cost,
        }
    }
}

impl Sub for Lex {
    type Output = Lex;
    fn sub(self, o: Lex) -> Lex {
        Lex {
            forbidden: self.forbidden - o.forbidden,
            cost: self.cost - o.cost,
        }
    }
}

impl PartialOrd for Lex {
    fn partial_cmp(&self, o: &Lex) -> Option<Ordering> {
        Some(
            self.forbidden
                .cmp(&o.forbidden)
                .then(self.cost.total_cmp(&o.cost)),
        )
    }
}

/// Minimum-cost assignment on a `rows × cols` row-major cost matrix.
/// `f64::INFINITY` marks a forbidden pair; NaN and −∞ are errors.
///
/// # Errors
///
/// [`EvalError`] for a non-finite cost or a ragged matrix.
pub fn min_cost_assignment(
    rows: usize,
    cols: usize,
    cost: &[f64],
) -> Result<Assignment, EvalError> {
    const WHAT: &str = "assignment cost matrix";
    let expected = rows.checked_mul(cols).ok_or(EvalError::BadParameter {
        what: WHAT,
        why: "rows × cols overflows".into(),
    })?;
    if cost.len() != expected {
        return Err(EvalError::LengthMismatch {
            what: WHAT,
            left: cost.len(),
            right: expected,
        });
    }
    if let Some(index) = cost
        .iter()
        .position(|c| c.is_nan() || *c == f64::NEG_INFINITY)
    {
        return Err(EvalError::Invalid {
            what: WHAT,
            index,
            field: "cost",
            why: format!("{} (use +inf for a forbidden pair)", cost[index]),
        });
    }
    if rows == 0 || cols == 0 {
        return Ok(Assignment {
            pairs: Vec::new(),
            total_cost: 0.0,
        });
    }
    let lex = |c: f64| {
        if c == f64::INFINITY {
            Lex {
                forbidden: 1,
                cost: 0.0,
            }
        } else {
            Lex {
                forbidden: 0,
                cost: c,
            }
        }
    };
    // The algorithm assigns every row of an n × m matrix with n ≤ m.
    let transposed = rows > cols;
    let (n, m) = if transposed {
        (cols, rows)
    } else {
        (rows, cols)
    };
    let at = |i: usize, j: usize| {
        if transposed {
            lex(cost[j * cols + i])
        } else {
            lex(cost[i * cols + j])
        }
    };
    let row_of_col = hungarian(n, m, at);
    let mut pairs = Vec::new();
    let mut total_cost = 0.0;
    for (j, &i) in row_of_col.iter().enumerate() {
        let Some(i) = i else { continue };
        let (r, c) = if transposed { (j, i) } else { (i, j) };
        let value = cost[r * cols + c];
        if value.is_finite() {
            pairs.push((r, c));
            total_cost += value;
        }
    }
    pairs.sort_unstable();
    Ok(Assignment { pairs, total_cost })
}

/// Shortest-augmenting-path Hungarian algorithm with row/column potentials
/// (the classic e-maxx formulation). Returns, per column, the assigned row.
fn hungarian(n: usize, m: usize, a: impl Fn(usize, usize) -> Lex) -> Vec<Option<usize>> {
    // 1-based internally; index 0 is the virtual start column/row.
    let mut u = vec![Lex::ZERO; n + 1];
    let mut v = vec![Lex::ZERO; m + 1];
    let mut p = vec![0usize; m + 1];
    let mut way = vec![0usize; m + 1];
    for i in 1..=n {
        p[0] = i;
        let mut j0 = 0usize;
        let mut minv = vec![Lex::INF; m + 1];
        let mut used = vec![false; m + 1];
        loop {
            used[j0] = true;
            let i0 = p[j0];
            let mut delta = Lex::INF;
            let mut j1 = 0usize;
            for j in 1..=m {
                if !used[j] {
                    let cur = a(i0 - 1, j - 1) - u[i0] - v[j];
                    if cur < minv[j] {
                        minv[j] = cur;
                        way[j] = j0;
                    }
                    if minv[j] < delta {
                        delta = minv[j];
                        j1 = j;
                    }
                }
            }
            for j in 0..=m {
                if used[j] {
                    u[p[j]] = u[p[j]] + delta;
                    v[j] = v[j] - delta;
                } else {
                    minv[j] = minv[j] - delta;
                }
            }
            j0 = j1;
            if p[j0] == 0 {
                break;
            }
        }
        loop {
            let j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    (1..=m)
        .map(|j| if p[j] == 0 { None } else { Some(p[j] - 1) })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const X: f64 = f64::INFINITY;

    #[test]
    fn square_hand_case() {
        #[rustfmt::skip]
        let c = [
            4.0, 1.0, 3.0,
            2.0, 0.0, 5.0,
            3.0, 2.0, 2.0,
        ];
        let a = min_cost_assignment(3, 3, &c).unwrap();
        assert_eq!(a.pairs, vec![(0, 1), (1, 0), (2, 2)]);
        assert_eq!(a.total_cost, 5.0);
    }

    #[test]
    fn forbidden_entries_maximise_matches_first() {
        // Cheapest single pair (0,0)=0 would block row 1; two pairs are preferred.
        #[rustfmt::skip]
        let c = [
            0.0, 10.0,
            5.0, X,
        ];
        let a = min_cost_assignment(2, 2, &c).unwrap();
        assert_eq!(a.pairs, vec![(0, 1), (1, 0)]);
        assert_eq!(a.total_cost, 15.0);
        let all_forbidden = [X; 6];
        assert!(
            min_cost_assignment(2, 3, &all_forbidden)
                .unwrap()
                .pairs
                .is_empty()
        );
    }

    #[test]
    fn rectangular_both_ways() {
        let c = [3.0, 1.0, 2.0];
        let wide = min_cost_assignment(1, 3, &c).unwrap();
        assert_eq!(wide.pairs, vec![(0, 1)]);
        let tall = min_cost_assignment(3, 1, &c).unwrap();
        assert_eq!(tall.pairs, vec![(1, 0)]);
        assert!(min_cost_assignment(0, 4, &[]).unwrap().pairs.is_empty());
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(matches!(
            min_cost_assignment(2, 2, &[1.0; 3]),
            Err(EvalError::LengthMismatch { .. })
        ));
        assert!(matches!(
            min_cost_assignment(1, 2, &[1.0, f64::NAN]),
            Err(EvalError::Invalid { index: 1, .. })
        ));
        assert!(min_cost_assignment(1, 1, &[f64::NEG_INFINITY]).is_err());
    }
}
