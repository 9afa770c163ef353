"""The stepper: cutback on failure, growth after easy steps, landing on must-hit times, unloading, clear failure.

The policy arithmetic is checked on a scalar stage (no finite elements), the
quasi-static stage on the coarse cantilever.
"""

from pathlib import Path

import numpy as np
import pytest

import hyperfem as hf
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load
from hyperfem.errors import ParameterError
from hyperfem.io import PointProbe
from hyperfem.solver.newton import SolveRecord
from hyperfem.solver.stepping import Stage, StepPolicy, run_steps

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
    assert steps[-1].time == pytest.approx(1.0)
    assert sum(s.rejected for s in steps) >= 1
    assert any(s.failed for s in steps)
    assert all(s.solve.converged for s in steps)
    # increments are never above the failed one and sum to the full load
    assert sum(s.dt for s in steps) == pytest.approx(1.0)
    probe = PointProbe(problem.domain.mesh, [TEST_POINT])
    np.testing.assert_allclose(probe(problem.u), probe(ref.u), rtol=1e-7, atol=1e-10)


def test_growth_after_easy_steps():
    problem = _bend()
    steps = hf.solve_quasistatic(
        hf.NewtonSolver(problem), stepping=hf.LoadStepping(initial_increment=0.125, growth=2.0)
    )
    increments = [s.dt for s in steps]
    assert increments[:3] == pytest.approx([0.125, 0.25, 0.5])
    assert steps[-1].time == pytest.approx(1.0)


def test_failure_names_time_and_keeps_history():
    problem = _bend(scale=1.0)
    solver = hf.NewtonSolver(problem, {"snes_max_it": 1})
    seen = []
    with pytest.raises(hf.ConvergenceError) as exc:
        hf.solve_quasistatic(
            solver, stepping=hf.LoadStepping(initial_increment=0.5, min_increment=0.1), on_step=seen.append
        )
    err = exc.value
    assert "reached t = " in str(err)
    assert err.time == pytest.approx(sum(s.dt for s in err.history))
    assert len(seen) == len(err.history)
    # the state is the last converged one
    assert problem.time == pytest.approx(err.time)


def test_inversion_precheck_refuses_inverting_steps():
    """A Newton direction that would invert every element is shortened until J > 0."""
    problem = _bend()
    solver = hf.NewtonSolver(problem, step_filter="bisection")
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


def test_unloading_ramps_down_to_the_same_state():
    """Asking for a time below the current one ramps the loads down (it used to return nothing)."""
    ref = _bend()
    hf.solve_quasistatic(hf.NewtonSolver(ref), target=0.5)
    problem = _bend()
    solver = hf.NewtonSolver(problem)
    hf.solve_quasistatic(solver, target=1.0)
    down = hf.solve_quasistatic(solver, target=0.5, stepping=hf.LoadStepping(initial_increment=0.25))
    assert [s.time for s in down] == pytest.approx([0.75, 0.5])
    assert all(s.dt < 0 for s in down) and sum(s.dt for s in down) == pytest.approx(-0.5)
    assert problem.time == pytest.approx(0.5)
    probe = PointProbe(problem.domain.mesh, [TEST_POINT])
    np.testing.assert_allclose(probe(problem.u), probe(ref.u), rtol=1e-6, atol=1e-9)
    hf.solve_quasistatic(solver, target=0.0)  # fully unloaded: back to the reference configuration
    assert np.abs(probe(problem.u)).max() < 1e-8


# -- the policy on a scalar stage ---------------------------------------------------------
class ScalarStage:
    """x' = x by forward Euler; a step longer than ``fail_above`` does not converge (2 iterations otherwise)."""

    kind = "quasi-static"

    def __init__(self, t=0.0, fail_above=np.inf):
        self._time, self.x, self.fail_above = t, 1.0, fail_above
        self._trial = None
        self.attempts = []

    @property
    def time(self):
        return self._time

    def save(self):
        return (self._time, self.x)

    def restore(self, state):
        self._time, self.x = state

    def advance(self, t, dt):
        assert t == self._time
        self.attempts.append(dt)
        ok = abs(dt) <= self.fail_above
        self._trial = (t + dt, self.x * (1.0 + dt))
        self.x = self._trial[1]
        return SolveRecord(ok, 2 if ok else -5, "CONVERGED" if ok else "DIVERGED", 2, 2, min_J=1.0)

    def commit(self):
        self._time = self._trial[0]

    def distance(self, state):
        return abs(self.x - state[1])


def _times(policy, stage=None):
    stage = ScalarStage() if stage is None else stage
    assert isinstance(stage, Stage)
    return [r.time for r in run_steps(stage, policy)], stage


def test_clip_landing_shortens_the_step_that_would_pass_a_must_hit_time():
    times, _ = _times(StepPolicy(end=1.0, increment=0.3, must_hit=[0.5, 7.0], easy_iterations=None, grow_after=99))
    assert times == pytest.approx([0.3, 0.5, 0.8, 1.0])


def test_equal_landing_splits_the_interval():
    times, _ = _times(StepPolicy(end=1.0, increment=0.3, must_hit=[0.5], landing="equal", grow_after=99))
    assert times == pytest.approx([0.25, 0.5, 0.75, 1.0])


def test_growth_after_easy_steps_only():
    grow = StepPolicy(end=4.0, increment=0.5, max_increment=2.0, grow_after=2, easy_iterations=2)
    records = run_steps(ScalarStage(), grow)
    assert [r.dt for r in records] == pytest.approx([0.5, 0.5, 1.0, 1.0, 1.0])
    hard = StepPolicy(end=2.0, increment=0.5, max_increment=2.0, grow_after=1, easy_iterations=1)
    assert [r.dt for r in run_steps(ScalarStage(), hard)] == pytest.approx([0.5] * 4)


def test_cutback_halves_the_failed_step_and_keeps_it():
    stage = ScalarStage(fail_above=0.2)
    records = run_steps(stage, StepPolicy(end=0.5, increment=0.5, easy_iterations=None, grow_after=99))
    assert stage.attempts[:3] == pytest.approx([0.5, 0.25, 0.125])
    assert records[0].rejected == 2 and len(records[0].failed) == 2 and records[0].dt == pytest.approx(0.125)
    assert [r.dt for r in records] == pytest.approx([0.125] * 4)
    assert stage.time == pytest.approx(0.5)


def test_unloading_on_the_scalar_stage():
    stage = ScalarStage(t=1.0)
    records = run_steps(stage, StepPolicy(end=0.0, increment=0.25, must_hit=[0.6], grow_after=99))
    assert [r.time for r in records] == pytest.approx([0.75, 0.6, 0.35, 0.1, 0.0])
    assert all(r.dt < 0 for r in records)


def test_step_doubling_keeps_the_error_below_the_tolerance():
    stage = ScalarStage()
    policy = StepPolicy(end=1.0, increment=0.25, tolerance=2e-3, landing="equal", easy_iterations=None, grow_after=2)
    records = run_steps(stage, policy)
    assert records[-1].time == pytest.approx(1.0)
    assert sum(r.rejected for r in records) >= 1
    assert all(r.error <= 2e-3 for r in records)
    assert all(len(r.solve_records) == 2 for r in records)  # the two half steps are kept
    # forward Euler with the accepted half steps
    expected = np.prod([(1.0 + r.dt / 2) ** 2 for r in records])
    assert stage.x == pytest.approx(expected, rel=1e-14)


def test_failure_below_the_minimum_and_too_many_steps():
    stage = ScalarStage(fail_above=0.0)
    with pytest.raises(hf.ConvergenceError, match=r"reached t = 0 of 1; step 0.125 below the minimum 0.25") as info:
        run_steps(stage, StepPolicy(end=1.0, increment=0.5, min_increment=0.25))
    assert info.value.time == 0.0 and info.value.history == []
    with pytest.raises(hf.ConvergenceError, match="exceeded 3 steps") as info:
        run_steps(ScalarStage(), StepPolicy(end=1.0, increment=0.1, grow_after=99, max_steps=3))
    assert info.value.time == pytest.approx(0.3) and len(info.value.history) == 3


@pytest.mark.parametrize(
    "kwargs, what",
    [
        ({"increment": 0.0}, "increment must be a finite number > 0"),
        ({"end": float("nan")}, "end must be a finite number"),
        ({"increment": 0.5, "max_increment": 0.25}, "need min_increment <= increment <= max_increment"),
        ({"cutback": 1.0}, "cutback must lie in"),
        ({"growth": 0.5}, "growth must be"),
        ({"grow_after": 0}, "grow_after must be an integer"),
        ({"easy_iterations": 1.5}, "easy_iterations must be an integer"),
        ({"landing": "exact"}, "landing must be one of"),
        ({"tolerance": -1.0}, "tolerance must be"),
        ({"must_hit": [0.5, float("inf")]}, "must_hit times must be finite"),
    ],
)
def test_step_policy_invalid(kwargs, what):
    with pytest.raises(ParameterError, match=f"StepPolicy: {what}"):
        StepPolicy(**kwargs)


def test_presets_are_policies():
    assert hf.LoadStepping(initial_increment=0.25).policy(2.0) == StepPolicy(
        end=2.0, increment=0.25, min_increment=1 / 1024, max_increment=1.0, reject_inversion=False
    )
    policy = hf.dynamics.TimeStepping(dt=0.1, t_end=1.0, adaptive=True, must_hit=[0.5]).policy()
    assert (policy.max_step, policy.min_step, policy.landing, policy.grow_after) == (1.6, 0.1 / 1024, "equal", 4)
    assert policy.tolerance == 1e-4 and policy.easy_iterations is None and policy.must_hit == (0.5,)
