//! MPI test (feature `mpi`, its own binary: MPI initialises once per process):
//! the ring-pass direct gravity against the single-process direct sum.
//!
//! ```text
//! cargo build --release -p cellist-sim --features mpi --tests
//! mpirun --allow-run-as-root --oversubscribe -np 4 target/release/deps/mpi_ring-<hash>
//! ```
//!
//! Rank 0 prints one line per case and `N passed, N failed`; the status is 1
//! when a case failed on any rank.

use cellist::interactions::GravityLaw;
use cellist::longrange::{DirectSum, FieldOut, Sources};
use cellist::models::gravity::plummer;
use cellist::Threads;
use cellist_sim::distributed::ring_gravity;
use mpi::traits::*;

/// The block of `n` bodies rank `rank` of `ranks` holds: contiguous, the first
/// `n % ranks` ranks one more (uneven blocks on purpose).
fn block(n: usize, rank: usize, ranks: usize) -> std::ops::Range<usize> {
    let (base, extra) = (n / ranks, n % ranks);
    let start = rank * base + rank.min(extra);
    start..start + base + usize::from(rank < extra)
}

/// The largest `|a_ring - a_direct| / |a_direct|` over this rank's bodies, and
/// the same for the potentials.
fn worst_error<C: Communicator>(world: &C, law: GravityLaw, n: usize, threads: &Threads) -> f64 {
    // every rank makes the same bodies (the same seed) and keeps its block
    let bodies = plummer(n, 11, &law, threads);
    let (mut acc, mut phi) = (vec![[0.0; 3]; n], vec![0.0; n]);
    DirectSum::new(law, n).compute(
        &Sources {
            mass: &bodies.mass,
            position: &bodies.position,
        },
        FieldOut {
            acc: &mut acc,
            phi: &mut phi,
        },
        threads,
    );
    let mine = block(n, world.rank() as usize, world.size() as usize);
    let (ring_acc, ring_phi) = ring_gravity(
        world,
        law,
        &bodies.position[mine.clone()],
        &bodies.mass[mine.clone()],
        threads,
    );
    let mut worst = 0.0f64;
    for (k, i) in mine.enumerate() {
        let norm = acc[i].iter().map(|v| v * v).sum::<f64>().sqrt();
        let diff = (0..3)
            .map(|a| (acc[i][a] - ring_acc[k][a]).powi(2))
            .sum::<f64>()
            .sqrt();
        worst = worst
            .max(diff / norm)
            .max((phi[i] - ring_phi[k]).abs() / phi[i].abs());
    }
    let mut all = 0.0f64;
    world.all_reduce_into(&worst, &mut all, mpi::collective::SystemOperation::max());
    all
}

fn main() {
    let universe = mpi::initialize().expect("MPI initialises once");
    let world = universe.world();
    let threads = Threads::new(1).expect("a thread pool");
    let cases = [
        (
            "softened, 1003 bodies",
            GravityLaw::new(1.0, 0.01, 0.0),
            1003,
        ),
        (
            "unsoftened, 257 bodies",
            GravityLaw::new(1.0, 0.0, 0.0),
            257,
        ),
        (
            "with repulsion, 500 bodies",
            GravityLaw::new(2.0, 0.02, 0.01),
            500,
        ),
        (
            "3 bodies (ranks without any on 4 ranks)",
            GravityLaw::new(1.0, 0.05, 0.0),
            3,
        ),
    ];
    let (mut passed, mut failed) = (0, 0);
    for (name, law, n) in cases {
        let law = law.expect("a valid law");
        let worst = worst_error(&world, law, n, &threads);
        let ok = worst <= 1e-13;
        if ok {
            passed += 1;
        } else {
            failed += 1;
        }
        if world.rank() == 0 {
            println!(
                "{} ring pass on {} ranks, {name}: largest relative difference {worst:.2e} (at most 1e-13)",
                if ok { "ok  " } else { "FAIL" },
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
