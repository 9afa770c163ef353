r"""Contact in implicit dynamics: the initial acceleration of a body that starts within reach of a barrier.

A free unit cube rests at :math:`\hat d/2` above a rigid plane, with no load and
no velocity: the only force at :math:`t = 0` is the barrier's, so Newton's second
law for the whole body gives :math:`\int_\Omega \rho\, a_0\, dX = F_\text{contact}`
(the internal forces sum to zero). Without the barrier force (as before) the body
would start with :math:`a_0 = 0`. Serially and on 2 ranks.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

pytest.importorskip("ipctk")

import hyperfem as hf  # noqa: E402
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.contact import PlaneContact  # noqa: E402

DHAT = 1e-3
RHO = 2.0


def _resting_cube(comm):
    mesh = dmesh.create_unit_cube(comm, 3, 3, 3)
    domain = hf.Domain.from_locators(mesh, {"bottom": lambda x: np.isclose(x[2], 0.0)}, source="cube(3)")
    params = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
    base = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params))
    problem = dyn.IncrementalProblem(base, dyn.Newmark(), dyn.MassDensity(RHO))
    contact = PlaneContact("bottom", point=(0.0, 0.0, -DHAT / 2), normal=(0.0, 0.0, 1.0), dhat=DHAT).bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[contact], check_rigid_motion=False)
    return problem, contact, solver


def _momentum_rate(problem) -> np.ndarray:
    """:math:`\\int \\rho a_0\\,dX`, every component (collective)."""
    a = problem.a
    domain = problem.base.domain
    rates = [fem.assemble_scalar(fem.form(RHO * a[i] * ufl.dx(domain=domain.mesh))) for i in range(3)]
    return np.array([domain.comm.allreduce(r, op=MPI.SUM) for r in rates])


def test_initial_acceleration_feels_the_barrier():
    problem, contact, solver = _resting_cube(MPI.COMM_WORLD)
    problem.initial_acceleration()
    assert np.allclose(_momentum_rate(problem), 0.0, atol=1e-14)  # without it: the barrier force is not seen
    problem.initial_acceleration(external=solver.external.gradient_array)
    force = contact.force()
    assert force[2] > 0.0 and np.allclose(force[:2], 0.0, atol=1e-12 * force[2])
    np.testing.assert_allclose(_momentum_rate(problem), force, rtol=1e-8, atol=1e-10 * force[2])
