//! Time to generate one ECrP table (r, s) in a fresh process, then (cached isolation) its
//! Gauss–Legendre rule alone. Run it unoptimised, as a downstream debug build runs the
//! generator inside `ecr_method!`:
//! `cargo run -p ecr-codegen --example gen_time --config 'profile.dev.package."*".opt-level=0' -- 16 16`.

use ecr_codegen::{Family, MethodTable, Quadrature};
use std::time::Instant;

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("usage: gen_time R S"))
        .collect();
    let (r, s) = match args[..] {
        [r, s] => (r, s),
        [r] => (r, r),
        _ => (16, 16),
    };
    let t0 = Instant::now();
    let t = MethodTable::generate(Family::Ec, r, s).expect("r, s in range");
    let total = t0.elapsed();
    let t1 = Instant::now();
    let q = Quadrature::gauss_legendre(s, t.bits);
    let quad = t1.elapsed();
    println!(
        "r = {r}, s = {s}: table {total:.3?} (certified at {} bits); its {}-point rule again \
         {quad:.3?}",
        t.bits,
        q.nodes.len()
    );
}
