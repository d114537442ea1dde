//! ecr: exponential collocation methods (facade).
pub use ecr_codegen as codegen;
pub use ecr_runtime as runtime;
