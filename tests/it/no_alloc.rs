//! A step of a fixed-order stepper with static dimension, a step of the NLS through its FFT
//! workspaces, every operator kind's `propagate_dd` and TCrP steps allocate nothing: counted
//! by a global allocator wrapper, per thread (the test harness allocates on its own threads
//! while a test runs).

use crate::counting::allocations;
use ecr::problems::Nls;
use ecr_runtime::ecr_method;
use ecr_runtime::operator::{
    Circulant, Circulant2d, DenseStatic, Diagonal, LinearOperator, PhiBank, Scalar, SkewPair,
    Symmetric,
};
use ecr_runtime::stepper::EcStepper;
use ecr_runtime::system::Semilinear;
use nalgebra::SMatrix;

ecr_method!(r = 3);
ecr_method!(r = 3, family = tc);

#[test]
fn steps_allocate_nothing() {
    let (omega, k) = (5.0_f64, 0.07_f64);
    let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -(omega * omega + k * k), 0.0);
    let g = move |y: &[f64], out: &mut [f64]| {
        out[0] = 0.0;
        out[1] = 2.0 * k * k * y[0].powi(3);
    };
    let mut fixed: Ec3<_, 2> =
        Ec3::fixed(Semilinear::new(DenseStatic::new(a).unwrap(), g), 0.01).unwrap();
    let mut run_time =
        EcStepper::new(Semilinear::new(DenseStatic::new(a).unwrap(), g), 3, 0.01).unwrap();
    let mut y = [0.0, omega];
    let mut z = [0.0, omega];
    // The NLS (skew pair of a circulant): a compensated step through FFT workspaces.
    let nls = Nls::new(32).unwrap();
    let mut spectral = EcStepper::new(nls.system().unwrap(), 3, 0.005).unwrap();
    let mut u = nls.initial_value();
    // Every operator kind's double-double propagator, with its bank's workspace.
    let lap = [-2.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let sym = nalgebra::DMatrix::from_fn(6, 6, |i, j| lap[(i + 6 - j) % 6]);
    let mut props = Props {
        diagonal: Prop::new(&Diagonal::new(vec![-1.0, 0.0, 2.0]).unwrap()),
        scalar: Prop::new(&Scalar::new(-0.5, 3).unwrap()),
        symmetric: Prop::new(&Symmetric::new(sym).unwrap()),
        circulant: Prop::new(&Circulant::new(lap.to_vec()).unwrap()),
        circulant2d: Prop::new(&Circulant2d::kron_sum(&lap[..3], &lap[..2]).unwrap()),
        skew: Prop::new(&SkewPair::new(Circulant::new(vec![-2.0, 1.0, 1.0]).unwrap()).unwrap()),
    };
    let before = allocations();
    for _ in 0..1000 {
        fixed.step(&mut y).unwrap();
        run_time.step(&mut z).unwrap();
    }
    for _ in 0..100 {
        spectral.step(&mut u).unwrap();
        props.run();
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "heap allocations during 2100 steps and 600 propagate_dd calls"
    );
    assert_eq!(y, z);
}

/// A kernel bank, its workspace and buffers for `propagate_dd` at τ = 1.
struct Prop<B: PhiBank> {
    bank: B,
    ws: B::Workspace,
    y: Vec<f64>,
    hi: Vec<f64>,
    lo: Vec<f64>,
}

impl<B: PhiBank> Prop<B> {
    fn new<A: LinearOperator<Bank = B>>(op: &A) -> Self {
        let bank = op.kernel_bank(0.1, &[0.5, 1.0], 2).unwrap();
        let ws = bank.workspace();
        let d = op.dim();
        Prop {
            bank,
            ws,
            y: (0..d).map(|i| 1.0 + i as f64).collect(),
            hi: vec![0.0; d],
            lo: vec![0.0; d],
        }
    }

    fn run(&mut self) {
        assert!(
            self.bank
                .propagate_dd(1, &self.y, &mut self.hi, &mut self.lo, &mut self.ws)
        );
    }
}

struct Props<B1: PhiBank, B2: PhiBank, B3: PhiBank, B4: PhiBank, B5: PhiBank, B6: PhiBank> {
    diagonal: Prop<B1>,
    scalar: Prop<B2>,
    symmetric: Prop<B3>,
    circulant: Prop<B4>,
    circulant2d: Prop<B5>,
    skew: Prop<B6>,
}

impl<B1: PhiBank, B2: PhiBank, B3: PhiBank, B4: PhiBank, B5: PhiBank, B6: PhiBank>
    Props<B1, B2, B3, B4, B5, B6>
{
    fn run(&mut self) {
        self.diagonal.run();
        self.scalar.run();
        self.symmetric.run();
        self.circulant.run();
        self.circulant2d.run();
        self.skew.run();
    }
}

#[test]
fn second_order_steps_allocate_nothing() {
    use ecr::problems::Fpu;
    use ecr_runtime::operator::Oscillator;
    use ecr_runtime::second_order::{Omega, SecondOrder, TcStepper};
    // One mode (fused sweeps, fixed-size storage) and six modes (the oscillator bank's
    // combine, run-time storage).
    let k2 = 0.07_f64 * 0.07;
    let sys = SecondOrder::new(
        Omega::scalar(25.0 + k2, 1).unwrap(),
        move |q: &[f64], f: &mut [f64]| f[0] = -2.0 * k2 * q[0].powi(3),
    );
    let mut fixed: Tc3<_, 1> = Tc3::fixed(&sys, 0.01).unwrap();
    let fpu = Fpu::new(3, 50.0).unwrap();
    let mut chain = TcStepper::new(fpu.system().unwrap(), 3, 0.01).unwrap();
    let (mut q, mut p) = ([0.0], [5.0]);
    let (mut qc, mut pc) = fpu.initial_value();
    // The oscillator bank's double-double propagator, modal and dense Ω.
    let dense_omega = nalgebra::DMatrix::from_row_slice(2, 2, &[2.0, -1.0, -1.0, 2.0]);
    let mut osc = Prop::new(&Oscillator::new(Omega::diagonal(vec![0.0, 4.0]).unwrap()));
    let mut osc_dense = Prop::new(&Oscillator::new(Omega::dense(dense_omega).unwrap()));
    let before = allocations();
    for _ in 0..1000 {
        fixed.step(&mut q, &mut p).unwrap();
    }
    for _ in 0..1000 {
        chain.step(&mut qc, &mut pc).unwrap();
        osc.run();
        osc_dense.run();
    }
    let after = allocations();
    assert_eq!(after - before, 0, "heap allocations during 2000 steps");
}
