"""The fusiform-muscle demo runs (serially and on 2 ranks, with the same numbers) and behaves physically."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from hyperfem.problem.mixed import VOLUME_CONSISTENCY_LIMIT

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "demos" / "muscle.py"
# Committed (gmsh 4.15, h = 8 mm, default geometry): a gmsh of another version meshes differently.
MESH = ROOT / "meshes" / "fusiform_h8mm.msh"

# Serial run of `demos/muscle.py --mesh meshes/fusiform_h8mm.msh --steps 3` (268 cells, three-field P2/P1/P1,
# 2180 dofs); 2 ranks must agree. The old two-field ln J form gave 1.4591467, 2.6522203, 3.6820586 N, bulge
# 1.31992 mm and shortening 13.04143 mm (0.2-0.6 % apart; 0.05-0.4 % at the default h = 0.005: discretisation error).
EXPECTED_REACTION = [0.0, 1.462016213502715, 2.6628865684311207, 3.7043146383794987]
EXPECTED_BULGE = 0.0013229982720117366
EXPECTED_SHORTENING = 0.013068608770634121


@pytest.fixture(scope="module")
def summary(tmp_path_factory):
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("muscle")), root=0))
    spec = importlib.util.spec_from_file_location("demo_muscle", DEMO)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    result = module.main(["--mesh", str(MESH), "--steps", "3", "--output", str(folder)])
    result["folder"] = folder
    return result


def test_demo_outputs(summary):
    folder = summary["folder"]
    assert summary["ranks"] == MPI.COMM_WORLD.size
    written = json.loads((folder / "muscle.json").read_text())
    assert written["activations"] == pytest.approx([0.0, 1 / 3, 2 / 3, 1.0])
    for kind in ("isometric", "free"):
        assert (folder / f"muscle_{kind}_u.bp").is_dir()
        assert (folder / f"muscle_{kind}_cells.bp").is_dir()


def test_isometric_reaction_rises_with_activation(summary):
    forces = np.array(summary["isometric_reaction"])
    assert abs(forces[0]) < 1e-9  # passive, unloaded
    assert np.all(np.diff(forces) > 0)
    np.testing.assert_allclose(forces, EXPECTED_REACTION, rtol=1e-6, atol=1e-9)
    # clamped ends: the lateral reaction components vanish by symmetry (up to the mesh)
    last = summary["isometric"]["steps"][-1]["reaction_insertion"]
    assert abs(last[0]) < 0.05 * last[2] and abs(last[1]) < 0.05 * last[2]


def test_bulge_and_shortening(summary):
    assert summary["isometric_bulge"] == pytest.approx(EXPECTED_BULGE, rel=1e-6)
    assert summary["free_shortening"] == pytest.approx(EXPECTED_SHORTENING, rel=1e-6)
    bulges = [row["max_radial_bulge"] for row in summary["isometric"]["steps"]]
    assert np.all(np.diff(bulges) > 0)
    # free contraction: the insertion moves towards the origin as activation rises
    uz = [row["insertion_uz"] for row in summary["free"]["steps"]]
    assert uz[0] > 0 and np.all(np.diff(uz) < 0)


def test_volume_consistency(summary):
    """J is resolved by the volume field at every step (measured up to 0.034 on this mesh)."""
    for kind in ("isometric", "free"):
        eta = [row["volume_consistency"] for row in summary[kind]["steps"]]
        assert max(eta) < 0.5 * VOLUME_CONSISTENCY_LIMIT


def test_free_contraction_equilibrium(summary):
    """The internal force at the (free) insertion face equals the applied dead traction at every step.

    Up to the Newton tolerance (rtol 1e-9 of the first residual): 1.6e-9 relative was measured,
    so 1e-6 is machine-independent and still catches a wrong reaction or load.
    """
    free = summary["free"]
    applied = 2.0e3 * free["insertion_area"]
    for row in free["steps"]:
        assert row["reaction_insertion"][2] == pytest.approx(applied, rel=1e-6)
