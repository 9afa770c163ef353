r"""Step filters of :class:`~hyperfem.solver.NewtonSolver`: how far along a Newton step the line search may go.

SNES line searches try :math:`x - \lambda y` with :math:`\lambda \le 1`, where
:math:`y` is the (negative) Newton step. Before they start, the solver's
pre-check asks its filters for the largest admissible fraction
:math:`\alpha \in (0, 1]` of :math:`y` and scales :math:`y` by it, so every
trial state of the line search lies on the admissible segment.

* :class:`NewtonStepFilter` — the protocol: one method,
  :meth:`~NewtonStepFilter.step_fraction`, plus the counters a
  :class:`~hyperfem.solver.SolveRecord` reports;
* :class:`ExactInversionFilter` — seed 004's exact inversion-free step for P1
  simplices (:class:`~hyperfem.solver.step_filter.StepFilter`), times
  :data:`STEP_SAFETY` when it shortens the step;
* :class:`JacobianBisectionFilter` — halve the step until :math:`J > J_\text{min}`
  at every quadrature point of the full (shortened) step;
* :class:`ComposedFilters` — several filters in sequence: each sees the step
  already scaled by the ones before it, so the fraction of the composition is
  the product of the fractions. For filters that return the largest
  admissible fraction of a segment whose admissible set is star-shaped from
  :math:`x` (the exact filter, a continuous collision detection), the product
  equals :math:`\min_i \alpha_i` of the filters applied to the unscaled step.

The solver's default composition is ``[exact, bisection]`` where both apply
(see :func:`inversion_filters`); filters added with
:meth:`~hyperfem.solver.NewtonSolver.add_step_filter` run after the exact
filter and before the bisection, which checks only the end point of the
step and so stays last.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable
from typing import Protocol, runtime_checkable

import numpy as np
from mpi4py import MPI  # (before dolfinx/petsc4py)
from petsc4py import PETSc

from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.problem.inversion import QuadratureMinimum
from hyperfem.problem.protocol import InvertibleProblem, SolidProblem
from hyperfem.solver.state import assign_state
from hyperfem.solver.step_filter import StepFilter, exact_filter_applies

__all__ = [
    "DEFAULT_MIN_JACOBIAN",
    "MAX_INVERSION_HALVINGS",
    "STEP_FILTERS",
    "STEP_SAFETY",
    "ComposedFilters",
    "ExactInversionFilter",
    "JacobianBisectionFilter",
    "NewtonStepFilter",
    "NoAdmissibleStep",
    "inversion_filters",
    "resolve_min_jacobian",
]

MAX_INVERSION_HALVINGS = 40
"""The pre-check halves a Newton step at most this often to keep :math:`J > J_{\\min}`."""

DEFAULT_MIN_JACOBIAN = 1e-6
"""``min_jacobian="auto"`` of a problem whose material is not invertible."""

STEP_FILTERS = ("auto", "exact", "bisection")
"""Values of ``NewtonSolver(step_filter=...)``."""

STEP_SAFETY = 0.9
r"""The exact filter scales a Newton step to this times its critical :math:`\alpha^*` (when :math:`\alpha^* < 1`).

At :math:`\alpha^*` the most compressed cell is at exactly :math:`\eta` of its
volume, where a barrier energy (:math:`-\mu\ln J`) is steep; the factor keeps
the first trial of the line search strictly inside (the volume ratio stays
above :math:`\eta` for every shorter step anyway). Not needed for
:math:`J > 0`; chosen by measurement (``benchmarks/step_filter.py``, results in
``benchmarks/results/step_filter.jsonl``): of the 16 one-step solves of the
cantilever bend and twist at 20, 50, 100 and 200 times the load on
``beam_h2``/``beam_h1`` (P1), 15 converge with 0.9, 14 with 0.8, 13 with
0.95, 12 with 1.0 and 10 with 0.5 (13 with the bisection guard). At these
loads the outcome is sensitive to any change of the Newton path, so read the
counts as "0.8–0.9 is a sound range", not as an optimum."""


class NoAdmissibleStep(Exception):
    """Raised by :meth:`NewtonStepFilter.step_fraction`: no fraction of the step is admissible.

    The solver then ends the solve as ``DIVERGED_FUNCTION_DOMAIN`` (a failed
    solve that the stepper cuts back), with the message in the record.

    Args:
        message: Why, for :attr:`SolveRecord.message <hyperfem.solver.SolveRecord.message>`.
        fraction: The fraction the step is scaled by all the same (the
            shortest one tried; the line search still runs once).
    """

    def __init__(self, message: str, fraction: float = 0.0):
        super().__init__(message)
        self.fraction = float(fraction)


@runtime_checkable
class NewtonStepFilter(Protocol):
    r"""What the Newton pre-check asks of a step filter.

    Attributes:
        cutbacks: Trial steps this filter has halved so far (reported as
            ``SolveRecord.inversion_cutbacks``, per solve).
        filtered_steps: Newton steps this filter has shortened so far
            (``SolveRecord.filtered_steps``, per solve).
        min_step_fraction: The smallest fraction this filter has allowed
            since the solver last set it to 1 (at the start of every solve;
            ``SolveRecord.min_step_fraction`` is the smallest over the filters).
    """

    cutbacks: int
    filtered_steps: int
    min_step_fraction: float

    def step_fraction(self, x: PETSc.Vec, y: PETSc.Vec) -> float:
        r"""The largest admissible fraction :math:`\alpha \in (0, 1]` of the step (trials :math:`x - \lambda\alpha y`).

        Collective: the same value on every rank. Must not change ``x`` or
        ``y``; may move the problem's unknown (the pre-check restores it).

        Args:
            x: The current iterate.
            y: The step (already scaled by the filters before this one).

        Raises:
            NoAdmissibleStep: No fraction of ``y`` is admissible.
        """
        ...


class ExactInversionFilter:
    r"""The exact inversion-free step of seed 004 (:class:`~hyperfem.solver.step_filter.StepFilter`).

    The fraction is :math:`\text{safety}\cdot\alpha^*` when the critical step
    :math:`\alpha^* < 1` (no cell shrinks below :math:`\eta` of its current
    volume on :math:`[0, \alpha^*)`), else 1.

    Args:
        u: The unknown (a P1 displacement on straight simplices).
        geometry: The exact filter of ``u``'s space.
        safety: :data:`STEP_SAFETY`.
    """

    def __init__(self, u: fem.Function, geometry: StepFilter, safety: float = STEP_SAFETY):
        self.u = u
        self.geometry = geometry
        self.safety = float(safety)
        self.cutbacks = 0
        self.filtered_steps = 0
        self.min_step_fraction = 1.0
        self._direction: fem.Function | None = None

    def step_fraction(self, x: PETSc.Vec, y: PETSc.Vec) -> float:
        """:data:`STEP_SAFETY` times the critical step when it is below 1 (see the class docstring)."""
        assign_state(x, self.u)
        if self._direction is None:
            self._direction = fem.Function(self.u.function_space)
        p = self._direction
        owned = y.getLocalSize()
        p.x.array[:owned] = y.array_r
        p.x.scatter_forward()  # ghost values of the direction, for the owned cells that touch them
        # The trial state is x - alpha * y: the direction is -y.
        alpha = self.geometry.max_step(self.u.x.array, -p.x.array)
        if alpha >= 1.0:
            return 1.0
        fraction = self.safety * alpha
        self.filtered_steps += 1
        self.min_step_fraction = min(self.min_step_fraction, fraction)
        return fraction


class JacobianBisectionFilter:
    r"""Halve the step until the full step keeps every quadrature point above ``min_jacobian``.

    The fraction is :math:`2^{-k}` with the smallest :math:`k` such that
    :math:`\min J(x - 2^{-k}y) > J_\text{min}`; after ``max_halvings`` halvings
    it gives up (:class:`NoAdmissibleStep`).

    Args:
        u: The unknown.
        min_J: The smallest :math:`J` over the quadrature points of ``u``'s current state.
        min_jacobian: :math:`J_\text{min}`.
        template: A vector of the unknown's layout (for the trial states).
        max_halvings: :data:`MAX_INVERSION_HALVINGS`.
    """

    def __init__(
        self,
        u: fem.Function,
        min_J: QuadratureMinimum,
        min_jacobian: float,
        template: PETSc.Vec,
        max_halvings: int = MAX_INVERSION_HALVINGS,
    ):
        self.u = u
        self.min_J = min_J
        self.min_jacobian = float(min_jacobian)
        self.max_halvings = int(max_halvings)
        self.cutbacks = 0
        self.filtered_steps = 0
        self.min_step_fraction = 1.0
        self._work = template.duplicate()

    def step_fraction(self, x: PETSc.Vec, y: PETSc.Vec) -> float:
        """:math:`2^{-k}` (see the class docstring); collective through ``min_J``."""
        fraction = 1.0
        for _ in range(self.max_halvings):
            self._work.waxpy(-fraction, y, x)
            assign_state(self._work, self.u)
            if self.min_J() > self.min_jacobian:
                return fraction
            fraction *= 0.5
            self.cutbacks += 1
        # Even a step 2^-40 as long inverts: the search direction is unusable.
        raise NoAdmissibleStep(
            f"every step along the Newton direction inverts elements (halved {self.max_halvings} times)", fraction
        )


class ComposedFilters:
    r"""Several step filters applied in sequence (module docstring); itself a :class:`NewtonStepFilter`.

    Args:
        filters: The filters, in the order they run.

    Raises:
        ParameterError: An entry does not meet :class:`NewtonStepFilter`.
    """

    def __init__(self, filters: Iterable[NewtonStepFilter] = ()):
        self.filters: list[NewtonStepFilter] = []
        for step_filter in filters:
            self.insert(len(self.filters), step_filter)

    def insert(self, index: int, step_filter: NewtonStepFilter) -> None:
        """Insert a filter before position ``index``.

        Raises:
            ParameterError: ``step_filter`` does not meet :class:`NewtonStepFilter`.
        """
        if not isinstance(step_filter, NewtonStepFilter):
            raise ParameterError(
                f"ComposedFilters: a step filter needs step_fraction(x, y), cutbacks, filtered_steps and "
                f"min_step_fraction, got {type(step_filter).__name__}"
            )
        self.filters.insert(index, step_filter)

    def apply(self, x: PETSc.Vec, y: PETSc.Vec) -> float:
        r"""Scale ``y`` in place by each filter's fraction in turn; return the product.

        Raises:
            NoAdmissibleStep: From a filter, after ``y`` was scaled by its ``fraction``.
        """
        comm = x.getComm().tompi4py()
        total = 1.0
        for step_filter in self.filters:
            fraction, refusal, error = self._agreed(comm, step_filter, x, y)
            if error:
                raise ParameterError(error)
            if refusal:
                y.scale(fraction)
                raise NoAdmissibleStep(refusal, fraction)
            if fraction < 1.0:
                y.scale(fraction)
                total *= fraction
        return total

    @staticmethod
    def _agreed(
        comm: MPI.Comm, step_filter: NewtonStepFilter, x: PETSc.Vec, y: PETSc.Vec
    ) -> tuple[float, str, str]:
        """One filter's fraction, refusal message and error, the same on every rank (collective).

        The inversion filters are collective already; a filter that looks at its own cells
        only (a contact filter sees a penetration where it happens) may refuse or shorten on
        one rank: without this agreement that rank's SNES stopped and the others waited.
        """
        refusal, error = "", ""
        try:
            fraction = _checked_fraction(step_filter.step_fraction(x, y), step_filter)
        except NoAdmissibleStep as exc:
            refusal, fraction = str(exc) or type(step_filter).__name__, exc.fraction
        except ParameterError as exc:
            error, fraction = str(exc), 1.0
        fraction = comm.allreduce(float(fraction), op=MPI.MIN)
        refusals = [r for r in comm.allgather(refusal) if r]
        errors = [e for e in comm.allgather(error) if e]
        return fraction, (refusals[0] if refusals else ""), (errors[0] if errors else "")

    def step_fraction(self, x: PETSc.Vec, y: PETSc.Vec) -> float:
        """The fraction of :meth:`apply`, on a copy of ``y``."""
        scaled = y.copy()
        try:
            return self.apply(x, scaled)
        finally:
            scaled.destroy()

    @property
    def cutbacks(self) -> int:
        """Trial steps halved, summed over the filters."""
        return sum(f.cutbacks for f in self.filters)

    @property
    def filtered_steps(self) -> int:
        """Newton steps shortened, summed over the filters."""
        return sum(f.filtered_steps for f in self.filters)

    @property
    def min_step_fraction(self) -> float:
        """The smallest fraction any filter allowed since the last reset."""
        return min((f.min_step_fraction for f in self.filters), default=1.0)

    @min_step_fraction.setter
    def min_step_fraction(self, value: float) -> None:
        for step_filter in self.filters:
            step_filter.min_step_fraction = value


def _checked_fraction(fraction: object, step_filter: NewtonStepFilter) -> float:
    """``fraction`` as a float in [0, 1] (0 included, see below), or a :class:`ParameterError` naming the filter.

    0 is let through (it zeroes the step, as the exact filter does when its
    critical step underflows); a filter that finds no admissible step should
    raise :class:`NoAdmissibleStep` instead.
    """
    if isinstance(fraction, numbers.Real) and not isinstance(fraction, bool) and 0.0 <= float(fraction) <= 1.0:
        return float(fraction)
    raise ParameterError(
        f"{type(step_filter).__name__}.step_fraction returned {fraction!r}; a step fraction must be in [0, 1] "
        "(raise NoAdmissibleStep when no step is admissible)"
    )


def resolve_min_jacobian(min_jacobian: float | str | None, problem: SolidProblem) -> float | None:
    """``min_jacobian`` with ``"auto"`` resolved (``None`` for an ``invertible`` problem).

    Raises:
        ParameterError: Not a number in [0, 1), ``None`` or ``"auto"``.
    """
    if isinstance(min_jacobian, str):
        if min_jacobian != "auto":
            raise ParameterError(f"NewtonSolver: min_jacobian must be a number, None or 'auto', got {min_jacobian!r}")
        invertible = isinstance(problem, InvertibleProblem) and problem.invertible
        return None if invertible else DEFAULT_MIN_JACOBIAN
    if min_jacobian is None:
        return None
    if isinstance(min_jacobian, bool) or not isinstance(min_jacobian, numbers.Real) or not np.isfinite(min_jacobian):
        raise ParameterError(
            f"NewtonSolver: min_jacobian must be a finite number, None or 'auto', got {min_jacobian!r}"
        )
    if not 0.0 <= min_jacobian < 1.0:
        raise ParameterError(
            f"NewtonSolver: min_jacobian must be in [0, 1) (the volume ratio J below which a state counts as "
            f"inverted; the reference state has J = 1), got {min_jacobian!r}"
        )
    return float(min_jacobian)


def _exact_geometry(
    problem: SolidProblem, step_filter: str, min_jacobian: float | None, volume_fraction: float
) -> StepFilter | None:
    """The exact filter's geometry where ``step_filter`` asks for it and it applies (see ``NewtonSolver``)."""
    if step_filter not in STEP_FILTERS:
        raise ParameterError(
            f"NewtonSolver: step_filter must be one of {', '.join(STEP_FILTERS)}, got {step_filter!r}"
        )
    if step_filter == "bisection" or (step_filter == "auto" and min_jacobian is None):
        return None
    V = problem.u.function_space
    plain = problem.displacement_space() is V  # the unknown is the displacement, nothing else
    if not (plain and exact_filter_applies(V)):
        if step_filter == "exact":
            raise ParameterError(
                "NewtonSolver: step_filter='exact' needs a displacement-only problem with P1 elements on "
                f"straight simplices (got {V.ufl_element()}); use 'auto' or 'bisection'"
            )
        return None
    return StepFilter(V, volume_fraction)


def inversion_filters(
    problem: SolidProblem,
    step_filter: str,
    min_jacobian: float | None,
    volume_fraction: float,
    min_J: QuadratureMinimum,
    template: PETSc.Vec,
) -> tuple[ExactInversionFilter | None, JacobianBisectionFilter | None]:
    """The inversion guard of a solver: the exact filter and the bisection check, each where it applies.

    Args:
        problem: The problem.
        step_filter: ``"auto"``, ``"exact"`` or ``"bisection"`` (:data:`STEP_FILTERS`).
        min_jacobian: The resolved :math:`J_\\text{min}` (``None``: no bisection check).
        volume_fraction: :math:`\\eta` of the exact filter.
        min_J: The quadrature minimum of :math:`J` of the problem.
        template: A vector of the unknown's layout.

    Raises:
        ParameterError: An unknown ``step_filter``, a ``volume_fraction`` outside (0, 1),
            or ``"exact"`` where the exact filter does not apply.
    """
    geometry = _exact_geometry(problem, step_filter, min_jacobian, volume_fraction)
    exact = None if geometry is None else ExactInversionFilter(problem.u, geometry)
    bisection = None if min_jacobian is None else JacobianBisectionFilter(problem.u, min_J, min_jacobian, template)
    return exact, bisection
