//! numpy arrays in and out. Inputs are read in place (a read-only view of the array's memory, no
//! conversion); outputs are new float64 arrays in C order. An input that is not a numpy array of
//! float64 is a `TypeError`, one of the wrong shape a `ValueError`, both naming the argument.

use gelenk::math::{Transform, Vec3};
use nalgebra::{DMatrix, DVector};
use numpy::{
    PyArray1, PyArray2, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// The error for an argument that is not a float64 array of `ndim` dimensions.
fn wrong_array(obj: &Bound<'_, PyAny>, name: &str, ndim: usize) -> PyErr {
    if let Ok(array) = obj.cast::<PyUntypedArray>() {
        let dtype = array.dtype();
        if dtype.is_equiv_to(&numpy::dtype::<f64>(obj.py())) {
            return PyValueError::new_err(format!(
                "{name}: expected a {ndim}-D array, got shape {:?}",
                array.shape()
            ));
        }
        let dtype = dtype.str().map(|s| s.to_string()).unwrap_or_else(|_| "?".to_string());
        return PyTypeError::new_err(format!(
            "{name}: expected a numpy array of float64, got one of {dtype} (convert it with \
             numpy.asarray({name}, dtype=numpy.float64))"
        ));
    }
    let type_name = obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".to_string());
    PyTypeError::new_err(format!(
        "{name}: expected a numpy array of float64, got {type_name} (convert it with \
         numpy.asarray({name}, dtype=numpy.float64))"
    ))
}

/// A read-only view of a 2-D float64 array.
pub fn array2<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<PyReadonlyArray2<'py, f64>> {
    match obj.cast::<PyArray2<f64>>() {
        Ok(a) => Ok(a.try_readonly().map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?),
        Err(_) => Err(wrong_array(obj, name, 2)),
    }
}

/// A read-only view of a 3-D float64 array.
pub fn array3<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<PyReadonlyArray3<'py, f64>> {
    match obj.cast::<numpy::PyArray3<f64>>() {
        Ok(a) => Ok(a.try_readonly().map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?),
        Err(_) => Err(wrong_array(obj, name, 3)),
    }
}

/// Copies a 1-D float64 array of `len` entries into `out` (resized if needed).
///
/// This is the path of every dynamics call, so it reads the array's memory directly instead of
/// registering a borrow with rust-numpy's borrow checker (which costs more than the copy).
pub fn read_into(obj: &Bound<'_, PyAny>, name: &str, len: usize, out: &mut DVector<f64>) -> PyResult<()> {
    let Ok(array) = obj.cast::<PyArray1<f64>>() else {
        return Err(wrong_array(obj, name, 1));
    };
    if array.len() != len {
        return Err(PyValueError::new_err(format!("{name}: expected {len} entries, got {}", array.len())));
    }
    if out.len() != len {
        *out = DVector::zeros(len);
    }
    // SAFETY: the GIL is held (the module declares it needs the GIL, so no other thread runs
    // Python code or writes the array meanwhile); the slice is read here and not kept; this
    // crate never holds a writable borrow of an array it was given as input.
    match unsafe { array.as_slice() } {
        Ok(slice) => out.as_mut_slice().copy_from_slice(slice),
        Err(_) => {
            let view = array.try_readonly().map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?;
            out.iter_mut().zip(view.as_array().iter()).for_each(|(o, x)| *o = *x);
        }
    }
    Ok(())
}

/// A 1-D float64 array of `len` entries as a new vector.
pub fn vector(obj: &Bound<'_, PyAny>, name: &str, len: usize) -> PyResult<DVector<f64>> {
    let mut out = DVector::zeros(len);
    read_into(obj, name, len, &mut out)?;
    Ok(out)
}

/// A 3-vector from a float64 array of 3 entries.
pub fn vec3(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec3> {
    let v = vector(obj, name, 3)?;
    Ok(Vec3::new(v[0], v[1], v[2]))
}

/// A new 1-D array holding `values`.
pub fn to_py1<'py>(py: Python<'py>, values: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, values)
}

/// A new 2-D array (C order) holding `m`.
pub fn to_py2<'py>(py: Python<'py>, m: &DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    let (rows, cols) = m.shape();
    let mut flat = Vec::with_capacity(rows * cols);
    for r in 0..rows {
        flat.extend(m.row(r).iter());
    }
    rows_to_py2(py, flat, cols)
}

/// A new 2-D array (C order) from its rows laid end to end, `cols` entries each.
pub fn rows_to_py2(py: Python<'_>, flat: Vec<f64>, cols: usize) -> Bound<'_, PyArray2<f64>> {
    let rows = flat.len().checked_div(cols).unwrap_or(0);
    let array = PyArray1::from_vec(py, flat);
    array.reshape([rows, cols]).expect("rows × cols entries")
}

/// The 4×4 homogeneous matrix `[R t; 0 1]` of a pose.
pub fn homogeneous<'py>(py: Python<'py>, x: &Transform) -> Bound<'py, PyArray2<f64>> {
    let mut flat = Vec::with_capacity(16);
    for r in 0..3 {
        flat.extend([x.rotation[(r, 0)], x.rotation[(r, 1)], x.rotation[(r, 2)], x.translation[r]]);
    }
    flat.extend([0.0, 0.0, 0.0, 1.0]);
    rows_to_py2(py, flat, 4)
}

/// A pose as 7 numbers: position, then the quaternion (x, y, z, w) — a free joint's q.
pub fn pose7(x: &Transform) -> [f64; 7] {
    let [qx, qy, qz, qw] = x.quaternion_xyzw();
    [x.translation.x, x.translation.y, x.translation.z, qx, qy, qz, qw]
}
