//! Empty: it exists so that the build-dependencies in Cargo.toml take part in feature resolution
//! of the proc macros and build scripts (see Cargo.toml).
fn main() {}
