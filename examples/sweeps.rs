//! Stage-iteration sweeps per step against h and r (ECrP, fixed-point sweeps, default
//! tolerance 1e−15), with the extrapolating predictor and without one, on Duffing ω = 20,
//! k = 0.07 (the benchmark's problem) and ω = 5 (the long-run problem), over t ∈ [0, 100]:
//! `cargo run --release --example sweeps`.

use ecr::problems::Duffing;
use ecr::runtime::stepper::{EcStepper, Predictor, SolverSettings};

fn mean_sweeps(d: &Duffing, r: usize, h: f64, predictor: Predictor) -> Result<f64, String> {
    let settings = SolverSettings {
        predictor,
        ..SolverSettings::default()
    };
    let err = |e: ecr::runtime::Error| e.to_string();
    let mut st = EcStepper::with_nodes(d.system().map_err(err)?, r, r, h, settings).map_err(err)?;
    let mut y = d.initial_value();
    let steps = (100.0 / h).round() as usize;
    let mut sweeps = 0;
    for _ in 0..steps {
        sweeps += st.step(&mut y).map_err(err)?.sweeps;
    }
    Ok(sweeps as f64 / steps as f64)
}

fn main() -> Result<(), String> {
    let hs = [0.25, 0.125, 0.0625, 0.03125, 0.015625];
    for omega in [20.0, 5.0] {
        let d = Duffing::new(omega, 0.07).map_err(|e| e.to_string())?;
        println!(
            "\nDuffing ω = {omega}, k = 0.07, T = 100: sweeps per step, extrapolating predictor / constant start\n"
        );
        print!("| r |");
        for h in hs {
            print!(" h = {h} |");
        }
        println!();
        println!("|---|{}", "---|".repeat(hs.len()));
        for r in 2..=8 {
            print!("| {r} |");
            for h in hs {
                let cell = match (
                    mean_sweeps(&d, r, h, Predictor::Extrapolate),
                    mean_sweeps(&d, r, h, Predictor::Constant),
                ) {
                    (Ok(a), Ok(b)) => format!(" {a:.2} / {b:.2} |"),
                    (Err(e), _) | (_, Err(e)) => format!(" ({e}) |"),
                };
                print!("{cell}");
            }
            println!();
        }
    }
    Ok(())
}
