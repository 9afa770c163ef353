"""Every cantilever demo runs (serially, and on 2 ranks when the suite runs under mpiexec).

The demos expose ``main(argv) -> summary``; the summary is also written as
JSON, and the displacement of the test point must equal the library run of
``test_cantilever.py`` (the demos add nothing but output).
"""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

DEMOS = Path(__file__).resolve().parent.parent / "demos"


def load_demo(name: str):
    spec = importlib.util.spec_from_file_location(f"demo_{name}", DEMOS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def shared_tmp(tmp_path):
    """A temporary folder that every rank agrees on."""
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))


@pytest.mark.parametrize(
    "name, expected",
    [
        ("bend", [0.135077318161, -0.852854731738, 0.003404957717]),
        ("twist", [0.000665339655, 0.08590129264, -0.094105853435]),
    ],
)
def test_cantilever_demo(name, expected, shared_tmp):
    demo = load_demo(name)
    mesh = Path(__file__).resolve().parent.parent / "meshes" / "beam_h2.msh"
    summary = demo.main(["--mesh", str(mesh), "--output", str(shared_tmp)])
    assert summary["completed"]
    assert summary["ranks"] == MPI.COMM_WORLD.size
    np.testing.assert_allclose(summary["probe_displacement"][0], expected, rtol=1e-6, atol=1e-9)
    written = json.loads((shared_tmp / f"{name}.json").read_text())
    assert written["load_steps"] == len(written["newton_iterations"]) >= 1
    assert (shared_tmp / f"{name}.bp").is_dir()


def test_demo_generates_mesh(shared_tmp):
    summary = load_demo("bend").main(["--h", "2.5", "--output", str(shared_tmp)])
    assert summary["completed"] and summary["dofs"] > 0


def test_demo_cli_reports_missing_mesh(shared_tmp):
    """The CLI wrapper prints one line and exits 1 (checked in-process)."""
    from hyperfem.cli import run

    demo = load_demo("bend")
    with pytest.raises(SystemExit) as exc:
        run(lambda: demo.main(["--mesh", str(shared_tmp / "missing.msh"), "--output", str(shared_tmp)]))
    assert exc.value.code == 1
