//! Islands: a step's constraint problem is solved as independent problems, one per group of
//! multibodies touching each other (through contacts, joint rows or loop closures), and with the
//! `parallel` feature on several threads — with the same trajectory, bit for bit, on any number
//! of threads. A thread count of 0 is a typed error, in the API and in a scene file.

use gelenk::io::scene::{self, Scene};
use gelenk::world::StepError;
use std::path::{Path, PathBuf};

fn models() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models")
}

/// FNV-1a over the bits of every multibody's q and v.
fn state_hash(scene: &Scene) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for m in 0..scene.world.multibody_count() {
        let state = &scene.world.multibody(m).state;
        for x in state.q.iter().chain(state.v.iter()) {
            for byte in x.to_bits().to_le_bytes() {
                hash ^= u64::from(byte);
                hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
    }
    hash
}

/// The twenty-ragdoll pile at 1/60 s for `steps` steps on `threads` threads: the state's hash,
/// the most islands of a step, and the steps solved as more than one island.
fn pile(threads: usize, steps: usize) -> (u64, usize, usize) {
    let mut s = scene::load_file(models().join("ragdoll_pile.toml")).unwrap();
    s.world.set_threads(threads).unwrap();
    assert_eq!(s.world.threads(), threads);
    let (mut most, mut split) = (0, 0);
    for step in 0..steps {
        s.world.step().unwrap_or_else(|e| panic!("{threads} threads, step {step}: {e}"));
        let stats = s.world.stats();
        most = most.max(stats.islands);
        split += usize::from(stats.islands > 1);
        assert!(stats.largest_island <= stats.rows);
    }
    (state_hash(&s), most, split)
}

#[test]
#[cfg(feature = "parallel")]
fn the_pile_is_the_same_bit_for_bit_on_one_two_and_four_threads() {
    // 150 steps of 2 ms: the ragdolls fall apart (one island each, their joint-limit rows) and
    // the first ones land on each other.
    let (one, most, split) = pile(1, 150);
    assert!(most >= 10, "the falling ragdolls are separate islands (at most {most} in a step)");
    assert!(split >= 100, "{split} of 150 steps split");
    for threads in [2, 4] {
        let (hash, ..) = pile(threads, 150);
        assert_eq!(hash, one, "{threads} threads give another trajectory than one");
    }
}

#[test]
fn a_thread_count_of_zero_is_refused() {
    let mut s = scene::load_file(models().join("ragdoll_fall.toml")).unwrap();
    assert!(matches!(s.world.set_threads(0), Err(StepError::Threads(_))));
    assert_eq!(s.world.threads(), 1, "a refused count leaves the setting as it was");
    #[cfg(not(feature = "parallel"))]
    assert!(matches!(s.world.set_threads(2), Err(StepError::Threads(_))));
}

#[test]
fn a_scene_with_zero_threads_is_an_error_naming_its_line() {
    let text = std::fs::read_to_string(models().join("ragdoll_fall.toml")).unwrap();
    let text = text.replace("[world]\n", "[world]\nthreads = 0\n");
    let dir = std::env::temp_dir().join(format!("gelenk-islands-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(models().join("ragdoll.urdf"), dir.join("ragdoll.urdf")).unwrap();
    let path = dir.join("zero_threads.toml");
    std::fs::write(&path, text).unwrap();
    let Err(error) = scene::load_file(&path) else { panic!("threads = 0 is refused") };
    let message = error.to_string();
    assert!(message.contains("line 8") && message.contains("threads"), "{message}");
    let _ = std::fs::remove_dir_all(&dir);
}
