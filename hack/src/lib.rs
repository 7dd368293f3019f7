//! No code. This crate only unifies the features of dependencies shared by the test suite and
//! the Python extension, so that one build of them serves both (see its Cargo.toml).
