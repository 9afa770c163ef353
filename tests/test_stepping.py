"""Load stepping: cutback on failure, growth after easy steps, clear failure."""

from pathlib import Path

import numpy as np
import pytest

import hyperfem as hf
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load
from hyperfem.io import PointProbe

MESH = Path(__file__).resolve().parent.parent / "meshes" / "beam_h2.msh"


def _bend(scale=1.0):
    domain = hf.read_mesh(MESH)
    params = CantileverSpec().lame
    return hf.HyperelasticProblem(
        domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("clamped")], loads=[bend_load(scale)]
    )


def test_cutback_reaches_full_load_and_same_answer():
    ref = _bend()
    hf.solve_quasistatic(hf.NewtonSolver(ref))
    problem = _bend()
    # Three Newton iterations are not enough for the full load in one step.
    solver = hf.NewtonSolver(problem, {"snes_max_it": 3})
    steps = hf.solve_quasistatic(solver, stepping=hf.LoadStepping(min_increment=1 / 64, easy_iterations=2))
    assert steps[-1].load_factor == pytest.approx(1.0)
    assert sum(s.cutbacks for s in steps) >= 1
    assert any(s.failed for s in steps)
    assert all(s.solve.converged for s in steps)
    # increments are never above the failed one and sum to the full load
    assert sum(s.increment for s in steps) == pytest.approx(1.0)
    probe = PointProbe(problem.domain.mesh, [TEST_POINT])
    np.testing.assert_allclose(probe(problem.u), probe(ref.u), rtol=1e-7, atol=1e-10)


def test_growth_after_easy_steps():
    problem = _bend()
    steps = hf.solve_quasistatic(
        hf.NewtonSolver(problem), stepping=hf.LoadStepping(initial_increment=0.125, growth=2.0)
    )
    increments = [s.increment for s in steps]
    assert increments[:3] == pytest.approx([0.125, 0.25, 0.5])
    assert steps[-1].load_factor == pytest.approx(1.0)


def test_failure_names_load_factor_and_keeps_history():
    problem = _bend(scale=1.0)
    solver = hf.NewtonSolver(problem, {"snes_max_it": 1})
    seen = []
    with pytest.raises(hf.ConvergenceError) as exc:
        hf.solve_quasistatic(
            solver, stepping=hf.LoadStepping(initial_increment=0.5, min_increment=0.1), on_step=seen.append
        )
    err = exc.value
    assert "reached load factor" in str(err)
    assert err.load_factor == pytest.approx(sum(s.increment for s in err.history))
    assert len(seen) == len(err.history)
    # the state is the last converged one
    assert problem.load_factor == pytest.approx(err.load_factor)


def test_inversion_precheck_refuses_inverting_steps():
    """A Newton direction that would invert every element is shortened until J > 0."""
    problem = _bend()
    solver = hf.NewtonSolver(problem)
    x = solver._nlp.x
    x.set(0.0)
    # Trial state x - y = -2 X: F = -I, J = -1 everywhere.
    trial = problem.u.copy()
    trial.interpolate(lambda X: -2.0 * X)
    y = x.duplicate()
    y.array[:] = -trial.x.array[: y.getLocalSize()]
    solver._precheck(x, y)
    # Halved twice: x - y = -X/2, F = I/2, J = 1/8.
    assert solver.inversion_cutbacks == 2
    problem.u.x.array[: y.getLocalSize()] = -y.array
    problem.u.x.scatter_forward()
    assert solver.min_J() == pytest.approx(0.125)
