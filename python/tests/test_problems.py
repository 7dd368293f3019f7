"""The problem-corpus loader: every problem of tests/problems/ reads into numpy/scipy arrays whose
cone program is the problem's own (P = upper triangle of A + R, q = b), and the reference
solutions of meta.json satisfy w = P λ + q; export_problems writes problems that load again."""

import numpy as np
import pytest

import gelenk
from gelenk import problems


def test_the_corpus_loads_with_consistent_arrays(repo):
    corpus = problems.corpus(repo / "tests/problems")
    assert len(corpus) >= 20
    for p in corpus:
        n = p.rows
        assert p.P.shape == (n, n) and p.q.shape == (n,)
        m = sum(dim for _, dim in p.cones)
        assert p.A.shape == (m, n) and p.b.shape == (m,), p
        c = p.constraint
        assert c["A"].shape == (n, n) and c["b"].shape == (n,) and len(c["laws"]) == n
        upper = np.triu(c["A"] + np.diag(c["R"]))
        P = p.P.toarray() if hasattr(p.P, "toarray") else p.P
        assert np.array_equal(P, upper), f"{p.path.name}: P is the upper triangle of A + R"
        assert np.array_equal(p.q, c["b"])
        has_soc = any(kind == "soc" for kind, _ in p.cones)
        assert (p.qp is None) == has_soc, f"{p.path.name}: qp.npz exactly when there is no friction cone"
        assert p.lcp is not None and set(p.lcp) == {"M", "q", "C", "c0"}
        assert p.meta["rows"] == n and p.meta["contacts"] == len(c["normal_rows"])
        if p.qp is not None:
            assert p.qp["P"].shape == (n, n)


def test_the_reference_solutions_satisfy_the_loaded_program(repo):
    """meta.json's impulses λ and row velocities w obey w = P λ + q with the loaded arrays."""
    checked = 0
    for p in problems.corpus(repo / "tests/problems"):
        for name, solution in p.meta["solutions"].items():
            if solution["lambda"] is None:
                continue
            lam, w = np.array(solution["lambda"]), np.array(solution["w"])
            scale = max(1.0, np.abs(w).max())
            assert np.abs(p.P_full() @ lam + p.q - w).max() <= 1e-9 * scale, f"{p.path.name} {name}"
            checked += 1
    assert checked >= 60


def test_exported_problems_load(tmp_path):
    written = gelenk.export_problems("box-drop", tmp_path, steps=70, friction="pyramid", only=[15, 64])
    loaded = problems.corpus(tmp_path)
    assert written == len(loaded) == 2
    assert [p.path.name for p in loaded] == ["step-0015", "step-0064"]
    assert all(p.constraint["friction"] == "pyramid4" and p.qp is not None for p in loaded)
    one = problems.load(tmp_path / "step-0064" / "problem.json")
    assert np.array_equal(one.P_full(), loaded[1].P_full())
    with pytest.raises(ValueError, match="unknown friction model"):
        gelenk.export_problems("box-drop", tmp_path, steps=1, friction="cube")
    with pytest.raises(ValueError, match="no-such-scene"):
        gelenk.export_problems("no-such-scene", tmp_path, steps=1)


def test_a_broken_problem_file_is_a_value_error_naming_it(tmp_path, repo):
    source = repo / "tests/problems/box-flat-0000"
    for f in source.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    (tmp_path / "problem.json").write_text('{"format": "gelenk-constraint-problem", "version": 1}')
    with pytest.raises(ValueError, match="problem.json"):
        problems.load(tmp_path)
