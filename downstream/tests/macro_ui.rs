//! Every misuse of `ecr_method!` is a compile error on the offending token, as a user's crate
//! sees it through the facade (`ecr::ecr_method`, `ecr::prelude`).
//!
//! The cases live in this crate rather than in `ecr-macros` (which would need a dev-dependency
//! on the runtime that depends on it) or in the root package: trybuild checks them in a crate of
//! its own that depends on what this crate depends on, here the library without the CLI and
//! without the root package's dev-dependencies.

#[test]
fn ui() {
    let t = trybuild::TestCases::new();
    t.compile_fail("tests/ui/*.rs");
}
