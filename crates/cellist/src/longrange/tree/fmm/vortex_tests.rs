use super::*;
use crate::longrange::biot_savart::{velocity_at, BlobKernel, PointVortex};
use crate::random::Rng;

/// `n` points uniformly in the unit square, or (`clustered`) half of them in
/// a small disc, with circulations of either sign.
fn cloud(seed: u64, n: usize, clustered: bool) -> (Vec<[f64; 2]>, Vec<f64>) {
    let mut rng = Rng::new(seed);
    let x = (0..n)
        .map(|i| {
            let p = [rng.uniform(), rng.uniform()];
            if clustered && i % 2 == 0 {
                [0.3 + 0.01 * p[0], 0.6 + 0.01 * p[1]]
            } else {
                p
            }
        })
        .collect();
    let gamma = (0..n).map(|_| rng.uniform() - 0.3).collect();
    (x, gamma)
}

/// The point vortices' velocities by brute force, written out here:
/// `u = -Gamma dy / (2 pi r^2)`, `v = Gamma dx / (2 pi r^2)`, nothing at `r = 0`.
fn point_reference(x: &[[f64; 2]], gamma: &[f64]) -> Vec<[f64; 2]> {
    x.iter()
        .map(|a| {
            let mut u = [0.0; 2];
            for (b, g) in x.iter().zip(gamma) {
                let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
                let r2 = dx * dx + dy * dy;
                if r2 > 0.0 {
                    u[0] -= g * dy / (2.0 * PI * r2);
                    u[1] += g * dx / (2.0 * PI * r2);
                }
            }
            u
        })
        .collect()
}

/// `(RMS |e| / RMS |u|, max |e| / max |u|)`.
fn errors(got: &[[f64; 2]], want: &[[f64; 2]]) -> (f64, f64) {
    let norm = |v: &[f64; 2]| v[0].hypot(v[1]);
    let diff: Vec<f64> = got
        .iter()
        .zip(want)
        .map(|(g, w)| (g[0] - w[0]).hypot(g[1] - w[1]))
        .collect();
    let rms = (diff.iter().map(|d| d * d).sum::<f64>()
        / want.iter().map(|w| norm(w).powi(2)).sum::<f64>())
    .sqrt();
    let max = diff.iter().copied().fold(0.0, f64::max) / want.iter().map(norm).fold(0.0, f64::max);
    (rms, max)
}

fn fmm<K: VortexLaw>(
    law: K,
    accuracy: FmmAccuracy,
    x: &[[f64; 2]],
    gamma: &[f64],
    threads: &Threads,
) -> Vec<[f64; 2]> {
    let mut solver = VortexFmm::new(law, accuracy).unwrap();
    let mut u = vec![[0.0; 2]; x.len()];
    solver.compute(x, gamma, &mut u, threads);
    u
}

/// Point vortices, uniform and clustered, and blobs: at every tolerance
/// from 1e-3 to 1e-10 the RMS and the largest error (over the largest
/// speed) stay below the tolerance.
#[test]
fn errors_stay_below_the_tolerance() {
    let one = Threads::single();
    for clustered in [false, true] {
        let (x, gamma) = cloud(11, 3000, clustered);
        let points = point_reference(&x, &gamma);
        let kernel = BlobKernel::new(0.004);
        let blobs = velocity_at(&kernel, &x, &x, &gamma, &one);
        for tolerance in [1e-3, 1e-4, 1e-6, 1e-8, 1e-10] {
            let accuracy = FmmAccuracy::Tolerance(tolerance);
            let p = errors(&fmm(PointVortex, accuracy, &x, &gamma, &one), &points);
            let b = errors(&fmm(kernel, accuracy, &x, &gamma, &one), &blobs);
            eprintln!(
                "clustered {clustered}, tolerance {tolerance:e} (order {}): points {:.2e} {:.2e}, blobs {:.2e} {:.2e}",
                accuracy.order(ErrorFit::VORTEX_2D),
                p.0,
                p.1,
                b.0,
                b.1
            );
            for (rms, max) in [p, b] {
                assert!(
                    rms < tolerance && max < tolerance,
                    "{tolerance}: {rms:e} {max:e}"
                );
            }
        }
    }
}

/// Several target groups (12000 points, groups of at most 4096): uniform
/// and clustered point vortices and blobs within the tolerance, on every
/// tenth particle against brute force.
#[test]
fn several_groups_stay_within_the_tolerance() {
    let one = Threads::single();
    let kernel = BlobKernel::new(0.002);
    for clustered in [false, true] {
        let (x, gamma) = cloud(17, 12000, clustered);
        let sample: Vec<usize> = (0..x.len()).step_by(10).collect();
        let targets: Vec<[f64; 2]> = sample.iter().map(|&i| x[i]).collect();
        let points = velocity_at(&PointVortex, &targets, &x, &gamma, &one);
        let blobs = velocity_at(&kernel, &targets, &x, &gamma, &one);
        for tolerance in [1e-4, 1e-8] {
            let accuracy = FmmAccuracy::Tolerance(tolerance);
            let at = |u: Vec<[f64; 2]>| sample.iter().map(|&i| u[i]).collect::<Vec<_>>();
            let p = errors(&at(fmm(PointVortex, accuracy, &x, &gamma, &one)), &points);
            let b = errors(&at(fmm(kernel, accuracy, &x, &gamma, &one)), &blobs);
            eprintln!("clustered {clustered}, {tolerance:e}: points {p:?}, blobs {b:?}");
            for (rms, max) in [p, b] {
                assert!(
                    rms < tolerance && max < tolerance,
                    "{tolerance}: {rms:e} {max:e}"
                );
            }
        }
    }
}

/// The expansions do work: with many particles most of the far field goes
/// through M2L, and the pair count is far below `N^2`.
#[test]
fn the_far_field_goes_through_the_expansions() {
    let (x, gamma) = cloud(3, 20000, false);
    let mut solver = VortexFmm::new(PointVortex, FmmAccuracy::Tolerance(1e-6)).unwrap();
    let mut u = vec![[0.0; 2]; x.len()];
    solver.compute(&x, &gamma, &mut u, &Threads::single());
    let (m2l, pairs) = solver.interactions();
    eprintln!("{m2l} M2L, {pairs} pairs");
    assert!(m2l > 1000 && pairs < (x.len() * x.len() / 20) as u64);
}

#[test]
fn one_and_two_threads_give_the_same_bits() {
    let (x, gamma) = cloud(5, 30000, true);
    let accuracy = FmmAccuracy::Tolerance(1e-8);
    let one = fmm(PointVortex, accuracy, &x, &gamma, &Threads::single());
    let two = Threads::new(2).unwrap();
    let mut solver = VortexFmm::new(PointVortex, accuracy).unwrap();
    let mut u = vec![[0.0; 2]; x.len()];
    // twice: the second on the kept scratch
    for _ in 0..2 {
        solver.compute(&x, &gamma, &mut u, &two);
        assert!(one
            .iter()
            .zip(&u)
            .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits)));
    }
}

/// No particles; one; two at one position (nothing between them, no NaN).
#[test]
fn edge_cases() {
    let one = Threads::single();
    let accuracy = FmmAccuracy::Tolerance(1e-6);
    assert!(fmm(PointVortex, accuracy, &[], &[], &one).is_empty());
    assert_eq!(
        fmm(PointVortex, accuracy, &[[0.2, 0.3]], &[1.0], &one),
        [[0.0; 2]]
    );
    let x = [[0.2, 0.3], [0.2, 0.3], [0.7, 0.3]];
    let u = fmm(PointVortex, accuracy, &x, &[1.0, 2.0, 1.0], &one);
    let want = point_reference(&x, &[1.0, 2.0, 1.0]);
    assert!(errors(&u, &want).0 < 1e-12, "{u:?} {want:?}");
}

#[test]
fn accuracy_ranges_and_orders() {
    assert!(FmmAccuracy::Tolerance(1e-15).check().is_err());
    assert!(FmmAccuracy::Tolerance(0.1).check().is_err());
    assert!(FmmAccuracy::Tolerance(f64::NAN).check().is_err());
    assert!(FmmAccuracy::Order(0).check().is_err());
    assert!(FmmAccuracy::Order(64).check().is_err());
    assert!(FmmAccuracy::Tolerance(1e-6).check().is_ok());
    // tighter tolerances ask for higher orders
    let orders: Vec<usize> = [1e-3, 1e-6, 1e-10]
        .map(|t| FmmAccuracy::Tolerance(t).order(ErrorFit::VORTEX_2D))
        .to_vec();
    assert!(orders[0] < orders[1] && orders[1] < orders[2], "{orders:?}");
    assert!(VortexFmm::new(PointVortex, FmmAccuracy::Order(70)).is_err());
}
