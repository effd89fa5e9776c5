//! Agreement of two orderings of the same items (e.g. variants ranked by
//! ATE_T on one sequence by us and by the paper): Kendall's τ_b, which
//! counts ties in either ordering as neither agreeing nor disagreeing
//! (Kendall 1945), and the set of best items.

/// Kendall's τ_b of the paired scores `a[i]`, `b[i]` (the same item scored
/// two ways; equal scores tie): +1 when both order every pair alike, -1 when
/// every pair is reversed. `None` for fewer than two items, unequal lengths,
/// a non-finite score, or an ordering that ties everything (τ_b is then
/// undefined).
///
/// ```
/// use limot::metrics::kendall_tau_b;
/// assert_eq!(kendall_tau_b(&[1.0, 2.0, 3.0], &[10.0, 20.0, 30.0]), Some(1.0));
/// assert_eq!(kendall_tau_b(&[1.0, 2.0, 3.0], &[30.0, 20.0, 10.0]), Some(-1.0));
/// assert_eq!(kendall_tau_b(&[1.0, 1.0], &[1.0, 2.0]), None);
/// ```
///
/// See also [`best_items`].
pub fn kendall_tau_b(a: &[f64], b: &[f64]) -> Option<f64> {
    if a.len() != b.len() || a.len() < 2 || a.iter().chain(b).any(|x| !x.is_finite()) {
        return None;
    }
    let sign = |x: f64, y: f64| i64::from(x > y) - i64::from(x < y);
    let (mut concordant, mut discordant) = (0i64, 0i64);
    let (mut untied_a, mut untied_b) = (0i64, 0i64);
    for i in 0..a.len() {
        for j in i + 1..a.len() {
            let (sa, sb) = (sign(a[i], a[j]), sign(b[i], b[j]));
            untied_a += sa.abs();
            untied_b += sb.abs();
            match sa * sb {
                1 => concordant += 1,
                -1 => discordant += 1,
                _ => {}
            }
        }
    }
    if untied_a == 0 || untied_b == 0 {
        return None;
    }
    Some((concordant - discordant) as f64 / ((untied_a as f64) * (untied_b as f64)).sqrt())
}

/// Indices of the lowest score (all of them when tied); empty when a score is
/// not finite or there is none.
///
/// ```
/// use limot::metrics::best_items;
/// assert_eq!(best_items(&[0.3, 0.1, 0.1]), vec![1, 2]);
/// ```
pub fn best_items(scores: &[f64]) -> Vec<usize> {
    if scores.iter().any(|x| !x.is_finite()) {
        return Vec::new();
    }
    let Some(best) = scores.iter().copied().reduce(f64::min) else {
        return Vec::new();
    };
    (0..scores.len()).filter(|&i| scores[i] == best).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tau_b_of_small_orderings() {
        // one swapped pair out of six
        let tau = kendall_tau_b(&[1.0, 2.0, 3.0, 4.0], &[1.0, 3.0, 2.0, 4.0]).unwrap();
        assert!((tau - 4.0 / 6.0).abs() < 1e-12, "{tau}");
        // a tie in one ordering: 5 untied pairs there, 6 in the other
        let tau = kendall_tau_b(&[1.0, 2.0, 3.0, 4.0], &[1.0, 1.0, 3.0, 4.0]).unwrap();
        assert!((tau - 5.0 / 30f64.sqrt()).abs() < 1e-12, "{tau}");
        assert_eq!(kendall_tau_b(&[1.0], &[1.0]), None);
        assert_eq!(kendall_tau_b(&[1.0, 2.0], &[1.0]), None);
        assert_eq!(kendall_tau_b(&[1.0, f64::NAN], &[1.0, 2.0]), None);
    }

    #[test]
    fn best_items_keep_ties() {
        assert_eq!(best_items(&[2.0, 1.0, 3.0]), vec![1]);
        assert!(best_items(&[]).is_empty());
        assert!(best_items(&[1.0, f64::INFINITY]).is_empty());
    }
}
