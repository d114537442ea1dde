//! ecr-runtime's integration tests in one binary, one module per area (one binary links the
//! steppers once). Run one area with its path, e.g. `cargo test -p ecr-runtime --test it phi::`.

mod boxed_integrator;
mod common_phi;
mod conserved_mean;
mod double_double_crates;
mod end_time;
mod f64_banks;
mod floors;
mod hbvm_equivalence;
mod legendre_kernels;
mod operators;
mod phi;
mod propagate_dd;
mod solve_setup;
