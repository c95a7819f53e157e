"""Shared fixtures: the `companion` CLI (built by cargo, the reference the package is held to)."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def cli():
    """Path of the `companion` binary: $COMPANION_BIN, else target/release/companion (built if missing)."""
    path = pathlib.Path(os.environ.get("COMPANION_BIN", ROOT / "target" / "release" / "companion"))
    if not path.exists():
        subprocess.run(["cargo", "build", "--release", "-p", "companion-runtime", "--bin", "companion"], cwd=ROOT, check=True)
    return path
