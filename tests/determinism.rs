//! Pinned trajectories: three shipped scenes (the ragdoll's fall, the 10-box stack settling, the
//! buggy driving off and into a turn) are stepped from their files and the bits of every
//! multibody's q and v are hashed. The hashes are constants here, as in Box2D's
//! `test_determinism.c`: any change to the last bit of a trajectory — a reordered sum, another
//! rounding, a changed default — fails this test, so that it is seen and stated.
//!
//! The step uses no fused multiply-add and no fast-math, so debug and release builds give the
//! same bits (both are checked by running this test in each profile). The constants are pinned
//! for x86-64 Linux: the step calls the C library's `sin`, `cos`, `acos` and `atan2`, whose last
//! bits may differ on another platform's libm; elsewhere only run-to-run identity is checked.

use gelenk::io::scene::{self, Scene};
use std::path::{Path, PathBuf};

/// One pinned run: a scene of `models/`, how many steps, and the hash after them.
struct Pinned {
    scene: &'static str,
    steps: usize,
    hash: u64,
}

/// The ragdoll lands at about 0.5 s and is sliding to rest at 1.5 s; the box stack's 1 mm gaps
/// close and it settles; the buggy settles on its springs, drives off at 0.5 s and steers into
/// its circle at 4 s.
const PINNED: [Pinned; 3] = [
    Pinned { scene: "ragdoll_fall.toml", steps: 750, hash: 0x051a_ae62_984b_74e3 },
    Pinned { scene: "box_stack10.toml", steps: 500, hash: 0x9c10_0ef2_4fb8_34c3 },
    Pinned { scene: "buggy_drive.toml", steps: 2250, hash: 0xd156_bbe5_0d9e_64c4 },
];

const UPDATE_RULE: &str = "A change that alters the last bits of a trajectory must update this \
constant in tests/determinism.rs in the same commit, and its commit message must say why the \
trajectory changed. If the change was not meant to alter any result, find what did.";

fn models() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models")
}

/// FNV-1a over the little-endian bits of every multibody's q, then v, in multibody order, and of
/// the world's time.
fn state_hash(scene: &Scene) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |x: f64| {
        for byte in x.to_bits().to_le_bytes() {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(scene.world.time());
    for m in 0..scene.world.multibody_count() {
        let state = &scene.world.multibody(m).state;
        state.q.iter().chain(state.v.iter()).for_each(|&x| eat(x));
    }
    hash
}

/// Steps the scene as `gelenk simulate` does (vehicle commands applied before each step).
fn run(pinned: &Pinned) -> u64 {
    let mut s = scene::load_file(models().join(pinned.scene)).unwrap();
    for step in 0..pinned.steps {
        s.apply_controls().unwrap();
        s.world.step().unwrap_or_else(|e| panic!("{} step {step}: {e}", pinned.scene));
    }
    state_hash(&s)
}

#[test]
fn pinned_trajectories_keep_their_hashes() {
    let mut report = Vec::new();
    for pinned in &PINNED {
        let (first, second) = (run(pinned), run(pinned));
        assert_eq!(first, second, "{}: two runs in one process differ", pinned.scene);
        if first != pinned.hash {
            report.push(format!(
                "{} after {} steps: hash {first:#018x}, pinned {:#018x}",
                pinned.scene, pinned.steps, pinned.hash
            ));
        }
    }
    let pinned_platform = cfg!(all(target_arch = "x86_64", target_os = "linux"));
    if !report.is_empty() {
        let message = format!("{}\n{UPDATE_RULE}", report.join("\n"));
        if pinned_platform {
            panic!("{message}");
        }
        eprintln!("not x86-64 Linux, where the constants are pinned (libm may differ): {message}");
    }
}

#[test]
fn the_hash_sees_the_last_bit() {
    let mut s = scene::load_file(models().join("box_stack10.toml")).unwrap();
    s.world.step().unwrap();
    let before = state_hash(&s);
    let v = &mut s.world.multibody_mut(0).state.v;
    v[0] = f64::from_bits(v[0].to_bits() ^ 1);
    assert_ne!(state_hash(&s), before, "one flipped bit of one velocity changes the hash");
}
