//! States files: joint states to evaluate the dynamics on (`gelenk dynamics --states`), as JSON
//! `{"states": [{"q": […], "v": […], "a": […], "tau": […]}]}`. `q` is required (nq numbers, in the
//! model's joint order); `v`, `a` (rad/s², m/s²) and `tau` (N·m, N) have nv numbers each and
//! default to zeros. An unknown key is an error (a misspelt `"tua"` would otherwise be zero
//! torque), as is a value that is not a finite number; a file is read within [`ReadLimits`].

use super::limits::ReadLimits;
use nalgebra::DVector;
use serde::Deserialize;
use std::path::Path;
use thiserror::Error;

/// One state: configuration, velocity, acceleration and joint forces.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Configuration (nq).
    pub q: DVector<f64>,
    /// Velocity (nv).
    pub v: DVector<f64>,
    /// Acceleration for inverse dynamics (nv).
    pub a: DVector<f64>,
    /// Joint forces for forward dynamics (nv).
    pub tau: DVector<f64>,
}

/// A states file that cannot be read as states of the model.
#[derive(Debug, Error)]
pub enum StatesError {
    /// The file could not be read (or is larger than [`ReadLimits::max_bytes`]).
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File path.
        file: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not JSON of the states format (syntax, an unknown key, a value of the wrong type).
    #[error("{file}: not a states file: {message}")]
    Parse {
        /// File path (`<string>` for text).
        file: String,
        /// The parser's message, with line and column.
        message: String,
    },
    /// A state that does not fit the model.
    #[error("{file}: state {index}: {what}")]
    State {
        /// File path (`<string>` for text).
        file: String,
        /// Index of the state in the file (from 0).
        index: usize,
        /// What is wrong.
        what: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StatesFile {
    states: Vec<StateFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StateFile {
    q: Vec<f64>,
    #[serde(default)]
    v: Option<Vec<f64>>,
    #[serde(default)]
    a: Option<Vec<f64>>,
    #[serde(default)]
    tau: Option<Vec<f64>>,
}

/// Reads a states file for a model with `nq` coordinates and `nv` velocities.
pub fn read_file(path: &Path, nq: usize, nv: usize, limits: &ReadLimits) -> Result<Vec<State>, StatesError> {
    let file = path.display().to_string();
    let text = limits.read_text_io(path).map_err(|source| StatesError::Io { file: file.clone(), source })?;
    parse_named(&text, &file, nq, nv, limits)
}

/// Parses states from JSON text for a model with `nq` coordinates and `nv` velocities.
pub fn parse(text: &str, nq: usize, nv: usize) -> Result<Vec<State>, StatesError> {
    parse_named(text, "<string>", nq, nv, &ReadLimits::default())
}

fn parse_named(
    text: &str,
    file: &str,
    nq: usize,
    nv: usize,
    limits: &ReadLimits,
) -> Result<Vec<State>, StatesError> {
    let parse_err = |message: String| StatesError::Parse { file: file.to_string(), message };
    limits.check_len(text).map_err(parse_err)?;
    limits.check_data_depth(text).map_err(parse_err)?;
    let doc: StatesFile = serde_json::from_str(text).map_err(|e| parse_err(e.to_string()))?;
    doc.states
        .into_iter()
        .enumerate()
        .map(|(index, s)| {
            let err = |what: String| StatesError::State { file: file.to_string(), index, what };
            let vector = |x: Option<Vec<f64>>, key: &str, len: usize| -> Result<DVector<f64>, StatesError> {
                let Some(x) = x else { return Ok(DVector::zeros(len)) };
                if x.len() != len {
                    return Err(err(format!("\"{key}\" has {} entries, the model needs {len}", x.len())));
                }
                if let Some(k) = x.iter().position(|e| !e.is_finite()) {
                    return Err(err(format!("\"{key}\"[{k}] is not a finite number")));
                }
                Ok(DVector::from_vec(x))
            };
            Ok(State {
                q: vector(Some(s.q), "q", nq)?,
                v: vector(s.v, "v", nv)?,
                a: vector(s.a, "a", nv)?,
                tau: vector(s.tau, "tau", nv)?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_state_reads_with_defaults() {
        let states = parse(r#"{"states": [{"q": [0.5], "tau": [2]}]}"#, 1, 1).unwrap();
        assert_eq!(states[0].q[0], 0.5);
        assert_eq!(states[0].v[0], 0.0);
        assert_eq!(states[0].tau[0], 2.0);
    }

    #[test]
    fn an_unknown_key_a_wrong_length_and_a_missing_q_are_errors() {
        let e = parse(r#"{"states": [{"q": [0], "tua": [1]}]}"#, 1, 1).unwrap_err().to_string();
        assert!(e.contains("unknown field `tua`"), "{e}");
        let e = parse(r#"{"states": [{"q": [0, 1]}]}"#, 1, 1).unwrap_err().to_string();
        assert!(e.contains("state 0: \"q\" has 2 entries, the model needs 1"), "{e}");
        let e = parse(r#"{"states": [{"v": [0]}]}"#, 1, 1).unwrap_err().to_string();
        assert!(e.contains("missing field `q`"), "{e}");
        let e = parse(r#"{"states": [], "x": 1}"#, 1, 1).unwrap_err().to_string();
        assert!(e.contains("unknown field `x`"), "{e}");
    }

    #[test]
    fn deep_nesting_is_refused_before_parsing() {
        let text = format!("{{\"states\": {}{}}}", "[".repeat(100_000), "]".repeat(100_000));
        let e = parse(&text, 1, 1).unwrap_err().to_string();
        assert!(e.contains("nested more than 128 deep"), "{e}");
    }
}
