//! MPI test (feature `mpi`, its own binary: MPI initialises once per process):
//! the ring-pass direct gravity against the single-process direct sum, the
//! slab-decomposed mesh solvers (PM, P3M, the 2D and 3D vortex-in-cell over
//! `MpiExchange`), gravity's Barnes-Hut tree by locally essential trees and
//! the 3D vortex direct sum with its block pairs dealt out against the same
//! solvers in one process.
//!
//! ```text
//! cargo build --release -p cellist-sim --features mpi --tests
//! mpirun --allow-run-as-root --oversubscribe -np 4 target/release/deps/mpi_ring-<hash>
//! ```
//!
//! Rank 0 prints one line per case and `N passed, N failed`; the status is 1
//! when a case failed on any rank.

use cellist::interactions::GravityLaw;
use cellist::longrange::{
    BarnesHut, BlobKernel, BlobKernel3, DirectBiotSavart3, DirectSum, FieldOut, MeshBoundary,
    MeshParams, P3m, ParticleMesh, Rank, Sources, TreeParams, Vic3Boundary, Vic3Params,
    VicBoundary, VicParams, VortexInCell, VortexInCell3,
};
use cellist::models::gravity::plummer;
use cellist::Threads;
use cellist_sim::distributed::mesh::MpiExchange;
use cellist_sim::distributed::ring_gravity;
use mpi::topology::SimpleCommunicator;
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

/// The largest over the ranks of `worst`.
fn largest<C: Communicator>(world: &C, worst: f64) -> f64 {
    let mut all = 0.0f64;
    world.all_reduce_into(&worst, &mut all, mpi::collective::SystemOperation::max());
    all
}

/// The largest `|a - b| / max |b|` over the numbers of `a` and `b`.
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    // a value that is not finite is infinitely wrong (`max` would skip a NaN)
    let worst = a.iter().zip(b).fold(0.0f64, |w, (x, y)| {
        let d = (x - y).abs();
        if d.is_finite() {
            w.max(d)
        } else {
            f64::INFINITY
        }
    });
    worst / scale
}

/// The largest relative difference of the accelerations and of the
/// potentials between gravity's mesh solver (P3M if `p3m`, else PM) on the
/// ranks of `world`, the bodies divided among them, and the same solver in
/// one process.
fn mesh_error(world: &SimpleCommunicator, params: MeshParams, p3m: bool, threads: &Threads) -> f64 {
    let law = GravityLaw::new(1.0, 0.01, 0.0).expect("a valid law");
    let n = 2000;
    let bodies = plummer(n, 5, &law, threads);
    let sources = Sources {
        mass: &bodies.mass,
        position: &bodies.position,
    };
    let exchange = MpiExchange::routing(world.duplicate());
    let rank = Rank::of(&exchange);
    // the bodies divided: each rank passes its own block and gets its
    // results, compared with its block of the single-process field
    let own = n * rank.index / rank.count..n * (rank.index + 1) / rank.count;
    let mine = Sources {
        mass: &bodies.mass[own.clone()],
        position: &bodies.position[own.clone()],
    };
    let (mut acc, mut phi) = (vec![[0.0; 3]; n], vec![0.0; n]);
    let (mut got_acc, mut got_phi) = (vec![[0.0; 3]; own.len()], vec![0.0; own.len()]);
    let whole = FieldOut {
        acc: &mut acc,
        phi: &mut phi,
    };
    let part = FieldOut {
        acc: &mut got_acc,
        phi: &mut got_phi,
    };
    if p3m {
        P3m::new(law, params, 1.25)
            .expect("a valid P3M")
            .compute(&sources, whole, threads);
        P3m::on_rank(law, params, 1.25, rank)
            .expect("a valid P3M")
            .compute_spread(&mine, part, threads, &exchange);
    } else {
        ParticleMesh::new(law, params)
            .expect("a valid PM")
            .compute(&sources, whole, threads);
        ParticleMesh::on_rank(law, params, rank)
            .expect("a valid PM")
            .compute_spread(&mine, part, threads, &exchange);
    }
    let want = (acc[own.clone()].to_vec(), phi[own].to_vec());
    let got = (got_acc, got_phi);
    let worst =
        relative(got.0.as_flattened(), want.0.as_flattened()).max(relative(&got.1, &want.1));
    largest(world, worst)
}

/// The largest relative difference of the accelerations and potentials
/// between gravity's Barnes-Hut tree on the ranks of `world`, the bodies
/// divided among them (locally essential trees), and the same tree in one
/// process, on `n` bodies of a Plummer sphere.
fn tree_error(world: &SimpleCommunicator, n: usize, threads: &Threads) -> f64 {
    let law = GravityLaw::new(1.0, 0.01, 0.0).expect("a valid law");
    let bodies = plummer(n, 7, &law, threads);
    let params = TreeParams {
        leaf_size: 8,
        group_size: 32,
        ..TreeParams::default()
    };
    let exchange = MpiExchange::essential(world.duplicate());
    let own = block(n, world.rank() as usize, world.size() as usize);
    let (mut acc, mut phi) = (vec![[0.0; 3]; n], vec![0.0; n]);
    let (mut got_acc, mut got_phi) = (vec![[0.0; 3]; own.len()], vec![0.0; own.len()]);
    let sources = Sources {
        mass: &bodies.mass,
        position: &bodies.position,
    };
    let whole = FieldOut {
        acc: &mut acc,
        phi: &mut phi,
    };
    BarnesHut::new(law, params)
        .expect("a valid tree")
        .compute(&sources, whole, threads);
    let mine = Sources {
        mass: &bodies.mass[own.clone()],
        position: &bodies.position[own.clone()],
    };
    let part = FieldOut {
        acc: &mut got_acc,
        phi: &mut got_phi,
    };
    BarnesHut::new(law, params)
        .expect("a valid tree")
        .compute_spread(&mine, part, threads, &exchange);
    // a rank without bodies has nothing to compare
    let worst = if own.is_empty() {
        0.0
    } else {
        relative(got_acc.as_flattened(), acc[own.clone()].as_flattened())
            .max(relative(&got_phi, &phi[own]))
    };
    largest(world, worst)
}

/// The largest relative difference of the velocities between the
/// vortex-in-cell solver on the ranks of `world`, each holding every
/// particle, and in one process.
fn vic_error(world: &SimpleCommunicator, params: VicParams, threads: &Threads) -> f64 {
    let n = 3000;
    // a deterministic scatter of blobs in [-1, 1)^2
    let x: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let t = i as f64;
            [
                (t * 0.618_034).fract() * 2.0 - 1.0,
                (t * 0.414_214).fract() * 2.0 - 1.0,
            ]
        })
        .collect();
    let gamma: Vec<f64> = (0..n)
        .map(|i| ((i * 7919) % 101) as f64 / 101.0 - 0.4)
        .collect();
    let kernel = BlobKernel::new(0.05);
    let exchange = MpiExchange::new(world.duplicate());
    let mut want = vec![[0.0; 2]; n];
    VortexInCell::new(params, kernel)
        .expect("a valid VIC")
        .compute(&x, &gamma, &mut want, threads);
    let mut got = vec![[0.0; 2]; n];
    VortexInCell::on_rank(params, kernel, Rank::of(&exchange))
        .expect("a valid VIC")
        .compute_shared(&x, &gamma, &mut got, threads, &exchange);
    largest(world, relative(got.as_flattened(), want.as_flattened()))
}

/// A deterministic scatter of `n` 3D blobs in `[-1, 1)^3` with strengths.
fn blobs3(n: usize) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let x = (0..n)
        .map(|i| {
            let t = i as f64;
            [0.618_034, 0.414_214, 0.732_051].map(|f| (t * f).fract() * 2.0 - 1.0)
        })
        .collect();
    let alpha = (0..n)
        .map(|i| [7919, 104_729, 1_299_709].map(|p| ((i * p) % 101) as f64 / 101.0 - 0.45))
        .collect();
    (x, alpha)
}

/// The largest relative difference of the 3D velocities and gradients
/// between a solver on the ranks of `world`, each holding every particle
/// (`shared`), and in one process (`alone`).
fn field3_error(
    world: &SimpleCommunicator,
    n: usize,
    alone: impl FnOnce(&[[f64; 3]], &[[f64; 3]], &mut [[f64; 3]], &mut [[f64; 9]]),
    shared: impl FnOnce(&[[f64; 3]], &[[f64; 3]], &mut [[f64; 3]], &mut [[f64; 9]]),
) -> f64 {
    let (x, alpha) = blobs3(n);
    let (mut u, mut g) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
    alone(&x, &alpha, &mut u, &mut g);
    let (mut u2, mut g2) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
    shared(&x, &alpha, &mut u2, &mut g2);
    let worst = relative(u2.as_flattened(), u.as_flattened())
        .max(relative(g2.as_flattened(), g.as_flattened()));
    largest(world, worst)
}

/// [`field3_error`] of the 3D vortex-in-cell on a slab-decomposed mesh.
fn vic3_error(world: &SimpleCommunicator, params: Vic3Params, threads: &Threads) -> f64 {
    let sigma = 0.12;
    let exchange = MpiExchange::new(world.duplicate());
    field3_error(
        world,
        2000,
        |x, a, u, g| {
            VortexInCell3::new(params, sigma)
                .expect("a valid VIC")
                .compute(x, a, u, g, threads)
        },
        |x, a, u, g| {
            VortexInCell3::on_rank(params, sigma, Rank::of(&exchange))
                .expect("a valid VIC")
                .compute_shared(x, a, u, g, threads, &exchange)
        },
    )
}

/// [`field3_error`] of the 3D direct sum with its block pairs dealt out.
fn pairs3_error(world: &SimpleCommunicator, n: usize, threads: &Threads) -> f64 {
    let kernel = BlobKernel3::new(0.1);
    let exchange = MpiExchange::summing(world.duplicate());
    field3_error(
        world,
        n,
        |x, a, u, g| DirectBiotSavart3::new(kernel, n).compute(x, a, u, g, threads),
        |x, a, u, g| {
            DirectBiotSavart3::new(kernel, n).compute_shared(x, a, u, g, threads, &exchange)
        },
    )
}

/// The cases' outcomes: rank 0 prints one line per case.
struct Tally {
    passed: usize,
    failed: usize,
    prints: bool,
}

impl Tally {
    fn new(prints: bool) -> Self {
        Tally {
            passed: 0,
            failed: 0,
            prints,
        }
    }

    /// Counts a case and prints its line, marked `ok` or `FAIL`.
    fn add(&mut self, ok: bool, line: String) {
        if ok {
            self.passed += 1;
        } else {
            self.failed += 1;
        }
        if self.prints {
            println!("{} {line}", if ok { "ok  " } else { "FAIL" });
        }
    }

    /// Prints `N passed, N failed` (rank 0).
    fn report(&self) {
        if self.prints {
            println!("{} passed, {} failed", self.passed, self.failed);
        }
    }
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
    let mut tally = Tally::new(world.rank() == 0);
    for (name, law, n) in cases {
        let law = law.expect("a valid law");
        let worst = worst_error(&world, law, n, &threads);
        let ok = worst <= 1e-13;
        tally.add(
            ok,
            format!(
                "ring pass on {} ranks, {name}: largest relative difference {worst:.2e} (at most 1e-13)",
                world.size()
            ),
        );
    }
    let periodic = MeshParams {
        grid: 16,
        boundary: MeshBoundary::Periodic {
            origin: [-4.0; 3],
            length: 8.0,
        },
    };
    let isolated = MeshParams {
        grid: 16,
        boundary: MeshBoundary::Isolated,
    };
    let square = VicParams {
        grid: 32,
        boundary: VicBoundary::Periodic {
            origin: [-1.0; 2],
            length: 2.0,
        },
    };
    let unbounded = VicParams {
        grid: 32,
        boundary: VicBoundary::Unbounded,
    };
    let cube = Vic3Params {
        grid: 16,
        boundary: Vic3Boundary::Periodic {
            origin: [-1.0; 3],
            length: 2.0,
        },
    };
    let open = Vic3Params {
        grid: 16,
        boundary: Vic3Boundary::Unbounded,
    };
    let meshes = [
        (
            "PM, isolated",
            mesh_error(&world, isolated, false, &threads),
        ),
        (
            "PM, periodic",
            mesh_error(&world, periodic, false, &threads),
        ),
        (
            "P3M, isolated",
            mesh_error(&world, isolated, true, &threads),
        ),
        (
            "P3M, periodic",
            mesh_error(&world, periodic, true, &threads),
        ),
        (
            "vortex-in-cell, unbounded",
            vic_error(&world, unbounded, &threads),
        ),
        (
            "vortex-in-cell, periodic",
            vic_error(&world, square, &threads),
        ),
        (
            "3D vortex-in-cell, unbounded",
            vic3_error(&world, open, &threads),
        ),
        (
            "3D vortex-in-cell, periodic",
            vic3_error(&world, cube, &threads),
        ),
    ];
    for (name, worst) in meshes {
        // the accelerations have the same bits; an isolated mesh's potentials
        // differ by rounding (its own-cloud sum over the modes is split)
        let ok = worst <= 1e-13;
        tally.add(
            ok,
            format!(
                "slab-decomposed mesh on {} ranks, {name}: largest relative difference from one \
                 process {worst:.2e} (at most 1e-13)",
                world.size()
            ),
        );
    }
    for n in [3000, 3] {
        // the tree's lists and moments are one process's: the same bits
        let worst = tree_error(&world, n, &threads);
        let ok = worst == 0.0;
        tally.add(
            ok,
            format!(
                "Barnes-Hut gravity by locally essential trees on {} ranks, {n} bodies: \
                 largest relative difference from one process {worst:.2e} (must be 0)",
                world.size()
            ),
        );
    }
    for n in [1000, 3] {
        // each pair once on one rank, each particle's partials added in rank order
        let worst = pairs3_error(&world, n, &threads);
        let ok = worst <= 1e-13;
        tally.add(
            ok,
            format!(
                "3D vortex direct sum with its block pairs dealt out on {} ranks, {n} \
                 particles: largest relative difference from one process {worst:.2e} (at most \
                 1e-13)",
                world.size()
            ),
        );
    }
    tally.report();
    if tally.failed > 0 {
        std::process::exit(1);
    }
}
