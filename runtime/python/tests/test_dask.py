"""docs/verify.md's Dask example, run as written (fewer runs): shards on a `LocalCluster`,
merged with `verify_merge`, must give one process's `runs.csv` and `report.json`, byte for
byte. Skipped where dask is not installed (.ci/python installs it)."""

import os
import re
import subprocess
import sys

import pytest

from conftest import run_cli

pytest.importorskip("dask.distributed", reason="dask is not installed (pip install \"dask[distributed]\")")

MARK = "<!-- ci: dask -->"


def documented_example(root) -> str:
    text = (root / "docs" / "verify.md").read_text(encoding="utf-8")
    after = text.split(MARK, 1)
    assert len(after) == 2, f"docs/verify.md has no {MARK}"
    block = re.match(r"\s*```python\n(.*?)\n```", after[1], re.S)
    assert block, f"docs/verify.md has no ```python block after {MARK}"
    return block.group(1)


def test_the_documented_dask_example_merges_to_the_single_process_batch(
        root, softcbf_bin, tmp_path):
    code, replaced = re.subn(r"^RUNS = \d+$", "RUNS = 8", documented_example(root), flags=re.M)
    assert replaced == 1, "the example has no `RUNS = N` line to make smaller"
    (tmp_path / "verify_dask.py").write_text(code, encoding="utf-8")
    for folder in ["scenarios", "robots"]:
        os.symlink(root / folder, tmp_path / folder)
    example = subprocess.run([sys.executable, "verify_dask.py"], cwd=tmp_path,
                             capture_output=True, text=True, timeout=600)
    assert example.returncode == 0, example.stdout + example.stderr

    single = run_cli(softcbf_bin, "verify", "--scenario", "scenarios/verify-paper.toml",
                     "--runs", 8, "--out", "single", cwd=tmp_path, check=False)
    assert single.returncode in (0, 3), single.stderr
    for name in ["runs.csv", "report.json"]:
        assert (tmp_path / "verify" / name).read_bytes() == \
            (tmp_path / "single" / name).read_bytes(), name
    assert sorted(os.listdir(tmp_path / "shards")) == [str(k) for k in range(8)]
    assert re.search(rf"^8 runs, \d+ unsafe \(exit status {single.returncode}\): "
                     r"verify/report.json$", example.stdout, re.M), example.stdout
