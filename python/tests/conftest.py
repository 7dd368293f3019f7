"""Shared fixtures: the repository's files (every file a test reads is inside the repository)
and the command-line tool built from the same sources."""

import os
import shutil
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo() -> Path:
    """The repository's root (the folder of the root Cargo.toml)."""
    return REPO


@pytest.fixture(scope="session")
def cli() -> str:
    """The `gelenk` command-line tool: $GELENK_CLI (set by .ci/run, which builds it first; a
    missing file there is a failure), else target/release/gelenk or one on PATH; skipped when
    none is built."""
    given = os.environ.get("GELENK_CLI")
    if given:
        assert Path(given).is_file(), f"GELENK_CLI={given} does not exist"
        return given
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    for candidate in (target / "release" / "gelenk", shutil.which("gelenk")):
        if candidate and Path(candidate).is_file():
            return str(candidate)
    pytest.skip("no gelenk binary: build it with `cargo build --release` or set GELENK_CLI")
