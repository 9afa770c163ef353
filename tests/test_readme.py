"""The README's Python examples run as written (from the repository root) and print the P2 answer."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _python_blocks() -> list[str]:
    text = (ROOT / "README.md").read_text()
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


@pytest.mark.serial
def test_readme_python_examples_run_and_print_the_p2_tip_displacement(tmp_path):
    """The first example is P2 and prints the tip displacement; the Simulation example keeps `make demo`'s files."""
    blocks = _python_blocks()
    assert len(blocks) >= 2
    script = tmp_path / "readme.py"
    script.write_text("\n".join(blocks[:2]))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "MPICH_"))}
    # Run in a copy of the layout the README assumes (meshes/ beside the working folder), not in the checkout.
    (tmp_path / "meshes").symlink_to(ROOT / "meshes")
    ran = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=tmp_path,
                         env=env)
    assert ran.returncode == 0, ran.stderr
    match = re.search(r"tip displacement \[\s*(\S+)\s+(\S+)\s+(\S+)\s*\] m", ran.stdout)
    assert match, ran.stdout
    u = [float(v) for v in match.groups()]
    assert u[1] == pytest.approx(-1.2736, rel=2e-3)  # P2, h = 1 (P1 would give -1.063)
    assert (tmp_path / "output" / "first" / "bend.json").is_file()
    assert not (tmp_path / "output" / "bend.json").exists()  # make demo's file is not overwritten
    assert "displacement at (4.5, 1.5, 1.5)" in ran.stdout
