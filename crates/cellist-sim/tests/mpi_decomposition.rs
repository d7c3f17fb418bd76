//! MPI test (feature `mpi`, its own binary): the domain decomposition's particle
//! exchanges against brute force. Every rank makes the same random particles,
//! starts with a block of them by id (not by place), migrates them to their
//! owners, receives its ghosts, moves them a little and migrates again. Checked
//! on every rank: it holds exactly the particles its subdomain owns, the total
//! count is kept, and its ghosts are exactly the images of particles within
//! reach of its subdomain. With balanced planes the particles crowd towards
//! the lower corner and every round places the planes again from the ranks'
//! summed histograms ([`balance`]) before the particles migrate.
//!
//! ```text
//! cargo test --release -p cellist-sim --features mpi --test mpi_decomposition --no-run
//! mpirun --allow-run-as-root --oversubscribe -np 4 target/release/deps/mpi_decomposition-<hash>
//! ```

use cellist::decomposition::{Balance, Decomposition, Images};
use cellist::geometry::{Boundary, Domain};
use cellist::random::Rng;
use cellist_sim::distributed::{balance, ghosts, migrate, LocalParticles};
use mpi::traits::*;

/// The particles every rank makes: id, position, and one more number (a
/// stand-in for a velocity) that must travel with them; uniform, or with
/// `crowded` each coordinate `lo + u^2 L`.
fn make<const D: usize>(
    domain: &Domain<D>,
    n: usize,
    seed: u64,
    crowded: bool,
) -> Vec<(u64, [f64; D], f64)> {
    let mut rng = Rng::new(seed);
    let spread = |u: f64| if crowded { u * u } else { u };
    (0..n as u64)
        .map(|id| {
            let x =
                std::array::from_fn(|k| domain.lo[k] + spread(rng.uniform()) * domain.length[k]);
            (id, x, id as f64 * 0.5)
        })
        .collect()
}

/// What this rank holds, sorted by id, as (id, position bits, extra).
fn held<const D: usize>(p: &LocalParticles) -> Vec<(u64, Vec<u64>, u64)> {
    let mut v: Vec<_> = (0..p.len())
        .map(|k| {
            let x: [f64; D] = p.position(k);
            (
                p.ids[k],
                x.iter().map(|c| c.to_bits()).collect(),
                p.values[k * p.width + D].to_bits(),
            )
        })
        .collect();
    v.sort();
    v
}

fn check<C: Communicator, const D: usize>(
    world: &C,
    name: &str,
    domain: Domain<D>,
    n: usize,
    reach: f64,
    planes: Balance,
) -> Result<(), String> {
    let ranks = world.size() as usize;
    let rank = world.rank() as usize;
    let mut decomposition = Decomposition::new(domain, ranks);
    decomposition.check_reach(reach)?;
    let mut all = make(&domain, n, 5 + D as u64, planes == Balance::Rcb);
    let mut mine = LocalParticles {
        width: D + 1,
        ..LocalParticles::default()
    };
    let block = n.div_ceil(ranks);
    for (id, x, extra) in all.iter().skip(rank * block).take(block) {
        mine.ids.push(*id);
        mine.values.extend_from_slice(x);
        mine.values.push(*extra);
    }
    for round in 0..2 {
        if planes == Balance::Rcb {
            let positions: Vec<[f64; D]> = (0..mine.len()).map(|k| mine.position(k)).collect();
            decomposition = balance(world, &decomposition, &positions, reach);
            decomposition.check_reach(reach)?;
        }
        migrate(world, &decomposition, &mut mine);
        // ownership against brute force
        let mut expected = LocalParticles {
            width: D + 1,
            ..LocalParticles::default()
        };
        for (id, x, extra) in &all {
            let x = domain.wrap(*x);
            if decomposition.owner(&x) == rank {
                expected.ids.push(*id);
                expected.values.extend_from_slice(&x);
                expected.values.push(*extra);
            }
        }
        if held::<D>(&mine) != held::<D>(&expected) {
            return Err(format!(
                "{name}, round {round}: rank {rank} holds {} particles, owns {}",
                mine.len(),
                expected.len()
            ));
        }
        let mut total = 0u64;
        world.all_reduce_into(
            &(mine.len() as u64),
            &mut total,
            mpi::collective::SystemOperation::sum(),
        );
        if total != n as u64 {
            return Err(format!("{name}, round {round}: {total} particles, not {n}"));
        }
        // ghosts against brute force: the images within reach, outside the subdomain
        let got = ghosts(world, &decomposition, &mine, reach, Images::All);
        let (lo, hi) = decomposition.bounds(rank);
        let mut want: Vec<(u64, Vec<i64>)> = Vec::new();
        for (id, x, _) in &all {
            let x = domain.wrap(*x);
            for code in 0..3usize.pow(D as u32) {
                let m: [i64; D] =
                    std::array::from_fn(|k| (code / 3usize.pow(k as u32) % 3) as i64 - 1);
                if (0..D).any(|k| m[k] != 0 && !domain.is_periodic(k)) {
                    continue;
                }
                let y: [f64; D] = std::array::from_fn(|k| x[k] + m[k] as f64 * domain.length[k]);
                let inside = (0..D).all(|k| y[k] >= lo[k] && y[k] < hi[k]);
                let shell = (0..D).all(|k| y[k] >= lo[k] - reach && y[k] <= hi[k] + reach);
                if shell && !inside {
                    want.push((*id, m.to_vec()));
                }
            }
        }
        let mut have: Vec<(u64, Vec<i64>)> = (0..got.len())
            .map(|k| {
                let id = got.ids[k];
                let y: [f64; D] = got.position(k);
                let x = domain.wrap(all[id as usize].1);
                let image = (0..D)
                    .map(|d| ((y[d] - x[d]) / domain.length[d]).round() as i64)
                    .collect();
                (id, image)
            })
            .collect();
        want.sort();
        have.sort();
        if want != have {
            return Err(format!(
                "{name}, round {round}: rank {rank} received {} ghosts, expected {}",
                have.len(),
                want.len()
            ));
        }
        // every particle moves by up to reach / 2 (some across subdomains and
        // periodic faces) on every rank alike
        let mut rng = Rng::new(100 + round as u64);
        for p in all.iter_mut() {
            for k in 0..D {
                p.1[k] += (rng.uniform() - 0.5) * reach;
            }
        }
        for k in 0..mine.len() {
            let id = mine.ids[k] as usize;
            mine.values[k * mine.width..k * mine.width + D].copy_from_slice(&all[id].1);
        }
    }
    Ok(())
}

fn main() {
    let universe = mpi::initialize().expect("MPI initialises once");
    let world = universe.world();
    let periodic3 = Domain::periodic([10.0, 12.0, 9.0]).unwrap();
    let periodic2 = Domain::periodic([11.0, 7.0]).unwrap();
    let mixed = Domain::new([10.0, 10.0], [Boundary::Periodic, Boundary::Open]).unwrap();
    let (equal, balanced) = (Balance::Uniform, Balance::Rcb);
    let results = [
        (
            "3D periodic, 2000 particles, reach 1.5",
            check(&world, "3D periodic", periodic3, 2000, 1.5, equal),
        ),
        (
            "2D periodic, 1000 particles, reach 1.2",
            check(&world, "2D periodic", periodic2, 1000, 1.2, equal),
        ),
        (
            "2D periodic x open, 800 particles, reach 1.0",
            check(&world, "2D mixed", mixed, 800, 1.0, equal),
        ),
        (
            "3D periodic, 2000 crowded particles, balanced planes, reach 1.5",
            check(&world, "3D balanced", periodic3, 2000, 1.5, balanced),
        ),
        (
            "2D periodic x open, 800 crowded particles, balanced planes, reach 1.0",
            check(&world, "2D mixed balanced", mixed, 800, 1.0, balanced),
        ),
    ];
    let (mut passed, mut failed) = (0, 0);
    for (name, result) in results {
        // a case fails when it failed on any rank
        let mine = i32::from(result.is_err());
        let mut any = 0i32;
        world.all_reduce_into(&mine, &mut any, mpi::collective::SystemOperation::max());
        if let Err(why) = &result {
            eprintln!("rank {}: {why}", world.rank());
        }
        if any == 0 {
            passed += 1;
        } else {
            failed += 1;
        }
        if world.rank() == 0 {
            println!(
                "{} decomposition on {} ranks, {name}",
                if any == 0 { "ok  " } else { "FAIL" },
                world.size()
            );
        }
    }
    if world.rank() == 0 {
        println!("{passed} passed, {failed} failed");
    }
    if failed > 0 {
        std::process::exit(1);
    }
}
