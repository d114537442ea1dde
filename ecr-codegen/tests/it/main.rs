//! ecr-codegen's integration tests in one binary, one module per area. Run one area with its
//! path, e.g. `cargo test -p ecr-codegen --test it exact_identities::`.

mod correct_rounding;
mod exact_identities;
