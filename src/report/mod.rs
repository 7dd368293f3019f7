//! Reports that run scenes and publish measured figures; the command line only parses arguments:
//! [`stability`] (the hard-case suite of `tests/hard_cases.rs`, per solver and time step;
//! `gelenk report stability`) and [`speed_error`] (error against cost of integrators and solver
//! settings; `gelenk report speed-error`).

pub mod speed_error;
pub mod stability;
