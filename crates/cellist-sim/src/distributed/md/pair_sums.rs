//! How a rank of a distributed md run sums the pair forces on its own atoms:
//! the half cluster list of its own atoms and ghosts (the default, each pair
//! once over the ranks) or the full rows sorted by id (`[run] reproducible =
//! true`), and what each needs at a rebuild.

use cellist::decomposition::{Images, Subdomain};
use cellist::interactions::{LennardJones, PairPotential};
use cellist::models::md::{AtomForce, HaloForces, MdError};
use cellist::neighbors::OrderedRows;
use cellist::Threads;

/// How a rank sums the pair forces on its own atoms.
pub(super) enum PairSums<const D: usize> {
    /// Over a half cluster list of own atoms and ghosts (`None` before the
    /// first build).
    Halo(Option<Box<HaloForces<D>>>),
    /// Over full rows sorted by id, and each own atom's sums.
    Ordered(OrderedRows<D>, Vec<AtomForce<D>>),
}

impl<const D: usize> PairSums<D> {
    /// The ghosts a rank needs: for the half list, across the cuts from half
    /// of the directions (it bins in a box periodic along the uncut axes, and
    /// sends the ghosts' reactions back); for the rows, every image (found in
    /// open space).
    pub(super) fn images(&self) -> Images {
        match self {
            PairSums::Halo(_) => Images::HalfShell,
            PairSums::Ordered(..) => Images::All,
        }
    }

    /// Builds the list or rows of the first `owned` of `points` (own atoms,
    /// then ghosts; `ids` alike), the list's cells sized for `share` atoms
    /// (the mean per rank); the failure (two atoms at one position, a
    /// geometry error) as its message. The half list looks for two atoms at
    /// one position at its first build only, as a single-process run does at
    /// set-up (later such a pair blows the run up); the rows at every build.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn build(
        &mut self,
        subdomain: &Subdomain<D>,
        points: &[[f64; D]],
        owned: usize,
        share: usize,
        ids: &[u64],
        potential: &LennardJones,
        skin: f64,
        threads: &Threads,
    ) -> Option<String> {
        let overlap = |(first, second)| MdError::Overlap { first, second }.to_string();
        match self {
            PairSums::Ordered(rows, _) => {
                match OrderedRows::build(points, owned, ids, potential.cutoff(), skin, threads) {
                    Ok(built) => {
                        *rows = built;
                        rows.coincident(points, ids).map(overlap)
                    }
                    Err(e) => Some(e.to_string()),
                }
            }
            PairSums::Halo(halo) => {
                // in place while the cells stay those of the last build
                if let Some(h) = halo.as_mut() {
                    match h.rebuild(subdomain, points, owned, share, threads) {
                        Ok(true) => return None,
                        Ok(false) => {}
                        Err(e) => return Some(e.to_string()),
                    }
                }
                // else the old list goes first: one list in memory at a time
                let first = halo.take().is_none();
                let built =
                    HaloForces::build(subdomain, points, owned, share, *potential, skin, threads);
                match built {
                    Ok(built) => {
                        let built = halo.insert(Box::new(built));
                        first
                            .then(|| built.coincident(points, ids))
                            .flatten()
                            .map(overlap)
                    }
                    Err(e) => Some(e.to_string()),
                }
            }
        }
    }

    /// True when the next build needs the ids of the points: the rows sort
    /// by id and look for two atoms at one position at every build, the half
    /// list looks at its first build only.
    pub(super) fn needs_ids(&self) -> bool {
        match self {
            PairSums::Halo(halo) => halo.is_none(),
            PairSums::Ordered(..) => true,
        }
    }

    /// The own atoms' positions at the last build.
    pub(super) fn reference(&self) -> &[[f64; D]] {
        match self {
            PairSums::Halo(halo) => halo.as_ref().map_or(&[], |h| h.reference()),
            PairSums::Ordered(rows, _) => rows.reference(),
        }
    }

    /// True when an own atom moved more than skin/2 since the last build.
    pub(super) fn needs_rebuild(&self, owned: &[[f64; D]]) -> bool {
        match self {
            PairSums::Halo(halo) => halo.as_ref().is_none_or(|h| h.needs_rebuild(owned)),
            PairSums::Ordered(rows, _) => rows.needs_rebuild(owned),
        }
    }
}
