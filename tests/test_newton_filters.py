r"""The step-filter protocol of :class:`~hyperfem.solver.NewtonSolver` (:mod:`hyperfem.solver.filters`).

The pre-check sets the Dirichlet rows of the Newton step, then asks each
filter in turn for the largest admissible fraction of the step, which it
applies before the next filter runs. The analytic case of the composition:
from :math:`u = -0.3X` (:math:`F = 0.7I`, :math:`J = 0.343`) along
:math:`y = 2X` (trial states :math:`u - \alpha y`, :math:`F = (0.7 - 2\alpha)I`)
the exact filter allows :math:`0.9\alpha^*` with
:math:`((0.7 - 2\alpha^*)/0.7)^3 = \eta`, i.e.
:math:`\alpha^* = 0.35(1 - \eta^{1/3})`; with :math:`J_\text{min} = 0.3` the
bisection then halves that four times (:math:`J` at the full filtered step is
0.048, 0.150, 0.233, 0.285, then 0.313).
"""

from pathlib import Path

import dolfinx.fem.petsc as fpetsc
import numpy as np
import pytest

import hyperfem as hf
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load
from hyperfem.errors import ParameterError
from hyperfem.io import PointProbe
from hyperfem.solver.filters import (
    MAX_INVERSION_HALVINGS,
    STEP_SAFETY,
    ComposedFilters,
    ExactInversionFilter,
    JacobianBisectionFilter,
    NewtonStepFilter,
    NoAdmissibleStep,
)
from hyperfem.solver.step_filter import StepFilter

MESH = Path(__file__).resolve().parent.parent / "meshes" / "beam_h2.msh"
ETA = 0.1


def _bend(scale=1.0):
    params = CantileverSpec().lame
    return hf.HyperelasticProblem(
        hf.read_mesh(MESH),
        lambda F: hf.materials.neo_hookean(F, params),
        bcs=[hf.Clamp("clamped")],
        loads=[bend_load(scale)],
        degree=1,
    )


class HalfStep:
    """A custom filter: every step at most half as long (and the calls it saw)."""

    def __init__(self):
        self.cutbacks = 0
        self.filtered_steps = 0
        self.min_step_fraction = 1.0
        self.seen: list[np.ndarray] = []

    def step_fraction(self, x, y):
        self.seen.append(y.array.copy())
        self.filtered_steps += 1
        self.min_step_fraction = 0.5
        return 0.5


class Refuse(HalfStep):
    """A custom filter that finds no admissible step."""

    def step_fraction(self, x, y):
        raise NoAdmissibleStep("blocked by the test filter")


def _vectors(solver, problem, x_of_X, y_of_X):
    """The SNES vectors x and y holding the P1 interpolants of x_of_X and y_of_X."""
    x = solver._nlp.x
    f = problem.u.copy()
    f.interpolate(x_of_X)
    x.array[:] = f.x.array[: x.getLocalSize()]
    f.interpolate(y_of_X)
    y = x.duplicate()
    y.array[:] = f.x.array[: y.getLocalSize()]
    return x, y


def _todays_guard(solver, problem, x, y, min_jacobian):
    """The pre-check of main before the split: Dirichlet rows, the exact fraction, then halve the scaled step."""
    fpetsc.set_bc(y, problem.bcs, x0=x, alpha=-1.0)
    geometry = StepFilter(problem.u.function_space, ETA)
    problem.u.x.array[: x.getLocalSize()] = x.array_r
    problem.u.x.scatter_forward()
    p = problem.u.copy()
    p.x.array[: y.getLocalSize()] = y.array_r
    p.x.scatter_forward()
    alpha = geometry.max_step(problem.u.x.array, -p.x.array)
    if alpha < 1.0:
        y.scale(STEP_SAFETY * alpha)
    trial = x.duplicate()
    for _ in range(MAX_INVERSION_HALVINGS):
        trial.waxpy(-1.0, y, x)
        problem.u.x.array[: x.getLocalSize()] = trial.array_r
        problem.u.x.scatter_forward()
        if solver.min_J() > min_jacobian:
            break
        y.scale(0.5)
    return alpha


def test_default_composition_is_exact_then_bisection_and_equals_todays_guard():
    """Both inversion filters act (analytic case, module docstring); the result is the old pre-check's, bit for bit."""
    problem = _bend()
    solver = hf.NewtonSolver(problem, min_jacobian=0.3)
    assert [type(f) for f in solver.step_filters.filters] == [ExactInversionFilter, JacobianBisectionFilter]
    x, y = _vectors(solver, problem, lambda X: -0.3 * X, lambda X: 2.0 * X)
    reference = y.copy()
    x_ref = x.copy()
    alpha = _todays_guard(solver, problem, x_ref, reference, 0.3)
    assert alpha == pytest.approx(0.35 * (1.0 - ETA ** (1.0 / 3.0)), rel=1e-10)
    original = y.copy()
    solver._precheck(x, y)
    assert np.array_equal(y.array, reference.array)
    assert solver.filtered_steps == 1 and solver.inversion_cutbacks == 4
    expected = STEP_SAFETY * alpha / 16.0
    assert solver.step_filters.min_step_fraction == pytest.approx(STEP_SAFETY * alpha, rel=1e-14)
    # The composition as a filter itself: the same fraction, on a copy (its argument is unchanged).
    saved = original.array.copy()
    fraction = ComposedFilters(solver.step_filters.filters).step_fraction(x, original)
    assert np.array_equal(original.array, saved)
    assert fraction == pytest.approx(expected, rel=1e-14)
    problem.u.x.array[: y.getLocalSize()] = x.array_r - y.array_r
    problem.u.x.scatter_forward()
    assert solver.min_J() == pytest.approx((0.7 - 2.0 * expected) ** 3, rel=1e-10)


def test_added_filter_runs_after_the_exact_one_and_before_the_bisection():
    """The step it sees is the exact filter's, with the Dirichlet rows already set; the bisection sees its output."""
    problem = _bend()
    half = HalfStep()
    solver = hf.NewtonSolver(problem, step_filters=[half])
    assert [type(f) for f in solver.step_filters.filters] == [ExactInversionFilter, HalfStep, JacobianBisectionFilter]
    x, y = _vectors(solver, problem, lambda X: 0.0 * X, lambda X: 2.0 * X)
    dirichlet = np.concatenate([bc.dof_indices()[0] for bc in problem.bcs])
    dirichlet = dirichlet[dirichlet < y.getLocalSize()]
    y.array[dirichlet] = 7.0  # a Krylov error in the clamped rows; the pre-check sets them to x - g = 0 first
    solver._precheck(x, y)
    alpha = STEP_SAFETY * (1.0 - ETA ** (1.0 / 3.0)) / 2.0
    (seen,) = half.seen
    assert np.all(seen[dirichlet] == 0.0)
    interior = np.setdiff1d(np.arange(y.getLocalSize()), dirichlet)
    f = problem.u.copy()
    f.interpolate(lambda X: 2.0 * X)
    np.testing.assert_allclose(seen[interior], alpha * f.x.array[interior], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(y.array[interior], 0.5 * alpha * f.x.array[interior], rtol=1e-9, atol=1e-12)
    assert solver.filtered_steps == 2 and solver.inversion_cutbacks == 0  # one each: exact and HalfStep


def test_half_step_filter_needs_more_iterations_for_the_same_state():
    """Capping every Newton step at one half: linear convergence, same solution, counters in the record."""
    results = {}
    for name, filters in (("plain", []), ("half", [HalfStep()])):
        problem = _bend()
        solver = hf.NewtonSolver(problem, {"snes_max_it": 200}, step_filters=filters)
        problem.set_time(1.0)
        record = solver.solve(raise_on_failure=True)
        results[name] = (record, PointProbe(problem.domain.mesh, [TEST_POINT])(problem.u)[0], filters)
    plain, half = results["plain"][0], results["half"][0]
    assert half.iterations >= 2 * plain.iterations
    (custom,) = results["half"][2]
    assert custom.filtered_steps >= half.iterations  # every Newton step was shortened
    assert half.filtered_steps >= custom.filtered_steps
    assert half.min_step_fraction <= 0.5
    np.testing.assert_allclose(results["half"][1], results["plain"][1], rtol=1e-6, atol=1e-9)


def test_a_refusing_filter_fails_the_solve_as_a_domain_error():
    problem = _bend()
    solver = hf.NewtonSolver(problem)
    solver.add_step_filter(Refuse())
    problem.set_time(1.0)
    record = solver.solve()
    assert not record.converged
    assert record.reason_name == "DIVERGED_FUNCTION_DOMAIN"
    assert record.message == "blocked by the test filter"
    with pytest.raises(hf.ConvergenceError, match="DIVERGED_FUNCTION_DOMAIN .*blocked by the test filter"):
        solver.solve(raise_on_failure=True)


def test_bisection_gives_up_with_a_message():
    """From an inverted state every trial inverts: 40 halvings, then a refusal.

    On main this raised AttributeError ('SNES' object has no attribute 'setFunctionDomainError').
    """
    problem = _bend()
    solver = hf.NewtonSolver(problem, step_filter="bisection")
    x, y = _vectors(solver, problem, lambda X: -2.0 * X, lambda X: 1e-3 * X)
    fpetsc.set_bc(y, problem.bcs, x0=x, alpha=-1.0)  # what the pre-check does first (idempotent)
    y0 = y.array.copy()
    solver._precheck(x, y)
    assert solver.inversion_cutbacks == MAX_INVERSION_HALVINGS
    halvings = MAX_INVERSION_HALVINGS
    assert solver._refusal == f"every step along the Newton direction inverts elements (halved {halvings} times)"
    np.testing.assert_array_equal(y.array, 0.5**MAX_INVERSION_HALVINGS * y0)
    np.testing.assert_array_equal(problem.u.x.array[: x.getLocalSize()], x.array_r)  # state back at x


def test_filters_are_checked():
    problem = _bend()
    solver = hf.NewtonSolver(problem)
    with pytest.raises(ParameterError, match="step filter needs step_fraction"):
        solver.add_step_filter(object())
    assert isinstance(HalfStep(), NewtonStepFilter)

    class TooLong(HalfStep):
        def step_fraction(self, x, y):
            return 1.5

    solver.add_step_filter(TooLong())
    problem.set_time(1.0)
    with pytest.raises(ParameterError, match=r"TooLong.step_fraction returned 1.5; a step fraction must be in"):
        solver.solve()


class _OnLastRank(HalfStep):
    """Acts on the last rank only, as a contact filter that sees a penetration on its own cells."""

    def __init__(self, refuse: bool):
        super().__init__()
        self.refuse = refuse

    def step_fraction(self, x, y):
        comm = x.getComm().tompi4py()
        if comm.rank != comm.size - 1:
            return 1.0
        if self.refuse:
            raise NoAdmissibleStep("penetration on the last rank")
        return 0.5


def test_a_filter_acting_on_one_rank_acts_on_every_rank():
    """A refusal or a shorter step on one rank is agreed on every rank (it hung the others before)."""
    refused = _bend()
    solver = hf.NewtonSolver(refused, step_filters=[_OnLastRank(refuse=True)])
    refused.set_time(1.0)
    record = solver.solve()
    assert record.reason_name == "DIVERGED_FUNCTION_DOMAIN" and record.message == "penetration on the last rank"
    results = {}
    for name, custom in (("one rank", _OnLastRank(refuse=False)), ("every rank", HalfStep())):
        problem = _bend()
        solver = hf.NewtonSolver(problem, {"snes_max_it": 200}, step_filters=[custom])
        problem.set_time(1.0)
        results[name] = (solver.solve(raise_on_failure=True).residual_norms, problem.u.x.array.copy())
    assert results["one rank"][0] == pytest.approx(results["every rank"][0], rel=1e-8)
    np.testing.assert_allclose(results["one rank"][1], results["every rank"][1], rtol=0, atol=1e-12)
