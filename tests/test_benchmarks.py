"""The benchmark scripts keep running (smoke mode: tiny meshes; timings are not checked)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.serial
def test_scale_smoke():
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "scale.py"), "--smoke"], capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr[-2000:]
    rows = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    runs = [r for r in rows if not r.get("summary")]
    assert len(runs) == 4 and all("error" not in r for r in runs)
    summary = rows[-1]
    # hyperfem and the plain-DOLFINx baseline solve the same problem
    assert all(d < 1e-8 for d in summary["test_point_rel_diff_vs_baseline"].values())


@pytest.mark.serial
def test_scale_smoke_mixed():
    """The three-field problem with the Schur field split and the plain-DOLFINx LU baseline agree."""
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "scale.py"), "--smoke", "--formulation", "mixed",
         "--variants", "hyperfem-iterative", "baseline"],
        capture_output=True, text=True, timeout=600,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    runs = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{") and "summary" not in line]
    assert len(runs) == 4 and all("error" not in r for r in runs)
    assert {r["linear_solver"] for r in runs} == {"fgmres+fieldsplit", "preonly+lu(mumps)"}
    for N in (2, 3):
        a, b = (np.array(r["test_point"]) for r in runs if r["N"] == N)
        assert np.linalg.norm(a - b) < 1e-8 * np.linalg.norm(b)


@pytest.mark.serial
def test_step_filter_smoke():
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "step_filter.py"), "--meshes", str(ROOT / "meshes" / "beam_h2.msh"),
         "--cases", "bend", "--scales", "20"],
        capture_output=True, text=True, timeout=600,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    runs = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{") and "summary" not in line]
    assert runs and all(r["converged"] for r in runs)


@pytest.mark.serial
def test_projected_newton_smoke():
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "projected_newton.py"), "--smoke"],
        capture_output=True, text=True, timeout=600,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    rows = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    assert len(rows) == 4 and all(r["converged"] for r in rows)
    d0 = rows[0]["test_point_displacement"]
    assert all(max(abs(a - b) for a, b in zip(r["test_point_displacement"], d0, strict=True)) < 1e-6 for r in rows)


@pytest.mark.serial
def test_checkpoint_io_smoke():
    """The checkpoint cost script runs; what it reads back is what it wrote."""
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "checkpoint_io.py"), "--sizes", "3"],
        capture_output=True, text=True, timeout=600,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    (row,) = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    assert row["unknowns"] == 3 * 7 * 4 * 4 and row["same_ranks_error"] == 0.0 and row["bytes"] > 0
