//! Every misuse of `ecr_method!` is a compile error on the offending token.
//!
//! The cases live here rather than in `ecr-macros`, so that the macro crate needs no
//! dev-dependency on the runtime that depends on it.

#[test]
fn ui() {
    let t = trybuild::TestCases::new();
    t.compile_fail("tests/ui/*.rs");
}
