//! Time to generate the certified tables for r = 1..=10 (s = r), as stated when resolving the
//! generator issue. Run: `cargo run --release -p ecr-codegen --example timing`.

use ecr_codegen::{Family, MethodTable};
use std::time::Instant;

fn main() {
    let total = Instant::now();
    for r in 1..=10 {
        let t0 = Instant::now();
        let t = MethodTable::generate(Family::Ec, r, r).expect("r <= MAX_R");
        println!(
            "r = {r:2}: {:>10.3?} (bisection depth {} bits)",
            t0.elapsed(),
            t.bits
        );
    }
    println!("total r = 1..=10: {:.3?}", total.elapsed());
}
