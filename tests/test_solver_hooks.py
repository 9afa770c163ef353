"""NewtonSolver's extension points: a replacement tangent form and state hooks."""

from __future__ import annotations

from mpi4py import MPI  # noqa: F401

import numpy as np
import ufl

import hyperfem as hf
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube


def _problem():
    params = hf.materials.LameParameters.from_youngs(1.0, 0.3)
    return hf.HyperelasticProblem(
        unit_cube(2), lambda F: hf.materials.neo_hookean(F, params), bcs=uniaxial_rollers(1.3)
    )


def test_state_hooks_see_every_assembled_state():
    """A hook runs after each state change, with problem.u already holding the new state."""
    problem = _problem()
    seen: list[float] = []
    solver = hf.NewtonSolver(problem, state_hooks=[lambda: seen.append(float(np.abs(problem.u.x.array).max()))])
    problem.set_time(1.0)
    record = solver.solve(raise_on_failure=True)
    # at least one residual and one tangent per Newton iteration, plus line-search energies
    assert len(seen) >= 2 * record.iterations
    np.testing.assert_allclose(seen[-1], np.abs(problem.u.x.array).max(), rtol=0, atol=0)

    reference = _problem()
    reference.set_time(1.0)
    hf.NewtonSolver(reference).solve(raise_on_failure=True)
    np.testing.assert_allclose(problem.u.x.array, reference.u.x.array, atol=1e-10)


def test_replacement_tangent_changes_the_iterations_not_the_solution():
    """A scaled tangent (damped Newton) converges to the same state: the residual decides the answer."""
    problem = _problem()
    problem.set_time(1.0)
    scaled = 2.0 * problem.jacobian
    record = hf.NewtonSolver(problem, jacobian=scaled, energy_line_search=False,
                             petsc_options={"snes_linesearch_type": "basic", "snes_max_it": 200}).solve(
        raise_on_failure=True
    )
    reference = _problem()
    reference.set_time(1.0)
    exact = hf.NewtonSolver(reference).solve(raise_on_failure=True)
    assert record.iterations > exact.iterations  # half steps: linear convergence
    np.testing.assert_allclose(problem.u.x.array, reference.u.x.array, atol=1e-8)
    assert isinstance(scaled, ufl.Form)
