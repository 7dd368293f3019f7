//! gelenk's errors as Python exceptions, with the message the command line prints after
//! `gelenk: error: `: a missing file is a `FileNotFoundError`, bad input a `ValueError` (an index
//! out of range an `IndexError`), a failed step a `gelenk.StepError`. A panic — a bug — never
//! crosses into the interpreter: [`guard`] turns it into a `RuntimeError`.

use gelenk::error::MjcfError;
use gelenk::io::problem::{ExportError, ProblemFileError};
use gelenk::io::scene::SceneError;
use gelenk::io::urdf::UrdfError;
use gelenk::world::StepError as RustStepError;
use gelenk::{DynamicsError, ModelError};
use pyo3::exceptions::{
    PyFileNotFoundError, PyIndexError, PyIsADirectoryError, PyNotADirectoryError, PyOSError,
    PyPermissionError, PyRuntimeError, PyValueError,
};
use pyo3::{create_exception, PyErr, PyResult};
use std::io::ErrorKind;

create_exception!(
    gelenk,
    StepError,
    PyRuntimeError,
    "A simulation step failed: a non-finite state, a singular mass matrix, every solver of the \
     chain failing, ... The world's state is left as it was before the step."
);

/// An I/O failure as the `OSError` subclass Python raises for the same cause.
pub fn io_error(kind: ErrorKind, message: String) -> PyErr {
    match kind {
        ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
        ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
        ErrorKind::IsADirectory => PyIsADirectoryError::new_err(message),
        ErrorKind::NotADirectory => PyNotADirectoryError::new_err(message),
        _ => PyOSError::new_err(message),
    }
}

/// A dynamics error: bad input (sizes, NaN, a degenerate quaternion, a singular mass matrix).
pub fn dynamics(e: DynamicsError) -> PyErr {
    match e {
        DynamicsError::IndexOutOfRange { .. } => PyIndexError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// An invalid model description.
pub fn model(e: ModelError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A URDF file that cannot be read or is not a valid model.
pub fn urdf(e: UrdfError) -> PyErr {
    match &e {
        UrdfError::Io { source, .. } => io_error(source.kind(), e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// An MJCF file that cannot be read or is not a valid scene.
pub fn mjcf(e: MjcfError) -> PyErr {
    match &e {
        MjcfError::Io { source, .. } => io_error(source.kind(), e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A step that failed.
pub fn step(e: RustStepError) -> PyErr {
    match e {
        RustStepError::IndexOutOfRange { .. } => PyIndexError::new_err(e.to_string()),
        _ => StepError::new_err(e.to_string()),
    }
}

/// A scene file that cannot be read, built or run.
pub fn scene(e: SceneError) -> PyErr {
    match &e {
        SceneError::Io { source, .. } => io_error(source.kind(), e.to_string()),
        SceneError::Urdf { source, .. } => match source.as_ref() {
            UrdfError::Io { source, .. } => io_error(source.kind(), e.to_string()),
            _ => PyValueError::new_err(e.to_string()),
        },
        SceneError::Step { .. } => StepError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A problem file that cannot be read or written.
pub fn problem_file(e: ProblemFileError) -> PyErr {
    match &e {
        ProblemFileError::Read { source, .. } | ProblemFileError::Write { source, .. } => {
            io_error(source.kind(), e.to_string())
        }
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// An export of problems that stopped.
pub fn export(e: ExportError) -> PyErr {
    match e {
        ExportError::BuiltIn(_) => PyValueError::new_err(e.to_string()),
        ExportError::Scene(e) => scene(e),
        ExportError::Mjcf(e) => mjcf(e),
        ExportError::World(e) => step(e),
        ExportError::Step { .. } => StepError::new_err(e.to_string()),
        ExportError::Write(e) => problem_file(e),
    }
}

/// Runs `f`, turning a panic into a `RuntimeError` instead of letting it unwind into Python.
pub fn guard<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(payload) => Err(panic_error(payload)),
    }
}

/// The `RuntimeError` of a caught panic's payload.
pub fn panic_error(payload: Box<dyn std::any::Any + Send>) -> PyErr {
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".to_string());
    PyRuntimeError::new_err(format!("internal error in gelenk (a bug, please report it): {message}"))
}
