//! The ecr package's integration tests in one binary (one module per area): each test binary
//! links the optimised steppers again, so one binary instead of forty keeps `cargo test
//! --workspace` in minutes. Modules that need a feature of the package are compiled with it
//! (`cargo test -p ecr --no-default-features` builds the rest). Run one area with its path,
//! e.g. `cargo test -p ecr --test it solve_suite::`.
//!
//! Two tests stay binaries of their own: `parallel_no_alloc` configures rayon's global pool
//! before anything else uses it, and `cli_ensemble_mpi` needs the `mpi` feature (CI builds it
//! on its own).

#[cfg(feature = "problems")]
mod bad_input;
#[cfg(feature = "baselines")]
mod baselines_collocation;
#[cfg(feature = "baselines")]
mod baselines_exponential;
#[cfg(feature = "baselines")]
mod baselines_krylov;
#[cfg(feature = "baselines")]
mod baselines_peers;
#[cfg(feature = "problems")]
mod between;
#[cfg(feature = "cli")]
mod bit_identity;
#[cfg(feature = "problems")]
mod circulant2d;
#[cfg(feature = "cli")]
mod cli_args;
#[cfg(feature = "cli")]
mod cli_bench;
#[cfg(feature = "cli")]
mod cli_ensemble;
#[cfg(feature = "cli")]
mod cli_kill;
#[cfg(feature = "cli")]
mod cli_output;
#[cfg(feature = "cli")]
mod cli_reproduce;
#[cfg(feature = "cli")]
mod cli_run;
#[cfg(feature = "cli")]
mod cli_tables;
#[cfg(feature = "cli")]
mod common;
#[cfg(feature = "problems")]
mod common_ec;
#[cfg(feature = "problems")]
mod common_suite;
#[cfg(feature = "problems")]
mod counting;
mod docs_links;
#[cfg(feature = "problems")]
mod double_double;
#[cfg(feature = "problems")]
mod ecrp;
#[cfg(feature = "problems")]
mod ecrp_properties;
#[cfg(feature = "problems")]
mod ensemble;
#[cfg(feature = "cli")]
mod ensemble_example;
mod fields;
#[cfg(feature = "problems")]
mod fpu_tc;
#[cfg(feature = "problems")]
mod long_run;
mod macro_quick_start;
#[cfg(feature = "problems")]
mod macro_stepper;
#[cfg(feature = "baselines")]
mod newton;
#[cfg(feature = "problems")]
mod no_alloc;
#[cfg(feature = "problems")]
mod parallel;
#[cfg(feature = "problems")]
mod predictor;
#[cfg(feature = "problems")]
mod second_order;
#[cfg(feature = "problems")]
mod solve;
#[cfg(feature = "problems")]
mod solve_edges;
mod solve_nonsmooth;
#[cfg(feature = "problems")]
mod solve_options;
#[cfg(feature = "problems")]
mod solve_roundoff;
#[cfg(feature = "problems")]
mod solve_suite;
mod solve_switch;
#[cfg(feature = "baselines")]
mod stage_scale;
#[cfg(feature = "baselines")]
mod step_errors;
#[cfg(feature = "problems")]
mod step_fuzz;
#[cfg(feature = "problems")]
mod tc;
