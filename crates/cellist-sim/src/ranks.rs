//! How a run's model is held across MPI ranks, and what the driver does about
//! it: the policy of a [`Job`](crate::driver::Job), not of the model. In one
//! process every rank question has the trivial answer; with the `mpi` feature a
//! distributed run says who writes, how failures are agreed and when the
//! spread state must be gathered.

#[cfg(feature = "mpi")]
use crate::distributed::mesh::MpiExchange;
#[cfg(feature = "mpi")]
use crate::distributed::parts::Figures;
#[cfg(feature = "mpi")]
use crate::distributed::{agree, all_reduce, fold_in_rank_order};
use crate::hosted::{Distribution, Hosted};
use cellist::longrange::{Alone, Exchange, Peers};
use cellist_io::Parts;
#[cfg(feature = "mpi")]
use mpi::collective::SystemOperation;
#[cfg(feature = "mpi")]
use mpi::topology::SimpleCommunicator;
#[cfg(feature = "mpi")]
use mpi::traits::{Communicator, CommunicatorCollectives};

/// Where a job's model lives.
#[derive(Default)]
pub enum Ranks {
    /// In this process alone.
    #[default]
    One,
    /// Spread over the ranks of `world` (md and pse by domain decomposition,
    /// gravity's direct sum and meshes by blocks of bodies): each rank steps its own
    /// particles, and rank 0 pulls the state whenever an observer or a
    /// checkpoint is due.
    #[cfg(feature = "mpi")]
    Spread(SimpleCommunicator),
    /// Held whole on every rank of `world`, which advance it alike and divide
    /// its field sums (the vortex model's direct solver by block pairs dealt
    /// out, its trees by parts, its fmm by runs of target groups, its meshes
    /// by slabs);
    /// `figures` are what the solver measures.
    #[cfg(feature = "mpi")]
    Replicated {
        /// The ranks.
        world: SimpleCommunicator,
        /// The solver's waiting time and the balance of its parts.
        figures: Figures,
    },
}

impl Ranks {
    /// The peers among which a model held whole on every rank divides the
    /// sums it makes itself (the vortex model's PSE rates, thermo pair sums
    /// and fmm), their waiting counted in the solver's figures; this process
    /// alone for any other run.
    pub fn peers(&self) -> Peers {
        match self {
            #[cfg(feature = "mpi")]
            Ranks::Replicated { world, figures } => Peers::new(Box::new(MpiExchange::counted_in(
                world.duplicate(),
                figures.clone(),
            ))),
            _ => Peers::default(),
        }
    }

    /// The number of ranks.
    pub fn count(&self) -> i32 {
        match self {
            Ranks::One => 1,
            #[cfg(feature = "mpi")]
            Ranks::Spread(world) | Ranks::Replicated { world, .. } => world.size(),
        }
    }

    /// False on the ranks other than 0 of a distributed run: they write no
    /// output (rank 0 writes the gathered state).
    pub fn writes_output(&self) -> bool {
        match self {
            Ranks::One => true,
            #[cfg(feature = "mpi")]
            Ranks::Spread(world) | Ranks::Replicated { world, .. } => world.rank() == 0,
        }
    }

    /// The outcome of a stage of the run made one for every rank: the failure
    /// of the lowest rank that failed, or `None`. In one process, `failure`
    /// itself.
    pub fn agree(&self, failure: Option<String>) -> Option<String> {
        match self {
            Ranks::One => failure,
            #[cfg(feature = "mpi")]
            Ranks::Spread(world) | Ranks::Replicated { world, .. } => agree(world, failure),
        }
    }

    /// True when the state is spread over the ranks and gathered for output:
    /// every step where an observer fires or a checkpoint is written is then
    /// an observed step, not only those that need thermo values or energies.
    pub fn observe_when_due(&self) -> bool {
        match self {
            Ranks::One => false,
            #[cfg(feature = "mpi")]
            Ranks::Spread(_) => true,
            #[cfg(feature = "mpi")]
            Ranks::Replicated { .. } => false,
        }
    }

    /// `(observe, due)` for a step, as rank 0's observers decide them (its
    /// state observed; an observer due, whose step every rank keeps as the
    /// last good state), made one for every rank of a replicated run: its
    /// other ranks have no observers, its model observes collectively (the
    /// vortex model's thermo pair sums are shared), and a blow-up restores
    /// the last good state on every rank collectively (its rates are shared).
    /// Elsewhere the flags themselves.
    pub fn agree_on_step(&self, observe: bool, due: bool) -> (bool, bool) {
        match self {
            #[cfg(feature = "mpi")]
            Ranks::Replicated { world, .. } => {
                let flag = |b: bool| f64::from(u8::from(b));
                let [o, d] = all_reduce(world, [flag(observe), flag(due)], SystemOperation::max());
                (o > 0.0, d > 0.0)
            }
            _ => (observe, due),
        }
    }

    /// The speed line `line` of the model completed with what the ranks
    /// cost: a replicated run's divided sums (their waiting time over the
    /// loop's `loop_seconds`).
    pub fn speed(&self, line: String, loop_seconds: f64) -> String {
        match self {
            #[cfg(feature = "mpi")]
            Ranks::Replicated { world, figures } => {
                let waited = figures.waited();
                format!(
                    "{line} (per rank)\n{} on {} ranks: {:.4} s on rank 0 {} ({:.1}% of the loop)",
                    figures.method,
                    world.size(),
                    waited.as_secs_f64(),
                    figures.waiting,
                    100.0 * waited.as_secs_f64() / loop_seconds.max(1e-300)
                )
            }
            _ => {
                let _ = loop_seconds;
                line
            }
        }
    }

    /// What the ranks measure of a distributed run of `model` on this rank:
    /// a spread model's own figures, or a replicated solver's waiting time and
    /// the balance of its parts; `None` in one process (the model has none).
    pub fn distribution<M: Hosted>(&self, model: &M) -> Option<Distribution> {
        match self {
            Ranks::One => model.distribution(),
            #[cfg(feature = "mpi")]
            Ranks::Spread(_) => model.distribution(),
            #[cfg(feature = "mpi")]
            Ranks::Replicated { figures, .. } => Some(Distribution {
                communication: figures.waited(),
                imbalance_particles: figures.imbalance(),
                particles: model.len(),
            }),
        }
    }

    /// Element by element, the largest of every rank's `values`, on every rank
    /// (collective); in one process, `values`.
    pub fn largest<const N: usize>(&self, values: [f64; N]) -> [f64; N] {
        match self {
            Ranks::One => values,
            #[cfg(feature = "mpi")]
            Ranks::Spread(world) | Ranks::Replicated { world, .. } => {
                all_reduce(world, values, SystemOperation::max())
            }
        }
    }

    /// Element by element, the sum of every rank's `values`, on every rank
    /// (collective); in one process, `values`.
    pub fn sum<const N: usize>(&self, values: [f64; N]) -> [f64; N] {
        match self {
            Ranks::One => values,
            #[cfg(feature = "mpi")]
            Ranks::Spread(world) | Ranks::Replicated { world, .. } => {
                all_reduce(world, values, SystemOperation::sum())
            }
        }
    }
}

impl Ranks {
    /// Whether the particles are divided among several ranks, each holding
    /// its block ([`Ranks::block_of`]).
    pub fn is_spread(&self) -> bool {
        #[cfg(feature = "mpi")]
        if let Ranks::Spread(_) = self {
            return true;
        }
        false
    }

    /// The run of the input order this process holds of `n` particles
    /// divided into blocks (rank `r` of `P` holding `n r / P .. n (r + 1) / P`):
    /// all of them in one process or on a replicated run's every rank.
    pub fn block_of(&self, n: usize) -> std::ops::Range<usize> {
        #[cfg(feature = "mpi")]
        if let Ranks::Spread(world) = self {
            return crate::distributed::ring::blocks(n, world).1;
        }
        0..n
    }

    /// The engine's collective exchanges among the ranks (collective: the
    /// ranks' communicator is duplicated).
    pub fn exchange(&self) -> Box<dyn Exchange> {
        match self {
            Ranks::One => Box::new(Alone),
            #[cfg(feature = "mpi")]
            Ranks::Spread(world) | Ranks::Replicated { world, .. } => {
                Box::new(MpiExchange::new(world.duplicate()))
            }
        }
    }
}

/// Each rank holding its run of the input order ([`Ranks::block_of`]): a
/// spread run's ranks their blocks, one process or a replicated run's every
/// rank all particles (a part of its own, as [`cellist_io::Whole`]).
impl Parts for Ranks {
    fn fold(&self, value: &mut [f64], add: &mut dyn FnMut(&mut [f64])) {
        #[cfg(feature = "mpi")]
        if let Ranks::Spread(world) = self {
            return fold_in_rank_order(world, value, add);
        }
        add(value)
    }

    fn add_up(&self, counts: &mut [u64]) {
        #[cfg(feature = "mpi")]
        if let Ranks::Spread(world) = self {
            let mine = counts.to_vec();
            world.all_reduce_into(&mine[..], counts, SystemOperation::sum());
        }
        let _ = counts;
    }
}
