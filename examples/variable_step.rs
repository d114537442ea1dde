//! Fixed against varying step sizes over 10⁶ steps of EC6P on Duffing ω = 20: the energy error
//! at 10 checkpoints. The varying run cycles pseudo-randomly through four step sizes around h
//! (one stepper per size, so no φ-bank is rebuilt per step), as a step-size controller would.
//!
//! Run: `cargo run --release --example variable_step`
use ecr::problems::Duffing;
use ecr::runtime::stepper::EcStepper;

fn main() -> ecr::runtime::Result<()> {
    let d = Duffing::new(20.0, 0.07)?;
    let (r, h, steps) = (6, 0.0576, 1_000_000);
    let h0 = d.energy(&d.initial_value());
    for varying in [false, true] {
        let factors: &[f64] = if varying {
            &[0.8, 0.95, 1.05, 1.2]
        } else {
            &[1.0]
        };
        let mut steppers = factors
            .iter()
            .map(|f| EcStepper::new(d.system()?, r, f * h))
            .collect::<ecr::runtime::Result<Vec<_>>>()?;
        let mut y = d.initial_value();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut line = Vec::new();
        let mut worst: f64 = 0.0;
        for n in 1..=steps {
            // xorshift: the next step size.
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let k = (state % steppers.len() as u64) as usize;
            steppers[k].step(&mut y)?;
            let e = (d.energy(&y) - h0).abs() / h0.abs();
            worst = worst.max(e);
            if n % (steps / 10) == 0 {
                line.push(format!("{e:.1e}"));
            }
        }
        let label = if varying {
            "varying h (0.8–1.2)"
        } else {
            "fixed h"
        };
        println!(
            "{label}: max relative energy error {worst:.2e}; at each 10⁵ steps: {}",
            line.join(" ")
        );
    }
    Ok(())
}
