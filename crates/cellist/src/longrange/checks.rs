//! The checks of every solver's input, for the particles of one process or
//! divided among the ranks of a distributed run (each rank holding a run of
//! the input order), with the same message either way.

use super::{Exchange, Sources};
use crate::interactions::GravityLaw;
use crate::longrange::Alone;

/// Checks shared by every solver's input: equal lengths, positive finite masses,
/// finite positions, and no two particles at one point when the law is unsoftened.
pub fn check_sources(law: &GravityLaw, sources: &Sources) -> Result<(), String> {
    check_sources_among(law, sources, 0, &Alone)
}

/// [`check_sources`] of particles divided among the ranks of `peers`
/// (collective), this rank holding `sources`, the particles `first..` of the
/// input order: each check looks at every rank's part, and every rank gets
/// the message of the first particle that fails it, the same as one process
/// holding them all would.
pub fn check_sources_among(
    law: &GravityLaw,
    sources: &Sources,
    first: usize,
    peers: &dyn Exchange,
) -> Result<(), String> {
    let (masses, positions) = (sources.mass.len(), sources.position.len());
    let lengths = (masses != positions).then_some((first, [masses as f64, positions as f64, 0.0]));
    if let Some((_, [m, x, _])) = first_failure(lengths, peers) {
        return Err(format!("{m} masses for {x} positions"));
    }
    let mass = sources
        .mass
        .iter()
        .position(|m| !(m.is_finite() && *m > 0.0));
    let mass = mass.map(|i| (first + i, [sources.mass[i], 0.0, 0.0]));
    if let Some((i, [m, ..])) = first_failure(mass, peers) {
        return Err(format!(
            "particle {i}: mass must be finite and > 0, got {m}"
        ));
    }
    let position = sources
        .position
        .iter()
        .position(|x| x.iter().any(|c| !c.is_finite()));
    let position = position.map(|i| (first + i, sources.position[i]));
    if let Some((i, x)) = first_failure(position, peers) {
        return Err(format!("particle {i}: position {x:?} is not finite"));
    }
    if law.softening() == 0.0 {
        if let Some((i, j, x)) = first_shared_point(sources.position, first, peers) {
            return Err(format!(
                "particles {i} and {j} are at the same point {x:?} and the softening is 0"
            ));
        }
    }
    Ok(())
}

/// The failure of the smallest index among every rank's `mine` (an index in
/// the input order and three numbers for the message), on every rank
/// (collective).
pub fn first_failure(
    mine: Option<(usize, [f64; 3])>,
    peers: &dyn Exchange,
) -> Option<(usize, [f64; 3])> {
    let ranks = peers.ranks();
    if ranks == 1 {
        return mine;
    }
    let row = mine.map_or([f64::INFINITY, 0.0, 0.0, 0.0], |(i, v)| {
        [i as f64, v[0], v[1], v[2]]
    });
    let mut all = vec![0.0; 4 * ranks];
    peers.all_gather(&row, &vec![4; ranks], &mut all);
    all.chunks_exact(4)
        .filter(|r| r[0].is_finite())
        .min_by(|a, b| a[0].total_cmp(&b[0]))
        .map(|r| (r[0] as usize, [r[1], r[2], r[3]]))
}

/// The point that two particles share (the same coordinates, `-0` taken as
/// `0`) with the smallest [`point_key`] among all ranks' particles, the two
/// smallest indices of the particles there and the first one's position;
/// collective. Each rank sends each of its points to the rank its key hashes
/// to, which finds the repeated keys among those it receives.
fn first_shared_point(
    positions: &[[f64; 3]],
    first: usize,
    peers: &dyn Exchange,
) -> Option<(usize, usize, [f64; 3])> {
    let ranks = peers.ranks();
    if ranks == 1 {
        return first_repeat(positions.len(), |k| (first + k, positions[k]));
    }
    let received = scatter_by_key(positions, first, peers);
    let found = first_repeat(received.len() / 4, |k| {
        let r = &received[4 * k..4 * k + 4];
        (r[3] as usize, [r[0], r[1], r[2]])
    });
    let row = found.map_or([0.0; 6], |(i, j, x)| {
        [1.0, x[0], x[1], x[2], i as f64, j as f64]
    });
    let mut all = vec![0.0; 6 * ranks];
    peers.all_gather(&row, &vec![6; ranks], &mut all);
    all.chunks_exact(6)
        .filter(|r| r[0] == 1.0)
        .map(|r| (r[4] as usize, r[5] as usize, [r[1], r[2], r[3]]))
        .min_by_key(|(.., x)| point_key(x))
}

/// The key of a point: its coordinates' bits, `-0` taken as `0`.
fn point_key(x: &[f64; 3]) -> [u64; 3] {
    x.map(|c| (c + 0.0).to_bits())
}

/// Among `n` particles, the `k`-th an index and a position `point(k)`, the
/// repeated point with the smallest [`point_key`]: the two smallest indices
/// there and the first one's position. Sorts the `n` numbers `k` (8 bytes a
/// particle), each key computed when compared.
fn first_repeat(
    n: usize,
    point: impl Fn(usize) -> (usize, [f64; 3]),
) -> Option<(usize, usize, [f64; 3])> {
    let key = |k: usize| {
        let (index, x) = point(k);
        (point_key(&x), index)
    };
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_unstable_by_key(|&k| key(k));
    order
        .windows(2)
        .find(|w| key(w[0]).0 == key(w[1]).0)
        .map(|w| {
            let ((i, x), (j, _)) = (point(w[0]), point(w[1]));
            (i, j, x)
        })
}

/// Every rank's points sent to the rank their key hashes to: the rows
/// `x y z index` this rank receives (collective).
fn scatter_by_key(positions: &[[f64; 3]], first: usize, peers: &dyn Exchange) -> Vec<f64> {
    let ranks = peers.ranks();
    let owner = |x: &[f64; 3]| {
        let [a, b, c] = point_key(x);
        let mixed = (a ^ b.rotate_left(21) ^ c.rotate_left(42)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        ((mixed >> 32) % ranks as u64) as usize
    };
    let mut counts = vec![0usize; ranks];
    for x in positions {
        counts[owner(x)] += 1;
    }
    let mut at: Vec<usize> = counts
        .iter()
        .scan(0, |sum, &c| {
            *sum += c;
            Some(*sum - c)
        })
        .collect();
    let mut send = vec![0.0; 4 * positions.len()];
    for (i, x) in positions.iter().enumerate() {
        let slot = &mut at[owner(x)];
        send[4 * *slot..4 * *slot + 4].copy_from_slice(&[x[0], x[1], x[2], (first + i) as f64]);
        *slot += 1;
    }
    let mut incoming = vec![0.0; ranks];
    let sent: Vec<f64> = counts.iter().map(|&c| c as f64).collect();
    peers.all_to_all(&sent, &vec![1; ranks], &mut incoming, &vec![1; ranks]);
    let incoming: Vec<usize> = incoming.iter().map(|&c| 4 * c as usize).collect();
    let mut received = vec![0.0; incoming.iter().sum()];
    let send_counts: Vec<usize> = counts.iter().map(|c| 4 * c).collect();
    peers.all_to_all(&send, &send_counts, &mut received, &incoming);
    received
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::mesh::slab::testkit::Hub;
    use crate::random::Rng;

    /// `check_sources_among` with the particles cut into `ranks` runs.
    fn among(
        law: &GravityLaw,
        mass: &[f64],
        position: &[[f64; 3]],
        ranks: usize,
    ) -> Vec<Result<(), String>> {
        let n = mass.len();
        Hub::run(ranks, |peers| {
            let part = n * peers.rank() / ranks..n * (peers.rank() + 1) / ranks;
            let sources = Sources {
                mass: &mass[part.clone()],
                position: &position[part.clone()],
            };
            check_sources_among(law, &sources, part.start, peers)
        })
    }

    #[test]
    fn every_rank_tells_the_first_failure_of_one_process() {
        let mut rng = Rng::new(3);
        let n = 600;
        let mut mass: Vec<f64> = (0..n).map(|_| 0.5 + rng.uniform()).collect();
        let mut position: Vec<[f64; 3]> = (0..n)
            .map(|_| std::array::from_fn(|_| rng.uniform() - 0.5))
            .collect();
        let plain = GravityLaw::new(1.0, 0.0, 0.0).unwrap();
        let soft = GravityLaw::new(1.0, 0.1, 0.0).unwrap();
        let mut cases = Vec::new();
        let sources = |m: &[f64], x: &[[f64; 3]]| (m.to_vec(), x.to_vec());
        cases.push(sources(&mass, &position));
        // two shared points, each three times, one of them spread over the ranks
        position[550] = position[20];
        position[590] = position[20];
        position[100] = [0.0, -0.0, 0.25];
        position[70] = [-0.0, 0.0, 0.25];
        position[450] = [0.0, 0.0, 0.25];
        cases.push(sources(&mass, &position));
        position[500][1] = f64::NAN;
        cases.push(sources(&mass, &position));
        mass[580] = 0.0;
        cases.push(sources(&mass, &position));
        let mut messages = Vec::new();
        for (m, x) in &cases {
            for law in [&plain, &soft] {
                let whole = check_sources(
                    law,
                    &Sources {
                        mass: m,
                        position: x,
                    },
                );
                for ranks in 2..=4 {
                    for got in among(law, m, x, ranks) {
                        assert_eq!(got, whole, "{ranks} ranks");
                    }
                }
                messages.push(whole);
            }
        }
        assert_eq!(messages[0..2], [Ok(()), Ok(())]);
        // the smaller key (x = 0 has the smallest bits), its two smallest
        // indices and the first one's position
        assert_eq!(
            messages[2],
            Err(
                "particles 70 and 100 are at the same point [-0.0, 0.0, 0.25] and the \
                 softening is 0"
                    .into()
            )
        );
        assert_eq!(messages[3], Ok(()));
        assert!(messages[4]
            .as_ref()
            .unwrap_err()
            .starts_with("particle 500: position"));
        assert_eq!(messages[5], messages[4]);
        assert_eq!(
            messages[6].as_ref().unwrap_err(),
            "particle 580: mass must be finite and > 0, got 0"
        );
    }
}
