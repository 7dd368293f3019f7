//! The corpus's standard formats (CBF, QPS, gelenk's JSON with A sparse; FCLIB's own tests are
//! in src/io/problem/fclib.rs, with the `fclib` feature): each written file reads back to the
//! last bit, the committed samples in `tests/problems/formats/` read and equal what the writers
//! make of the committed problems, a CBF file poses the problem it came from (clarabel solves it
//! to the same optimum), and bad files are typed errors naming the file and the field.

use gelenk::io::problem::{
    cbf_of, cbf_text, parse_cbf, parse_qps, problem_from_json, problem_to_json_sparse, qp_of, qps_text,
    read_cbf, read_meta, read_problem, read_qps, solve_cbf_with_clarabel, ProblemFileError, QpForm,
};
use std::path::{Path, PathBuf};

fn problems() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/problems")
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

fn same_qp(a: &QpForm, b: &QpForm) {
    for (x, y) in [(&a.p, &b.p), (&a.g, &b.g), (&a.a, &b.a)] {
        assert_eq!(x.shape(), y.shape());
        assert_eq!(bits(x.as_slice()), bits(y.as_slice()));
    }
    for (x, y) in [(&a.q, &b.q), (&a.h, &b.h), (&a.b, &b.b), (&a.lb, &b.lb), (&a.ub, &b.ub)] {
        assert_eq!(bits(x.as_slice()), bits(y.as_slice()));
    }
}

const CONE_PROBLEMS: [&str; 3] = ["stack2-cone-0000", "box-drop-cone-0015", "sphere-incline-cone-0030"];
const QP_PROBLEMS: [&str; 4] =
    ["stack2-pyramid4-0004", "box-flat-0000", "four-bar-0050", "limit-pendulum-0020"];

#[test]
fn cbf_files_round_trip_and_pose_the_problem() {
    for name in CONE_PROBLEMS.iter().chain(&QP_PROBLEMS) {
        let dir = problems().join(name);
        let problem = read_problem(&dir).unwrap();
        let file = cbf_of(&problem).unwrap();
        let text = cbf_text(&file);
        let back = parse_cbf(&text, Path::new("x.cbf")).unwrap();
        assert_eq!(back, file, "{name}");
        assert_eq!(cbf_text(&back), text, "{name}: not the same bits");
        // The optimum of the CBF file is the objective of clarabel's reference answer.
        let (optimum, x) = solve_cbf_with_clarabel(&back).unwrap();
        let reference = read_meta(&dir).unwrap().solutions["clarabel"].objective.unwrap();
        let scale = 1.0 + reference.abs();
        assert!(
            (optimum - reference).abs() <= 1e-6 * scale,
            "{name}: CBF optimum {optimum}, reference {reference}"
        );
        assert_eq!(x.len(), problem.rows() + 1);
    }
}

#[test]
fn qps_files_round_trip_to_the_last_bit() {
    for name in QP_PROBLEMS {
        let problem = read_problem(&problems().join(name)).unwrap();
        let qp = qp_of(&problem).unwrap();
        let text = qps_text(name, &qp);
        let (title, back) = parse_qps(&text, Path::new("x.qps")).unwrap();
        assert_eq!(title, name);
        same_qp(&back, &qp);
        assert_eq!(qps_text(name, &back), text);
    }
}

#[test]
fn sparse_problem_json_reads_back_the_same_problem() {
    for name in CONE_PROBLEMS.iter().chain(&QP_PROBLEMS) {
        let problem = read_problem(&problems().join(name)).unwrap();
        let text = problem_to_json_sparse(&problem).unwrap();
        assert!(text.contains("delassus_entries") && !text.contains("\"delassus\""));
        let back = problem_from_json(&text, Path::new("p.json")).unwrap();
        assert_eq!(back, problem, "{name}");
        assert_eq!(bits(back.delassus.as_slice()), bits(problem.delassus.as_slice()));
    }
}

#[test]
fn the_committed_samples_read_back_as_written() {
    let formats = problems().join("formats");
    for name in ["stack2-cone-0000", "sphere-incline-cone-0030"] {
        let problem = read_problem(&problems().join(name)).unwrap();
        let path = formats.join(format!("{name}.cbf"));
        assert_eq!(read_cbf(&path).unwrap(), cbf_of(&problem).unwrap(), "{}", path.display());
    }
    for name in ["stack2-pyramid4-0004", "box-flat-0000"] {
        let problem = read_problem(&problems().join(name)).unwrap();
        let path = formats.join(format!("{name}.qps"));
        let (_, qp) = read_qps(&path).unwrap();
        same_qp(&qp, &qp_of(&problem).unwrap());
    }
}

fn invalid(result: Result<impl std::fmt::Debug, ProblemFileError>, file: &str, field: &str) {
    let error = result.unwrap_err();
    let text = error.to_string();
    assert!(matches!(error, ProblemFileError::Invalid { .. }), "{text}");
    assert!(text.starts_with(file) && text.contains(field), "expected {file} and {field} in: {text}");
}

#[test]
fn bad_cbf_and_qps_files_are_typed_errors_naming_the_file_and_the_field() {
    let problem = read_problem(&problems().join("stack2-pyramid4-0004")).unwrap();
    let cbf = cbf_text(&cbf_of(&problem).unwrap());
    let path = Path::new("bad.cbf");
    invalid(parse_cbf(&cbf[..cbf.len() / 2], path), "bad.cbf", "line ");
    invalid(parse_cbf(&cbf.replacen("L+", "L*", 1), path), "bad.cbf", "unknown cone \"L*\"");
    invalid(
        parse_cbf(&cbf.replacen("\nACOORD\n", "\nACOORD\n1\n99999 0 1.0\n", 1), path),
        "bad.cbf",
        "ACOORD: entry (99999, 0)",
    );
    invalid(
        parse_cbf(&cbf.replacen("\nBCOORD\n", "\nBCOORD\n1\n0 nan\n", 1), path),
        "bad.cbf",
        "BCOORD: \"nan\"",
    );
    invalid(parse_cbf("VAR\n1 1\nF 2\n", path), "bad.cbf", "VAR: the cones hold 2 entries");
    invalid(parse_cbf("", path), "bad.cbf", "no VER section");
    // A second CON after ACOORD would leave the entries outside the new rows (found by the fuzzer:
    // solving it indexed past the rows).
    invalid(parse_cbf(&format!("{cbf}\nCON\n1 1\nL= 1\n"), path), "bad.cbf", "a second CON section");
    let qps = qps_text("p", &qp_of(&problem).unwrap());
    let path = Path::new("bad.qps");
    invalid(parse_qps(&qps[..qps.len() / 2], path), "bad.qps", "no ENDATA");
    // An entry of P that overflows to infinity (found by the fuzzer) is not a QP.
    let quadobj = qps.find("QUADOBJ\n").unwrap() + "QUADOBJ\n".len();
    let value_at = quadobj + qps[quadobj..].find('\n').unwrap();
    let value_start = qps[..value_at].rfind(' ').unwrap() + 1;
    let overflow = format!("{}5e308{}", &qps[..value_start], &qps[value_at..]);
    invalid(parse_qps(&overflow, path), "bad.qps", "\"5e308\" is not a finite number");
    invalid(parse_qps(&qps.replacen(" g0 ", " nosuchrow ", 1), path), "bad.qps", "unknown row \"nosuchrow\"");
    invalid(
        parse_qps(&qps.replacen("FR bnd", "XX bnd", 1), path),
        "bad.qps",
        "is not FR, MI, PL, LO, UP or FX",
    );
    invalid(
        parse_qps(&qps.replacen("QUADOBJ", "RANGES", 1), path),
        "bad.qps",
        "section RANGES is not supported",
    );
    assert!(matches!(read_cbf(Path::new("/no/such/file.cbf")), Err(ProblemFileError::Read { .. })));
    // Sparse JSON: an entry outside A, a non-symmetric A, a negative μ.
    let json = problem_to_json_sparse(&problem).unwrap();
    let path = Path::new("bad.json");
    invalid(
        problem_from_json(&json.replacen("[0,0,", "[0,999,", 1), path),
        "bad.json",
        "\"delassus_entries\": entry (0, 999)",
    );
    let mut skew: serde_json::Value = serde_json::from_str(&json).unwrap();
    let entries = skew["delassus_entries"].as_array_mut().unwrap();
    let off = entries.iter().position(|e| e[0] != e[1]).unwrap();
    entries[off][2] = serde_json::json!(1e3);
    invalid(problem_from_json(&skew.to_string(), path), "bad.json", "A is not symmetric");
    invalid(
        problem_from_json(&json.replacen("\"mu\":", "\"mu\":-1.0,\"x\":", 1), path),
        "bad.json",
        "must be finite and ≥ 0",
    );
}
