//! Helpers shared by the mesh solvers' tests: clouds, the direct reference and
//! error measures.

use crate::interactions::GravityLaw;
use crate::longrange::{DirectSum, FieldOut, Sources};
use crate::random::Rng;
use crate::threads::Threads;

/// Accelerations and potentials of one evaluation.
pub(crate) type Field = (Vec<[f64; 3]>, Vec<f64>);

/// Runs `solve` on `(m, x)` into fresh buffers.
pub(crate) fn run(m: &[f64], x: &[[f64; 3]], mut solve: impl FnMut(&Sources, FieldOut)) -> Field {
    let mut acc = vec![[0.0; 3]; m.len()];
    let mut phi = vec![0.0; m.len()];
    solve(
        &Sources {
            mass: m,
            position: x,
        },
        FieldOut {
            acc: &mut acc,
            phi: &mut phi,
        },
    );
    (acc, phi)
}

/// The exact field of `(m, x)` under `law`.
pub(crate) fn direct(law: GravityLaw, m: &[f64], x: &[[f64; 3]]) -> Field {
    let mut solver = DirectSum::new(law, m.len());
    run(m, x, |s, o| solver.compute(s, o, &Threads::single()))
}

/// A clustered cloud of `n` particles around `centre`: half in a Gaussian of
/// standard deviation `sigma`, half in 5 Gaussian clumps of `sigma / 10` spread
/// over the first; masses uniform in `[0.5, 1.5)`.
pub(crate) fn cloud(
    n: usize,
    sigma: f64,
    centre: [f64; 3],
    seed: u64,
) -> (Vec<f64>, Vec<[f64; 3]>) {
    let mut rng = Rng::new(seed);
    let clumps: Vec<[f64; 3]> = (0..5)
        .map(|_| std::array::from_fn(|a| centre[a] + sigma * rng.normal()))
        .collect();
    let m = (0..n).map(|_| 0.5 + rng.uniform()).collect();
    let x = (0..n)
        .map(|i| {
            if i % 2 == 0 {
                std::array::from_fn(|a| centre[a] + sigma * rng.normal())
            } else {
                let c = clumps[i / 2 % clumps.len()];
                std::array::from_fn(|a| c[a] + 0.1 * sigma * rng.normal())
            }
        })
        .collect();
    (m, x)
}

/// `n` particles in a Gaussian of standard deviation `sigma` around the origin,
/// masses uniform in `[0.5, 1.5)`.
pub(crate) fn gaussian(n: usize, sigma: f64, seed: u64) -> (Vec<f64>, Vec<[f64; 3]>) {
    let mut rng = Rng::new(seed);
    let m = (0..n).map(|_| 0.5 + rng.uniform()).collect();
    let x = (0..n)
        .map(|_| std::array::from_fn(|_| sigma * rng.normal()))
        .collect();
    (m, x)
}

/// `sqrt(mean_i |a_i - b_i|^2 / |b_i|^2)`.
pub(crate) fn rms_relative(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(a, b)| {
            let e: f64 = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum();
            let s: f64 = b.iter().map(|v| v * v).sum();
            e / s
        })
        .sum();
    (sum / a.len() as f64).sqrt()
}

/// The relative error of the force between two unit masses `sep` cells apart,
/// over `trials` random placements and directions: `(rms, max)`. An isolated
/// `grid` mesh is pinned to the cell 1 by two light anchors `grid - 4` cells
/// apart; `solve` sees the four particles.
pub(crate) fn pair_error(
    law: GravityLaw,
    grid: usize,
    sep: f64,
    trials: usize,
    seed: u64,
    mut solve: impl FnMut(&Sources, FieldOut),
) -> (f64, f64) {
    let mut rng = Rng::new(seed);
    let (mut sum, mut max) = (0.0, 0.0f64);
    for _ in 0..trials {
        let far = (grid - 4) as f64;
        let a: [f64; 3] = std::array::from_fn(|_| far / 2.0 - sep / 2.0 + rng.uniform());
        let dir = loop {
            let v: [f64; 3] = std::array::from_fn(|_| 2.0 * rng.uniform() - 1.0);
            let r2: f64 = v.iter().map(|c| c * c).sum();
            if r2 > 0.01 && r2 <= 1.0 {
                break v.map(|c| c / r2.sqrt());
            }
        };
        let b = std::array::from_fn(|k| a[k] + sep * dir[k]);
        let x = [a, b, [0.0; 3], [far; 3]];
        let m = [1.0, 1.0, 1e-12, 1e-12];
        let (acc, _) = run(&m, &x, &mut solve);
        let k = law.unit_pair(sep * sep).1;
        for (i, sign) in [(0, 1.0), (1, -1.0)] {
            let want: [f64; 3] = std::array::from_fn(|c| sign * k * sep * dir[c]);
            let e = rms_relative(&acc[i..i + 1], &[want]);
            sum += e * e;
            max = max.max(e);
        }
    }
    ((sum / (2 * trials) as f64).sqrt(), max)
}
