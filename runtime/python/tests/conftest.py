"""Shared fixtures: the checkout, and the `softcbf` command-line binary the package's
results are compared with (built from the same checkout)."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def softcbf_bin() -> Path:
    """The `softcbf` binary: $SOFTCBF_BIN, else target/release/softcbf of the checkout,
    built with cargo if missing. Fails (never skips) when there is none: these tests are the
    package's agreement with the command line."""
    given = os.environ.get("SOFTCBF_BIN")
    if given:
        path = Path(given)
        if not path.is_file():
            pytest.fail(f"SOFTCBF_BIN={given} is not a file")
        return path
    path = ROOT / "target" / "release" / "softcbf"
    if not path.is_file():
        if shutil.which("cargo") is None:
            pytest.fail(f"no {path} and no cargo to build it; set SOFTCBF_BIN")
        subprocess.run(
            ["cargo", "build", "--release", "-p", "softcbf", "--bin", "softcbf"],
            cwd=ROOT,
            check=True,
        )
    return path


def run_cli(binary: Path, *args, cwd=None, check=True) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(binary), *map(str, args)], cwd=cwd, capture_output=True, text=True, check=check
    )
