//! Every misuse of `ecr_method!`'s arguments is a compile error on the offending token: the
//! cases in `tests/ui`, each with the compiler's output as committed (`.stderr`). They check the
//! macro alone, so trybuild's crate for them depends on this crate only and builds in seconds.
//! A user reaches the macro as `ecr::ecr_method` or `ecr_runtime::ecr_method`, the same macro.
//!
//! A stepper whose dimension cannot be inferred (`Ec3::fixed(..)` without `Ec3<_, D>`) is a
//! type error of the calling code rather than of the macro's arguments: it is the
//! `compile_fail,E0284` doctest on `ecr_runtime::ecr_method`.

#[test]
fn ui() {
    let t = trybuild::TestCases::new();
    t.compile_fail("tests/ui/*.rs");
}
