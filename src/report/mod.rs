//! Reports computed by the `gelenk report` commands; the command line only parses arguments.

pub mod speed_error;
mod speed_error_plot;
mod speed_error_scenes;
