"""Solver-side failures say what went wrong (serially and on 2 ranks).

Each case used to surface as a PETSc traceback, as a misleading "load stepping
failed ... DIVERGED_LINE_SEARCH", or as a ConvergenceError after every cutback.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.cases import CantileverSpec, bend_load
from hyperfem.errors import ParameterError

MESHES = Path(__file__).resolve().parent.parent / "meshes"


def _beam_problem(bcs=None, loads=None):
    domain = hf.read_mesh(MESHES / "beam_h2.msh")
    params = CantileverSpec().lame
    return hf.HyperelasticProblem(
        domain,
        lambda F: hf.materials.neo_hookean(F, params),
        bcs=[hf.Clamp("clamped")] if bcs is None else bcs,
        loads=[bend_load()] if loads is None else loads,
    )


def test_invalid_petsc_option_value():
    problem = _beam_problem()
    with pytest.raises(ParameterError, match="pc_type = 'no_such_pc'"):
        hf.NewtonSolver(problem, {"pc_type": "no_such_pc"})
    # The failed construction left nothing behind in PETSc's options database.
    solver = hf.NewtonSolver(problem)
    problem.set_time(1.0)
    assert solver.solve().converged


def test_no_dirichlet_condition_names_rigid_motion():
    problem = _beam_problem(bcs=[])
    with pytest.raises(ParameterError, match="rigid-body motion unconstrained .*translation x"):
        hf.NewtonSolver(problem)


def test_partial_constraint_lists_the_free_motions():
    problem = _beam_problem(bcs=[hf.PrescribedDisplacement("clamped", [0.0], components=[0])])
    with pytest.raises(ParameterError) as info:
        hf.NewtonSolver(problem)
    message = str(info.value)
    for free in ("translation y", "translation z", "rotation about x"):
        assert free in message
    assert "rotation about z" not in message  # u_x on the clamped face fixes it
    assert "\n" not in message


def test_constraint_check_2d():
    mesh = dmesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    params = hf.materials.LameParameters.from_youngs(1.0, 0.3)
    free = hf.HyperelasticProblem(
        domain, lambda F: hf.materials.neo_hookean(F, params),
        bcs=[hf.PrescribedDisplacement("left", [0.0], components=[0])],
    )
    with pytest.raises(ParameterError, match="translation y"):
        hf.NewtonSolver(free)
    fixed = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("left")])
    hf.NewtonSolver(fixed)  # no error


def test_callable_load_that_evaluates_to_nan():
    nan_traction = hf.DeadTraction("free_end", lambda X: ufl.as_vector((0.0, ufl.ln(X[0] - 100.0), 0.0)))
    problem = _beam_problem(loads=[nan_traction])
    solver = hf.NewtonSolver(problem)
    problem.set_time(1.0)
    with pytest.raises(ParameterError, match="NaN/inf .*DeadTraction on 'free_end'"):
        solver.solve()


def test_exception_in_a_callback_surfaces():
    problem = _beam_problem()
    solver = hf.NewtonSolver(problem)

    def broken():
        raise RuntimeError("energy assembly exploded")

    solver._energies = broken
    problem.set_time(1.0)
    with pytest.raises(RuntimeError, match="energy assembly exploded"):
        solver.solve()


def test_inconsistent_converged_state_is_a_failure():
    """A problem's check_solution() veto turns SNES convergence into a failed solve with the reason."""
    problem = _beam_problem()
    problem.check_solution = lambda: ({"volume_consistency": 0.3}, "J oscillates inside cells")
    solver = hf.NewtonSolver(problem)
    problem.set_time(1.0)
    rec = solver.solve()
    assert not rec.converged
    assert rec.message == "J oscillates inside cells"
    assert rec.indicators == {"volume_consistency": 0.3}
    with pytest.raises(hf.errors.ConvergenceError, match="J oscillates inside cells"):
        problem.u.x.array[:] = 0.0
        solver.solve(raise_on_failure=True)


@pytest.mark.parametrize(
    "kwargs, what",
    [
        ({"growth": float("nan")}, "growth"),
        ({"easy_iterations": -1}, "easy_iterations"),
        ({"max_steps": 0}, "max_steps"),
        ({"initial_increment": float("inf")}, "initial_increment"),
        ({"min_increment": 0.5, "initial_increment": 0.25}, "min_increment <= initial_increment"),
    ],
)
def test_load_stepping_parameters(kwargs, what):
    with pytest.raises(ParameterError, match=what):
        hf.LoadStepping(**kwargs)
