//! Gravity's node moments on the tree: each node's mass, centre of mass and
//! traceless quadrupole, as running sums over its sorted bodies (so that a
//! node's sums may run over its bodies in pieces, on one rank after another,
//! to the bits of one pass).

use super::build::Node;
use super::walk::Walk;
use std::ops::Range;

/// A node's mass and traceless quadrupole `xx, xy, xz, yy, yz, zz` about its
/// centre of mass.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Multipole {
    pub mass: f64,
    pub quad: [f64; 6],
}

/// A node's centre of mass and multipole, from the sorted masses `walk.w`.
pub(super) fn of_node(node: &Node, walk: &Walk) -> ([f64; 3], Multipole) {
    let range = node.start as usize..node.end as usize;
    let sums = mass_sums(MASS_SUMS_START, walk, range.clone());
    let com = centre_of_mass(&sums);
    let quad = quadrupole_sums([0.0; 6], &com, walk, range);
    (
        com,
        Multipole {
            mass: sums[0],
            quad,
        },
    )
}

/// Where [`mass_sums`] starts for a node (the start of `f64`'s `sum`).
pub(super) const MASS_SUMS_START: [f64; 4] = [-0.0; 4];

/// `sums` continued over the sorted particles `range` in order: `[sum m, sum
/// m x, sum m y, sum m z]`, each a running sum (so that a node's sums may run
/// over its particles in pieces, one after the other, to the same bits).
pub(super) fn mass_sums(mut sums: [f64; 4], walk: &Walk, range: Range<usize>) -> [f64; 4] {
    let (x, m) = (&walk.x, &walk.w);
    for s in range {
        sums[0] += m[s];
        for a in 0..3 {
            sums[a + 1] += m[s] * x[a][s];
        }
    }
    sums
}

/// The centre of mass `sum m x / sum m` of [`mass_sums`]' sums.
pub(super) fn centre_of_mass(sums: &[f64; 4]) -> [f64; 3] {
    [sums[1] / sums[0], sums[2] / sums[0], sums[3] / sums[0]]
}

/// `quad` continued over the sorted particles `range` in order: the traceless
/// quadrupole `sum m (3 y_a y_b - |y|^2 delta_ab)`, `y = x - com`, as `xx, xy,
/// xz, yy, yz, zz` (running sums, as [`mass_sums`]).
pub(super) fn quadrupole_sums(
    mut quad: [f64; 6],
    com: &[f64; 3],
    walk: &Walk,
    range: Range<usize>,
) -> [f64; 6] {
    let (x, m) = (&walk.x, &walk.w);
    for s in range {
        let y = [x[0][s] - com[0], x[1][s] - com[1], x[2][s] - com[2]];
        let y2 = y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
        let w = m[s];
        quad[0] += w * (3.0 * y[0] * y[0] - y2);
        quad[1] += w * 3.0 * y[0] * y[1];
        quad[2] += w * 3.0 * y[0] * y[2];
        quad[3] += w * (3.0 * y[1] * y[1] - y2);
        quad[4] += w * 3.0 * y[1] * y[2];
        quad[5] += w * (3.0 * y[2] * y[2] - y2);
    }
    quad
}
