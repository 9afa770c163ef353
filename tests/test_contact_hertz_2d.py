r"""Hertz in plane strain (issue 19): a rigid cylinder (a disc, R = 0.5) pressed 0.01 into an elastic square.

The 2D counterpart of ``test_contact_hertz.py``: half of a unit square (a roller on
its symmetry line :math:`x = 0`, the bottom held) with the cells crowded toward the
contact (half of them in the top and left fifth), Neo-Hookean with :math:`E = 1`,
:math:`\nu = 0.3`, and a rigid disc (:class:`~hyperfem.contact.SphereContact` in 2D)
moved down onto the top edge. For a rigid cylinder on an elastic half-space the
contact half-width under the force :math:`P` per unit length is

.. math::
    b = \sqrt{\frac{4PR}{\pi E^*}}, \qquad E^* = \frac{E}{1-\nu^2},

with the elliptic pressure :math:`p(x) = p_0\sqrt{1 - x^2/b^2}`, whose second moment
gives :math:`b` from the nodal contact forces: :math:`b_h^2 = 4\sum_k f_k x_k^2/\sum_k f_k`.
Measured (``b_h/b``): 0.978 with 32 and 0.988 with 64 cells per side (0.976, 0.981,
0.985 with 32, 64, 128 at twice the depth), the force balancing the bottom's reaction
to round-off. The 1 % left is the finite square (the half-space is 19 half-widths
deep here) and the finite strain (:math:`b/R \approx 0.1`).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI

import hyperfem as hf
from dolfinx import mesh as dmesh
from hyperfem.contact import SphereContact
from hyperfem.simulation.reactions import ReactionForce

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
R, DEPTH, DHAT = 0.5, 0.01, 1e-4


def _crowded(t: np.ndarray, near: float = 0.2) -> np.ndarray:
    """The unit interval with half of its cells in ``[0, near]`` (piecewise linear)."""
    return np.where(t < 0.5, 2.0 * near * t, near + (t - 0.5) * 2.0 * (1.0 - near))


def _indent(n: int, comm: MPI.Comm = MPI.COMM_WORLD) -> dict:
    """The disc pressed ``DEPTH`` into the half square of ``n x n`` cells: half-width, force, reaction, gap."""
    mesh = dmesh.create_unit_square(comm, n, n)
    x = mesh.geometry.x
    x[:, 0], x[:, 1] = _crowded(x[:, 0]), 1.0 - _crowded(1.0 - x[:, 1])
    groups = {"top": lambda x: np.isclose(x[1], 1.0), "bottom": lambda x: np.isclose(x[1], 0.0),
              "x0": lambda x: np.isclose(x[0], 0.0)}
    domain = hf.Domain.from_locators(mesh, groups, source=f"half square, {n} x {n}")
    bcs = [hf.PrescribedDisplacement("bottom", [0.0, 0.0]), hf.PrescribedDisplacement("x0", [0.0], components=[0])]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)
    disc = SphereContact("top", center=(0.0, 1.0 + R + DHAT / 2), radius=R, motion=(0.0, -DEPTH), dhat=DHAT)
    tool = disc.bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10, "snes_atol": 1e-12}, external_energies=[tool])
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.25, max_increment=0.25))
    u = problem.u.x.array
    dofs, values = tool.gradient(u)
    where = {int(d): k for k, d in enumerate(tool.nodes.dofs[:, 0])}
    rows = np.array([where[int(d)] for d in dofs[:, 0]], dtype=int)
    at = tool.nodes.positions(u)[rows] if len(rows) else np.zeros((0, 2))
    f = -values[:, 1]
    moments = comm.allreduce(np.array([f.sum(), (f * at[:, 0] ** 2).sum()]))
    force = 2.0 * tool.force()[1]  # both halves, per unit length
    return {
        "b": 2.0 * math.sqrt(moments[1] / moments[0]),
        "hertz": math.sqrt(4.0 * abs(force) * R * (1.0 - 0.3**2) / (math.pi * 1.0)),
        "force": force,
        "reaction": 2.0 * ReactionForce(problem, "bottom")()[1],
        "gap": tool.min_distance(),
    }


def test_cylinder_contact_half_width_converges_to_hertz():
    """b_h/b: 0.978 (32 cells per side) and 0.988 (64); asserted: within 3 % on the finer mesh and closer than on the
    coarser one; the contact force = the bottom's reaction to 1e-8; the disc never reached (gap > 0)."""
    coarse, fine = _indent(32), _indent(64)
    for run in (coarse, fine):
        assert run["force"] == pytest.approx(-run["reaction"], rel=1e-8)
        assert run["gap"] > 0.0
    assert fine["b"] / fine["hertz"] == pytest.approx(1.0, abs=0.03)
    assert abs(fine["b"] / fine["hertz"] - 1.0) < abs(coarse["b"] / coarse["hertz"] - 1.0)


def test_cylinder_contact_one_rank_equals_two_ranks():
    """Half-width, force, reaction and gap (16 cells per side) on the ranks of ``mpiexec -n 2`` equal 1 rank's to
    1e-10."""
    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")
    one = comm.bcast(_indent(16, MPI.COMM_SELF) if comm.rank == 0 else None, root=0)
    many = _indent(16)
    for key in ("b", "force", "reaction", "gap"):
        assert many[key] == pytest.approx(one[key], rel=1e-10), key
