//! Runtime of the ecr exponential collocation methods.
#![deny(missing_docs)]

pub mod error;
pub mod integrate;
pub mod operator;
pub mod phi;
pub mod problems;
pub mod special;
pub mod stepper;
pub mod system;
pub mod tables;

pub use error::{Error, Result};
