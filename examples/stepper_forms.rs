//! The three forms of one ECrP step, for counting what each costs: Duffing ω = 20 (k = 0.07),
//! r = s = 6, h = 0.1, 10⁴ steps, with
//!
//! - `macro`: the `ecr_method!(r = 6)` stepper `Ec6<_, 2>` on a static 2 × 2 operator,
//! - `sized`: [`SizedEcStepper`] (the run-time kernel on fixed-size buffers, what `ecr run`
//!   uses for d = 2, s = r ≤ 8),
//! - `heap`: [`EcStepper`] (the run-time kernel on heap buffers, any sizes).
//!
//! All three print the same final state, bit for bit. Count instructions with
//!
//! ```text
//! cargo build --release --example stepper_forms
//! valgrind --tool=callgrind --callgrind-out-file=/dev/null \
//!     target/release/examples/stepper_forms sized
//! ```

use ecr::ecr_method;
use ecr::runtime::operator::{Dense, DenseStatic};
use ecr::runtime::stepper::{EcStepper, SizedEcStepper, SolverSettings};
use ecr::runtime::system::Semilinear;
use nalgebra::{DMatrix, SMatrix};

ecr_method!(r = 6);

const STEPS: usize = 10_000;

fn main() {
    let form = std::env::args().nth(1).unwrap_or_default();
    match run(&form) {
        Ok(y) => println!("{form}: y = {y:?} (bits {:x?})", y.map(f64::to_bits)),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    }
}

fn run(form: &str) -> Result<[f64; 2], String> {
    let (omega, k, h) = (20.0f64, 0.07f64, 0.1);
    let g = move |y: &[f64], out: &mut [f64]| {
        out[0] = 0.0;
        out[1] = 2.0 * k * k * y[0].powi(3);
    };
    let a = [0.0, 1.0, -(omega * omega + k * k), 0.0];
    let mut y = [0.0, omega];
    let err = |e: ecr::runtime::Error| e.to_string();
    match form {
        "macro" => {
            let op = DenseStatic::new(SMatrix::<f64, 2, 2>::from_row_slice(&a)).map_err(err)?;
            let mut st: Ec6<_, 2> = Ec6::fixed(Semilinear::new(op, g), h).map_err(err)?;
            for _ in 0..STEPS {
                st.step(&mut y).map_err(err)?;
            }
        }
        "sized" => {
            let op = Dense::new(DMatrix::from_row_slice(2, 2, &a)).map_err(err)?;
            let system = Semilinear::new(op, g);
            let settings = SolverSettings::default();
            let mut st = SizedEcStepper::with_nodes(system, 6, 6, h, settings).map_err(err)?;
            for _ in 0..STEPS {
                st.step(&mut y).map_err(err)?;
            }
        }
        "heap" => {
            let op = Dense::new(DMatrix::from_row_slice(2, 2, &a)).map_err(err)?;
            let mut st = EcStepper::new(Semilinear::new(op, g), 6, h).map_err(err)?;
            for _ in 0..STEPS {
                st.step(&mut y).map_err(err)?;
            }
        }
        other => {
            return Err(format!(
                "unknown form {other:?}: give one of macro, sized, heap"
            ));
        }
    }
    Ok(y)
}
