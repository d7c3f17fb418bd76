use super::*;
use crate::random::Rng;

/// `n` blobs with random positions in the unit cube and random strengths.
fn cloud(n: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut rng = Rng::new(seed);
    let mut draw = |scale: f64| scale * (2.0 * rng.uniform() - 1.0);
    let x = (0..n).map(|_| [draw(0.5), draw(0.5), draw(0.5)]).collect();
    let a = (0..n)
        .map(|_| [draw(1e-3), draw(1e-3), draw(1e-3)])
        .collect();
    (x, a)
}

fn params(nu: f64, stretching: Stretching) -> Vortex3Params {
    Vortex3Params {
        nu,
        spacing: 0.1,
        sigma: 0.15,
        pse_cutoff_factor: 4.0,
        remesh_every: 0,
        remesh_threshold: 0.0,
        stretching,
        relaxation: None,
        solver: Velocity3Solver::Direct,
    }
}

#[test]
fn the_transpose_scheme_keeps_the_total_vorticity() {
    let (x, a) = cloud(300, 1);
    let threads = Threads::new(2).unwrap();
    let total = |s: &Vortex3System| {
        s.alpha()
            .iter()
            .fold([0.0; 3], |t, a| [t[0] + a[0], t[1] + a[1], t[2] + a[2]])
    };
    let size: f64 = a.iter().map(|a| dot(*a, *a).sqrt()).sum();
    for nu in [0.0, 0.01] {
        let mut s = Vortex3System::new(
            params(nu, Stretching::Transpose),
            x.clone(),
            a.clone(),
            &threads,
        )
        .unwrap();
        let before = total(&s);
        for step in 1..=5 {
            s.step(Integrator::Rk4, 0.05, step, &threads).unwrap();
        }
        let after = total(&s);
        for c in 0..3 {
            assert!(
                (after[c] - before[c]).abs() < 1e-13 * size,
                "nu {nu}: {before:?} -> {after:?}"
            );
        }
        // the strengths did change: stretching acts
        assert_ne!(s.alpha(), &a[..]);
    }
    // the classical scheme does not keep it (a check that the test can fail)
    let mut s = Vortex3System::new(params(0.0, Stretching::Classical), x, a, &threads).unwrap();
    let before = total(&s);
    for step in 1..=5 {
        s.step(Integrator::Rk4, 0.05, step, &threads).unwrap();
    }
    let after = total(&s);
    assert!((0..3).any(|c| (after[c] - before[c]).abs() > 1e-10 * size));
}

#[test]
fn one_and_two_threads_and_a_restart_give_the_same_bits() {
    let (x, a) = cloud(200, 2);
    let mut p = params(0.01, Stretching::Transpose);
    p.relaxation = Some(Relaxation {
        factor: 0.3,
        every: 2,
    });
    let run =
        |threads: usize, steps: std::ops::RangeInclusive<u64>, from: Option<&Vortex3System>| {
            let threads = Threads::new(threads).unwrap();
            let mut s = Vortex3System::new(p, x.clone(), a.clone(), &threads).unwrap();
            if let Some(from) = from {
                s.set_particles(from.positions(), from.alpha(), from.dropped(), &threads)
                    .unwrap();
            }
            for step in steps {
                s.step(Integrator::Rk2, 0.05, step, &threads).unwrap();
            }
            s
        };
    let one = run(1, 1..=4, None);
    let two = run(2, 1..=4, None);
    assert_eq!(one.positions(), two.positions());
    assert_eq!(one.alpha(), two.alpha());
    assert_eq!(one.velocity(), two.velocity());
    let half = run(2, 1..=2, None);
    let resumed = run(1, 3..=4, Some(&half));
    assert_eq!(one.positions(), resumed.positions());
    assert_eq!(one.alpha(), resumed.alpha());
}

#[test]
fn relaxation_turns_towards_the_curl_and_a_full_one_keeps_the_size() {
    let (x, a) = cloud(150, 3);
    let threads = Threads::new(1).unwrap();
    let mut s = Vortex3System::new(params(0.0, Stretching::Transpose), x, a, &threads).unwrap();
    let before: Vec<[f64; 3]> = s.alpha().to_vec();
    let curls: Vec<[f64; 3]> = s.gradient().iter().map(curl).collect();
    let size = |a: [f64; 3]| dot(a, a).sqrt();
    let cosine = |a: [f64; 3], b: [f64; 3]| dot(a, b) / (size(a) * size(b));
    s.relax(0.5);
    for ((new, old), w) in s.alpha().iter().zip(&before).zip(&curls) {
        assert!(size(*new) <= size(*old) * (1.0 + 1e-12));
        assert!(cosine(*new, *w) >= cosine(*old, *w) - 1e-12);
    }
    let half: Vec<[f64; 3]> = s.alpha().to_vec();
    s.relax(1.0);
    for ((new, old), w) in s.alpha().iter().zip(&half).zip(&curls) {
        assert!((size(*new) - size(*old)).abs() < 1e-12 * size(*old));
        assert!((cosine(*new, *w) - 1.0).abs() < 1e-12);
    }
}

#[test]
fn stretching_and_curl_read_the_gradient_by_its_layout() {
    // u = (y, 2 z, 3 x): d u_a / d x_b
    let g = [0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 3.0, 0.0, 0.0];
    let alpha = [1.0, 10.0, 100.0];
    // (alpha . grad) u = (alpha_y, 2 alpha_z, 3 alpha_x)
    assert_eq!(stretching(&alpha, &g, false), [10.0, 200.0, 3.0]);
    // (alpha . grad^T) u: component a = sum_b alpha_b d u_b / d x_a = (3 alpha_z, alpha_x, 2 alpha_y)
    assert_eq!(stretching(&alpha, &g, true), [300.0, 1.0, 20.0]);
    // curl (y, 2z, 3x) = (0 - 2, 0 - 3, 0 - 1)
    assert_eq!(curl(&g), [-2.0, -3.0, -1.0]);
}

#[test]
fn bad_parameters_are_named() {
    let mut p = params(0.0, Stretching::Transpose);
    p.relaxation = Some(Relaxation {
        factor: 1.5,
        every: 1,
    });
    assert!(p.check().unwrap_err().contains("relaxation.factor"));
    p.relaxation = Some(Relaxation {
        factor: 0.5,
        every: 0,
    });
    assert!(p.check().unwrap_err().contains("relaxation.every"));
    let (x, mut a) = cloud(10, 4);
    a[3][1] = f64::NAN;
    let threads = Threads::new(1).unwrap();
    let e = Vortex3System::new(params(0.0, Stretching::Transpose), x, a, &threads).unwrap_err();
    assert!(e.to_string().contains("particle 3"), "{e}");
}
