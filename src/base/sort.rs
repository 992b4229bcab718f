//! Orders by floating-point keys (times, scores, eigenvalues), compiled once.
//!
//! The standard library's stable sort is compiled anew for every element type and
//! comparison; the crate's dozen sorts by an `f64` key took tens of kilobytes of the
//! page's module. Here the one sort is of indices by their keys, and each caller only
//! reorders its items.

/// The indices of `keys` in ascending order (`f64::total_cmp`: NaN last), equal keys in
/// their order.
pub fn ascending(keys: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..keys.len()).collect();
    order.sort_by(|&a, &b| keys[a].total_cmp(&keys[b]));
    order
}

/// The indices of `keys` in descending order (the reverse of `f64::total_cmp`), equal
/// keys in their order.
pub fn descending(keys: &[f64]) -> Vec<usize> {
    let negated: Vec<f64> = keys.iter().map(|&key| -key).collect();
    ascending(&negated)
}

/// Sorts `items` by `key`, ascending as [`ascending`] orders, equal keys in their order.
pub fn sort_by_key<T: Clone>(items: &mut [T], key: impl Fn(&T) -> f64) {
    let keys: Vec<f64> = items.iter().map(key).collect();
    if keys
        .windows(2)
        .all(|pair| pair[0].total_cmp(&pair[1]).is_le())
    {
        return;
    }
    let sorted: Vec<T> = ascending(&keys)
        .into_iter()
        .filter_map(|idx| items.get(idx).cloned())
        .collect();
    items.clone_from_slice(&sorted);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orders_are_stable_and_total() {
        let keys = [2.0, f64::NAN, -1.0, 2.0, 0.0, -0.0];
        assert_eq!(ascending(&keys), vec![2, 5, 4, 0, 3, 1]);
        assert_eq!(descending(&keys), vec![1, 0, 3, 4, 5, 2]);
        let mut items = [(3.0, 'a'), (1.0, 'b'), (3.0, 'c'), (2.0, 'd')];
        sort_by_key(&mut items, |item| item.0);
        assert_eq!(items, [(1.0, 'b'), (2.0, 'd'), (3.0, 'a'), (3.0, 'c')]);
    }

    /// The same order as the standard library's stable sort, on random keys with ties.
    #[test]
    fn agrees_with_the_standard_sort() {
        let mut state = 12345u64;
        let keys: Vec<f64> = (0..500)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 33) % 40) as f64 - 20.0
            })
            .collect();
        let mut expected: Vec<usize> = (0..keys.len()).collect();
        expected.sort_by(|&a, &b| keys[a].total_cmp(&keys[b]));
        assert_eq!(ascending(&keys), expected);
        expected.sort_by(|&a, &b| keys[b].total_cmp(&keys[a]));
        assert_eq!(descending(&keys), expected);
    }
}
