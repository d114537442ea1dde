//! A crate that uses `ecr` as a user's program does, written only from the repository's
//! README.md and docs/: everything it needs comes from `ecr::prelude::*`. Its tests
//! (`tests/`) check that those programs compile and give the results the documents promise.
//! Not published.
