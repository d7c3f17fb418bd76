//! The fast collision step (grid candidates, components in parallel) against the
//! literal O(N^2) loops of SPEC.md section 4, bit for bit.

use cellist::models::billiards::{Billiards, BilliardsError, Table};
use cellist::Threads;
use proptest::prelude::*;

fn component() -> impl Strategy<Value = f64> {
    // exact zeros of both signs: their signs must come out as the literal loop's
    prop_oneof![3 => -1.5f64..1.5, 1 => Just(0.0), 1 => Just(-0.0)]
}

fn discs() -> impl Strategy<Value = (Table, Vec<[f64; 4]>)> {
    (2i64..60, 1i64..4, 0usize..80, any::<bool>()).prop_flat_map(|(side, radius, n, coarse)| {
        let l = side as f64;
        // the course's recipe: centres in [0, L), overlaps allowed; or on a coarse
        // lattice, where discs share coordinates (and separations are exact zeros)
        let coordinate = move || {
            (0.0..l).prop_map(move |c: f64| if coarse { (2.0 * c).floor() / 2.0 } else { c })
        };
        let disc = (coordinate(), coordinate(), component(), component())
            .prop_map(|(x, y, vx, vy)| [x, y, vx, vy]);
        (Just(Table { side, radius }), prop::collection::vec(disc, n))
    })
}

fn table_of(table: Table, discs: &[[f64; 4]]) -> Billiards {
    Billiards::new(
        table,
        discs.iter().map(|d| d[0]).collect(),
        discs.iter().map(|d| d[1]).collect(),
        discs.iter().map(|d| [d[2], d[3]]).collect(),
    )
    .expect("finite discs")
    // random states need not settle (the benchmark assumes its inputs do); both
    // ways must then stop at the same step
    .with_max_sweeps(2_000)
}

fn bits(b: &Billiards) -> Vec<u64> {
    b.x.iter()
        .chain(&b.y)
        .chain(b.v.iter().flatten())
        .map(|v| v.to_bits())
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn fast_steps_equal_the_literal_loops((table, discs) in discs(), steps in 1u64..6) {
        let mut brute = table_of(table, &discs);
        let mut one = brute.clone();
        let mut two = brute.clone();
        let (single, pair) = (Threads::single(), Threads::new(2).unwrap());
        for step in 1..=steps {
            let (expected, a, b) = match (brute.step_brute(step), one.step(step, &single), two.step(step, &pair)) {
                (Ok(e), Ok(a), Ok(b)) => (e, a, b),
                (Err(_), Err(a), Err(b)) => {
                    prop_assert_eq!(a, b);
                    break;
                }
                (e, a, b) => panic!("step {step}: brute {e:?}, 1 thread {a:?}, 2 threads {b:?}"),
            };
            prop_assert_eq!(a, b);
            prop_assert_eq!(a.sweeps, expected.sweeps);
            prop_assert_eq!(a.wall_discs, expected.wall_discs);
            prop_assert_eq!(a.pairs, expected.pairs);
            prop_assert_eq!(bits(&one), bits(&brute));
            prop_assert_eq!(bits(&two), bits(&brute));
        }
    }
}

#[test]
fn a_pair_found_from_its_second_disc_keeps_the_sign_of_zero() {
    // disc 0 is found from disc 1's square; dx = 0 must be +0.0, as x_1 - x_0
    let table = Table {
        side: 100,
        radius: 1,
    };
    let discs = [
        [50.0, 58.0, -0.0, -1.0],
        [50.0, 54.0, 0.0, 1.0],
        [50.0, 48.5, 0.0, 0.0],
    ];
    let mut brute = table_of(table, &discs);
    let mut fast = brute.clone();
    brute.step_brute(1).unwrap();
    fast.step(1, &Threads::single()).unwrap();
    assert_eq!(bits(&fast), bits(&brute));
}

#[test]
fn a_tight_cluster_needs_many_sweeps_and_still_matches() {
    // discs on a line, all overlapping their neighbours, squeezed together
    let n = 40;
    let discs: Vec<[f64; 4]> = (0..n)
        .map(|k| {
            let s = if k % 2 == 0 { 1.0 } else { -1.0 };
            [10.0 + 1.5 * k as f64, 30.0 + 0.1 * s, 0.3 * s, -0.2 * s]
        })
        .collect();
    let table = Table {
        side: 100,
        radius: 1,
    };
    let mut brute = table_of(table, &discs);
    let mut fast = brute.clone();
    for step in 1..=5 {
        let expected = brute.step_brute(step).unwrap();
        let got = fast.step(step, &Threads::new(2).unwrap()).unwrap();
        assert_eq!(got.sweeps, expected.sweeps);
        assert_eq!(bits(&fast), bits(&brute));
    }
}

#[test]
fn a_step_that_does_not_settle_names_the_step() {
    // two discs approaching head on need a second sweep to see that nothing is left
    let table = Table {
        side: 20,
        radius: 1,
    };
    let discs = [[5.0, 5.0, 0.5, 0.0], [7.5, 5.0, -0.5, 0.0]];
    let mut b = table_of(table, &discs).with_max_sweeps(1);
    let err = b.step(1, &Threads::single()).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("step 1: the collisions did not settle within 1 sweeps"),
        "{err}"
    );
}

#[test]
fn an_overflow_names_the_first_disc_to_leave_the_finite_numbers_on_any_thread_count() {
    // two discs overflow in the first move, one in each half of the discs
    let n = 10_000;
    let mut discs: Vec<[f64; 4]> = (0..n)
        .map(|k| [(k % 100) as f64 * 9.0, (k / 100) as f64 * 9.0, 0.5, -0.5])
        .collect();
    for k in [3_000, 9_000] {
        discs[k] = [f64::MAX, 5.0, f64::MAX, 0.0];
    }
    let table = Table {
        side: 1000,
        radius: 1,
    };
    let expected = BilliardsError::Overflow {
        step: 1,
        index: 3_000,
    };
    assert_eq!(table_of(table, &discs).step_brute(1), Err(expected.clone()));
    for threads in [1, 2, 3] {
        let pool = Threads::new(threads).unwrap();
        let result = table_of(table, &discs).step(1, &pool);
        assert_eq!(result, Err(expected.clone()), "{threads} thread(s)");
    }
}
