use ecr::ecr_method;
use ecr::runtime::operator::{Dense, DenseStatic};
use ecr::runtime::stepper::{EcStepper, RuntimeKernel, SolverSettings, StaticBuffers, Stepper};
use ecr::runtime::system::Semilinear;
use nalgebra::{DMatrix, SMatrix};
ecr_method!(r = 6);
fn main() {
    let which = std::env::args().nth(1).unwrap();
    let (omega, k) = (20.0f64, 0.07f64);
    let g = move |y: &[f64], out: &mut [f64]| {
        out[0] = 0.0;
        out[1] = 2.0 * k * k * y[0].powi(3);
    };
    let h = 0.1;
    let mut y = [0.0, omega];
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -(omega * omega + k * k), 0.0]);
    if which == "macro" {
        let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -(omega * omega + k * k), 0.0);
        let mut st: Ec6<_, 2> =
            Ec6::fixed(Semilinear::new(DenseStatic::new(a).unwrap(), g), h).unwrap();
        for _ in 0..10000 {
            st.step(&mut y).unwrap();
        }
    } else if which == "static" {
        let mut st = Stepper::<RuntimeKernel, _, StaticBuffers<2, 6, 6>>::from_kernel(
            RuntimeKernel::new(6, 6).unwrap(),
            Semilinear::new(Dense::new(a).unwrap(), g),
            h,
            SolverSettings::default(),
        )
        .unwrap();
        for _ in 0..10000 {
            st.step(&mut y).unwrap();
        }
    } else {
        let mut st = EcStepper::new(Semilinear::new(Dense::new(a).unwrap(), g), 6, h).unwrap();
        for _ in 0..10000 {
            st.step(&mut y).unwrap();
        }
    }
    println!("{:?}", y);
}
