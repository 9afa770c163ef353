r"""Stepping: one loop that takes a run from its time to an end time, with cutback and growth.

A *stage* owns the state of a run and takes one step at a time
(:class:`Stage`): :class:`QuasiStaticStage` moves the loads of a problem to
the new time and solves for equilibrium; :class:`DynamicStage` takes a time
step of an :class:`~hyperfem.dynamics.IncrementalProblem`. :func:`run_steps`
drives either under a :class:`StepPolicy`:

* the nominal increment starts at ``increment``. Steps land exactly on every
  *must-hit* time and on ``end``: ``landing="clip"`` shortens the one step that
  would pass such a time, ``landing="equal"`` splits the interval to it into
  equal steps no longer than the increment (no sliver steps; the nominal
  increment is unchanged);
* an attempt fails when Newton does not converge or (``reject_inversion``) the
  state has :math:`J \le 0` at a quadrature point. The stage is restored and
  the step retried with ``cutback`` times its length, which also becomes the
  nominal increment; below ``min_increment`` a
  :class:`~hyperfem.errors.ConvergenceError` names the time reached;
* with a ``tolerance``, step doubling (seed 003 §5.7.7): one step of
  :math:`\Delta t` and two of :math:`\Delta t/2` from the same state. If the
  nodal positions differ by more,

  .. math::
      e = \max_\text{nodes} \bigl|x^{(\Delta t)} - x^{(\Delta t/2, \Delta t/2)}\bigr| > \text{tol},

  the attempt fails (and is cut back); otherwise the more accurate
  two-half-step result is kept;
* after ``grow_after`` consecutive accepted *easy* steps (no solve needed more
  than ``easy_iterations`` Newton iterations; every step is easy when that is
  ``None``) the increment is multiplied by ``growth``, up to ``max_increment``.

``t`` is time throughout: the pseudo-time (load factor) of a quasi-static ramp
or the physical time of a dynamic run. An ``end`` below the stage's time ramps
down (unloading). Every accepted step is handed to ``on_step`` before the next
one starts, so a later failure loses nothing.

:class:`LoadStepping` (for :func:`solve_quasistatic`) and :class:`TimeStepping`
(for :func:`integrate`) are the two presets of the policy, with the parameters
and defaults they always had.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar, runtime_checkable

import numpy as np
from mpi4py import MPI

from hyperfem.errors import ConvergenceError, ParameterError
from hyperfem.problem.protocol import SolidProblem, TimeStepProblem
from hyperfem.validation import check_count, check_finite_scalar, check_positive, is_finite_number
from hyperfem.solver.newton import NewtonSolver, SolveRecord

__all__ = [
    "LANDINGS",
    "DynamicStage",
    "LoadStepping",
    "QuasiStaticStage",
    "Stage",
    "StepPolicy",
    "StepRecord",
    "TimeStepping",
    "integrate",
    "run_steps",
    "solve_quasistatic",
]

UNBOUNDED = 1e299
"""Ends at or beyond this magnitude are not reached (:meth:`_Course.of` does not name them)."""

LANDINGS = ("clip", "equal")
"""How steps land on must-hit times (see :class:`StepPolicy`)."""


# -- policy -------------------------------------------------------------------------------
@dataclass(frozen=True)
class StepPolicy:
    """How a run steps from its time to ``end`` (see the module docstring).

    Attributes:
        end: Time to reach (below the start: ramp down).
        increment: First nominal increment (> 0).
        min_increment: Smallest step before giving up (default ``increment / 1024``).
        max_increment: Largest step (default ``increment``; ``16 increment`` with a ``tolerance``).
        cutback: Factor in (0, 1) applied to a failed step.
        growth: Factor (>= 1) applied to the increment after ``grow_after`` easy steps.
        grow_after: Consecutive accepted easy steps before growing.
        easy_iterations: A step is easy when none of its solves took more
            Newton iterations; ``None``: every accepted step is easy.
        must_hit: Times that steps land on exactly (ends of ramps, output times).
        landing: ``"clip"`` (shorten the step that would pass a must-hit time)
            or ``"equal"`` (equal steps up to it).
        tolerance: Step-doubling tolerance on nodal positions (length units);
            ``None``: no error control.
        reject_inversion: A converged state with :math:`J \\le 0` at a quadrature point is a failure.
        max_steps: Hard limit on attempts (accepted and rejected).
    """

    end: float = 1.0
    increment: float = 1.0
    min_increment: float | None = None
    max_increment: float | None = None
    cutback: float = 0.5
    growth: float = 2.0
    grow_after: int = 1
    easy_iterations: int | None = 6
    must_hit: Sequence[float] = ()
    landing: str = "clip"
    tolerance: float | None = None
    reject_inversion: bool = True
    max_steps: int = 10000

    def __post_init__(self) -> None:
        where = "StepPolicy"
        check_finite_scalar(self.end, where, "end")
        check_positive("increment", self.increment, where)
        for name in ("min_increment", "max_increment", "tolerance"):
            if getattr(self, name) is not None:
                check_positive(name, getattr(self, name), where)
        if not self.min_step <= self.increment <= self.max_step:
            raise ParameterError(
                f"{where}: need min_increment <= increment <= max_increment, got "
                f"{self.min_step}, {self.increment}, {self.max_step}"
            )
        if not (is_finite_number(self.cutback) and 0 < self.cutback < 1):
            raise ParameterError(f"{where}: cutback must lie in (0, 1), got {self.cutback!r}")
        if not (is_finite_number(self.growth) and self.growth >= 1):
            raise ParameterError(f"{where}: growth must be a finite number >= 1, got {self.growth!r}")
        check_count("grow_after", self.grow_after, where)
        check_count("max_steps", self.max_steps, where)
        if self.easy_iterations is not None:
            check_count("easy_iterations", self.easy_iterations, where)
        bad = [t for t in self.must_hit if not is_finite_number(t)]
        if bad:
            raise ParameterError(f"{where}: must_hit times must be finite numbers, got {bad[0]!r}")
        object.__setattr__(self, "must_hit", tuple(float(t) for t in self.must_hit))
        if self.landing not in LANDINGS:
            raise ParameterError(f"{where}: landing must be one of {LANDINGS}, got {self.landing!r}")

    @property
    def min_step(self) -> float:
        """Effective ``min_increment``."""
        return self.min_increment if self.min_increment is not None else self.increment / 2**10

    @property
    def max_step(self) -> float:
        """Effective ``max_increment``."""
        if self.max_increment is not None:
            return self.max_increment
        return 16 * self.increment if self.tolerance is not None else self.increment


@dataclass(frozen=True)
class LoadStepping:
    """Preset of :class:`StepPolicy` for a quasi-static ramp (:func:`solve_quasistatic`).

    Attributes:
        initial_increment: First increment of the load factor (time of the ramp).
        min_increment: Smallest increment before giving up.
        max_increment: Largest increment.
        growth: Factor applied to the increment after an easy step.
        easy_iterations: A step converging in at most this many Newton
            iterations counts as easy.
        max_steps: Hard limit on attempted steps.
    """

    initial_increment: float = 1.0
    min_increment: float = 1.0 / 1024
    max_increment: float = 1.0
    growth: float = 2.0
    easy_iterations: int = 6
    max_steps: int = 10000

    def __post_init__(self) -> None:
        for name in ("initial_increment", "min_increment", "max_increment", "growth"):
            check_positive(name, getattr(self, name), "LoadStepping")
        for name in ("easy_iterations", "max_steps"):
            check_count(name, getattr(self, name), "LoadStepping")
        if not 0 < self.min_increment <= self.initial_increment <= self.max_increment:
            raise ParameterError(
                "LoadStepping: need 0 < min_increment <= initial_increment <= max_increment, got "
                f"{self.min_increment}, {self.initial_increment}, {self.max_increment}"
            )
        if self.growth < 1:
            raise ParameterError(f"LoadStepping: growth must be >= 1, got {self.growth}")

    def policy(self, end: float = 1.0) -> StepPolicy:
        """The policy to reach ``end``: growth after every easy step, the last step clipped."""
        return StepPolicy(
            end=end,
            increment=self.initial_increment,
            min_increment=self.min_increment,
            max_increment=self.max_increment,
            growth=self.growth,
            grow_after=1,
            easy_iterations=self.easy_iterations,
            landing="clip",
            reject_inversion=False,  # the solver's pre-check already refuses J <= min_jacobian
            max_steps=self.max_steps,
        )


@dataclass(frozen=True)
class TimeStepping:
    """Preset of :class:`StepPolicy` for a time integration (:func:`integrate`).

    Attributes:
        dt: Initial (nominal) step.
        t_end: Final time.
        dt_min: Smallest step before giving up (default ``dt / 2**10``).
        dt_max: Largest step (default ``dt`` when not adaptive, ``16 dt`` when adaptive).
        adaptive: Step-doubling error control.
        tolerance: Allowed nodal position difference (length units) in adaptive mode.
        grow_after: Accepted steps without reduction before trying :math:`2\\Delta t`.
        must_hit: Times that steps must land on (in equal steps).
        reject_inversion: Treat a state with :math:`J \\le 0` at a quadrature point as a failure.
        max_steps: Hard limit on attempted steps.
    """

    dt: float
    t_end: float
    dt_min: float | None = None
    dt_max: float | None = None
    adaptive: bool = False
    tolerance: float = 1e-4
    grow_after: int = 4
    must_hit: Sequence[float] = ()
    reject_inversion: bool = True
    max_steps: int = 1_000_000

    def __post_init__(self) -> None:
        where = "TimeStepping"
        for name in (
            ("dt", "t_end", "tolerance")
            + (("dt_min",) if self.dt_min is not None else ())
            + (("dt_max",) if self.dt_max is not None else ())
        ):
            check_finite_scalar(getattr(self, name), where, name)
        if not self.dt > 0:
            raise ParameterError(f"{where}: dt must be > 0, got {self.dt!r}")
        if not (self.dt_min is None or 0 < self.dt_min <= self.dt):
            raise ParameterError(f"{where}: need 0 < dt_min <= dt, got dt_min={self.dt_min!r}")
        if not (self.dt_max is None or self.dt_max >= self.dt):
            raise ParameterError(f"{where}: need dt_max >= dt, got dt_max={self.dt_max!r}")
        if not self.tolerance > 0:
            raise ParameterError(f"{where}: tolerance must be > 0, got {self.tolerance!r}")
        for name in ("grow_after", "max_steps"):
            check_count(name, getattr(self, name), where)
        bad = [t for t in self.must_hit if not is_finite_number(t)]
        if bad:
            raise ParameterError(f"{where}: must_hit times must be finite numbers, got {bad[0]!r}")

    @property
    def min_step(self) -> float:
        """Effective ``dt_min``."""
        return self.dt_min if self.dt_min is not None else self.dt / 2**10

    @property
    def max_step(self) -> float:
        """Effective ``dt_max``."""
        if self.dt_max is not None:
            return self.dt_max
        return 16 * self.dt if self.adaptive else self.dt

    def policy(self) -> StepPolicy:
        """The policy: equal steps to the must-hit times, doubling after ``grow_after`` steps."""
        return StepPolicy(
            end=self.t_end,
            increment=self.dt,
            min_increment=self.min_step,
            max_increment=self.max_step,
            growth=2.0,
            grow_after=self.grow_after,
            easy_iterations=None,
            must_hit=self.must_hit,
            landing="equal",
            tolerance=self.tolerance if self.adaptive else None,
            reject_inversion=self.reject_inversion,
            max_steps=self.max_steps,
        )


# -- records ------------------------------------------------------------------------------
@dataclass
class StepRecord:
    """An accepted step.

    Attributes:
        step: Index of the accepted step (1, 2, ...).
        time: Time reached.
        dt: Increment of this step (negative when ramping down).
        solve_records: The solves that produced the accepted state (two half
            steps with step doubling).
        failed: The solves of the rejected attempts.
        solves: All solves spent on this step (rejected attempts and the
            coarse step of the error estimate included).
        rejected: Rejected attempts (failures and error-control reductions).
        error: Step-doubling estimate (``nan`` without error control).
        wall_time: Seconds spent on this step.
    """

    step: int
    time: float
    dt: float
    solve_records: list[SolveRecord] = field(default_factory=list, repr=False)
    failed: list[SolveRecord] = field(default_factory=list, repr=False)
    solves: int = 1
    rejected: int = 0
    error: float = float("nan")
    wall_time: float = 0.0

    @property
    def solve(self) -> SolveRecord:
        """The last accepted solve."""
        return self.solve_records[-1]

    @property
    def iterations(self) -> int:
        """Newton iterations of the accepted solves."""
        return sum(r.iterations for r in self.solve_records)

    @property
    def min_J(self) -> float:
        """Smallest quadrature-point :math:`J` of the accepted state."""
        return self.solve.min_J

    def as_dict(self) -> dict:
        """JSON-serialisable summary (without the solve records)."""
        return {
            "step": self.step,
            "time": self.time,
            "dt": self.dt,
            "iterations": self.iterations,
            "solves": self.solves,
            "rejected": self.rejected,
            "error": self.error,
            "min_J": self.min_J,
            "reason": self.solve.reason_name,
            "wall_time": self.wall_time,
        }


"""The record of an accepted time step (one record type for every run)."""


# -- stages -------------------------------------------------------------------------------
_SnapshotT = TypeVar("_SnapshotT")


@runtime_checkable
class Stage(Protocol[_SnapshotT]):
    """What :func:`run_steps` steps: the stage owns its state (unknowns, rates, time).

    :func:`run_steps` calls :meth:`save` at the start of each step,
    :meth:`advance` for an attempt, :meth:`commit` when the attempt passes and
    :meth:`restore` when it fails (or to take the two half steps of an error
    estimate from the same state).

    Attributes:
        kind: ``"quasi-static"`` or ``"dynamic"`` (for summaries).
    """

    kind: str

    @property
    def time(self) -> float:
        """Time of the accepted state."""

    def save(self) -> _SnapshotT:
        """Snapshot of the accepted state."""

    def restore(self, state: _SnapshotT) -> None:
        """Return to a snapshot (loads and boundary values included)."""

    def advance(self, t: float, dt: float) -> SolveRecord:
        """Solve for the state at ``t + dt`` from the accepted state at ``t`` (not yet accepted)."""

    def commit(self) -> None:
        """Accept the state of the last :meth:`advance`."""

    def distance(self, state: _SnapshotT) -> float:
        """Largest nodal displacement difference between the current state and a snapshot."""


def _displacement_dofs(problem: SolidProblem) -> np.ndarray | None:
    """Owned displacement entries of ``problem.u``'s array; ``None`` when all of ``u`` is displacement."""
    space = problem.displacement_space()
    if not space.component():
        return None
    collapsed, dofs = space.collapse()
    n = collapsed.dofmap.index_map.size_local * collapsed.dofmap.index_map_bs
    return np.asarray(dofs, dtype=np.int32).reshape(-1)[:n]


def _max_nodal_distance(problem: SolidProblem, dofs: np.ndarray | None, a: np.ndarray, b: np.ndarray) -> float:
    if dofs is None:
        imap = problem.u.function_space.dofmap.index_map
        bs = problem.u.function_space.dofmap.index_map_bs
        n = imap.size_local * bs
        d = (a[:n] - b[:n]).reshape(-1, bs)
    else:
        d = (a[dofs] - b[dofs]).reshape(-1, problem.domain.gdim)
    local = float(np.sqrt((d**2).sum(axis=1)).max()) if d.size else 0.0
    return problem.domain.comm.allreduce(local, op=MPI.MAX)


@dataclass
class _Snapshot:
    time: float
    u: np.ndarray
    inner: object = None


class QuasiStaticStage:
    """A quasi-static ramp: :meth:`advance` moves the loads to ``t + dt`` and solves.

    Args:
        problem: A :class:`~hyperfem.problem.protocol.SolidProblem`; its time is the start.
        solver: The Newton solver built on it.
    """

    kind = "quasi-static"

    def __init__(self, problem: SolidProblem, solver: NewtonSolver) -> None:
        self.problem = problem
        self.solver = solver
        self._time = float(problem.time)
        self._trial = self._time
        self._dofs = _displacement_dofs(problem)

    @property
    def time(self) -> float:
        """Time of the accepted state."""
        return self._time

    def save(self) -> _Snapshot:
        """Copy of the unknown and the time."""
        return _Snapshot(self._time, self.problem.u.x.array.copy())

    def restore(self, state: _Snapshot) -> None:
        """Back to ``state``: unknown, loads and boundary values."""
        self.problem.u.x.array[:] = state.u
        self.problem.set_time(state.time)
        self._time = self._trial = state.time

    def advance(self, t: float, dt: float) -> SolveRecord:
        """Loads at ``t + dt``, Newton from the current state."""
        self._trial = t + dt
        self.problem.set_time(self._trial)
        return self.solver.solve()

    def commit(self) -> None:
        """The solved state becomes the accepted one."""
        self._time = self._trial

    def distance(self, state: _Snapshot) -> float:
        """Largest nodal displacement difference from ``state``."""
        return _max_nodal_distance(self.problem, self._dofs, self.problem.u.x.array, state.u)


class DynamicStage:
    """Time steps of an :class:`~hyperfem.dynamics.IncrementalProblem` (any integrator).

    :meth:`advance` is ``prepare(dt)`` (loads, boundary values, predictor) and a
    solve; :meth:`commit` updates velocity, acceleration and time.

    Args:
        problem: The incremental problem (a :class:`~hyperfem.problem.protocol.TimeStepProblem`);
            its accepted state is the start.
        solver: The Newton solver built on it.
    """

    kind = "dynamic"

    def __init__(self, problem: TimeStepProblem, solver: NewtonSolver):
        self.problem = problem
        self.solver = solver
        self._time = float(problem.save().t)  # the accepted time t_n
        self._pending: tuple[float, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._dofs = _displacement_dofs(problem)

    @property
    def time(self) -> float:
        """Time of the accepted state."""
        return self._time

    def save(self) -> _Snapshot:
        """The incremental problem's snapshot :math:`(t, u, v, a)`."""
        return _Snapshot(self._time, self.problem.u.x.array.copy(), self.problem.save())

    def restore(self, state: _Snapshot) -> None:
        """Back to ``state`` (loads and boundary values included)."""
        self.problem.restore(state.inner)
        self._time = state.time
        self._pending = None

    def advance(self, t: float, dt: float) -> SolveRecord:
        """Prepare and solve the step from the accepted state to ``t + dt``."""
        if not dt > 0:
            raise ParameterError(
                f"DynamicStage: time steps must be > 0 (time runs forward), got dt = {dt:g} at t = {t:g}"
            )
        inputs = self.problem.step_inputs()
        self.problem.prepare(dt)
        self._pending = (dt, inputs)
        return self.solver.solve()

    def commit(self) -> None:
        """Update velocity and acceleration; the step's end becomes the accepted time."""
        assert self._pending is not None  # commit follows advance
        dt, inputs = self._pending
        self.problem.commit(dt, *inputs)
        self._time += dt
        self._pending = None

    def distance(self, state: _Snapshot) -> float:
        """Largest nodal displacement difference from ``state``."""
        return _max_nodal_distance(self.problem, self._dofs, self.problem.u.x.array, state.u)


# -- the loop -----------------------------------------------------------------------------
@dataclass
class _Attempt:
    ok: bool
    accepted: list[SolveRecord]
    records: list[SolveRecord]
    error: float
    reason: str


def _acceptable(record: SolveRecord, policy: StepPolicy) -> bool:
    return record.converged and (not policy.reject_inversion or record.min_J > 0.0)


def _why(record: SolveRecord) -> str:
    detail = f": {record.message}" if record.message else ""
    return f"SNES {record.reason_name}{detail}, min J {record.min_J:.3g}"


def _landing(t: float, target: float) -> float:
    """The increment ``dt`` with ``t + dt == target`` exactly in floating point (``target - t`` may miss by one ulp)."""
    dt = target - t
    for _ in range(4):
        if t + dt == target:
            break
        dt = math.nextafter(dt, math.inf if t + dt < target else -math.inf)
    return dt


def _attempt(
    stage: Stage[Any], policy: StepPolicy, t: float, sign: float, h: float, state: object, target: float | None = None
) -> _Attempt:
    """One attempt of a step of length ``h`` (and its error estimate); committed if it passes.

    A step that ends on ``target`` (a must-hit time or the end) lands on it exactly.
    """
    dt = sign * h
    if target is not None and abs(t + dt - target) <= 1e-12 * max(1.0, abs(target)):
        dt = _landing(t, target)
    record = stage.advance(t, dt)
    records = [record]
    ok = _acceptable(record, policy)
    if ok:
        stage.commit()
    accepted, error, reason = [record], float("nan"), ""
    if ok and policy.tolerance is not None:
        coarse = stage.save()
        stage.restore(state)
        accepted = []
        for half in range(2):
            # Two halves: the second ends where the full step ended (exactly, on a target).
            record = stage.advance(stage.time, sign * (h / 2) if half == 0 else _landing(stage.time, t + dt))
            records.append(record)
            ok = _acceptable(record, policy)
            if not ok:
                break
            stage.commit()
            accepted.append(record)
        if ok:
            error = stage.distance(coarse)
            if error > policy.tolerance:
                ok, reason = False, f"error {error:.3g} > tolerance {policy.tolerance:g}"
    if not ok and not reason:
        reason = _why(records[-1])
    return _Attempt(ok, accepted, records, error, reason)


@dataclass
class _Course:
    """Where a run goes from its start: the direction, the end and the must-hit times in between, in order."""

    end: float
    sign: float
    eps: float
    hits: list[float]

    @classmethod
    def plan(cls, t0: float, policy: StepPolicy) -> _Course:
        """The course from ``t0`` to ``policy.end`` (down when the end lies below ``t0``)."""
        end = float(policy.end)
        eps = 1e-12 * max(1.0, abs(end))
        if not end < t0:
            return cls(end, 1.0, eps, sorted({h for h in policy.must_hit if t0 + eps < h < end - eps} | {end}))
        hits = sorted({h for h in policy.must_hit if end + eps < h < t0 - eps} | {end}, reverse=True)
        return cls(end, -1.0, eps, hits)

    def of(self) -> str:
        """`` of END`` for messages (empty for an end no run reaches: a continuation that stops by other means)."""
        return f" of {self.end:g}" if abs(self.end) < UNBOUNDED else ""

    def remaining(self, t: float) -> bool:
        """Whether ``t`` falls short of the end."""
        return t < self.end - self.eps if self.sign > 0 else t > self.end + self.eps

    def target(self, t: float) -> float:
        """The next must-hit time (or the end) beyond ``t``."""
        if self.sign > 0:
            return next(hit for hit in self.hits if hit > t + self.eps)
        return next(hit for hit in self.hits if hit < t - self.eps)


@dataclass
class _Control:
    """The increment control carried from step to step: nominal increment, easy streak, attempts spent."""

    dt: float
    streak: int
    attempts: int


def _step_length(policy: StepPolicy, dt: float, span: float) -> float:
    """The first length tried for a step ``span`` short of its target (``landing``: clipped or equal steps)."""
    if policy.landing == "equal":
        return span / max(1, math.ceil(span / dt - 1e-6))
    return min(dt, span)


def _grow(policy: StepPolicy, control: _Control, accepted: list[SolveRecord]) -> None:
    """Count an easy step towards growth; after ``grow_after`` of them the increment grows."""
    easy = policy.easy_iterations is None or max(r.iterations for r in accepted) <= policy.easy_iterations
    control.streak = control.streak + 1 if easy else 0
    if control.streak >= policy.grow_after:
        control.dt = min(control.dt * policy.growth, policy.max_step)
        control.streak = 0


def _step(
    stage: Stage[Any], policy: StepPolicy, course: _Course, control: _Control, t: float, history: list[StepRecord]
) -> StepRecord:
    """One accepted step from ``t``: attempts cut back until one passes, then the increment control."""
    start = _time.perf_counter()
    h = _step_length(policy, control.dt, course.sign * (course.target(t) - t))
    state = stage.save()
    solves, rejected = 0, 0
    failed: list[SolveRecord] = []
    while True:
        control.attempts += 1
        if control.attempts > policy.max_steps:
            raise ConvergenceError(
                f"stepping exceeded {policy.max_steps} steps (rejected attempts included) at t = {t:g} "
                f"{course.of()}",
                t,
                history,
            )
        attempt = _attempt(stage, policy, t, course.sign, h, state, course.target(t))
        solves += len(attempt.records)
        if attempt.ok:
            break
        failed.extend(attempt.records)
        stage.restore(state)
        rejected += 1
        control.streak = 0
        h = h * policy.cutback
        control.dt = h
        if h < policy.min_step:
            raise ConvergenceError(
                f"stepping failed: reached t = {t:g}{course.of()}; step {h:g} below the minimum "
                f"{policy.min_step:g} ({attempt.reason})",
                t,
                history,
            )
    _grow(policy, control, attempt.accepted)
    # A stage whose time increment is not the step length asked for (continuation) says what it was.
    increment = getattr(stage, "last_increment", None)
    return StepRecord(
        step=len(history) + 1,
        time=stage.time,
        dt=course.sign * h if increment is None else float(increment),
        solve_records=attempt.accepted,
        failed=failed,
        solves=solves,
        rejected=rejected,
        error=attempt.error,
        wall_time=_time.perf_counter() - start,
    )


def run_steps(
    stage: Stage[Any],
    policy: StepPolicy,
    on_step: Callable[[StepRecord], None] | None = None,
    *,
    streak: int = 0,
    attempts: int = 0,
    stop: Callable[[StepRecord], bool] | None = None,
) -> list[StepRecord]:
    """Step ``stage`` from its time to ``policy.end``.

    Args:
        stage: What to step (its state is the start and, after a failure, the
            last accepted state).
        policy: Increment control.
        on_step: Called after every accepted step (output, diagnostics).
        streak: Easy steps already counted towards the next growth of the
            increment (a run continued from a checkpoint carries on its count).
        attempts: Attempts already spent of ``policy.max_steps`` (likewise).
        stop: Called after ``on_step``; ``True`` ends the run before ``policy.end``
            (a probe reached a value, a continuation its last step).

    Returns:
        The accepted steps.

    Raises:
        ConvergenceError: When a step falls below ``policy.min_step`` or
            ``policy.max_steps`` attempts are spent; ``time`` is the last time
            reached and ``history`` the accepted steps.
    """
    t = stage.time
    course = _Course.plan(t, policy)
    if not (isinstance(streak, int) and 0 <= streak < policy.grow_after):
        raise ParameterError(f"run_steps: streak must be an integer in [0, grow_after), got {streak!r}")
    if not (isinstance(attempts, int) and attempts >= 0):
        raise ParameterError(f"run_steps: attempts must be an integer >= 0, got {attempts!r}")
    control = _Control(min(policy.increment, policy.max_step), streak, attempts)
    history: list[StepRecord] = []
    while course.remaining(t):
        record = _step(stage, policy, course, control, t, history)
        t = record.time
        history.append(record)
        if on_step is not None:
            on_step(record)
        if stop is not None and stop(record):
            break
    return history


# -- the two classic entry points ---------------------------------------------------------
def solve_quasistatic(
    solver: NewtonSolver,
    target: float = 1.0,
    stepping: LoadStepping | None = None,
    on_step: Callable[[StepRecord], None] | None = None,
) -> list[StepRecord]:
    """Ramp the time (load factor) of ``solver.problem`` to ``target``, up or down.

    Args:
        solver: The Newton solver (its problem holds the state).
        target: Final time; below the problem's time the loads ramp down.
        stepping: Increment control (default :class:`LoadStepping`).
        on_step: Called after every converged step (e.g. to write output).

    Returns:
        The converged steps.

    Raises:
        ConvergenceError: When the increment falls below ``min_increment``;
            ``time`` and ``history`` tell how far it got.
    """
    stepping = LoadStepping() if stepping is None else stepping
    return run_steps(QuasiStaticStage(solver.problem, solver), stepping.policy(target), on_step)


def integrate(
    problem: TimeStepProblem,
    solver: NewtonSolver,
    stepping: TimeStepping,
    on_step: Callable[[StepRecord], None] | None = None,
) -> list[StepRecord]:
    """Advance ``problem`` (an :class:`~hyperfem.dynamics.IncrementalProblem`) to ``stepping.t_end``.

    Args:
        problem: The incremental problem; its state is the start.
        solver: A :class:`~hyperfem.solver.NewtonSolver` built on ``problem``.
        stepping: Step control.
        on_step: Called after every accepted step (diagnostics, output).

    Returns:
        The accepted steps.

    Raises:
        ConvergenceError: When the step falls below ``dt_min``; ``time`` holds
            the last time reached and ``history`` the accepted steps.
        ParameterError: If ``t_end`` lies before the problem's time.
    """
    if not stepping.t_end > problem.time:
        raise ParameterError(
            f"integrate: t_end = {stepping.t_end:g} is not after the problem's time {problem.time:g} "
            "(time runs forward; a quasi-static ramp can go down, a time integration cannot)"
        )
    return run_steps(DynamicStage(problem, solver), stepping.policy(), on_step)
