"""The contact force, traction and gap fields (issue 19 outputs): :class:`~hyperfem.contact.ContactField`.

Their sums are the recorded totals: the nodal forces add up to ``<name>_force``, the tractions times the
lumped areas too; the gap is the recorded smallest distance at the contact nodes and the distance to the
obstacle away from it; the series is written as VTX frames.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

ipctk = pytest.importorskip("ipctk")

import hyperfem as hf  # noqa: E402
from hyperfem.contact import ContactField, PlaneContact, ToolContact  # noqa: E402
from hyperfem.simulation import Recorder, Simulation  # noqa: E402
from test_contact import DHAT, _block  # noqa: E402
from test_contact_surfaces import PLATE, PLATE_TRIANGLES  # noqa: E402


def _owned_sum(function) -> np.ndarray:
    space = function.function_space
    owned = space.dofmap.index_map.size_local * space.dofmap.index_map_bs
    local = function.x.array[:owned].reshape(-1, 3).sum(axis=0)
    return space.mesh.comm.allreduce(local, op=MPI.SUM)


@pytest.mark.parametrize("kind", ["plane", "tool"])
def test_contact_field_sums_to_the_recorded_force(kind, shared_tmp):
    """The pressed cube: the field's nodal forces sum to the contact force, its tractions times the areas too; the
    traction is the uniaxial stress (about 0.24 Pa here) on the bottom, the gap within dhat there; frames written."""
    problem = _block(n=3, delta=0.2)
    if kind == "plane":
        contact = PlaneContact("bottom", point=(0.0, 0.0, -DHAT / 2), normal=(0.0, 0.0, 1.0), dhat=DHAT)
    else:
        contact = ToolContact.from_arrays(["bottom"], PLATE, PLATE_TRIANGLES, dhat=DHAT)
    barrier = contact.bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10}, external_energies=[barrier])
    field = ContactField(shared_tmp / f"{kind}.bp", [barrier])
    summary = Simulation(problem, solver, hf.StepPolicy(increment=0.5), [Recorder(barrier), field]).run()
    force = barrier.force()
    assert _owned_sum(field.force) == pytest.approx(force, rel=1e-12, abs=1e-12 * force[2])
    space = field.force.function_space
    owned = space.dofmap.index_map.size_local * space.dofmap.index_map_bs
    weighted = (field.traction.x.array[:owned] * field._area[:owned]).reshape(-1, 3).sum(axis=0)
    assert MPI.COMM_WORLD.allreduce(weighted, op=MPI.SUM) == pytest.approx(force, rel=1e-12, abs=1e-12 * force[2])
    tz = field.traction.x.array[:owned].reshape(-1, 3)[:, 2]
    inner = tz[np.abs(tz) > 0.0]
    mean = MPI.COMM_WORLD.allreduce(float(inner.sum()), op=MPI.SUM) / MPI.COMM_WORLD.allreduce(len(inner), op=MPI.SUM)
    assert mean == pytest.approx(force[2], rel=0.3)  # the stress over the unit area: corners and edges differ
    assert summary["files"]["contact_vtx"].endswith(f"{kind}.bp") and (shared_tmp / f"{kind}.bp").is_dir()
    # The gap: finite; on the bottom within (0, dhat], its smallest value the recorded min distance; on the top the
    # distance to the plane (height 0.8 + dhat/2), or for the tool dhat (out of reach of every pair).
    gap = field.gap.x.array
    assert field.gap.name == "contact_gap" and np.all(np.isfinite(gap))
    X = field.gap.function_space.tabulate_dof_coordinates()
    comm = MPI.COMM_WORLD
    bottom, top = gap[np.isclose(X[:, 2], 0.0)], gap[np.isclose(X[:, 2], 1.0)]
    low = comm.allreduce(float(bottom.min()) if len(bottom) else np.inf, op=MPI.MIN)
    high = comm.allreduce(float(bottom.max()) if len(bottom) else -np.inf, op=MPI.MAX)
    assert low == pytest.approx(barrier.min_distance(), rel=1e-10) and 0.0 < low <= high <= DHAT
    far = 0.8 + DHAT / 2 if kind == "plane" else DHAT
    assert np.allclose(top, far, rtol=1e-10, atol=0.0)


def test_case_files_write_the_contact_field_beside_the_fields():
    """A case with [[contact]] and fields writes <name>_contact.bp too (the script shows the output)."""
    from pathlib import Path

    from hyperfem.app.casefile import load_case
    from hyperfem.app.script import script

    root = Path(__file__).resolve().parents[1]
    text = script(load_case(root / "cases" / "block_on_plane.toml"))
    assert "ContactField(out / 'block_on_plane_contact.bp', [contact])" in text
    quiet = script(load_case(root / "cases" / "block_on_plane.toml", ["output.fields=[]"]))
    assert "ContactField" not in quiet
