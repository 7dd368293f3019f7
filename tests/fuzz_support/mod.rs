//! A corpus-driven mutation fuzzer on stable Rust: each target reads the files of one folder of
//! `tests/fuzz_corpus/`, then mutates them (numbers replaced by extreme values, ranges deleted,
//! duplicated and repeated, tokens of the format inserted, bytes flipped, two inputs spliced) for
//! a time budget, and runs the target on every input on a worker thread. A finding is a panic, a
//! case over its time budget (CPU time of the worker thread: a hang), or a target's own complaint (a non-finite number in a
//! result returned as `Ok`); the input is saved under the target directory and the test fails.
//!
//! `GELENK_FUZZ_SECONDS` (default 8) is each target's budget; `GELENK_FUZZ_SEED` (default fixed,
//! so CI is reproducible; `random` for a fresh one) seeds the mutations.

#![allow(dead_code)]

#[cfg(feature = "fclib")]
pub mod fclib;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// What a target says about one input: `Ok` when it ended well (a typed error counts), `Err`
/// with a description of a wrong result.
pub type Verdict = Result<(), String>;

/// Numbers a mutation writes in place of a number of the input.
const EXTREMES: &[&str] = &[
    "0",
    "-0",
    "-1",
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "1e-320",
    "5e-324",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e9",
    "1e10",
    "1e-9",
    "1e-12",
    "3e38",
    "18446744073709551616",
    "-2147483649",
    "4294967297",
    "1e6",
    "100000",
    "0.5",
    "1e400",
    "-1e-300",
    "2",
    "7",
];

/// The files of `tests/fuzz_corpus/<name>/`, sorted by name.
pub fn corpus(name: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_corpus").join(name);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{}: empty corpus", dir.display());
    files.into_iter().map(|p| (p.clone(), std::fs::read(&p).unwrap())).collect()
}

/// Each target's time budget (s): `GELENK_FUZZ_SECONDS`, default 8.
pub fn budget() -> f64 {
    std::env::var("GELENK_FUZZ_SECONDS").ok().and_then(|s| s.parse().ok()).unwrap_or(8.0)
}

fn seed() -> u64 {
    match std::env::var("GELENK_FUZZ_SEED") {
        Ok(s) if s == "random" => {
            let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
            now.as_nanos() as u64 ^ u64::from(std::process::id())
        }
        Ok(s) => s.parse().unwrap_or(1),
        Err(_) => 0x6765_6c65_6e6b,
    }
}

/// One mutation of `input` (with `corpus` to splice from and `tokens` of the format to insert).
fn mutate_once(rng: &mut StdRng, input: &mut Vec<u8>, corpus: &[(PathBuf, Vec<u8>)], tokens: &[&str]) {
    let len = input.len();
    let at = |rng: &mut StdRng| if len == 0 { 0 } else { rng.random_range(0..=len) };
    match rng.random_range(0..9) {
        // A number replaced by an extreme one.
        0 | 1 => {
            let starts: Vec<usize> = (0..len)
                .filter(|&i| input[i].is_ascii_digit() && (i == 0 || !input[i - 1].is_ascii_alphanumeric()))
                .collect();
            if starts.is_empty() {
                return;
            }
            let s = starts[rng.random_range(0..starts.len())];
            let mut e = s;
            while e < len && (input[e].is_ascii_digit() || b".eE+-".contains(&input[e])) {
                e += 1;
            }
            let with = EXTREMES[rng.random_range(0..EXTREMES.len())];
            input.splice(s..e, with.bytes());
        }
        // A range deleted.
        2 => {
            if len > 0 {
                let a = rng.random_range(0..len);
                let b = (a + rng.random_range(1..=64.min(len - a))).min(len);
                input.drain(a..b);
            }
        }
        // A range copied elsewhere.
        3 => {
            if len > 0 {
                let a = rng.random_range(0..len);
                let b = (a + rng.random_range(1..=256.min(len - a))).min(len);
                let piece = input[a..b].to_vec();
                let to = at(rng);
                input.splice(to..to, piece);
            }
        }
        // A range repeated many times (deep nesting, long lists).
        4 => {
            if len > 0 && len < 1 << 20 {
                let a = rng.random_range(0..len);
                let b = (a + rng.random_range(1..=32.min(len - a))).min(len);
                let most = if rng.random_bool(0.1) { 5000 } else { 64 };
                let times = rng.random_range(2..=most);
                let piece = input[a..b].repeat(times);
                input.splice(b..b, piece);
            }
        }
        // A token of the format inserted.
        5 | 6 => {
            if !tokens.is_empty() {
                let token = tokens[rng.random_range(0..tokens.len())];
                let to = at(rng);
                input.splice(to..to, token.bytes());
            }
        }
        // A byte changed.
        7 => {
            if len > 0 {
                let i = rng.random_range(0..len);
                input[i] = if rng.random_bool(0.8) { rng.random_range(0x20..0x7f) } else { rng.random() };
            }
        }
        // Spliced with another input.
        _ => {
            let other = &corpus[rng.random_range(0..corpus.len())].1;
            if !other.is_empty() {
                let cut = at(rng).min(len);
                let from = rng.random_range(0..other.len());
                input.truncate(cut);
                input.extend_from_slice(&other[from..]);
            }
        }
    }
}

/// A saved finding's path: `<target dir>/fuzz-findings/<target>-<n>`.
fn save(target: &str, input: &[u8]) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-findings");
    std::fs::create_dir_all(&dir).unwrap();
    let hash =
        input.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ *b as u64).wrapping_mul(0x100_0000_01b3));
    let path = dir.join(format!("{target}-{hash:016x}"));
    std::fs::write(&path, input).unwrap();
    path
}

/// CPU time (s) used so far by the thread whose `/proc/<pid>/task/<tid>` is `task` (Linux), or
/// `None` where there is no such file: a case's budget is CPU time, so that a machine shared
/// with other work does not turn a slow case into a "hang".
fn thread_cpu_seconds(task: &Path) -> Option<f64> {
    let stat = std::fs::read_to_string(task.join("stat")).ok()?;
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    // After the command name: state is field 3, utime field 14 and stime field 15 (man proc).
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// Runs `run` on the corpus of `target`, then on mutations of it for [`budget`] seconds; every
/// case must end within `case_budget`. Panics (fails the test) on the first finding, naming the
/// saved input. Returns the number of cases run.
pub fn fuzz(
    target: &str,
    tokens: &'static [&'static str],
    case_budget: Duration,
    run: fn(&[u8]) -> Verdict,
) -> u64 {
    let corpus = corpus(target);
    let (to_worker, inputs) = mpsc::channel::<Vec<u8>>();
    let (to_main, verdicts) = mpsc::channel::<Result<Verdict, String>>();
    std::thread::Builder::new()
        .name(format!("fuzz-{target}"))
        .stack_size(64 << 20)
        .spawn(move || {
            let _ = to_main.send(Err(std::fs::read_link("/proc/thread-self")
                .map(|p| Path::new("/proc").join(p).display().to_string())
                .unwrap_or_default()));
            for input in inputs {
                let outcome = std::panic::catch_unwind(|| run(&input)).map_err(|panic| {
                    panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default()
                });
                if to_main.send(outcome).is_err() {
                    return;
                }
            }
        })
        .unwrap();
    // The worker's first message names its /proc task directory (empty where there is none).
    let task = match verdicts.recv() {
        Ok(Err(path)) if !path.is_empty() => Some(PathBuf::from(path)),
        _ => None,
    };
    let seed = seed();
    let mut rng = StdRng::seed_from_u64(seed);
    let start = Instant::now();
    let (mut cases, mut longest) = (0u64, Duration::ZERO);
    // The case that used the most CPU time, kept so that a slow input can be studied before
    // it becomes a hang on a slower machine.
    let (mut slowest_cpu, mut slowest) = (0.0f64, Vec::new());
    let mut next = 0usize;
    loop {
        let input = if next < corpus.len() {
            next += 1;
            corpus[next - 1].1.clone()
        } else {
            if start.elapsed().as_secs_f64() >= budget() {
                break;
            }
            let mut input = corpus[rng.random_range(0..corpus.len())].1.clone();
            for _ in 0..rng.random_range(1..=4) {
                mutate_once(&mut rng, &mut input, &corpus, tokens);
            }
            input
        };
        let began = Instant::now();
        let cpu_before = task.as_deref().and_then(thread_cpu_seconds);
        to_worker.send(input.clone()).unwrap();
        // A case is over budget when its CPU time is (or, without /proc, its wall time); a
        // machine busy with other work gets up to 20 times the budget in wall time.
        let outcome = loop {
            match verdicts.recv_timeout(case_budget.min(Duration::from_secs(1))) {
                Ok(outcome) => break Ok(outcome),
                Err(_) => {
                    let cpu = cpu_before
                        .zip(task.as_deref().and_then(thread_cpu_seconds))
                        .map(|(before, now)| now - before);
                    let used = cpu.unwrap_or_else(|| began.elapsed().as_secs_f64());
                    if used > case_budget.as_secs_f64() || began.elapsed() > 20 * case_budget {
                        break Err(used);
                    }
                }
            }
        };
        longest = longest.max(began.elapsed());
        if let Some(cpu) = cpu_before.zip(task.as_deref().and_then(thread_cpu_seconds)).map(|(b, a)| a - b) {
            if cpu > slowest_cpu {
                (slowest_cpu, slowest) = (cpu, input.clone());
            }
        }
        cases += 1;
        let problem = match outcome {
            Ok(Ok(Ok(()))) => continue,
            Ok(Ok(Err(wrong))) => format!("wrong result: {wrong}"),
            Ok(Err(panic)) => format!("panic: {panic}"),
            Err(used) => format!("no answer after {used:.1} s of CPU, budget {case_budget:?} (a hang)"),
        };
        let path = save(target, &input);
        panic!("fuzz {target} (seed {seed}, case {cases}): {problem}; input saved as {}", path.display());
    }
    let slowest_note = if slowest_cpu >= 1.0 {
        format!(", saved as {}", save(&format!("{target}-slowest"), &slowest).display())
    } else {
        String::new()
    };
    eprintln!(
        "fuzz {target}: {cases} cases in {:.1} s (seed {seed}), longest case {:.3} s, most CPU {slowest_cpu:.2} s{slowest_note}",
        start.elapsed().as_secs_f64(),
        longest.as_secs_f64()
    );
    cases
}

/// `Err` naming the first non-finite entry of `values` (`what`), for a target's verdict.
pub fn finite(what: &str, values: &[f64]) -> Verdict {
    match values.iter().position(|x| !x.is_finite()) {
        None => Ok(()),
        Some(i) => Err(format!("{what}[{i}] = {} returned as Ok", values[i])),
    }
}
