//! The accuracy a GNSS fix is taken at, before any filter sees it.
//!
//! A receiver's accuracy estimate follows its satellites and their geometry, which
//! change over tens of seconds, not from one fix to the next; a single fix that claims
//! much better than its neighbours is more likely a lucky estimate than a better
//! position (the first fix of IPIN 2023's Trial21 rep. 3 reports 24 m among fixes of
//! 31-44 m, and sits 30 m from all of them). So a fix is taken at no better than
//! [`ACCURACY_CLAIM_SHARE`] of the median accuracy of the fixes within
//! [`ACCURACY_NEIGHBOURHOOD_S`] of it. A fix's own worse accuracy is always kept, and a
//! fix without one is left as it is.

use super::fusion::FixInput;

/// The neighbourhood (s either side).
pub const ACCURACY_NEIGHBOURHOOD_S: f64 = 15.0;
/// How much better than its neighbourhood a fix may claim to be. Of 0.6, 0.75, 0.9 and 1
/// (ACCURACY.md), 0.75-1 are alike on route 01 (P75 3.5-3.6 m against 3.8 m without a
/// floor); at 0.9 and 1 the σ covers 99 % of the 160 landmark errors at 2σ, too cautious.
pub const ACCURACY_CLAIM_SHARE: f64 = 0.75;

/// The fixes with each accuracy floored at [`ACCURACY_CLAIM_SHARE`] of its
/// neighbourhood's median.
pub fn with_neighbourhood_accuracy(fixes: &[FixInput]) -> Vec<FixInput> {
    let reported: Vec<(f64, f64)> = fixes
        .iter()
        .filter_map(|fix| {
            let hacc_m = fix.hacc_m.filter(|hacc| hacc.is_finite() && *hacc > 0.0)?;
            Some((fix.t_s, hacc_m))
        })
        .collect();
    fixes
        .iter()
        .map(|fix| {
            let first =
                reported.partition_point(|(t_s, _)| *t_s < fix.t_s - ACCURACY_NEIGHBOURHOOD_S);
            let last =
                reported.partition_point(|(t_s, _)| *t_s <= fix.t_s + ACCURACY_NEIGHBOURHOOD_S);
            let mut around: Vec<f64> = reported
                .get(first..last)
                .unwrap_or(&[])
                .iter()
                .map(|&(_, hacc_m)| hacc_m)
                .collect();
            let median = crate::base::stats::median(&mut around);
            FixInput {
                hacc_m: match (fix.hacc_m, median) {
                    (Some(hacc_m), Some(median_m)) if hacc_m.is_finite() => {
                        Some(hacc_m.max(ACCURACY_CLAIM_SHARE * median_m))
                    }
                    (hacc_m, _) => hacc_m,
                },
                ..*fix
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(t_s: f64, hacc_m: Option<f64>) -> FixInput {
        FixInput {
            t_s,
            en_m: [0.0, 0.0],
            hacc_m,
        }
    }

    #[test]
    fn a_fix_claiming_far_better_than_its_neighbours_is_taken_at_their_share() {
        let mut fixes: Vec<FixInput> = (0..20).map(|k| fix(k as f64, Some(40.0))).collect();
        fixes[0].hacc_m = Some(24.0);
        fixes[5].hacc_m = Some(35.0);
        fixes[9].hacc_m = None;
        fixes[12].hacc_m = Some(60.0);
        let taken = with_neighbourhood_accuracy(&fixes);
        assert_eq!(taken[0].hacc_m, Some(ACCURACY_CLAIM_SHARE * 40.0));
        // Within the share, and worse than the neighbours: as reported.
        assert_eq!(taken[5].hacc_m, Some(35.0));
        assert_eq!(taken[12].hacc_m, Some(60.0));
        assert_eq!(taken[9].hacc_m, None);
        assert_eq!(taken[3].hacc_m, Some(40.0));
        // Far from the others, a fix has only its own accuracy to go by.
        let lone = with_neighbourhood_accuracy(&[fix(0.0, Some(40.0)), fix(100.0, Some(5.0))]);
        assert_eq!(lone[1].hacc_m, Some(5.0));
    }
}
