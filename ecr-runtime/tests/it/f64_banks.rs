//! The f64 banks of a dense operator (`BankArithmetic::F64`) against the default banks (the
//! double-double exponential at every node of a kernel bank up to d = 64, the double-double
//! propagator at τ = 1): every entry of every matrix, over a family of normal and non-normal
//! matrices with ‖hA‖ from 0.1 to 1e4 and eigenvalues down to −1e8. The normal route must stay
//! within its stated bound ([`Dense::f64_bank_bound`]); the general route (scaling and
//! squaring in f64) within `GENERAL_MAX` of the largest entry. The banks of `solve`'s runs
//! (`BankArithmetic::StepExtended`) are the default bank at τ = 1 bit for bit and f64 banks at
//! the other nodes.
//!
//! `cargo test -p ecr-runtime --test it f64_banks -- --nocapture` prints every case.

use ecr_runtime::nalgebra::DMatrix;
use ecr_runtime::operator::{BankArithmetic, Dense, LinearOperator, PhiBank};

/// A small deterministic generator (xorshift64*), uniform in (−1, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let u = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11;
        2.0 * (u as f64 / (1u64 << 53) as f64) - 1.0
    }
    fn matrix(&mut self, d: usize) -> DMatrix<f64> {
        DMatrix::from_fn(d, d, |_, _| self.next())
    }
    /// A random orthogonal matrix (QR of a random matrix).
    fn orthogonal(&mut self, d: usize) -> DMatrix<f64> {
        self.matrix(d).qr().q()
    }
}

/// Q B Qᵀ with B block diagonal: 2 × 2 blocks [[a, b], [−b, a]] and 1 × 1 blocks a.
fn normal(
    rng: &mut Rng,
    d: usize,
    re: impl Fn(usize) -> f64,
    im: impl Fn(usize) -> f64,
) -> DMatrix<f64> {
    let mut b = DMatrix::zeros(d, d);
    let mut i = 0;
    while i < d {
        if i + 1 < d {
            b[(i, i)] = re(i);
            b[(i + 1, i + 1)] = re(i);
            b[(i, i + 1)] = im(i);
            b[(i + 1, i)] = -im(i);
            i += 2;
        } else {
            b[(i, i)] = re(i);
            i += 1;
        }
    }
    let q = rng.orthogonal(d);
    &q * b * q.transpose()
}

/// The nodes of the banks compared: c = 0, the three Gauss points of r = 3 and 1 (a step's), and
/// a predictor's node beyond the step (1.5; the `StepExtended` banks only).
const TAUS: [f64; 6] = [
    0.0,
    0.112_701_665_379_258_3,
    0.5,
    0.887_298_334_620_741_7,
    1.0,
    1.5,
];

/// The worst entry error of the f64 bank against the default one, relative to the largest
/// entry of each matrix.
fn worst(a: &DMatrix<f64>, h: f64) -> f64 {
    let op = Dense::new(a.clone()).unwrap();
    let taus = &TAUS[..5];
    let n = 4;
    let fast = op.kernel_bank_in(h, taus, n, BankArithmetic::F64).unwrap();
    let exact = op.kernel_bank(h, taus, n).unwrap();
    assert_eq!(fast.len(), exact.len());
    let mut worst = 0.0f64;
    for i in 0..taus.len() {
        for k in 0..=n {
            let (f, e) = (fast.matrix(i, k), exact.matrix(i, k));
            let scale = e.amax().max(f64::MIN_POSITIVE);
            worst = worst.max((f - e).amax() / scale);
        }
    }
    worst
}

/// `expect_normal`: the matrix is normal after balancing (whichever route its bank at h takes).
fn case(name: &str, a: DMatrix<f64>, h: f64, expect_normal: bool) {
    let op = Dense::new(a.clone()).unwrap();
    let is_normal = op.is_normal_after_balancing();
    let err = worst(&a, h);
    let bound = op.f64_bank_bound(h);
    println!(
        "{name:<44} d = {:>2}  ‖hA‖₁ = {:.1e}  route {:<28}  error {err:.2e}  bound {}",
        a.nrows(),
        h * a.column_iter().map(|c| c.abs().sum()).fold(0.0, f64::max),
        match (bound, is_normal) {
            (None, _) => "default",
            (Some(_), true) => "f64, normal after balancing",
            (Some(_), false) => "f64, not normal",
        },
        bound.map_or("—".into(), |b| format!("{b:.1e}")),
    );
    assert_eq!(is_normal, expect_normal, "{name}: route");
    match bound {
        Some(b) => assert!(
            err <= b,
            "{name}: error {err:e} above the stated bound {b:e}"
        ),
        None => assert_eq!(err, 0.0, "{name}: no f64 route, yet not the default bank"),
    }
    step_extended(name, &op, h);
}

/// The banks of `solve`'s runs (`BankArithmetic::StepExtended`): at τ = 1 every matrix and the
/// double-double propagator bit for bit the default bank's; at the other nodes within the f64
/// route's bound of the nodes other than τ = 1 (or the default bank's where no route serves).
fn step_extended(name: &str, op: &Dense, h: f64) {
    let taus = TAUS;
    let n = 4;
    let mixed = op
        .kernel_bank_in(h, &taus, n, BankArithmetic::StepExtended)
        .unwrap();
    let exact = op.kernel_bank(h, &taus, n).unwrap();
    let end = 4;
    for k in 0..=n {
        assert_eq!(
            mixed.matrix(end, k),
            exact.matrix(end, k),
            "{name}: StepExtended at τ = 1, function {k}"
        );
    }
    let d = op.dim();
    let y0: Vec<f64> = (0..d).map(|i| (0.7 * i as f64 + 0.3).sin()).collect();
    let (mut h1, mut l1, mut h2, mut l2) = (vec![0.0; d], vec![0.0; d], vec![0.0; d], vec![0.0; d]);
    let carried = mixed.propagate_dd(end, &y0, &mut h1, &mut l1, &mut ());
    assert_eq!(
        carried,
        exact.propagate_dd(end, &y0, &mut h2, &mut l2, &mut ())
    );
    assert_eq!((h1, l1), (h2, l2), "{name}: the double-double propagator");
    // The other nodes: the route of the largest of them.
    let bound = op.f64_bank_bound(1.5 * h);
    for i in (0..taus.len()).filter(|&i| i != end) {
        for k in 0..=n {
            let (f, e) = (mixed.matrix(i, k), exact.matrix(i, k));
            let scale = e.amax().max(f64::MIN_POSITIVE);
            let err = (f - e).amax() / scale;
            match bound {
                Some(b) => assert!(err <= b, "{name}: τ = {}: {err:e} above {b:e}", taus[i]),
                // The default route with the stage propagators in f64 (scaling and squaring).
                None => assert!(
                    err <= GENERAL_STAGE_MAX,
                    "{name}: τ = {}: {err:e} without a route",
                    taus[i]
                ),
            }
        }
    }
}

/// Where no f64 route serves (‖hA‖ of 1e4 and more), `StepExtended` takes the stage
/// propagators from f64 scaling and squaring on the unbalanced matrix, which the default bank
/// takes from the double-double exponential (d ≤ 64): their difference relative to the largest
/// entry (measured up to 1.2e−12 on this family: periodic advection, d = 64, ‖hA‖₁ = 1e4).
const GENERAL_STAGE_MAX: f64 = 1e-11;

/// The central first difference on a periodic grid of d points (skew: advection).
fn advection(d: usize) -> DMatrix<f64> {
    let mut a = DMatrix::zeros(d, d);
    for i in 0..d {
        a[(i, (i + 1) % d)] = 0.5;
        a[((i + 1) % d, i)] = -0.5;
    }
    a
}

#[test]
fn normal_matrices_take_the_normal_route_within_its_bound() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for scale in [0.1, 10.0, 1e4] {
        let s = rng.matrix(7);
        // Negative semidefinite: e^{hA} stays in range at every scale.
        let sym = -(s.transpose() * &s) * (scale / 7.0);
        case(&format!("symmetric 7 x 7, scale {scale:e}"), sym, 1.0, true);
        let skew = (&s - s.transpose()) * (0.5 * scale / 7.0);
        case(&format!("skew 7 x 7, scale {scale:e}"), skew, 1.0, true);
    }
    for d in [16, 64] {
        for h in [0.1, 10.0, 1e4] {
            case(
                &format!("advection d = {d}, h = {h:e}"),
                advection(d),
                h,
                true,
            );
        }
    }
    for w in [1.0, 20.0, 1e3] {
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, 0.0]);
        case(
            &format!("oscillator [[0, 1], [-w^2, 0]], w = {w:e}"),
            a,
            0.1,
            true,
        );
    }
    // Rotation with decay, down to stiff: −1e8 real parts next to |Im| of order 1.
    for decay in [1.0, 1e4, 1e8] {
        let a = normal(
            &mut rng,
            9,
            |i| -decay * (1.0 + i as f64) / 9.0,
            |i| 1.0 + i as f64,
        );
        case(&format!("rotation with decay to -{decay:e}"), a, 1.0, true);
    }
}

#[test]
fn non_normal_matrices_take_the_general_route() {
    let mut rng = Rng(0x1234_5678_9abc_def1);
    // A Jordan-like block: −1 on the diagonal, 1 above.
    let mut j = DMatrix::from_element(8, 8, 0.0);
    for i in 0..8 {
        j[(i, i)] = -1.0;
        if i + 1 < 8 {
            j[(i, i + 1)] = 1.0;
        }
    }
    case("Jordan -1, d = 8", j, 1.0, false);
    for scale in [0.1, 10.0, 100.0] {
        let a = rng.matrix(16) * (scale / 16.0);
        case(&format!("random 16 x 16, scale {scale:e}"), a, 1.0, false);
    }
    // A normal matrix plus a coupling well above rounding: no longer normal.
    let mut a = normal(&mut rng, 6, |_| -1.0, |i| 2.0 + i as f64);
    a[(0, 5)] += 1e-6;
    case("rotation plus a 1e-6 coupling", a, 1.0, false);
}
