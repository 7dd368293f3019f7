//! `.npy` arrays and `.npz` archives (stored zip files that `numpy.load` reads): `lcp.npz` and
//! `qp.npz`.

use super::qp_of;
use crate::constraints::{ConstraintProblem, FrictionModel};
use crate::solvers::{lcp_of, LemkeSolver};
use nalgebra::{DMatrix, DVector};

/// One `.npy` file (format 1.0, little-endian f64, C order) of an array of `shape` whose
/// elements, in C (row-major) order, are `data`.
pub fn npy_bytes(shape: &[usize], data: &[f64]) -> Vec<u8> {
    let dims = match shape {
        [d] => format!("({d},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    };
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {dims}, }}");
    // Magic (6) + version (2) + length (2) + header, padded with spaces and ended by '\n' to a
    // multiple of 64 bytes.
    let total = (10 + header.len() + 1).div_ceil(64) * 64;
    header.extend(std::iter::repeat_n(' ', total - 10 - header.len() - 1));
    header.push('\n');
    let mut out = Vec::with_capacity(total + 8 * data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for x in data {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out
}

/// CRC-32 (IEEE 802.3, as zip uses).
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

/// A zip archive of stored (uncompressed) files `(name, content)`, as `numpy.savez` writes
/// `.npz` files. Sizes and offsets must fit zip's 32-bit fields.
pub fn stored_zip(files: &[(String, Vec<u8>)]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    let u32_of =
        |x: usize, what: &str| u32::try_from(x).map_err(|_| format!("{what} too large for a zip archive"));
    for (name, content) in files {
        let crc = crc32(content);
        let size = u32_of(content.len(), name)?;
        let offset = u32_of(out.len(), "archive")?;
        let name_len = u16::try_from(name.len()).map_err(|_| format!("entry name {name} too long"))?;
        // Fields shared by the local and the central header: version needed 2.0, no flags,
        // stored, time 00:00, date 1980-01-01, CRC, sizes, name length, no extra field.
        let mut common = Vec::new();
        for x in [20u16, 0, 0, 0, 0x21] {
            common.extend_from_slice(&x.to_le_bytes());
        }
        for x in [crc, size, size] {
            common.extend_from_slice(&x.to_le_bytes());
        }
        common.extend_from_slice(&name_len.to_le_bytes());
        common.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        out.extend_from_slice(&common);
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(content);
        central.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        central.extend_from_slice(&20u16.to_le_bytes()); // made by: 2.0
        central.extend_from_slice(&common);
        for x in [0u16, 0, 0] {
            central.extend_from_slice(&x.to_le_bytes()); // comment length, disk, internal attributes
        }
        central.extend_from_slice(&0u32.to_le_bytes()); // external attributes
        central.extend_from_slice(&offset.to_le_bytes());
        central.extend_from_slice(name.as_bytes());
    }
    let count = u16::try_from(files.len()).map_err(|_| "too many zip entries".to_string())?;
    let (central_offset, central_size) = (u32_of(out.len(), "archive")?, u32_of(central.len(), "directory")?);
    out.extend_from_slice(&central);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    for x in [0u16, 0, count, count] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&central_size.to_le_bytes());
    out.extend_from_slice(&central_offset.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    Ok(out)
}

/// An `.npz` archive of dense arrays `(name, shape, C-order data)` (entries `NAME.npy`).
pub fn npz_bytes(arrays: &[(&str, Vec<usize>, Vec<f64>)]) -> Result<Vec<u8>, String> {
    let files: Vec<(String, Vec<u8>)> =
        arrays.iter().map(|(name, shape, data)| (format!("{name}.npy"), npy_bytes(shape, data))).collect();
    stored_zip(&files)
}

fn matrix_entry<'a>(name: &'a str, m: &DMatrix<f64>) -> (&'a str, Vec<usize>, Vec<f64>) {
    (name, vec![m.nrows(), m.ncols()], m.transpose().as_slice().to_vec())
}

fn vector_entry<'a>(name: &'a str, v: &DVector<f64>) -> (&'a str, Vec<usize>, Vec<f64>) {
    (name, vec![v.len()], v.as_slice().to_vec())
}

/// Friction directions of the LCP written for `problem` (the problem's own pyramid, else
/// [`LemkeSolver`]'s default).
pub fn lcp_facets(problem: &ConstraintProblem) -> usize {
    match problem.friction {
        FrictionModel::Pyramid { facets } => facets,
        FrictionModel::Cone => LemkeSolver::default().facets,
    }
}

/// `lcp.npz`'s bytes: `M`, `q`, `C`, `c0` of [`lcp_of`] with [`lcp_facets`] directions.
pub fn lcp_npz(problem: &ConstraintProblem) -> Result<Vec<u8>, String> {
    let lcp = lcp_of(problem, lcp_facets(problem));
    npz_bytes(&[
        matrix_entry("M", &lcp.m),
        vector_entry("q", &lcp.q),
        matrix_entry("C", &lcp.c),
        vector_entry("c0", &lcp.c0),
    ])
}

/// `qp.npz`'s bytes (`P`, `q`, `G`, `h`, `A`, `b`, `lb`, `ub`), or `None` when the problem has a
/// second-order cone.
pub fn qp_npz(problem: &ConstraintProblem) -> Option<Result<Vec<u8>, String>> {
    let qp = qp_of(problem)?;
    Some(npz_bytes(&[
        matrix_entry("P", &qp.p),
        vector_entry("q", &qp.q),
        matrix_entry("G", &qp.g),
        vector_entry("h", &qp.h),
        matrix_entry("A", &qp.a),
        vector_entry("b", &qp.b),
        vector_entry("lb", &qp.lb),
        vector_entry("ub", &qp.ub),
    ]))
}
