"""A full disk ends a run with one line, exit 1, and no half-written files.

Before: one clean line, then an ADIOS2 ``terminate`` from the destructor of
the ParaView writer and SIGABRT (exit 134), and stray ``.partial`` files.
Needs a small file system: a 600 kB tmpfs, mounted by the test where it may
mount (root); skipped elsewhere.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from case_texts import ROOT

pytestmark = pytest.mark.serial


@pytest.fixture
def small_disk(tmp_path):
    mount = tmp_path / "small"
    mount.mkdir()
    if shutil.which("mount") is None or os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=600k", "tmpfs", str(mount)], capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", str(mount)], capture_output=True)


def _env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "MPICH_"))}
    env["PYTHONWARNINGS"] = "ignore"
    return env


@pytest.mark.parametrize("ranks, checkpoint", [(1, True), (1, False), (2, False)])
def test_a_full_disk_is_one_line_and_exit_1(small_disk, ranks, checkpoint):
    out = small_disk / "out"
    cmd = [sys.executable, "-m", "hyperfem.app.main", "run", str(ROOT / "cases" / "dynamics_bend.toml"),
           "--set", "stepping.t_end=30", "--output", str(out)]
    if not checkpoint:
        cmd += ["--set", "output.checkpoint=false"]
    if ranks > 1:
        mpiexec = Path(sys.executable).parent / "mpiexec"
        if not mpiexec.exists():
            pytest.skip("no mpiexec beside the interpreter")
        cmd = [str(mpiexec), "-n", str(ranks), *cmd]
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=_env(), cwd=ROOT)
    assert result.returncode == 1, result.stderr[-2000:]
    # Only hyperfem's own lines: an MPI launcher may add its own banner about the exit status.
    lines = [line for line in result.stderr.splitlines() if line.startswith("hyperfem:")]
    assert len(lines) == 1, result.stderr[-2000:]
    assert "terminate called" not in result.stderr and "Traceback" not in result.stderr, result.stderr[-2000:]
    assert lines[0].startswith("hyperfem: error: cannot write ") and lines[0].endswith(": No space left on device")
    assert not list(small_disk.rglob("*.partial")), sorted(map(str, small_disk.rglob("*")))
