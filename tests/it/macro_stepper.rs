//! `ecr_method!` steppers against the run-time stepper: bit for bit the same steps, for
//! r = 1..8 and s ∈ {r, r + 2}, static and dynamic dimension.

use ecr::problems::{Duffing, Wind};
use ecr_runtime::ecr_method;
use ecr_runtime::operator::{Dense, DenseStatic};
use ecr_runtime::stepper::{EcStepper, SolverSettings};
use ecr_runtime::system::Semilinear;
use nalgebra::SMatrix;

ecr_method!(r = 1);
ecr_method!(r = 1, s = 3);
ecr_method!(r = 2);
ecr_method!(r = 2, s = 4);
ecr_method!(r = 3);
ecr_method!(r = 3, s = 5);
ecr_method!(r = 4);
ecr_method!(r = 4, s = 6);
ecr_method!(r = 5);
ecr_method!(r = 5, s = 7);
ecr_method!(r = 6);
ecr_method!(r = 6, s = 8);
ecr_method!(r = 7);
ecr_method!(r = 7, s = 9);
ecr_method!(pub(crate) r = 8, name = Eight);
ecr_method!(r = 8, s = 10, name = EightS10);

fn bits(y: &[f64]) -> Vec<u64> {
    y.iter().map(|x| x.to_bits()).collect()
}

/// Runs `steps` steps with a fixed stepper (static and dynamic storage) and the run-time
/// stepper on Duffing and on the wind problem; asserts identical bits after every step.
macro_rules! check {
    ($stat:ident, $dynamic:ident, $r:expr, $s:expr) => {{
        for (a, y0, g) in problems() {
            let sa: SMatrix<f64, 2, 2> = SMatrix::from_iterator(a.iter().copied());
            let h = 0.05;
            let mut fixed: $stat<_, 2> =
                $stat::fixed(Semilinear::new(DenseStatic::new(sa).unwrap(), g), h).unwrap();
            let mut dynamic: $dynamic<_> =
                $dynamic::fixed(Semilinear::new(Dense::new(a.clone()).unwrap(), g), h).unwrap();
            let sys = Semilinear::new(Dense::new(a.clone()).unwrap(), g);
            let mut run_time =
                EcStepper::with_nodes(sys, $r, $s, h, SolverSettings::default()).unwrap();
            let (mut y1, mut y2, mut y3) = ([y0[0], y0[1]], y0.clone(), y0.clone());
            for n in 0..200 {
                let r1 = fixed.step(&mut y1).unwrap();
                let r2 = dynamic.step(&mut y2).unwrap();
                let r3 = run_time.step(&mut y3).unwrap();
                assert_eq!(
                    bits(&y1),
                    bits(&y3),
                    "static r = {}, s = {}, step {n}",
                    $r,
                    $s
                );
                assert_eq!(
                    bits(&y2),
                    bits(&y3),
                    "dynamic r = {}, s = {}, step {n}",
                    $r,
                    $s
                );
                assert_eq!((r1.sweeps, r2.sweeps), (r3.sweeps, r3.sweeps));
            }
        }
    }};
}

type G = fn(&[f64], &mut [f64]);

fn problems() -> Vec<(nalgebra::DMatrix<f64>, Vec<f64>, G)> {
    fn duffing_g(y: &[f64], o: &mut [f64]) {
        Duffing::default().nonlinear(y, o)
    }
    fn wind_g(y: &[f64], o: &mut [f64]) {
        Wind::conservative().nonlinear(y, o)
    }
    vec![
        (
            Duffing::default().linear_matrix(),
            Duffing::default().initial_value(),
            duffing_g as G,
        ),
        (
            Wind::conservative().linear_matrix(),
            Wind::conservative().initial_value(),
            wind_g as G,
        ),
    ]
}

#[test]
fn macro_steppers_equal_the_run_time_stepper_bit_for_bit() {
    check!(Ec1, Ec1Dyn, 1, 1);
    check!(Ec1S3, Ec1S3Dyn, 1, 3);
    check!(Ec2, Ec2Dyn, 2, 2);
    check!(Ec2S4, Ec2S4Dyn, 2, 4);
    check!(Ec3, Ec3Dyn, 3, 3);
    check!(Ec3S5, Ec3S5Dyn, 3, 5);
    check!(Ec4, Ec4Dyn, 4, 4);
    check!(Ec4S6, Ec4S6Dyn, 4, 6);
    check!(Ec5, Ec5Dyn, 5, 5);
    check!(Ec5S7, Ec5S7Dyn, 5, 7);
    check!(Ec6, Ec6Dyn, 6, 6);
    check!(Ec6S8, Ec6S8Dyn, 6, 8);
    check!(Ec7, Ec7Dyn, 7, 7);
    check!(Ec7S9, Ec7S9Dyn, 7, 9);
    check!(Eight, EightDyn, 8, 8);
    check!(EightS10, EightS10Dyn, 8, 10);
}

#[test]
fn emitted_constants_are_the_generator_values() {
    let t = ecr_codegen_values(3, 5);
    assert_eq!(Ec3S5Kernel::NODES.map(f64::to_bits).to_vec(), bits(&t.0));
    assert_eq!(Ec3S5Kernel::WEIGHTS.map(f64::to_bits).to_vec(), bits(&t.1));
    let w: Vec<f64> = Ec3S5Kernel::W.iter().flatten().copied().collect();
    assert_eq!(bits(&w), bits(&t.2));
}

fn ecr_codegen_values(r: usize, s: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let c = ecr_runtime::tables::coefficients(r, s).unwrap();
    (c.nodes.clone(), c.weights.clone(), c.w.clone())
}

#[test]
fn static_stepper_rejects_a_system_of_the_wrong_dimension() {
    let a = SMatrix::<f64, 3, 3>::identity();
    let sys = Semilinear::new(DenseStatic::new(a).unwrap(), |_: &[f64], o: &mut [f64]| {
        o.fill(0.0)
    });
    let r: Result<Ec2<_, 2>, _> = Ec2::fixed(sys, 0.1);
    assert!(matches!(
        r,
        Err(ecr_runtime::Error::DimensionMismatch { .. })
    ));
}

/// [`SizedEcStepper`] (what `ecr run` and `ecr bench` use for the planar problems) puts d = 2,
/// s = r <= 8 on fixed-size buffers (the run-time kernel on `StaticBuffers<2, r, r>`) and
/// everything else on `EcStepper`'s heap buffers, and is bit for bit `EcStepper` either way,
/// step by step, for r = 1..10 (s = r, and s = r + 1) on Duffing and the wind problem, with the
/// default solver, the extrapolating predictor, Newton and the paper's settings; dense output
/// and a change of step size included. Sizes that are not the buffers' are refused.
#[test]
fn sized_stepper_equals_ec_stepper_bit_for_bit() {
    use ecr_runtime::stepper::{
        Predictor, RuntimeKernel, SizedEcStepper, StageSolver, StaticBuffers, Stepper,
    };
    let settings = [
        SolverSettings::default(),
        SolverSettings {
            predictor: Predictor::Extrapolate,
            ..SolverSettings::default()
        },
        SolverSettings {
            solver: StageSolver::Newton,
            ..SolverSettings::default()
        },
        SolverSettings::paper(),
    ];
    let mut fixed_seen = 0;
    for r in 1..=10 {
        for s in [r, r + 1] {
            for (a, y0, g) in problems() {
                for set in &settings {
                    let sys = || Semilinear::new(Dense::new(a.clone()).unwrap(), g);
                    let mut sized = SizedEcStepper::with_nodes(sys(), r, s, 0.05, *set).unwrap();
                    let mut dynamic = EcStepper::with_nodes(sys(), r, s, 0.05, *set).unwrap();
                    assert_eq!(sized.is_fixed_size(), s == r && r <= 8, "r = {r}, s = {s}");
                    fixed_seen += usize::from(sized.is_fixed_size());
                    assert_eq!((sized.r(), sized.s()), (r, s));
                    let (mut y1, mut y2) = (y0.clone(), y0.clone());
                    for n in 0..200 {
                        if n == 100 {
                            sized.set_step_size(0.04).unwrap();
                            dynamic.set_step_size(0.04).unwrap();
                        }
                        let r1 = sized.step(&mut y1).unwrap();
                        let r2 = dynamic.step(&mut y2).unwrap();
                        let at = format!("r = {r}, s = {s}, {set:?}, step {n}");
                        assert_eq!(bits(&y1), bits(&y2), "{at}");
                        assert_eq!((r1.sweeps, r1.g_evals), (r2.sweeps, r2.g_evals), "{at}");
                    }
                    let (d1, d2) = (sized.dense_output(0.3), dynamic.dense_output(0.3));
                    assert_eq!(bits(&d1.unwrap()), bits(&d2.unwrap()));
                }
            }
        }
    }
    assert_eq!(fixed_seen, 8 * 2 * settings.len());
    // Sizes that are not the buffers' are an error, not a panic.
    let (a, _, g) = problems().remove(0);
    let wrong = Stepper::<RuntimeKernel, _, StaticBuffers<2, 3, 3>>::with_nodes(
        Semilinear::new(Dense::new(a).unwrap(), g),
        4,
        4,
        0.05,
        SolverSettings::default(),
    );
    assert!(wrong.is_err());
}
