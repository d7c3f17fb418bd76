//! Particle strength exchange: conservation, thread independence, direct against
//! cell list, the discrete decay rate of a sine mode, and second-order convergence
//! in eps.

use cellist::models::pse::{lattice, InitialField, Integrator, Method, PseParams, PseSystem};
use cellist::{Domain, Threads};
use proptest::prelude::*;
use std::f64::consts::PI;

fn system<const D: usize>(
    n: usize,
    jitter: f64,
    eps_over_h: f64,
    method: Method,
    field: InitialField<D>,
    threads: &Threads,
) -> PseSystem<D> {
    let domain = Domain::periodic([1.0; D]).unwrap();
    let points = lattice::<D>(n, 1.0, jitter, 7);
    let phi = field.exact_at(&points, 0.0, 1.0, &domain.length);
    let params = PseParams {
        nu: 1.0,
        epsilon: eps_over_h / n as f64,
        method,
    };
    PseSystem::new(domain, &points, &phi, params, threads).unwrap()
}

const GAUSSIAN2: InitialField<2> = InitialField::Gaussian {
    center: [0.3, 0.6],
    width: 0.1,
};

#[test]
fn the_total_is_conserved_over_a_run() {
    let threads = Threads::single();
    for method in [Method::Direct, Method::CellList { cutoff_factor: 5.0 }] {
        for integrator in [Integrator::Euler, Integrator::Rk4] {
            let mut s = system::<2>(24, 0.4, 1.3, method, GAUSSIAN2, &threads);
            let dt = 0.9 * s.stability_limit(integrator, &threads);
            let start = s.total();
            for _ in 0..200 {
                s.step(integrator, dt, &threads).unwrap();
            }
            let drift = (s.total() - start).abs() / start.abs();
            assert!(drift < 1e-12, "{method:?} {integrator:?}: {drift:e}");
            // the field did change
            let (l2, _) = s.errors(&GAUSSIAN2.exact_at(&s.positions(), 0.0, 1.0, &[1.0; 2]));
            assert!(l2 > 1e-3, "{l2}");
        }
    }
}

fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

#[test]
fn one_and_two_threads_give_the_same_bits() {
    let two = Threads::new(2).unwrap();
    let one = Threads::single();
    // 600 particles make three all-pairs blocks; 3D runs over several layers
    for method in [Method::Direct, Method::CellList { cutoff_factor: 3.0 }] {
        let run2 = |threads: &Threads| {
            let mut s = system::<2>(25, 0.5, 1.0, method, GAUSSIAN2, threads);
            for _ in 0..5 {
                s.step(Integrator::Rk2, 1e-5, threads).unwrap();
            }
            s.phi()
        };
        assert!(same_bits(&run2(&one), &run2(&two)), "{method:?} 2D");
        let field3 = InitialField::Sine { k: [1, 2, 1] };
        let run3 = |threads: &Threads| {
            let mut s = system::<3>(12, 0.5, 1.0, method, field3, threads);
            for _ in 0..3 {
                s.step(Integrator::Rk4, 1e-5, threads).unwrap();
            }
            s.phi()
        };
        assert!(same_bits(&run3(&one), &run3(&two)), "{method:?} 3D");
    }
}

/// `lambda = sum_o w(o) (prod_d cos(kappa_d o_d) - 1)` over the lattice offsets `o`
/// within the cutoff: the eigenvalue of the discrete operator for the sine mode,
/// summed here straight from the definition of seed 002 with the library's `exp`.
fn lattice_eigenvalue(n: usize, eps: f64, cutoff: f64, k: [i64; 2]) -> f64 {
    let h = 1.0 / n as f64;
    let volume = h * h;
    let reach = (cutoff / h).ceil() as i64;
    let mut lambda = 0.0;
    for i in -reach..=reach {
        for j in -reach..=reach {
            let o = [i as f64 * h, j as f64 * h];
            let r2 = o[0] * o[0] + o[1] * o[1];
            if (i, j) == (0, 0) || r2 >= cutoff * cutoff {
                continue;
            }
            let eta = 4.0 / PI / (eps * eps) * (-r2 / (eps * eps)).exp();
            let cos = (2.0 * PI * k[0] as f64 * o[0]).cos() * (2.0 * PI * k[1] as f64 * o[1]).cos();
            lambda += volume / (eps * eps) * eta * (cos - 1.0);
        }
    }
    lambda
}

#[test]
fn the_sine_mode_decays_at_the_rate_of_the_discrete_operator() {
    let threads = Threads::single();
    let (n, k) = (64, [1, 2]);
    let eps = 1.0 / n as f64;
    let s0 = system::<2>(
        n,
        0.0,
        1.0,
        Method::CellList { cutoff_factor: 5.0 },
        InitialField::Sine { k },
        &threads,
    );
    let lambda = lattice_eigenvalue(n, eps, 5.0 * eps, k);
    let mut s = s0.clone();
    let (steps, dt) = (200, 2e-6);
    for _ in 0..steps {
        s.step(Integrator::Rk4, dt, &threads).unwrap();
    }
    let decay = (lambda * steps as f64 * dt).exp();
    let (before, after) = (s0.phi(), s.phi());
    let mut worst = 0.0f64;
    for (b, a) in before.iter().zip(&after) {
        if b.abs() > 0.1 {
            worst = worst.max((a / b - decay).abs() / decay);
        }
    }
    eprintln!("worst relative deviation from exp(lambda t): {worst:e}");
    assert!(worst < 1e-9, "{worst:e}");
    // and the decay is a real one: a tenth of the amplitude over the run
    assert!(decay < 0.95, "{decay}");
}

#[test]
fn the_error_against_the_heat_equation_falls_as_eps_squared() {
    // h / eps = 1/2 fixed; time error negligible (RK4, small dt)
    let threads = Threads::single();
    let field = InitialField::Sine { k: [1, 1] };
    let t_end = 0.0005;
    let mut errors = Vec::new();
    for n in [32, 64, 128] {
        let mut s = system::<2>(
            n,
            0.0,
            2.0,
            Method::CellList { cutoff_factor: 6.0 },
            field,
            &threads,
        );
        let steps = 10;
        let dt = t_end / steps as f64;
        assert!(dt < s.stability_limit(Integrator::Rk4, &threads));
        for _ in 0..steps {
            s.step(Integrator::Rk4, dt, &threads).unwrap();
        }
        let exact = field.exact_at(&s.positions(), t_end, 1.0, &[1.0; 2]);
        errors.push(s.errors(&exact).0);
    }
    eprintln!("L2 errors at n = 32, 64, 128: {errors:?}");
    for w in errors.windows(2) {
        let order = (w[0] / w[1]).log2();
        assert!((order - 2.0).abs() < 0.2, "orders from {errors:?}");
    }
}

#[test]
fn euler_at_the_stability_limit_does_not_grow() {
    let threads = Threads::single();
    let mut s = system::<2>(20, 0.6, 1.5, Method::Direct, GAUSSIAN2, &threads);
    // a rough field: alternating signs excite the fastest mode
    let points = s.positions();
    let rough: Vec<f64> = (0..points.len())
        .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    s = PseSystem::new(*s.domain(), &points, &rough, *s.params(), &threads).unwrap();
    let dt = s.stability_limit(Integrator::Euler, &threads);
    let norm = |s: &PseSystem<2>| s.phi().iter().map(|v| v * v).sum::<f64>();
    let mut last = norm(&s);
    for _ in 0..300 {
        s.step(Integrator::Euler, dt, &threads).unwrap();
        let now = norm(&s);
        assert!(now <= last * (1.0 + 1e-12), "{now} > {last}");
        last = now;
    }
    // far beyond it the same field blows up
    let mut unstable = PseSystem::new(*s.domain(), &points, &rough, *s.params(), &threads).unwrap();
    let mut blew_up = false;
    for _ in 0..2000 {
        if unstable
            .step(Integrator::Euler, 5.0 * dt, &threads)
            .is_err()
        {
            blew_up = true;
            break;
        }
    }
    assert!(blew_up);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn direct_and_cell_list_agree_beyond_six_eps(
        n in 24usize..34,
        jitter in 0.0f64..0.9,
        eps_over_h in 0.5f64..1.4,
        factor in 6.0f64..7.0,
        kx in 1i64..3,
    ) {
        let threads = Threads::single();
        let field = InitialField::Sine { k: [kx, 1] };
        let mut direct = system::<2>(n, jitter, eps_over_h, Method::Direct, field, &threads);
        let mut cells = system::<2>(n, jitter, eps_over_h, Method::CellList { cutoff_factor: factor }, field, &threads);
        let (a, b) = (direct.rate(&threads), cells.rate(&threads));
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (x, y) in a.iter().zip(&b) {
            prop_assert!((x - y).abs() <= 1e-12 * scale, "{} vs {} (scale {})", x, y, scale);
        }
    }

    #[test]
    fn the_rates_sum_to_zero(n in 6usize..20, jitter in 0.0f64..1.0, eps_over_h in 0.3f64..2.0) {
        let threads = Threads::single();
        for method in [Method::Direct, Method::CellList { cutoff_factor: 2.5 }] {
            let mut s = system::<3>(n, jitter, eps_over_h.min(n as f64 / 5.5), method, InitialField::Gaussian { center: [0.5; 3], width: 0.15 }, &threads);
            let rate = s.rate(&threads);
            let sum: f64 = rate.iter().sum();
            let scale: f64 = rate.iter().map(|r| r.abs()).sum();
            prop_assert!(sum.abs() <= 1e-13 * scale.max(1e-300));
        }
    }
}

/// The rate over id-sorted rows of the particles and their periodic images
/// (what one subdomain holding the whole box sees) equals the periodic cell-list
/// rate, for 1 and 2 threads alike.
#[test]
fn ordered_rows_give_the_periodic_rate() {
    use cellist::models::pse::{ordered_rate, row_weights, PairWeight};
    use cellist::neighbors::OrderedRows;
    let threads = Threads::single();
    let cutoff_factor = 5.0;
    let mut s = system::<2>(
        24,
        0.4,
        1.3,
        Method::CellList { cutoff_factor },
        GAUSSIAN2,
        &threads,
    );
    let expected = s.rate(&threads);
    let own = s.positions();
    let n = own.len();
    let mut points = own.clone();
    let mut ids: Vec<u64> = (0..n as u64).collect();
    for sx in [-1.0, 0.0, 1.0] {
        for sy in [-1.0, 0.0, 1.0] {
            if sx != 0.0 || sy != 0.0 {
                points.extend(own.iter().map(|x| [x[0] + sx, x[1] + sy]));
                ids.extend(0..n as u64);
            }
        }
    }
    let phi: Vec<f64> = (0..points.len()).map(|k| s.phi()[k % n]).collect();
    let params = *s.params();
    let cutoff = cutoff_factor * params.epsilon;
    let weight = PairWeight::new(2, params.nu, params.epsilon, s.volume());
    let mut rates = Vec::new();
    for t in [1, 2] {
        let threads = Threads::new(t).unwrap();
        let rows = OrderedRows::build(&points, n, &ids, cutoff, 0.0, &threads).unwrap();
        let weights = row_weights(&rows, &weight, &points, cutoff);
        let mut out = vec![0.0; n];
        ordered_rate(&rows, &weights, &phi, &mut out, &threads);
        rates.push(out);
    }
    assert!(same_bits(&rates[0], &rates[1]));
    let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in rates[0].iter().zip(&expected) {
        assert!((a - b).abs() <= 1e-12 * scale, "{a} against {b}");
    }
}

/// The PSE rate of moving particles with three components per particle (the 3D
/// vortex strengths): each component has the bits of a scalar call with it
/// alone, 1 and 2 threads give the same bits, and the open-domain rate matches
/// an all-pairs sum within the cutoff.
#[test]
fn the_vector_moving_rate_is_three_scalar_rates() {
    use cellist::longrange::Alone;
    use cellist::models::pse::{moving_rate, PairWeight};
    use cellist::random::Rng;
    let mut rng = Rng::new(3);
    let n = 1500;
    let x: Vec<[f64; 3]> = (0..n)
        .map(|_| [rng.uniform(), rng.uniform(), rng.uniform()])
        .collect();
    let alpha: Vec<[f64; 3]> = (0..n)
        .map(|_| [rng.normal(), rng.uniform() - 0.5, 2.0 * rng.normal() + 1.0])
        .collect();
    let eps = 0.04;
    let cutoff = 3.0 * eps;
    let weight = PairWeight::new(3, 0.01, eps, 1.0 / n as f64);
    let (one, two) = (Threads::single(), Threads::new(2).unwrap());
    for domain in [Domain::open_around(&x), Domain::periodic([1.0; 3]).unwrap()] {
        let mut rates = Vec::new();
        for threads in [&one, &two] {
            let mut out = vec![[0.0; 3]; n];
            moving_rate(
                &domain, &weight, cutoff, &x, &alpha, &mut out, &Alone, threads,
            )
            .unwrap();
            rates.push(out);
        }
        assert!(same_bits(rates[0].as_flattened(), rates[1].as_flattened()));
        for c in 0..3 {
            let phi: Vec<[f64; 1]> = alpha.iter().map(|a| [a[c]]).collect();
            let mut out = vec![[0.0; 1]; n];
            moving_rate(&domain, &weight, cutoff, &x, &phi, &mut out, &Alone, &one).unwrap();
            let column: Vec<f64> = rates[0].iter().map(|r| r[c]).collect();
            assert!(same_bits(&column, out.as_flattened()), "component {c}");
        }
        if domain.is_periodic(0) {
            continue;
        }
        // all pairs within the cutoff, open domain
        let mut scale = 0.0f64;
        let expected: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let mut rate = [0.0; 3];
                for j in 0..n {
                    let r2: f64 = (0..3).map(|a| (x[j][a] - x[i][a]).powi(2)).sum();
                    if j != i && r2.sqrt() < cutoff {
                        let w = weight.scale * (-r2 / (eps * eps)).exp();
                        for c in 0..3 {
                            rate[c] += w * (alpha[j][c] - alpha[i][c]);
                        }
                    }
                }
                scale = rate.iter().fold(scale, |m, v| m.max(v.abs()));
                rate
            })
            .collect();
        assert!(scale > 0.0);
        for (a, b) in rates[0].iter().zip(&expected) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-12 * scale, "{a:?} against {b:?}");
            }
        }
    }
}
