"""Python gives the command-line tool's numbers bit for bit: `gelenk dynamics` on the reference
states, `gelenk simulate --out` on scenes (a ragdoll falling onto the ground; a buggy driven by
its timed commands), and `gelenk export-problems` writes the same files."""

import json
import subprocess

import numpy as np
import pytest

import gelenk


def run(cli, *args, cwd=None):
    result = subprocess.run([cli, *map(str, args)], capture_output=True, text=True, cwd=cwd)
    assert result.returncode == 0, result.stderr
    return result.stdout


@pytest.mark.parametrize("case", ["ur5", "panda", "solo12_floating"])
def test_dynamics_equal_the_clis(cli, repo, tmp_path, case):
    reference = json.loads((repo / f"tests/data/reference/{case}.json").read_text())
    states = [{k: s[k] for k in ("q", "v", "a", "tau")} for s in reference["states"]]
    path = tmp_path / "states.json"
    path.write_text(json.dumps({"states": states}))
    floating = ["--floating"] if reference["floating_base"] else []
    out = json.loads(run(cli, "dynamics", repo / reference["urdf"], "--states", path, *floating))
    model = gelenk.load_urdf(repo / reference["urdf"], floating=reference["floating_base"])
    data = gelenk.Data(model)
    assert (out["nq"], out["nv"]) == (model.nq, model.nv)
    for s, want in zip(states, out["results"]):
        q, v, a, tau = (np.array(s[k], dtype=float) for k in ("q", "v", "a", "tau"))
        got = {
            "mass_matrix": gelenk.crba(model, data, q),
            "nle": gelenk.nonlinear_effects(model, data, q, v),
            "gravity": gelenk.generalized_gravity(model, data, q),
            "rnea": gelenk.rnea(model, data, q, v, a),
            "aba": gelenk.aba(model, data, q, v, tau),
            "kinetic_energy": gelenk.kinetic_energy(model, data, q, v),
            "potential_energy": gelenk.potential_energy(model, data, q),
            "com": gelenk.center_of_mass(model, data, q),
            "mass": model.mass,
        }
        for key, value in got.items():
            assert np.array_equal(np.asarray(value), np.asarray(want[key])), f"{case}: {key}"


@pytest.mark.parametrize("scene,duration", [("ragdoll_fall.toml", 0.8), ("buggy_drive.toml", 1.5)])
def test_stepping_equals_simulate(cli, repo, tmp_path, scene, duration):
    out = tmp_path / "run.json"
    run(cli, "simulate", repo / "models" / scene, "--duration", duration, "--out", out)
    recording = json.loads(out.read_text())
    world = gelenk.load_scene(repo / "models" / scene)
    labels = world.state_labels()
    columns = [labels.index(c) for c in recording["columns"]]
    rows = recording["rows"]
    assert rows[0]["step"] == 0 and rows[-1]["step"] == round(duration / world.dt) and len(rows) > 10
    contacts = 0
    for row in rows:
        world.step(row["step"] - world.stats["step"])
        got = world.get_state()[columns]
        assert np.array_equal(got, np.array(row["values"])), f"{scene}: step {row['step']}"
        assert world.stats["contacts"] == row["contacts"] and world.stats["rows"] == row["rows"]
        contacts += row["contacts"]
    assert contacts > 0, "the run has contacts"


def test_export_problems_writes_the_clis_files(cli, tmp_path):
    cli_dir, py_dir = tmp_path / "cli", tmp_path / "py"
    run(cli, "export-problems", "stack2", "--steps", "6", "--out", cli_dir, "--friction", "pyramid8")
    written = gelenk.export_problems("stack2", py_dir, steps=6, friction="pyramid8")
    files = sorted(p.relative_to(cli_dir) for p in cli_dir.rglob("*") if p.is_file())
    assert written == 6 and len(files) == 6 * 5
    assert files == sorted(p.relative_to(py_dir) for p in py_dir.rglob("*") if p.is_file())
    for f in files:
        assert (cli_dir / f).read_bytes() == (py_dir / f).read_bytes(), f


def cli_error(cli, *args):
    """The message the command line prints after `gelenk: error: ` (it must fail)."""
    result = subprocess.run([cli, *map(str, args)], capture_output=True, text=True)
    assert result.returncode != 0, result.stdout
    lines = [l for l in result.stderr.splitlines() if l.startswith("gelenk: error: ")]
    assert len(lines) == 1, result.stderr
    return lines[0][len("gelenk: error: "):]


def test_errors_carry_the_clis_message(cli, repo, tmp_path):
    missing = tmp_path / "missing.urdf"
    with pytest.raises(FileNotFoundError) as error:
        gelenk.load_urdf(missing)
    assert str(error.value) == cli_error(cli, "inspect", missing)
    bad_urdf = tmp_path / "bad.urdf"
    bad_urdf.write_text("<robot name='r'><link name='a'/><joint name='j' type='revolute'>"
                        "<parent link='a'/><child link='nowhere'/></joint></robot>")
    with pytest.raises(ValueError) as error:
        gelenk.load_urdf(bad_urdf)
    assert str(error.value) == cli_error(cli, "inspect", bad_urdf)
    bad_scene = tmp_path / "bad.toml"
    bad_scene.write_text("[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\nmass = -1\n")
    with pytest.raises(ValueError) as error:
        gelenk.load_scene(bad_scene)
    assert str(error.value) == cli_error(cli, "simulate", bad_scene, "--duration", 0.1)
