//! Runtime of the ecr exponential collocation methods.
#![deny(missing_docs)]

pub mod error;
pub mod operator;
pub mod phi;
pub mod problems;
pub mod special;
pub mod tables;

pub use error::{Error, Result};
