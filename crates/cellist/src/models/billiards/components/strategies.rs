//! The random pairs two of the components' tests share (a proptest strategy).

use proptest::prelude::*;

/// Distinct pairs `(a, b)`, `a != b`, of discs below `n`, in any order.
pub(super) fn pairs() -> impl Strategy<Value = (usize, Vec<(u32, u32)>)> {
    (2usize..60).prop_flat_map(|n| {
        let pair = (0..n as u32, 0..n as u32).prop_filter("two discs", |(a, b)| a != b);
        (
            Just(n),
            prop::collection::vec(pair, 0..300).prop_map(|mut pairs| {
                let mut seen = std::collections::HashSet::new();
                pairs.retain(|&p| seen.insert(p));
                pairs
            }),
        )
    })
}
