//! Values of particles divided among processes (the ranks of a distributed
//! run, each holding a run of the input order), and what a picture's view and
//! colour scale need of them: sums in input order and an order statistic,
//! each the same bits as one process holding every particle computes.

/// The processes among which a set of particles is divided, each holding a
/// run of the input order, and the two collective steps over them. Every
/// process calls each method at the same point. [`Whole`] is one process
/// holding every particle.
pub trait Parts {
    /// Runs `add` on `value` once per process in input order, each process
    /// continuing from the value the process before it left, so that a sum
    /// is added up in input order; every process gets the final value.
    fn fold(&self, value: &mut [f64], add: &mut dyn FnMut(&mut [f64]));

    /// Sums `counts` element by element over the processes, on every process.
    fn add_up(&self, counts: &mut [u64]);
}

/// One process holding every particle.
#[derive(Clone, Copy, Debug, Default)]
pub struct Whole;

impl Parts for Whole {
    fn fold(&self, value: &mut [f64], add: &mut dyn FnMut(&mut [f64])) {
        add(value);
    }

    fn add_up(&self, _: &mut [u64]) {}
}

/// The values a process holds, handed one by one to the visitor.
pub type Values<'a> = dyn FnMut(&mut dyn FnMut(f64)) + 'a;

/// The `k`-th smallest (from 1) of every process's values in the order of
/// `f64::total_cmp`: the value at `k - 1` of them all sorted. A radix
/// selection on the order's 64-bit keys, a byte at a time from the top, each
/// byte's histogram added up over the processes: eight passes over the values,
/// no copy of them. `k` must be in `1..=` the number of values.
pub fn kth_smallest(k: u64, parts: &dyn Parts, values: &mut Values) -> f64 {
    assert!(k >= 1, "kth_smallest: k counts from 1");
    // the key's bits above the byte being found, in place
    let (mut known, mut k) = (0u64, k);
    let high = |key: u64, shift: u32| key.checked_shr(shift + 8).unwrap_or(0);
    for shift in (0..8).rev().map(|byte| 8 * byte) {
        let mut counts = [0u64; 256];
        values(&mut |v| {
            let key = order_key(v);
            if high(key, shift) == high(known, shift) {
                counts[((key >> shift) & 0xff) as usize] += 1;
            }
        });
        parts.add_up(&mut counts);
        let mut digit = 0;
        while k > counts[digit] {
            k -= counts[digit];
            digit += 1;
            assert!(
                digit < 256,
                "kth_smallest: k is larger than the number of values"
            );
        }
        known |= (digit as u64) << shift;
    }
    value_of_key(known)
}

/// A key whose unsigned order is `f64::total_cmp`'s.
fn order_key(v: f64) -> u64 {
    let bits = v.to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | 1 << 63
    }
}

/// The value of an [`order_key`].
fn value_of_key(key: u64) -> f64 {
    f64::from_bits(if key >> 63 == 1 {
        key & !(1 << 63)
    } else {
        !key
    })
}

/// Processes as threads for the tests: [`testkit::run`] hands each of
/// `ranks` threads its [`Parts`].
#[cfg(test)]
pub(crate) mod testkit {
    use super::Parts;
    use std::sync::{Barrier, Condvar, Mutex};

    /// What the threads share: the fold's turn and value, the counts' sums.
    struct Meeting {
        barrier: Barrier,
        fold: Mutex<(usize, Vec<f64>)>,
        turn: Condvar,
        counts: Mutex<Vec<u64>>,
    }

    /// One thread's view of the [`Meeting`].
    pub(crate) struct Rank<'a> {
        pub(crate) rank: usize,
        meeting: &'a Meeting,
    }

    impl Parts for Rank<'_> {
        fn fold(&self, value: &mut [f64], add: &mut dyn FnMut(&mut [f64])) {
            let m = self.meeting;
            let mut shared = m.fold.lock().unwrap();
            while shared.0 != self.rank {
                shared = m.turn.wait(shared).unwrap();
            }
            if self.rank > 0 {
                value.copy_from_slice(&shared.1);
            }
            add(value);
            shared.1 = value.to_vec();
            shared.0 += 1;
            m.turn.notify_all();
            drop(shared);
            m.barrier.wait();
            value.copy_from_slice(&m.fold.lock().unwrap().1);
            m.barrier.wait();
            if self.rank == 0 {
                m.fold.lock().unwrap().0 = 0;
                m.turn.notify_all();
            }
        }

        fn add_up(&self, counts: &mut [u64]) {
            let m = self.meeting;
            {
                let mut sums = m.counts.lock().unwrap();
                sums.resize(counts.len(), 0);
                sums.iter_mut()
                    .zip(counts.iter())
                    .for_each(|(s, c)| *s += c);
            }
            m.barrier.wait();
            counts.copy_from_slice(&m.counts.lock().unwrap());
            m.barrier.wait();
            if self.rank == 0 {
                m.counts.lock().unwrap().clear();
            }
            m.barrier.wait();
        }
    }

    /// `f(rank)` on `ranks` threads at once; their results in rank order.
    pub(crate) fn run<T: Send>(ranks: usize, f: impl Fn(&Rank) -> T + Sync) -> Vec<T> {
        let meeting = Meeting {
            barrier: Barrier::new(ranks),
            fold: Mutex::new((0, Vec::new())),
            turn: Condvar::new(),
            counts: Mutex::new(Vec::new()),
        };
        std::thread::scope(|scope| {
            let handles: Vec<_> = (0..ranks)
                .map(|rank| {
                    let (f, meeting) = (&f, &meeting);
                    scope.spawn(move || f(&Rank { rank, meeting }))
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kth_smallest_is_the_sorted_values_kth() {
        let mut values: Vec<f64> = vec![
            3.0,
            -1.0,
            0.0,
            -0.0,
            f64::INFINITY,
            2.5,
            2.5,
            1e-300,
            -1e300,
            f64::NAN,
            7.0,
            0.1,
        ];
        values.extend((0..500).map(|i| ((i * 7919) % 1000) as f64 / 37.0 - 5.0));
        let mut sorted = values.clone();
        sorted.sort_by(f64::total_cmp);
        for k in 1..=values.len() {
            let got = kth_smallest(k as u64, &Whole, &mut |visit| {
                values.iter().for_each(|&v| visit(v))
            });
            assert_eq!(got.to_bits(), sorted[k - 1].to_bits(), "k = {k}");
        }
        // the values cut into runs among 2 to 4 processes, the first empty
        let n = values.len();
        for ranks in 2..=4 {
            let cut = |r: usize| if r == 1 { 0 } else { n * r / ranks };
            for k in [1, 2, 7, n / 2, n] {
                let got = testkit::run(ranks, |me| {
                    let mine = &values[cut(me.rank)..cut(me.rank + 1)];
                    kth_smallest(k as u64, me, &mut |visit| {
                        mine.iter().for_each(|&v| visit(v))
                    })
                });
                for got in got {
                    assert_eq!(
                        got.to_bits(),
                        sorted[k - 1].to_bits(),
                        "{ranks} ranks, k = {k}"
                    );
                }
            }
        }
        for v in [0.0, -0.0, 1.5, -2.0, f64::MAX, f64::NEG_INFINITY] {
            assert_eq!(value_of_key(order_key(v)).to_bits(), v.to_bits());
        }
    }
}
