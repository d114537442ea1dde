//! Links the `ecr` executable position-dependent (`-no-pie`) on Linux with glibc.
//!
//! The executable is large (about 11 MB, most of it the steppers compiled per problem), and
//! as a position-independent executable the dynamic loader relocates it at every start: about
//! 8 000 relative relocations over the vtables and constant tables, whose pages are then
//! copied on write. A short `ecr run` spent about 7 % of its time there (1.24 → 1.15 ms of
//! process CPU and 175 → 149 page faults, Duffing, one step; `perf stat -r 60`). The only
//! thing given up is address-space randomisation of the executable's own image (libraries,
//! heap and stack are still randomised); the library crates and the tests are not affected.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let var = |name| std::env::var(name).unwrap_or_default();
    if var("CARGO_CFG_TARGET_OS") == "linux" && var("CARGO_CFG_TARGET_ENV") == "gnu" {
        println!("cargo:rustc-link-arg-bin=ecr=-no-pie");
    }
}
