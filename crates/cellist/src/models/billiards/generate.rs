//! Random inputs for the collision benchmark: the course generator's uniform
//! placement (overlaps allowed), or a placement without any overlap.

use super::contacts::ContactGrid;
use super::rules::Table;
use crate::random::Rng;
use crate::threads::Threads;
use std::collections::HashSet;

/// Discs drawn at random: positions, velocities.
#[derive(Clone, Debug, PartialEq)]
pub struct Drawn {
    /// x of each disc.
    pub x: Vec<f64>,
    /// y of each disc.
    pub y: Vec<f64>,
    /// vx, vy of each disc.
    pub v: Vec<[f64; 2]>,
}

/// The course generator's recipe (`gen_testcase.py`): x and y uniform in `[0, L)`,
/// each velocity component uniform in `[vmin, vmax]`; discs may overlap each other
/// and the walls.
pub fn uniform_discs(n: usize, table: &Table, vmin: f64, vmax: f64, seed: u64) -> Drawn {
    let mut rng = Rng::new(seed);
    let l = table.side_f();
    let mut drawn = Drawn {
        x: Vec::with_capacity(n),
        y: Vec::with_capacity(n),
        v: Vec::with_capacity(n),
    };
    for _ in 0..n {
        drawn.x.push(rng.uniform() * l);
        drawn.y.push(rng.uniform() * l);
        let mut component = || vmin + rng.uniform() * (vmax - vmin);
        let v = [component(), component()];
        drawn.v.push(v);
    }
    drawn
}

/// Discs that overlap nothing: the box is cut into `m x m` squares of side
/// `L / m > 2r`, `n` distinct squares are drawn at random, and each disc sits at a
/// random place inside its square, clear of the square's edges. Velocities as in
/// [`uniform_discs`]. Fails when `n > m^2` (the density is too high for this
/// placement: at most `pi / 4`). The result is checked: no pair within `2r`, no
/// disc touching a wall.
pub fn separated_discs(
    n: usize,
    table: &Table,
    vmin: f64,
    vmax: f64,
    seed: u64,
) -> Result<Drawn, String> {
    let l = table.side_f();
    let r = table.radius_f();
    let per_axis = (l / (2.0 * r * (1.0 + 1e-6))).floor();
    let squares = per_axis * per_axis;
    if (n as f64) > squares {
        return Err(format!(
            "cannot place {n} discs of radius {r} without overlap in a box of side {l}: this \
             placement fits at most {squares} (one per square of side > 2r); use --overlaps, or \
             a larger box"
        ));
    }
    let m = per_axis as u64;
    let side = l / per_axis;
    let slack = side - 2.0 * r;
    let mut rng = Rng::new(seed);
    let chosen = distinct_squares(n, m * m, &mut rng);
    let mut drawn = Drawn {
        x: Vec::with_capacity(n),
        y: Vec::with_capacity(n),
        v: Vec::with_capacity(n),
    };
    for square in chosen {
        let (i, j) = ((square % m) as f64, (square / m) as f64);
        let mut inside = |k: f64| k * side + r + slack * (0.001 + 0.998 * rng.uniform());
        let (x, y) = (inside(i), inside(j));
        drawn.x.push(x);
        drawn.y.push(y);
        let mut component = || vmin + rng.uniform() * (vmax - vmin);
        let v = [component(), component()];
        drawn.v.push(v);
    }
    let mut contacts = Vec::new();
    ContactGrid::default().find(
        &drawn.x,
        &drawn.y,
        table.contact(),
        &Threads::single(),
        &mut contacts,
    );
    let on_wall = (0..n).any(|k| table.walls_at(drawn.x[k], drawn.y[k]).any());
    if !contacts.is_empty() || on_wall {
        return Err(format!(
            "the separated placement left {} overlapping pair(s) and {} disc(s) on a wall \
             (the radius is too close to the square side for binary64); use --overlaps",
            contacts.len(),
            usize::from(on_wall)
        ));
    }
    Ok(drawn)
}

/// `n` distinct numbers in `0..total`, in random order.
fn distinct_squares(n: usize, total: u64, rng: &mut Rng) -> Vec<u64> {
    let below = |rng: &mut Rng, bound: u64| ((rng.uniform() * bound as f64) as u64).min(bound - 1);
    if total <= 16 * n as u64 + 1024 {
        // partial Fisher-Yates
        let mut all: Vec<u64> = (0..total).collect();
        for k in 0..n {
            let pick = k as u64 + below(rng, total - k as u64);
            all.swap(k, pick as usize);
        }
        all.truncate(n);
        all
    } else {
        // sparse: rejections are rare
        let mut seen = HashSet::with_capacity(n);
        let mut chosen = Vec::with_capacity(n);
        while chosen.len() < n {
            let square = below(rng, total);
            if seen.insert(square) {
                chosen.push(square);
            }
        }
        chosen
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_placements_follow_their_recipe() {
        let table = Table {
            side: 100,
            radius: 2,
        };
        let u = uniform_discs(1000, &table, -0.5, 0.5, 3);
        assert!(u.x.iter().chain(&u.y).all(|&c| (0.0..100.0).contains(&c)));
        assert!(u.v.iter().flatten().all(|&c| (-0.5..=0.5).contains(&c)));
        assert_eq!(u, uniform_discs(1000, &table, -0.5, 0.5, 3));
        for n in [1, 100, 576] {
            let s = separated_discs(n, &table, 2.0, 5.0, 9).unwrap();
            assert_eq!(s.x.len(), n);
        }
        // squares of side > 2r = 4: 24 per axis
        let err = separated_discs(24 * 24 + 1, &table, 0.0, 1.0, 1).unwrap_err();
        assert!(err.contains("fits at most 576"), "{err}");
        // a big sparse box takes the other path
        let sparse = Table {
            side: 1_000_000,
            radius: 1,
        };
        assert_eq!(
            separated_discs(500, &sparse, 0.0, 1.0, 2).unwrap().x.len(),
            500
        );
    }
}
