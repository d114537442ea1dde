//! Why `ecr_runtime::precision::DoubleDouble` is hand-written: the maintained double-double
//! crate `twofloat` against it, accuracy against 320-bit references and the cost of a
//! multiply–add. Prints the comparison; asserts only this crate's accuracy.
//!
//! `cargo test --release -p ecr-runtime --test it double_double_crates:: -- --ignored --nocapture`

use astro_float::{BigFloat, Consts, RoundingMode, Sign};
use ecr_runtime::precision::{DoubleDouble, Real};
use std::time::Instant;
use twofloat::TwoFloat;

const P: usize = 320;
const RM: RoundingMode = RoundingMode::ToEven;

fn big(x: f64) -> BigFloat {
    BigFloat::from_f64(x, P)
}
fn pair(h: f64, l: f64) -> BigFloat {
    big(h).add(&big(l), P, RM)
}
fn to_f64(x: &BigFloat) -> f64 {
    if x.is_zero() {
        return 0.0;
    }
    let (m, _, s, e, _) = x.as_raw_parts().unwrap();
    let v = *m.last().unwrap() as f64 / 18446744073709551616.0 * 2f64.powi(e);
    if s == Sign::Neg { -v } else { v }
}
fn rel(a: &BigFloat, b: &BigFloat) -> f64 {
    (to_f64(&a.sub(b, P, RM)) / to_f64(b)).abs()
}

#[test]
#[ignore = "a comparison for the record (docs: ecr_runtime::precision); run with --ignored"]
fn twofloat_against_the_hand_written_core() {
    let mut cc = Consts::new().unwrap();
    let mut state = 12345u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    // [twofloat, ours] for mul, div, sqrt, exp (of an f64), sin (absolute, of an f64).
    let mut worst = [[0.0f64; 2]; 5];
    for _ in 0..2000 {
        let (a, b) = (next() * 4.0 - 2.0, next() * 4.0 - 2.0);
        let (al, bl) = (a * 1e-17 * next(), b * 1e-17 * next());
        let (ta, tb) = (TwoFloat::new_add(a, al), TwoFloat::new_add(b, bl));
        let (oa, ob) = (
            DoubleDouble::from_parts(ta.hi(), ta.lo()),
            DoubleDouble::from_parts(tb.hi(), tb.lo()),
        );
        let (ba, bb) = (pair(ta.hi(), ta.lo()), pair(tb.hi(), tb.lo()));
        let t = |x: TwoFloat| pair(x.hi(), x.lo());
        let o = |x: DoubleDouble| pair(x.hi(), x.lo());
        let exact = ba.mul(&bb, P, RM);
        worst[0][0] = worst[0][0].max(rel(&t(ta * tb), &exact));
        worst[0][1] = worst[0][1].max(rel(&o(oa * ob), &exact));
        let exact = ba.div(&bb, P, RM);
        worst[1][0] = worst[1][0].max(rel(&t(ta / tb), &exact));
        worst[1][1] = worst[1][1].max(rel(&o(oa / ob), &exact));
        let exact = ba.abs().sqrt(P, RM);
        worst[2][0] = worst[2][0].max(rel(&t(ta.abs().sqrt()), &exact));
        worst[2][1] = worst[2][1].max(rel(&o(oa.abs().sqrt()), &exact));
        // exp and sin of the f64 a (the runtime's functions take an f64 argument).
        let exact = big(a).exp(P, RM, &mut cc);
        worst[3][0] = worst[3][0].max(rel(&t(TwoFloat::from(a).exp()), &exact));
        let (c, s) = <DoubleDouble as Real>::cos_sin(a);
        let exact_s = big(a).sin(P, RM, &mut cc);
        let exact_c = big(a).cos(P, RM, &mut cc);
        worst[4][0] =
            worst[4][0].max(to_f64(&t(TwoFloat::from(a).sin()).sub(&exact_s, P, RM)).abs());
        worst[4][1] = worst[4][1]
            .max(to_f64(&o(s).sub(&exact_s, P, RM)).abs())
            .max(to_f64(&o(c).sub(&exact_c, P, RM)).abs());
    }
    for (name, w) in ["mul (rel)", "div (rel)", "sqrt (rel)", "sin (abs)"]
        .iter()
        .zip([worst[0], worst[1], worst[2], worst[4]])
    {
        println!("{name:>10}: twofloat {:.1e}   ecr {:.1e}", w[0], w[1]);
    }
    // ecr's e^x is crate-internal (the φ-functions' phi::exp_dd), tested there: ≤ 2e−31.
    println!(
        " exp (rel): twofloat {:.1e}   ecr ≤ 2e-31 (its own test)",
        worst[3][0]
    );
    let eps2 = f64::EPSILON * f64::EPSILON;
    assert!(worst[0][1] < 4.0 * eps2 && worst[1][1] < 4.0 * eps2 && worst[2][1] < 4.0 * eps2);
    assert!(worst[4][1] < 1e-31);
    // Cost of a multiply–add chain (min of 3 rounds; printed, not asserted).
    let xs: Vec<(f64, f64)> = (0..1000).map(|i| (1.0 + i as f64 * 1e-3, 1e-20)).collect();
    let reps = 5000;
    let (mut best_t, mut best_o) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..3 {
        let start = Instant::now();
        let mut acc = TwoFloat::from(0.0);
        for _ in 0..reps {
            for &(h, l) in &xs {
                acc = acc * TwoFloat::from(0.999999) + TwoFloat::new_add(h, l);
            }
        }
        std::hint::black_box(acc);
        best_t = best_t.min(start.elapsed().as_secs_f64());
        let start = Instant::now();
        let mut acc = DoubleDouble::from(0.0);
        for _ in 0..reps {
            for &(h, l) in &xs {
                acc = acc * DoubleDouble::from(0.999999) + DoubleDouble::from_parts(h, l);
            }
        }
        std::hint::black_box(acc);
        best_o = best_o.min(start.elapsed().as_secs_f64());
    }
    let n = (reps * xs.len()) as f64;
    println!(
        "multiply-add: twofloat {:.1} ns, ecr {:.1} ns",
        best_t * 1e9 / n,
        best_o * 1e9 / n
    );
}
