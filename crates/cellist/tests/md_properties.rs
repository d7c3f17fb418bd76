//! Molecular dynamics against brute force: forces, energy and virial of the
//! layer-coloured half-list sum against all pairs by minimum image; 1 against 2
//! threads bit for bit; Newton's third law; energy conservation.
#![allow(clippy::needless_range_loop)]

use cellist::geometry::{norm2, Boundary, Domain};
use cellist::interactions::{LennardJones, PairPotential};
use cellist::models::md::{lattice, Atoms, Integrator, LatticeKind, MdSystem, StageTimes};
use cellist::neighbors::RebuildRule;
use cellist::random::Rng;
use cellist::Threads;
use proptest::prelude::*;

/// Forces (by id order), energy and virial from all pairs.
fn brute_force<const D: usize>(
    domain: &Domain<D>,
    positions: &[[f64; D]],
    lj: &LennardJones,
) -> (Vec<[f64; D]>, f64, f64) {
    let mut f = vec![[0.0; D]; positions.len()];
    let (mut energy, mut virial) = (0.0, 0.0);
    for i in 0..positions.len() {
        for j in i + 1..positions.len() {
            let d =
                domain.minimum_image(std::array::from_fn(|a| positions[i][a] - positions[j][a]));
            let r2 = norm2(&d);
            if r2 < lj.cutoff2() {
                let (e, fr) = lj.energy_and_force(r2);
                for a in 0..D {
                    f[i][a] += d[a] * fr;
                    f[j][a] -= d[a] * fr;
                }
                energy += e;
                virial += fr * r2;
            }
        }
    }
    (f, energy, virial)
}

/// A jittered lattice (no two atoms closer than ~0.8 sigma) with random boundaries.
fn jittered<const D: usize>(
    cells: [usize; D],
    seed: u64,
    open: [bool; D],
) -> (Domain<D>, Vec<[f64; D]>) {
    let kind = if D == 3 {
        LatticeKind::Fcc
    } else {
        LatticeKind::Hex
    };
    let (mut domain, mut pts) = lattice::<D>(kind, 0.8, cells).unwrap();
    let mut rng = Rng::new(seed);
    for p in &mut pts {
        for a in 0..D {
            p[a] = domain.wrap(*p)[a] + 0.1 * (rng.uniform() - 0.5);
        }
    }
    for a in 0..D {
        if open[a] {
            domain.boundary[a] = Boundary::Open;
            domain.lo[a] = -0.1;
            domain.length[a] += 0.2;
        }
    }
    let pts = pts.into_iter().map(|p| domain.wrap(p)).collect();
    (domain, pts)
}

fn check_against_brute_force<const D: usize>(
    cells: [usize; D],
    seed: u64,
    open: [bool; D],
    skin: f64,
    shift: bool,
) {
    let (domain, pts) = jittered(cells, seed, open);
    let lj = LennardJones::new(1.0, 1.0, 2.5, shift).unwrap();
    let (f_ref, e_ref, w_ref) = brute_force(&domain, &pts, &lj);
    let one = MdSystem::new(
        domain,
        Atoms::at_rest(pts.clone(), 1.0),
        lj,
        skin,
        &Threads::single(),
    )
    .unwrap();
    let two = MdSystem::new(
        domain,
        Atoms::at_rest(pts, 1.0),
        lj,
        skin,
        &Threads::new(2).unwrap(),
    )
    .unwrap();
    assert_eq!(
        one.atoms().forces,
        two.atoms().forces,
        "1 and 2 threads differ"
    );
    assert_eq!(one.pair_totals(), two.pair_totals());
    let atoms = one.atoms();
    let scale: f64 = f_ref.iter().map(|f| norm2(f).sqrt()).sum::<f64>() / f_ref.len() as f64;
    let mut total = [0.0; D];
    for k in 0..atoms.len() {
        let want = &f_ref[(atoms.ids[k] - 1) as usize];
        for a in 0..D {
            assert!(
                (atoms.forces[k][a] - want[a]).abs() <= 1e-12 * scale.max(1.0),
                "atom {} axis {a}",
                atoms.ids[k]
            );
            total[a] += atoms.forces[k][a];
        }
    }
    for a in 0..D {
        assert!(
            total[a].abs() <= 1e-12 * scale.max(1.0) * atoms.len() as f64,
            "total force {total:?}"
        );
    }
    let t = one.pair_totals().unwrap();
    assert!((t.energy - e_ref).abs() <= 1e-12 * e_ref.abs().max(1.0));
    assert!((t.virial - w_ref).abs() <= 1e-12 * w_ref.abs().max(1.0));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn forces_3d_match_brute_force(nx in 4usize..6, ny in 4usize..6, nz in 4usize..7, seed in 0u64..1000,
                                   open in prop::array::uniform3(any::<bool>()), skin in 0.0f64..0.4, shift: bool) {
        check_against_brute_force([nx, ny, nz], seed, open, skin, shift);
    }

    #[test]
    fn forces_2d_match_brute_force(nx in 5usize..14, ny in 3usize..9, seed in 0u64..1000,
                                   open in prop::array::uniform2(any::<bool>()), skin in 0.0f64..0.4, shift: bool) {
        check_against_brute_force([nx, ny], seed, open, skin, shift);
    }
}

#[test]
fn velocity_verlet_conserves_energy_and_threads_agree_bit_for_bit() {
    let (domain, pts) = jittered([5, 5, 5], 11, [false; 3]);
    let lj = LennardJones::new(1.0, 1.0, 2.5, true).unwrap();
    let mut atoms = Atoms::at_rest(pts, 1.0);
    cellist::models::md::create_velocities(
        &mut atoms,
        1.0,
        5,
        cellist::models::md::VelocityDistribution::Uniform,
    );
    let run = |threads: &Threads| {
        let mut sys = MdSystem::new(domain, atoms.clone(), lj, 0.3, threads).unwrap();
        let e0 = sys.thermo().etotal;
        let mut times = StageTimes::default();
        for step in 1..=200 {
            sys.step(
                &Integrator::VelocityVerlet,
                0.002,
                step,
                true,
                threads,
                &mut times,
            )
            .unwrap();
        }
        assert!(sys.rebuilds() > 0);
        (sys.atoms().clone(), e0, sys.thermo().etotal)
    };
    let (a1, e0, e1) = run(&Threads::single());
    let (a2, _, _) = run(&Threads::new(2).unwrap());
    assert_eq!(a1, a2);
    assert!((e1 - e0).abs() < 2e-4, "energy drift {e0} -> {e1}");
}

#[test]
fn refuses_overlapping_atoms_and_small_boxes() {
    let domain = Domain::periodic([10.0, 10.0]).unwrap();
    let lj = LennardJones::new(1.0, 1.0, 2.5, false).unwrap();
    let atoms = Atoms::at_rest(vec![[1.0, 1.0], [5.0, 5.0], [1.0, 1.0]], 1.0);
    let err = MdSystem::new(domain, atoms, lj, 0.3, &Threads::single())
        .err()
        .unwrap();
    assert_eq!(
        err.to_string(),
        "atoms 1 and 3 are at the same position (infinite force)"
    );
    let small = Domain::periodic([4.0, 10.0]).unwrap();
    let atoms = Atoms::at_rest(vec![[1.0, 1.0]], 1.0);
    assert!(MdSystem::new(small, atoms, lj, 0.0, &Threads::single()).is_err());
}

/// A 256-atom fcc crystal from rest with velocities at `t0`.
fn small_crystal(t0: f64) -> (Domain<3>, Atoms<3>) {
    let (domain, pts) = lattice::<3>(LatticeKind::Fcc, 0.8442, [4, 4, 4]).unwrap();
    let mut atoms = Atoms::at_rest(pts, 1.0);
    cellist::models::md::create_velocities(
        &mut atoms,
        t0,
        9,
        cellist::models::md::VelocityDistribution::Gaussian,
    );
    (domain, atoms)
}

#[test]
fn langevin_thermostat_reaches_its_temperature_independently_of_threads() {
    let (domain, atoms) = small_crystal(0.1);
    let lj = LennardJones::new(1.0, 1.0, 2.5, true).unwrap();
    let thermostat = Integrator::Langevin(cellist::models::md::Langevin {
        temperature: 1.5,
        damping: 0.5,
        seed: 3,
    });
    let run = |threads: &Threads| {
        let mut sys = MdSystem::new(domain, atoms.clone(), lj, 0.3, threads).unwrap();
        let mut times = StageTimes::default();
        let mut temps = Vec::new();
        for step in 1..=3000 {
            sys.step(&thermostat, 0.005, step, false, threads, &mut times)
                .unwrap();
            if step > 1000 {
                temps.push(cellist::models::md::temperature(sys.atoms()));
            }
        }
        (
            sys.atoms().clone(),
            temps.iter().sum::<f64>() / temps.len() as f64,
        )
    };
    let (a1, mean) = run(&Threads::single());
    let (a2, _) = run(&Threads::new(2).unwrap());
    assert_eq!(a1, a2);
    assert!((mean - 1.5).abs() < 0.05 * 1.5, "mean temperature {mean}");
}

#[test]
fn energy_errors_order_the_integrators() {
    // max |E(t) - E(0)| over 400 steps of dt 0.001 (Euler blows up at larger dt):
    // velocity Verlet << symplectic Euler << Euler
    let (domain, atoms) = small_crystal(1.0);
    let lj = LennardJones::new(1.0, 1.0, 2.5, true).unwrap();
    let threads = Threads::single();
    let drift = |integrator: Integrator| {
        let mut sys = MdSystem::new(domain, atoms.clone(), lj, 0.3, &threads).unwrap();
        let e0 = sys.thermo().etotal;
        let mut times = StageTimes::default();
        let mut worst: f64 = 0.0;
        for step in 1..=400 {
            sys.step(&integrator, 0.001, step, true, &threads, &mut times)
                .unwrap();
            worst = worst.max((sys.thermo().etotal - e0).abs());
        }
        worst
    };
    let vv = drift(Integrator::VelocityVerlet);
    let se = drift(Integrator::SymplecticEuler);
    let eu = drift(Integrator::Euler);
    assert!(
        vv < 1e-3 && vv < se && se < eu,
        "vv {vv}, symplectic Euler {se}, Euler {eu}"
    );
}

/// The fcc melt of `cells^3` cells at temperature `t`, run `steps` steps of dt
/// 0.005 with the list rebuilt by `rule`: the atoms in id order and the list's
/// counters.
fn melt_with_rule(
    cells: usize,
    t: f64,
    steps: u64,
    rule: RebuildRule,
) -> (Atoms<3>, cellist::models::md::ListCounts) {
    let (domain, pts) = lattice(LatticeKind::Fcc, 0.8442, [cells; 3]).unwrap();
    let lj = LennardJones::new(1.0, 1.0, 2.5, false).unwrap();
    let mut atoms = Atoms::at_rest(pts, 1.0);
    cellist::models::md::create_velocities(
        &mut atoms,
        t,
        87287,
        cellist::models::md::VelocityDistribution::Uniform,
    );
    let threads = Threads::single();
    let mut sys = MdSystem::new(domain, atoms, lj, 0.3, &threads).unwrap();
    sys.set_rebuild_rule(rule);
    let mut times = StageTimes::default();
    for step in 1..=steps {
        sys.step(
            &Integrator::VelocityVerlet,
            0.005,
            step,
            step == steps,
            &threads,
            &mut times,
        )
        .unwrap();
    }
    let atoms = sys.atoms().select(&sys.atoms().slots_by_id());
    (atoms, sys.list_counts())
}

#[test]
fn a_list_rebuilt_every_n_steps_without_the_check_follows_the_checked_run_while_the_skin_holds() {
    // cold: no atom crosses skin/2 in 10 steps, so every pair within the cutoff
    // is on both lists and only the order of the sums differs
    let (checked, counts) = melt_with_rule(5, 0.05, 60, RebuildRule::default());
    assert_eq!(counts.late_builds, 0);
    let every_10 = RebuildRule {
        every: 10,
        check: false,
    };
    let (sparse, counts) = melt_with_rule(5, 0.05, 60, every_10);
    assert_eq!(counts.rebuilds, 6, "rebuilt on steps 10, 20, ..., 60");
    assert_eq!(counts.since_build, 0);
    assert_eq!(
        counts.late_builds, 0,
        "no atom moved skin/2 in 10 cold steps"
    );
    // the runs wrap positions into the box at different steps: compare them
    // under the minimum image
    let side = 5.0 * (4.0f64 / 0.8442).cbrt();
    for (a, b) in checked.positions.iter().zip(&sparse.positions) {
        for k in 0..3 {
            let d = a[k] - b[k];
            let d = d - side * (d / side).round();
            assert!(d.abs() < 1e-9, "{a:?} against {b:?}");
        }
    }
}

#[test]
fn a_hot_melt_looked_at_too_rarely_reports_late_builds() {
    let rule = RebuildRule {
        every: 25,
        check: true,
    };
    let (_, counts) = melt_with_rule(4, 3.0, 60, rule);
    assert_eq!(
        counts.rebuilds, 2,
        "looked at on steps 25 and 50, rebuilt both times"
    );
    assert_eq!(counts.since_build, 10);
    assert_eq!(counts.late_builds, 2);
}
