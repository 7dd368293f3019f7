//! Reports that run scenes and publish measured figures: [`stability`] (the hard-case suite of
//! `tests/hard_cases.rs`, per solver and time step; `gelenk report stability`).

pub mod stability;
