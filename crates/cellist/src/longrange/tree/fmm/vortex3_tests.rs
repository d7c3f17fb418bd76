use super::*;
use crate::longrange::biot_savart3::velocity_and_gradient_at;
use crate::longrange::blobs3_testkit::{cloud, ring, rms_error, same_bits};

type Field = (Vec<[f64; 3]>, Vec<[f64; 9]>);

fn fmm_field(
    accuracy: FmmAccuracy,
    kernel: BlobKernel3,
    x: &[[f64; 3]],
    alpha: &[[f64; 3]],
    threads: &Threads,
) -> Field {
    let mut fmm = VortexFmm3::new(kernel, accuracy).unwrap();
    let (mut u, mut g) = (vec![[0.0; 3]; x.len()], vec![[0.0; 9]; x.len()]);
    fmm.compute(x, alpha, &mut u, &mut g, threads);
    assert!(fmm.interactions().0 > 0, "no M2L at {accuracy:?}");
    (u, g)
}

/// The FMM against the brute-force blob sums (the reference of
/// `biot_savart3`, its own code) on a random cloud and on a ring: the RMS
/// errors of the velocity and of the gradient stay below each tolerance.
#[test]
fn errors_stay_below_the_tolerance() {
    let one = Threads::single();
    let cases = [
        ("cloud", cloud(3, 3000), &[1e-3, 1e-4, 1e-6][..]),
        ("small cloud", cloud(4, 2000), &[1e-8, 1e-10][..]),
        ("ring", ring(0.1), &[1e-3, 1e-4, 1e-6][..]),
    ];
    for (name, (x, alpha, kernel), tolerances) in cases {
        let (u, g) = velocity_and_gradient_at(&kernel, &x, &x, &alpha, &one);
        for &tolerance in tolerances {
            let accuracy = FmmAccuracy::Tolerance(tolerance);
            let (fu, fg) = fmm_field(accuracy, kernel, &x, &alpha, &one);
            let (eu, eg) = (rms_error(&fu, &u), rms_error(&fg, &g));
            assert!(
                eu < tolerance && eg < tolerance,
                "{name} ({} blobs) at {tolerance:e}: velocity {eu:e}, gradient {eg:e}",
                x.len()
            );
        }
    }
}

/// With every pair in the blob rest's reach (a cutoff beyond the cloud) and a
/// high order, the split of the law into the point law and the rest gives
/// the blob law to round-off.
#[test]
fn the_split_law_is_the_blob_law() {
    let one = Threads::single();
    let (x, alpha, kernel) = cloud(5, 600);
    let (u, g) = velocity_and_gradient_at(&kernel, &x, &x, &alpha, &one);
    let mut fmm = VortexFmm3::new(kernel, FmmAccuracy::Order(30)).unwrap();
    fmm.rest = BlobRest::new(kernel, 1e-300);
    assert!(fmm.cutoff() > 2.0, "{}", fmm.cutoff());
    let (mut fu, mut fg) = (vec![[0.0; 3]; x.len()], vec![[0.0; 9]; x.len()]);
    fmm.compute(&x, &alpha, &mut fu, &mut fg, &one);
    let (eu, eg) = (rms_error(&fu, &u), rms_error(&fg, &g));
    assert!(eu < 1e-12 && eg < 1e-12, "velocity {eu:e}, gradient {eg:e}");
}

/// The locals of the derivatives give the derivatives of the local: at a
/// point, `d_b Phi` from [`derivative_locals`] equals the gradient that
/// `solid::l2p` takes from the local itself.
#[test]
fn derivative_locals_differentiate() {
    let p = 9;
    let terms = solid::terms(p);
    // a real field's local: m = 0 terms real
    let mut local: Vec<Complex64> = (0..terms)
        .map(|k| {
            let v = ((k * 37 % 11) as f64 - 5.0) / 7.0;
            Complex64::new(v, v * 0.3 - 0.1)
        })
        .collect();
    for n in 0..=p {
        local[at(n, 0)].im = 0.0;
    }
    let (centre, scale) = ([0.1, -0.2, 0.3], 0.7);
    let below = solid::terms(p - 1);
    let mut derived = vec![Complex64::new(0.0, 0.0); 3 * below];
    derivative_locals(p, &local, 1.0 / scale, &mut derived);
    let mut h = vec![Complex64::new(0.0, 0.0); terms];
    for x in [[0.3, 0.1, 0.2], [-0.2, 0.25, 0.5], [0.0, 0.0, 0.3]] {
        let want = solid::l2p(p, &local, centre, scale, x, &mut h);
        for b in 0..3 {
            let d = &derived[b * below..(b + 1) * below];
            let got = solid::l2p(p - 1, d, centre, scale, x, &mut h)[3];
            assert!(
                (got - want[b]).abs() < 1e-12 * want[b].abs().max(1.0),
                "d_{b} at {x:?}: {got} against {}",
                want[b]
            );
        }
    }
}

/// More particles than a target group holds: groups in parallel, the leaf
/// pairs of two groups summed once, by the earlier.
#[test]
fn threads_give_the_same_bits() {
    let (x, alpha, kernel) = cloud(9, 3 * GROUP);
    let run =
        |threads: &Threads| fmm_field(FmmAccuracy::Tolerance(1e-6), kernel, &x, &alpha, threads);
    let (u1, g1) = run(&Threads::single());
    let (u2, g2) = run(&Threads::new(2).unwrap());
    assert!(same_bits(&u1, &u2) && same_bits(&g1, &g2));
}

#[test]
fn a_tolerance_out_of_range_is_refused() {
    let kernel = BlobKernel3::new(0.1);
    for t in [0.0, 1e-16, 0.5, f64::NAN] {
        let e = VortexFmm3::new(kernel, FmmAccuracy::Tolerance(t)).unwrap_err();
        assert!(e.contains("tolerance"), "{e}");
    }
}

/// No particle, one, and two at one position (plus one apart): the blob
/// sums' values, finite.
#[test]
fn edge_cases() {
    let one = Threads::single();
    let kernel = BlobKernel3::new(0.1);
    let accuracy = FmmAccuracy::Tolerance(1e-8);
    let mut fmm = VortexFmm3::new(kernel, accuracy).unwrap();
    fmm.compute(&[], &[], &mut [], &mut [], &one);
    type Blobs = (Vec<[f64; 3]>, Vec<[f64; 3]>);
    let cases: [Blobs; 2] = [
        (vec![[0.3, 0.1, -0.2]], vec![[1.0, 2.0, 3.0]]),
        (
            vec![[0.0; 3], [0.0; 3], [0.05, 0.0, 0.0]],
            vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        ),
    ];
    for (x, alpha) in cases {
        let (u, g) = velocity_and_gradient_at(&kernel, &x, &x, &alpha, &one);
        let (mut fu, mut fg) = (vec![[0.0; 3]; x.len()], vec![[0.0; 9]; x.len()]);
        fmm.compute(&x, &alpha, &mut fu, &mut fg, &one);
        for (got, want) in fu.iter().flatten().zip(u.iter().flatten()) {
            assert!(
                (got - want).abs() <= 1e-12 * want.abs().max(1.0),
                "{fu:?} {u:?}"
            );
        }
        for (got, want) in fg.iter().flatten().zip(g.iter().flatten()) {
            assert!(
                (got - want).abs() <= 1e-12 * want.abs().max(1.0),
                "{fg:?} {g:?}"
            );
        }
    }
}
