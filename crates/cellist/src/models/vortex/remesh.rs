//! Remeshing: the particles' circulations are spread onto the lattice
//! `c + h (k, l)` with the M4' kernel,
//!
//! ```text
//! Gamma_kl = sum_p Gamma_p M4'((x_p - c_x) / h - k) M4'((y_p - c_y) / h - l),
//! ```
//!
//! and the nodes become the new particles. M4' reproduces polynomials up to
//! degree 2, so the circulation `sum Gamma`, the linear impulse `sum Gamma x` and
//! the angular impulse `sum Gamma |x|^2` are unchanged to round-off. Nodes with
//! `|Gamma_kl| <= threshold * max |Gamma|` are dropped (the circulation they
//! carried is reported, not lost silently).

use crate::interpolation::m4prime_stencil;

/// The remeshing lattice: nodes `origin + h (k, l)`; in a periodic box
/// `[lo, lo + L)^2` (`L` a whole number `n` of spacings) node `k` and `k + n`
/// are one node, kept at its position inside the box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    /// A node.
    pub origin: [f64; 2],
    /// The spacing `h`.
    pub spacing: f64,
    /// The periodic box `(lo, L)`, if any.
    pub periodic: Option<([f64; 2], f64)>,
    /// Nodes within this many spacings (per axis) of a node above the threshold
    /// are kept whatever their value: PSE needs every neighbour within its
    /// cutoff, a zero among them included.
    pub reach: usize,
}

/// The particles after a remeshing.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Remeshed {
    /// Node positions, `l` (y) slowest.
    pub positions: Vec<[f64; 2]>,
    /// Their circulations.
    pub gamma: Vec<f64>,
    /// The summed circulation of the dropped nodes.
    pub dropped: f64,
}

/// Spreads `gamma` at `positions` onto the lattice of spacing `h` through
/// `origin` and keeps the nodes above `threshold` (relative to the largest).
/// The sums run particle by particle in input order, so the result does not
/// depend on anything but the data.
///
/// Refuses (naming the lattice's size) particles spread over more than
/// `64 N + 10^6` nodes: a particle thrown far away by too large a step, which a
/// dense lattice could not hold.
pub fn remesh(
    positions: &[[f64; 2]],
    gamma: &[f64],
    lattice: &Lattice,
    threshold: f64,
) -> Result<Remeshed, String> {
    let (origin, h) = (lattice.origin, lattice.spacing);
    if positions.is_empty() {
        return Ok(Remeshed::default());
    }
    let stencils: Vec<[(i64, [f64; 4]); 2]> = positions
        .iter()
        .map(|x| {
            [
                m4prime_stencil((x[0] - origin[0]) / h),
                m4prime_stencil((x[1] - origin[1]) / h),
            ]
        })
        .collect();
    // periodic: node k is node first + (k - first) mod n, inside the box
    let fold = lattice.periodic.map(|(lo, length)| {
        let n = (length / h).round() as i64;
        let first = [0, 1].map(|a| ((lo[a] - origin[a]) / h - 1e-9).ceil() as i64);
        (first, n)
    });
    let (lo, hi) = match fold {
        Some((first, n)) => (first, first.map(|f| f + n - 1)),
        None => {
            let reach = lattice.reach as i64;
            (
                [0, 1].map(|a| stencils.iter().map(|s| s[a].0).min().unwrap_or(0) - reach),
                [0, 1].map(|a| stencils.iter().map(|s| s[a].0 + 3).max().unwrap_or(0) + reach),
            )
        }
    };
    let node = |a: usize, k: i64| -> usize {
        match fold {
            Some((first, n)) => (k - first[a]).rem_euclid(n) as usize,
            None => (k - lo[a]) as usize,
        }
    };
    let (width, height) = ((hi[0] - lo[0] + 1) as u64, (hi[1] - lo[1] + 1) as u64);
    let most = 64 * positions.len() as u64 + 1_000_000;
    if width.saturating_mul(height) > most {
        return Err(format!(
            "remeshing: the {} particles spread over {width} x {height} lattice nodes (at most {most}): a particle was thrown far from the others",
            positions.len()
        ));
    }
    let (width, height) = (width as usize, height as usize);
    let mut nodes = vec![0.0; width * height];
    for (s, &g) in stencils.iter().zip(gamma) {
        let [(kx, wx), (ky, wy)] = *s;
        for (dy, wy) in wy.iter().enumerate() {
            let row = node(1, ky + dy as i64);
            let gy = g * wy;
            for (dx, wx) in wx.iter().enumerate() {
                nodes[row * width + node(0, kx + dx as i64)] += gy * wx;
            }
        }
    }
    let largest = nodes.iter().fold(0.0f64, |m, g| m.max(g.abs()));
    let keep = threshold * largest;
    let strong: Vec<bool> = nodes.iter().map(|g| g.abs() > keep).collect();
    let periodic = fold.is_some();
    let kept = dilate(&strong, width, lattice.reach, periodic);
    let kept = transpose(
        &dilate(&transpose(&kept, width), height, lattice.reach, periodic),
        height,
    );
    let mut out = Remeshed::default();
    for (at, &g) in nodes.iter().enumerate() {
        if kept[at] {
            let (k, l) = ((at % width) as i64 + lo[0], (at / width) as i64 + lo[1]);
            out.positions
                .push([origin[0] + k as f64 * h, origin[1] + l as f64 * h]);
            out.gamma.push(g);
        } else {
            out.dropped += g;
        }
    }
    Ok(out)
}

/// `mask` (rows of `width`) with every true entry spread `reach` entries left and
/// right along its row (around the row if `periodic`).
fn dilate(mask: &[bool], width: usize, reach: usize, periodic: bool) -> Vec<bool> {
    let mut out = vec![false; mask.len()];
    for (row, dst) in mask.chunks(width).zip(out.chunks_mut(width)) {
        // distance to the nearest true entry, scanning both ways
        let mut last: Option<usize> = None;
        let span = if periodic { 2 * width } else { width };
        for step in 0..span {
            let x = step % width;
            if row[x] {
                last = Some(step);
            }
            if last.is_some_and(|l| step - l <= reach) {
                dst[x] = true;
            }
        }
        last = None;
        for step in (0..span).rev() {
            let x = step % width;
            if row[x] {
                last = Some(step);
            }
            if last.is_some_and(|l| l - step <= reach) {
                dst[x] = true;
            }
        }
    }
    out
}

/// The transpose of `mask` (rows of `width`).
fn transpose(mask: &[bool], width: usize) -> Vec<bool> {
    let height = mask.len() / width;
    let mut out = vec![false; mask.len()];
    for y in 0..height {
        for x in 0..width {
            out[x * height + y] = mask[y * width + x];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::Rng;

    #[test]
    fn remeshing_keeps_circulation_and_impulses() {
        let mut rng = Rng::new(11);
        let x: Vec<[f64; 2]> = (0..500)
            .map(|_| [rng.normal() * 0.3 + 0.1, rng.normal() * 0.2])
            .collect();
        let g: Vec<f64> = (0..500).map(|_| rng.uniform() - 0.2).collect();
        let moments = |x: &[[f64; 2]], g: &[f64]| -> [f64; 4] {
            let mut m = [0.0; 4];
            for (p, &w) in x.iter().zip(g) {
                m[0] += w;
                m[1] += w * p[0];
                m[2] += w * p[1];
                m[3] += w * (p[0] * p[0] + p[1] * p[1]);
            }
            m
        };
        let before = moments(&x, &g);
        let lattice = Lattice {
            origin: [0.013, -0.02],
            spacing: 0.05,
            periodic: None,
            reach: 0,
        };
        let after = remesh(&x, &g, &lattice, 0.0).unwrap();
        assert_eq!(after.dropped, 0.0);
        let now = moments(&after.positions, &after.gamma);
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
        let g = vec![1.0, 1e-14, -0.5];
        let open = Lattice {
            origin: [0.0, 0.0],
            spacing: h,
            periodic: None,
            reach: 0,
        };
        let r = remesh(&x, &g, &open, 1e-12).unwrap();
        let far = remesh(&[[0.0, 0.0], [1e9, 0.0]], &[1.0, 1.0], &open, 0.0);
        assert!(far.unwrap_err().contains("thrown far"));
        // in the periodic box [-0.5, 0.5)^2 (8 nodes a side), a particle at the
        // edge spreads across it, and every node stays in the box
        let boxed = Lattice {
            periodic: Some(([-0.5, -0.5], 1.0)),
            ..open
        };
        let wrapped = remesh(&[[0.49, 0.0]], &[1.0], &boxed, 0.0).unwrap();
        assert!((wrapped.gamma.iter().sum::<f64>() - 1.0).abs() < 1e-15);
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
        let kept = remesh(&[[0.0, 0.0]], &[1.0], &near, 1e-12).unwrap();
        assert_eq!(kept.positions.len(), 25);
        assert_eq!(kept.gamma.iter().filter(|g| **g != 0.0).count(), 1);
        assert_eq!(r.positions, vec![[0.0, 0.0], [0.375, 0.25]]);
        assert_eq!(r.gamma, vec![1.0, -0.5]);
        assert_eq!(r.dropped, 1e-14);
    }
}
