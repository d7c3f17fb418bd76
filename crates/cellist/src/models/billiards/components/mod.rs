//! Connected components of the overlap graph (SPEC.md section 4, E2): a resolution
//! changes velocities only inside one component, so each component runs the
//! canonical loop on its own (its wall discs ascending, then its pairs in
//! lexicographic order, until a sweep changes nothing), and components run in
//! parallel. Each component's discs are gathered into one contiguous block of
//! velocities, so every task owns its own range; the gather and the write-back
//! run in parts (a disc belongs to one component: each velocity is written once).
//!
//! Within a sweep only the order of the pairs that share a disc matters: each pair
//! reads and writes the velocities of its two discs alone. The pairs are therefore
//! run by *level* (a pair's level is one more than the highest level of the earlier
//! pairs, in canonical order, that share a disc with it). Every disc meets its
//! pairs in the canonical order, so the bits are those of the canonical loop, and
//! the pairs of one level share no disc, so they run four at a time in SIMD lanes
//! without waiting for each other.

mod group;
mod label;
mod levels;
mod resolve;
#[cfg(test)]
mod strategies;
#[cfg(test)]
mod testing;

pub(super) use label::SlotSets;
pub(super) use resolve::Components;
