"""The benchmark scripts keep running (smoke mode: tiny meshes; timings are not checked)."""

import json
import subprocess
import sys
from pathlib import Path

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
