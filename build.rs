//! Links the `ecr` executable position-dependent (`-no-pie`) on Linux with glibc, and with the
//! `cli` feature compiles `ecr bench`'s Duffing peer in C.
//!
//! The executable is large (about 11 MB, most of it the steppers compiled per problem), and
//! as a position-independent executable the dynamic loader relocates it at every start: about
//! 8 000 relative relocations over the vtables and constant tables, whose pages are then
//! copied on write. A short `ecr run` spent about 7 % of its time there (1.24 → 1.15 ms of
//! process CPU and 175 → 149 page faults, Duffing, one step; `perf stat -r 60`). The only
//! thing given up is address-space randomisation of the executable's own image (libraries,
//! heap and stack are still randomised); the library crates and the tests are not affected.
//! Built with a static C runtime (docs/cli.md, its opening section) the executable is left
//! as rustc links it.
//!
//! The peer, `benches/c/rotation_splitting_duffing.c`, is compiled at `-O2` whatever the
//! profile (the benchmark and the tests time and run it) and with `-ffp-contract=off`: the
//! file chooses where a fused multiply-add goes, the compiler may not contract its sums (that
//! would lengthen the loop's dependency chain and change its results from one build to the
//! next).

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let var = |name| std::env::var(name).unwrap_or_default();
    // Not with a static C runtime (`-C target-feature=+crt-static`, docs/cli.md): rustc links
    // that as a static position-independent executable, and `-no-pie` on top of it gave a
    // binary that died of a segmentation fault when run (2026-12-02).
    let static_crt = var("CARGO_CFG_TARGET_FEATURE")
        .split(',')
        .any(|f| f == "crt-static");
    if var("CARGO_CFG_TARGET_OS") == "linux" && var("CARGO_CFG_TARGET_ENV") == "gnu" && !static_crt
    {
        println!("cargo:rustc-link-arg-bin=ecr=-no-pie");
    }
    #[cfg(feature = "cli")]
    {
        const PEER: &str = "benches/c/rotation_splitting_duffing.c";
        println!("cargo:rerun-if-changed={PEER}");
        cc::Build::new()
            .file(PEER)
            .opt_level(2)
            .flag_if_supported("-ffp-contract=off")
            .compile("ecr_rotation_peer");
    }
}
