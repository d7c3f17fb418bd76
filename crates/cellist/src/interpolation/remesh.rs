//! Remeshing: strengths carried by particles are spread onto the lattice
//! `c + h k` (`k` a multi-index) with the tensor-product M4' kernel,
//!
//! ```text
//! S_k = sum_p S_p prod_{a < D} M4'((x_p,a - c_a) / h - k_a),
//! ```
//!
//! and the nodes become the new particles. `S` has `W` components, spread
//! alike: a circulation in 2D (`W = 1`), a vector strength `alpha` in 3D
//! (`W = 3`). M4' reproduces polynomials up to degree 2, so every component's
//! total `sum S`, first moments `sum S x_a` and second moments `sum S x_a x_b`
//! are unchanged to round-off (in 2D: the circulation, the linear and the
//! angular impulse). Nodes with `|S_k| <= threshold * max |S|` (`|.|` the
//! Euclidean norm over the components) are dropped; the strength they carried
//! is reported, not lost silently.

use super::m4prime_stencil;

/// The remeshing lattice: nodes `origin + h k`; in a periodic box
/// `lo + [0, L_a)` (each `L_a` a whole number `n_a` of spacings) node `k` and
/// `k + n_a e_a` are one node, kept at its position inside the box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice<const D: usize> {
    /// A node.
    pub origin: [f64; D],
    /// The spacing `h`.
    pub spacing: f64,
    /// The periodic box `(lo, [L_a])`, if any.
    pub periodic: Option<([f64; D], [f64; D])>,
    /// Nodes within this many spacings (per axis) of a node above the threshold
    /// are kept whatever their value: PSE needs every neighbour within its
    /// cutoff, a zero among them included.
    pub reach: usize,
}

/// The particles after a remeshing.
#[derive(Clone, Debug, PartialEq)]
pub struct Remeshed<const D: usize, const W: usize> {
    /// Node positions, the first axis fastest, the last slowest.
    pub positions: Vec<[f64; D]>,
    /// Their strengths.
    pub strength: Vec<[f64; W]>,
    /// The summed strength of the dropped nodes, component by component.
    pub dropped: [f64; W],
}

/// Spreads `strength` at `positions` onto the lattice of spacing `h` through
/// `origin` and keeps the nodes whose norm `|S_k|` is above `threshold` times
/// the largest. The sums run particle by particle in input order, so the
/// result depends on nothing but the data.
///
/// The lattice is dense over the particles' bounding box (with the `reach`
/// halo and the stencil), or the periodic box. Refuses (naming its size) a
/// lattice of more than `64 N + 10^(D + 4)` nodes (`10^6` in 2D, `10^7` in
/// 3D): a particle thrown far away by too large a step, or a periodic box far
/// finer than the particles need; a periodic box less than one spacing wide;
/// and positions and strengths of different lengths.
pub fn remesh<const D: usize, const W: usize>(
    positions: &[[f64; D]],
    strength: &[[f64; W]],
    lattice: &Lattice<D>,
    threshold: f64,
) -> Result<Remeshed<D, W>, String> {
    let (origin, h) = (lattice.origin, lattice.spacing);
    let mut out = Remeshed {
        positions: Vec::new(),
        strength: Vec::new(),
        dropped: [0.0; W],
    };
    if positions.len() != strength.len() {
        return Err(format!(
            "remeshing: {} positions but {} strengths",
            positions.len(),
            strength.len()
        ));
    }
    if positions.is_empty() {
        return Ok(out);
    }
    let stencils: Vec<[(i64, [f64; 4]); D]> = positions
        .iter()
        .map(|x| std::array::from_fn(|a| m4prime_stencil((x[a] - origin[a]) / h)))
        .collect();
    // periodic: node k is node first + (k - first) mod n, inside the box
    let fold = lattice.periodic.map(|(lo, length)| {
        let n: [i64; D] = std::array::from_fn(|a| (length[a] / h).round() as i64);
        let first: [i64; D] =
            std::array::from_fn(|a| ((lo[a] - origin[a]) / h - 1e-9).ceil() as i64);
        (first, n)
    });
    if let Some((_, n)) = fold {
        if n.iter().any(|&n| n < 1) {
            return Err(format!(
                "remeshing: the periodic box is less than one spacing ({h}) wide on some axis"
            ));
        }
    }
    let (lo, hi): ([i64; D], [i64; D]) = match fold {
        Some((first, n)) => (first, std::array::from_fn(|a| first[a] + n[a] - 1)),
        None => {
            let reach = lattice.reach as i64;
            (
                std::array::from_fn(|a| stencils.iter().map(|s| s[a].0).min().unwrap_or(0) - reach),
                std::array::from_fn(|a| {
                    stencils.iter().map(|s| s[a].0 + 3).max().unwrap_or(0) + reach
                }),
            )
        }
    };
    let dims: [u64; D] = std::array::from_fn(|a| (hi[a] - lo[a] + 1) as u64);
    let total = dims.iter().fold(1u64, |t, &d| t.saturating_mul(d));
    let most = 64 * positions.len() as u64 + 10u64.pow(D as u32 + 4);
    if total > most {
        let sizes: Vec<String> = dims.iter().map(u64::to_string).collect();
        return Err(format!(
            "remeshing: the {} particles spread over {} lattice nodes (at most {most}): a particle was thrown far from the others",
            positions.len(),
            sizes.join(" x ")
        ));
    }
    let dims = dims.map(|d| d as usize);
    let mut stride = [1usize; D];
    for a in 1..D {
        stride[a] = stride[a - 1] * dims[a - 1];
    }
    // the index of node k along axis a, times the axis' stride
    let offset = |a: usize, k: i64| -> usize {
        let i = match fold {
            Some((first, n)) => (k - first[a]).rem_euclid(n[a]) as usize,
            None => (k - lo[a]) as usize,
        };
        i * stride[a]
    };
    let mut nodes = vec![[0.0; W]; total as usize];
    for (s, g) in stencils.iter().zip(strength) {
        let at: [[usize; 4]; D] =
            std::array::from_fn(|a| std::array::from_fn(|t| offset(a, s[a].0 + t as i64)));
        // the 4^D stencil nodes, the first axis fastest; the weight is applied
        // from the last axis to the first
        for t in 0..1usize << (2 * D) {
            let mut node = 0;
            let mut value = *g;
            for a in (0..D).rev() {
                let digit = (t >> (2 * a)) & 3;
                node += at[a][digit];
                let w = s[a].1[digit];
                for v in &mut value {
                    *v *= w;
                }
            }
            for (n, v) in nodes[node].iter_mut().zip(value) {
                *n += v;
            }
        }
    }
    let largest = nodes.iter().fold(0.0f64, |m, s| m.max(norm(s)));
    let keep = threshold * largest;
    let mut kept: Vec<bool> = nodes.iter().map(|s| norm(s) > keep).collect();
    let periodic = fold.is_some();
    let mut spread = vec![false; kept.len()];
    for a in 0..D {
        dilate(
            &kept,
            &mut spread,
            dims[a],
            stride[a],
            lattice.reach,
            periodic,
        );
        std::mem::swap(&mut kept, &mut spread);
    }
    for (at, s) in nodes.iter().enumerate() {
        if kept[at] {
            out.positions.push(std::array::from_fn(|a| {
                let k = ((at / stride[a]) % dims[a]) as i64 + lo[a];
                origin[a] + k as f64 * h
            }));
            out.strength.push(*s);
        } else {
            for (d, v) in out.dropped.iter_mut().zip(s) {
                *d += v;
            }
        }
    }
    Ok(out)
}

/// The Euclidean norm `|s|`, scaled by the largest component (no overflow or
/// underflow in the squares; exactly `|s_0|` for one component).
fn norm<const W: usize>(s: &[f64; W]) -> f64 {
    let largest = s.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if largest == 0.0 {
        return 0.0;
    }
    let sum: f64 = s.iter().map(|v| (v / largest) * (v / largest)).sum();
    largest * sum.sqrt()
}

/// `out` = `mask` with every true entry spread `reach` entries both ways along
/// the lines of one axis (`width` entries `stride` apart; around the line if
/// `periodic`).
fn dilate(
    mask: &[bool],
    out: &mut [bool],
    width: usize,
    stride: usize,
    reach: usize,
    periodic: bool,
) {
    out.fill(false);
    let span = if periodic { 2 * width } else { width };
    // the first entry of every line: its index along the axis is 0
    for start in (0..mask.len()).filter(|i| (i / stride).is_multiple_of(width)) {
        let at = |step: usize| start + (step % width) * stride;
        // distance to the nearest true entry, scanning both ways
        let mut last: Option<usize> = None;
        for step in 0..span {
            if mask[at(step)] {
                last = Some(step);
            }
            if last.is_some_and(|l| step - l <= reach) {
                out[at(step)] = true;
            }
        }
        last = None;
        for step in (0..span).rev() {
            if mask[at(step)] {
                last = Some(step);
            }
            if last.is_some_and(|l| l - step <= reach) {
                out[at(step)] = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::Rng;

    /// Circulations as one-component strengths.
    fn scalar(g: &[f64]) -> Vec<[f64; 1]> {
        g.iter().map(|&g| [g]).collect()
    }

    #[test]
    fn remeshing_keeps_circulation_and_impulses() {
        let mut rng = Rng::new(11);
        let x: Vec<[f64; 2]> = (0..500)
            .map(|_| [rng.normal() * 0.3 + 0.1, rng.normal() * 0.2])
            .collect();
        let g: Vec<f64> = (0..500).map(|_| rng.uniform() - 0.2).collect();
        let moments = |x: &[[f64; 2]], g: &[[f64; 1]]| -> [f64; 4] {
            let mut m = [0.0; 4];
            for (p, &[w]) in x.iter().zip(g) {
                m[0] += w;
                m[1] += w * p[0];
                m[2] += w * p[1];
                m[3] += w * (p[0] * p[0] + p[1] * p[1]);
            }
            m
        };
        let before = moments(&x, &scalar(&g));
        let lattice = Lattice {
            origin: [0.013, -0.02],
            spacing: 0.05,
            periodic: None,
            reach: 0,
        };
        let after = remesh(&x, &scalar(&g), &lattice, 0.0).unwrap();
        assert_eq!(after.dropped, [0.0]);
        let now = moments(&after.positions, &after.strength);
        for k in 0..4 {
            assert!(
                (now[k] - before[k]).abs() < 1e-12,
                "{k}: {now:?} {before:?}"
            );
        }
    }

    #[test]
    fn particles_on_the_nodes_stay_and_small_nodes_go() {
        let h = 0.125;
        let x = vec![[0.0, 0.0], [0.125, 0.0], [0.375, 0.25]];
        let g = vec![[1.0], [1e-14], [-0.5]];
        let open = Lattice {
            origin: [0.0, 0.0],
            spacing: h,
            periodic: None,
            reach: 0,
        };
        let r = remesh(&x, &g, &open, 1e-12).unwrap();
        let far = remesh(&[[0.0, 0.0], [1e9, 0.0]], &[[1.0], [1.0]], &open, 0.0);
        assert!(far.unwrap_err().contains("thrown far"));
        assert!(remesh(&x, &g[..2], &open, 0.0).is_err());
        // in the periodic box [-0.5, 0.5)^2 (8 nodes a side), a particle at the
        // edge spreads across it, and every node stays in the box
        let boxed = Lattice {
            periodic: Some(([-0.5, -0.5], [1.0, 1.0])),
            ..open
        };
        let wrapped = remesh(&[[0.49, 0.0]], &[[1.0]], &boxed, 0.0).unwrap();
        assert!((wrapped.strength.iter().map(|s| s[0]).sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(wrapped
            .positions
            .iter()
            .all(|p| (-0.5..0.5).contains(&p[0])));
        assert!(wrapped
            .positions
            .iter()
            .any(|p| p[0] == -0.5 && p[1] == 0.0));
        // with a reach, the zero nodes around a kept one stay (PSE needs them)
        let near = Lattice { reach: 2, ..open };
        let kept = remesh(&[[0.0, 0.0]], &[[1.0]], &near, 1e-12).unwrap();
        assert_eq!(kept.positions.len(), 25);
        assert_eq!(kept.strength.iter().filter(|g| g[0] != 0.0).count(), 1);
        assert_eq!(r.positions, vec![[0.0, 0.0], [0.375, 0.25]]);
        assert_eq!(r.strength, vec![[1.0], [-0.5]]);
        assert_eq!(r.dropped, [1e-14]);
    }

    /// A 3D blob of `n` particles with vector strengths.
    fn blob(n: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let mut rng = Rng::new(seed);
        let x = (0..n)
            .map(|_| {
                [
                    0.3 * rng.normal() + 0.1,
                    0.2 * rng.normal(),
                    0.25 * rng.normal() - 0.05,
                ]
            })
            .collect();
        let alpha = (0..n)
            .map(|_| [rng.uniform() - 0.3, rng.normal(), 0.5 - rng.uniform()])
            .collect();
        (x, alpha)
    }

    /// Per component `c`: `sum alpha_c`, `sum alpha_c x_d`, `sum alpha_c x_d x_e`.
    fn moments_3d(x: &[[f64; 3]], alpha: &[[f64; 3]]) -> Vec<f64> {
        let mut m = vec![0.0; 3 * 13];
        for (p, s) in x.iter().zip(alpha) {
            for c in 0..3 {
                let m = &mut m[13 * c..13 * (c + 1)];
                m[0] += s[c];
                for d in 0..3 {
                    m[1 + d] += s[c] * p[d];
                    for e in 0..3 {
                        m[4 + 3 * d + e] += s[c] * p[d] * p[e];
                    }
                }
            }
        }
        m
    }

    #[test]
    fn remeshing_in_3d_keeps_every_moment_up_to_the_second() {
        let (x, alpha) = blob(400, 5);
        let lattice = Lattice {
            origin: [0.013, -0.02, 0.031],
            spacing: 0.07,
            periodic: None,
            reach: 1,
        };
        let before = moments_3d(&x, &alpha);
        let after = remesh(&x, &alpha, &lattice, 0.0).unwrap();
        assert_eq!(after.dropped, [0.0; 3]);
        // every node lies on the lattice
        for p in &after.positions {
            for a in 0..3 {
                let k = (p[a] - lattice.origin[a]) / lattice.spacing;
                assert!((k - k.round()).abs() < 1e-9, "{p:?}");
            }
        }
        let now = moments_3d(&after.positions, &after.strength);
        for k in 0..before.len() {
            assert!(
                (now[k] - before[k]).abs() < 1e-11,
                "{k}: {} {}",
                now[k],
                before[k]
            );
        }
        // off the lattice, the particles spread over more nodes than particles
        assert!(after.positions.len() > x.len());
    }

    #[test]
    fn components_are_remeshed_as_independent_scalars() {
        let (x, alpha) = blob(200, 8);
        let lattice = Lattice {
            origin: [0.0; 3],
            spacing: 0.1,
            periodic: None,
            reach: 0,
        };
        let all = remesh(&x, &alpha, &lattice, 0.0).unwrap();
        for c in 0..3 {
            let one: Vec<[f64; 1]> = alpha.iter().map(|s| [s[c]]).collect();
            let alone = remesh(&x, &one, &lattice, 0.0).unwrap();
            assert_eq!(alone.positions, all.positions);
            let column: Vec<u64> = all.strength.iter().map(|s| s[c].to_bits()).collect();
            let single: Vec<u64> = alone.strength.iter().map(|s| s[0].to_bits()).collect();
            assert_eq!(column, single, "component {c}");
        }
    }

    #[test]
    fn periodic_folding_in_3d_keeps_the_strength_inside_the_box() {
        // the box [-0.5, 0.5) x [0, 1) x [-1, 0.5) with spacing 0.125: 8 x 8 x 12 nodes
        let lattice = Lattice {
            origin: [0.0; 3],
            spacing: 0.125,
            periodic: Some(([-0.5, 0.0, -1.0], [1.0, 1.0, 1.5])),
            reach: 0,
        };
        // near a corner: the stencil wraps on every axis
        let x = [[0.49, 0.99, -0.99], [0.0, 0.5, 0.0]];
        let alpha = [[1.0, -2.0, 0.5], [0.25, 0.0, -1.0]];
        let r = remesh(&x, &alpha, &lattice, 0.0).unwrap();
        let (lo, length) = lattice.periodic.unwrap();
        for p in &r.positions {
            for a in 0..3 {
                assert!((lo[a]..lo[a] + length[a]).contains(&p[a]), "{p:?}");
            }
        }
        assert_eq!(r.positions.len(), 64 + 1);
        for c in 0..3 {
            let total: f64 = r.strength.iter().map(|s| s[c]).sum();
            assert!((total - alpha[0][c] - alpha[1][c]).abs() < 1e-14, "{c}");
        }
        // x_0's nearest node (0.5, 1.0, -1.0), outside the box on two axes, is
        // folded onto (-0.5, 0.0, -1.0) (its weight M4'(0.08)^3 ~ 0.96)
        let corner = r
            .positions
            .iter()
            .position(|p| *p == [-0.5, 0.0, -1.0])
            .unwrap();
        assert!(r.strength[corner][0] > 0.9);
        // the second particle sits on a node: kept as it is
        let own = r
            .positions
            .iter()
            .position(|p| *p == [0.0, 0.5, 0.0])
            .unwrap();
        assert_eq!(r.strength[own], [0.25, 0.0, -1.0]);
        let flat = Lattice {
            periodic: Some(([0.0; 3], [1.0, 0.05, 1.0])),
            ..lattice
        };
        assert!(remesh(&x, &alpha, &flat, 0.0)
            .unwrap_err()
            .contains("one spacing"));
    }

    #[test]
    fn the_3d_threshold_drops_small_norms_and_reports_them() {
        let h = 0.5;
        let lattice = Lattice {
            origin: [0.0; 3],
            spacing: h,
            periodic: None,
            reach: 0,
        };
        // on the nodes: no spreading. The threshold is 1e-10 times the largest
        // norm, 2: |alpha| of the second is 1e-9 (above), of the third
        // 5e-11 sqrt(3) (below)
        let x = [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 1.0, 1.5]];
        let alpha = [
            [0.0, 2.0, 0.0],
            [6e-10, 0.0, -8e-10],
            [5e-11, -5e-11, 5e-11],
        ];
        let r = remesh(&x, &alpha, &lattice, 1e-10).unwrap();
        assert_eq!(r.positions, vec![[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]]);
        assert_eq!(r.strength, vec![alpha[0], alpha[1]]);
        assert_eq!(r.dropped, alpha[2]);
        // with reach 1 the 3 x 3 x 3 cubes around the kept nodes stay (36 nodes)
        // and the dropped node, two spacings away on two axes, still goes
        let near = Lattice {
            reach: 1,
            ..lattice
        };
        let r = remesh(&x, &alpha, &near, 1e-10).unwrap();
        assert_eq!(r.positions.len(), 36);
        assert_eq!(r.dropped, alpha[2]);
        // 3.2e7 nodes, more than 64 N + 10^7
        let far = remesh(&[[0.0; 3], [0.0, 0.0, 1e6]], &[[1.0; 3]; 2], &lattice, 0.0);
        assert!(far.unwrap_err().contains("4 x 4 x 2000004"));
    }
}
