//! The order of the runs of a campaign: every combination once per round, forwards and
//! backwards in an ABBA pattern across rounds.
//!
//! With the combinations `c_0 … c_{n−1}` in their natural order (controller, then wait
//! mode, then condition), round `r` runs them forwards when `r mod 4` is 0 or 3 and
//! backwards when it is 1 or 2: `A B B A A B B A …`. Over any two consecutive rounds every
//! combination holds the mean position `(n − 1)/2`, and over any four a slow linear drift
//! of the machine (warming up, a backup starting) weighs on every combination alike.

/// True when round `round` (0-based) runs the combinations forwards.
pub fn forwards(round: usize) -> bool {
    matches!(round % 4, 0 | 3)
}

/// The indices of `n` combinations in the order round `round` (0-based) runs them.
pub fn round_order(n: usize, round: usize) -> Vec<usize> {
    if forwards(round) {
        (0..n).collect()
    } else {
        (0..n).rev().collect()
    }
}

/// The whole campaign: `(round, combination)` for `rounds` rounds of `n` combinations, in
/// the order they run.
pub fn campaign_order(n: usize, rounds: usize) -> Vec<(usize, usize)> {
    (0..rounds)
        .flat_map(|r| round_order(n, r).into_iter().map(move |c| (r, c)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_alternate_abba() {
        assert_eq!(round_order(3, 0), vec![0, 1, 2]);
        assert_eq!(round_order(3, 1), vec![2, 1, 0]);
        assert_eq!(round_order(3, 2), vec![2, 1, 0]);
        assert_eq!(round_order(3, 3), vec![0, 1, 2]);
        assert_eq!(round_order(3, 4), vec![0, 1, 2]);
        assert_eq!(round_order(3, 5), vec![2, 1, 0]);
        assert!(round_order(0, 1).is_empty());
    }

    #[test]
    fn every_combination_runs_once_per_round_with_balanced_positions() {
        let (n, rounds) = (4, 8);
        let order = campaign_order(n, rounds);
        assert_eq!(order.len(), n * rounds);
        for r in 0..rounds {
            let mut seen: Vec<usize> = order
                .iter()
                .filter(|(rr, _)| *rr == r)
                .map(|(_, c)| *c)
                .collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..n).collect::<Vec<_>>());
        }
        // Every combination's mean position in the campaign is the same.
        let mean_pos = |c: usize| {
            order
                .iter()
                .enumerate()
                .filter(|(_, (_, cc))| *cc == c)
                .map(|(i, _)| i)
                .sum::<usize>()
        };
        let first = mean_pos(0);
        assert!((1..n).all(|c| mean_pos(c) == first));
    }
}
