"""Constraint problems as files, for solver authors: read what ``gelenk export-problems`` (or
:func:`gelenk.export_problems`) writes, and the corpus of ``tests/problems/``.

Each problem directory holds ``problem.json`` (gelenk's own form), ``cone.json`` (the cone
program in clarabel's schema), ``lcp.npz`` (the LCP Lemke's method solves), ``qp.npz`` (only for
problems without second-order cones: the QP in qpsolvers' form) and ``meta.json`` (each reference
solver's status, impulses, objective and residuals). :func:`load` reads one into a
:class:`Problem`; :func:`corpus` reads every problem below a directory.

The cone program is ``minimise ½ xᵀ P x + qᵀ x  subject to  A x + s = b,  s ∈ K``, with ``P`` the
upper triangle of the Delassus matrix plus its regularization, and ``K`` a product of cones
listed in row order as ``(kind, dimension)``: ``"zero"`` (equalities), ``"nonnegative"``, and
``"soc"`` (second-order cones ``‖(s₂, s₃)‖ ≤ s₁``, one per friction cone). ``P`` and ``A`` are
``scipy.sparse.csc_matrix`` when scipy is installed, dense ``numpy.ndarray`` otherwise.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

from ._gelenk import read_problem

__all__ = ["Problem", "load", "corpus", "CONE_NAMES"]

#: clarabel's cone names in cone.json and the short names used here.
CONE_NAMES = {
    "ZeroConeT": "zero",
    "NonnegativeConeT": "nonnegative",
    "SecondOrderConeT": "soc",
}


@dataclass
class Problem:
    """One exported constraint problem.

    Attributes:
        path: the problem's directory.
        P, q, A, b: the cone program ``min ½xᵀPx + qᵀx, Ax + s = b, s ∈ cones`` (P upper
            triangular; scipy CSC matrices when scipy is installed, else dense arrays).
        cones: the cones of the rows of ``A``, in order, as ``(kind, dimension)`` with kind
            ``"zero"``, ``"nonnegative"`` or ``"soc"``.
        constraint: the problem in gelenk's own form ``w = (A + R) λ + b`` (a dict: ``A`` the
            Delassus matrix, ``R``, ``b``, ``target``, ``J``, ``laws``, ``lo``, ``hi``,
            ``normal_rows``, ``mu``, ``mu2``, ``friction``), from problem.json.
        meta: meta.json (each reference solver's status, impulses ``lambda``, velocities ``w``,
            objective, residuals; the tolerances), or None when absent.
        lcp: lcp.npz's arrays (``M``, ``q``, ``C``, ``c0``: the LCP ``w = M z + q`` whose
            solution gives the impulses ``λ = C z + c0``), or None when absent.
        qp: qp.npz's arrays (``P``, ``q``, ``G``, ``h``, ``A``, ``b``, ``lb``, ``ub``: qpsolvers'
            ``min ½xᵀPx + qᵀx, Gx ≤ h, Ax = b, lb ≤ x ≤ ub``), or None (a problem with friction
            cones is not a QP).
    """

    path: Path
    P: Any
    q: np.ndarray
    A: Any
    b: np.ndarray
    cones: List[Tuple[str, int]]
    constraint: Dict[str, Any]
    meta: Optional[Dict[str, Any]] = None
    lcp: Optional[Dict[str, np.ndarray]] = None
    qp: Optional[Dict[str, np.ndarray]] = field(default=None)

    @property
    def rows(self) -> int:
        """Number of constraint rows (impulses)."""
        return int(self.q.shape[0])

    def P_full(self) -> np.ndarray:
        """The symmetric P (dense), from its stored upper triangle."""
        upper = _dense(self.P)
        return upper + upper.T - np.diag(np.diag(upper))

    def __repr__(self) -> str:
        cones = ", ".join(f"{k}({n})" for k, n in self.cones)
        return f"gelenk.problems.Problem({str(self.path)!r}, rows={self.rows}, cones=[{cones}])"


def _dense(matrix: Any) -> np.ndarray:
    return matrix.toarray() if hasattr(matrix, "toarray") else np.asarray(matrix)


def _csc(entry: Dict[str, Any]) -> Any:
    """A matrix of cone.json (clarabel's CSC: m, n, colptr, rowval, nzval)."""
    m, n = int(entry["m"]), int(entry["n"])
    data = np.asarray(entry["nzval"], dtype=np.float64)
    indices = np.asarray(entry["rowval"], dtype=np.int64)
    indptr = np.asarray(entry["colptr"], dtype=np.int64)
    try:
        from scipy.sparse import csc_matrix
    except ImportError:
        dense = np.zeros((m, n))
        for j in range(n):
            for k in range(indptr[j], indptr[j + 1]):
                dense[indices[k], j] = data[k]
        return dense
    return csc_matrix((data, indices, indptr), shape=(m, n))


def _cones(entries: List[Dict[str, Any]], path: Path) -> List[Tuple[str, int]]:
    cones = []
    for entry in entries:
        ((name, dim),) = entry.items()
        if name not in CONE_NAMES:
            raise ValueError(f"{path}: unknown cone {name!r}")
        cones.append((CONE_NAMES[name], int(dim)))
    return cones


def _npz(path: Path) -> Optional[Dict[str, np.ndarray]]:
    if not path.is_file():
        return None
    with np.load(path) as archive:
        return {name: archive[name] for name in archive.files}


def load(path: Union[str, os.PathLike]) -> Problem:
    """Reads the problem in directory ``path`` (or the directory of the ``problem.json`` file
    ``path``). Raises FileNotFoundError when problem.json or cone.json is missing, ValueError
    when a file is not a valid problem (the message names the file)."""
    path = Path(path)
    directory = path.parent if path.is_file() else path
    if not (directory / "problem.json").is_file():
        raise FileNotFoundError(
            f"{directory}: no problem.json (gelenk.problems.corpus reads a directory of problems)"
        )
    constraint = read_problem(str(directory))
    cone_path = directory / "cone.json"
    try:
        with open(cone_path, encoding="utf-8") as f:
            cone = json.load(f)
    except json.JSONDecodeError as e:
        raise ValueError(f"{cone_path}: not valid JSON: {e}") from None
    meta_path = directory / "meta.json"
    meta = None
    if meta_path.is_file():
        with open(meta_path, encoding="utf-8") as f:
            meta = json.load(f)
    problem = Problem(
        path=directory,
        P=_csc(cone["P"]),
        q=np.asarray(cone["q"], dtype=np.float64),
        A=_csc(cone["A"]),
        b=np.asarray(cone["b"], dtype=np.float64),
        cones=_cones(cone["cones"], cone_path),
        constraint=constraint,
        meta=meta,
        lcp=_npz(directory / "lcp.npz"),
        qp=_npz(directory / "qp.npz"),
    )
    if problem.q.shape[0] != constraint["b"].shape[0]:
        raise ValueError(
            f"{cone_path}: {problem.q.shape[0]} variables, but problem.json has "
            f"{constraint['b'].shape[0]} rows"
        )
    return problem


def corpus(directory: Union[str, os.PathLike]) -> List[Problem]:
    """Every problem below ``directory`` (each directory holding a problem.json, found at any
    depth), sorted by path: the corpus ``tests/problems/``, or the output of
    :func:`gelenk.export_problems`. Raises FileNotFoundError when ``directory`` does not exist."""
    directory = Path(directory)
    if not directory.is_dir():
        raise FileNotFoundError(f"{directory}: no such directory")
    found = sorted({p.parent for p in directory.rglob("problem.json")})
    return [load(d) for d in found]
