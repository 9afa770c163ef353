r"""Time stepping with cutback and step-doubling error control.

One loop serves every scheme (quasi-static included). A step of size
:math:`\Delta t` is *rejected* and retried with :math:`\Delta t/2` when

* SNES does not converge, or the solution has an inverted quadrature point
  (:math:`J \le 0`) — the automatic cutback; or
* (adaptive mode, seed 003 §5.7.7) one step of :math:`\Delta t` and two steps
  of :math:`\Delta t/2` from the same state end at nodal positions that differ
  by more than ``tolerance``:

  .. math::
      e = \max_\text{nodes} \bigl|x^{(\Delta t)} - x^{(\Delta t/2, \Delta t/2)}\bigr| > \text{tol}.

  Otherwise the (more accurate) two-half-step result is accepted.

After ``grow_after`` consecutive accepted steps without a reduction the step
is doubled, up to ``dt_max``. Steps are shortened to land exactly on the
*must-hit* times (ends of ramps, output times) and on ``t_end``: the interval
to the next such time is split into equal steps no longer than :math:`\Delta t`,
so no sliver steps arise; this does not change the nominal :math:`\Delta t`.
"""

from __future__ import annotations

import math
import numbers
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from hyperfem.errors import ConvergenceError, ParameterError
from hyperfem.materials.parameters import is_finite_number
from hyperfem.solver.newton import SolveRecord

__all__ = ["TimeStepRecord", "TimeStepping", "integrate"]


@dataclass(frozen=True)
class TimeStepping:
    """Parameters of the time loop.

    Attributes:
        dt: Initial (nominal) step.
        t_end: Final time.
        dt_min: Smallest step before giving up (default ``dt / 2**10``).
        dt_max: Largest step (default ``dt`` when not adaptive, ``16 dt`` when adaptive).
        adaptive: Step-doubling error control.
        tolerance: Allowed nodal position difference (length units) in adaptive mode.
        grow_after: Accepted steps without reduction before trying :math:`2\\Delta t`.
        must_hit: Times that steps must land on.
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
            value = getattr(self, name)
            if not is_finite_number(value):
                raise ParameterError(f"{where}: {name} must be a finite number, got {value!r}")
        if not self.dt > 0:
            raise ParameterError(f"{where}: dt must be > 0, got {self.dt!r}")
        if not (self.dt_min is None or 0 < self.dt_min <= self.dt):
            raise ParameterError(f"{where}: need 0 < dt_min <= dt, got dt_min={self.dt_min!r}")
        if not (self.dt_max is None or self.dt_max >= self.dt):
            raise ParameterError(f"{where}: need dt_max >= dt, got dt_max={self.dt_max!r}")
        if not self.tolerance > 0:
            raise ParameterError(f"{where}: tolerance must be > 0, got {self.tolerance!r}")
        for name in ("grow_after", "max_steps"):
            value = getattr(self, name)
            if not (isinstance(value, numbers.Integral) and not isinstance(value, bool) and value >= 1):
                raise ParameterError(f"{where}: {name} must be an integer >= 1, got {value!r}")
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


@dataclass
class TimeStepRecord:
    """An accepted time step.

    Attributes:
        step: Index of the accepted step (1, 2, ...).
        time: Time reached.
        dt: Size of the step.
        iterations: Newton iterations of the solves that produced the accepted
            state (two half steps in adaptive mode).
        solves: All nonlinear solves spent on this step, rejected attempts and
            the coarse step of the error estimate included.
        rejected: Rejected attempts (failures and error-control reductions).
        error: Step-doubling estimate (``nan`` when not adaptive).
        min_J: Smallest quadrature-point :math:`J` of the accepted state.
        wall_time: Seconds spent on this step.
        solve_records: The :class:`SolveRecord` of the accepted solves.
    """

    step: int
    time: float
    dt: float
    iterations: int
    solves: int
    rejected: int
    error: float
    min_J: float
    wall_time: float
    solve_records: list[SolveRecord] = field(default_factory=list, repr=False)

    def as_dict(self) -> dict:
        """JSON-serialisable form (without the solve records)."""
        return {k: v for k, v in self.__dict__.items() if k != "solve_records"}


def _max_nodal_distance(problem, a: np.ndarray, b: np.ndarray) -> float:
    imap = problem.V.dofmap.index_map
    bs = problem.V.dofmap.index_map_bs
    n = imap.size_local * bs
    d = (a[:n] - b[:n]).reshape(-1, bs)
    local = float(np.sqrt((d**2).sum(axis=1)).max()) if d.size else 0.0
    return problem.domain.comm.allreduce(local, op=MPI.MAX)


def integrate(
    problem,
    solver,
    stepping: TimeStepping,
    on_step: Callable[[TimeStepRecord], None] | None = None,
) -> list[TimeStepRecord]:
    """Advance ``problem`` (an :class:`~hyperfem.dynamics.IncrementalProblem`) to ``stepping.t_end``.

    Args:
        problem: The incremental problem; its state is the start.
        solver: A :class:`~hyperfem.solver.NewtonSolver` built on ``problem``.
        stepping: Step control.
        on_step: Called after every accepted step (diagnostics, output).

    Returns:
        The accepted steps.

    Raises:
        ConvergenceError: When the step falls below ``dt_min``; ``load_factor``
            holds the last time reached and ``history`` the accepted steps.
    """
    t_end = float(stepping.t_end)
    eps = 1e-12 * max(1.0, abs(t_end))
    hits = sorted({float(h) for h in stepping.must_hit if problem.time + eps < h < t_end - eps} | {t_end})
    dt = min(stepping.dt, stepping.max_step)
    streak = 0
    history: list[TimeStepRecord] = []
    attempts = 0

    def advance(h: float) -> tuple[bool, SolveRecord]:
        u_n, v_n, a_n = problem.step_inputs()
        problem.prepare(h)
        rec = solver.solve()
        ok = rec.converged and (not stepping.reject_inversion or rec.min_J > 0.0)
        if ok:
            problem.commit(h, u_n, v_n, a_n)
        return ok, rec

    while problem.time < t_end - eps:
        start = _time.perf_counter()
        t = problem.time
        target = next(hit for hit in hits if hit > t + eps)
        # Land on the next must-hit time in equal steps no longer than dt (no slivers).
        h = (target - t) / max(1, math.ceil((target - t) / dt - 1e-6))
        state = problem.save()
        solves, rejected = 0, 0
        while True:
            attempts += 1
            if attempts > stepping.max_steps:
                raise ConvergenceError(
                    f"time stepping exceeded {stepping.max_steps} attempts at t = {problem.time:g}",
                    problem.time,
                    history,
                )
            error = float("nan")
            ok, rec = advance(h)
            solves += 1
            accepted = [rec]
            if ok and stepping.adaptive:
                u_coarse = problem.u.x.array.copy()
                problem.restore(state)
                ok, rec1 = advance(h / 2)
                solves += 1
                accepted = [rec1]
                if ok:
                    ok, rec2 = advance(h / 2)
                    solves += 1
                    accepted.append(rec2)
                    rec = rec2
                else:
                    rec = rec1
                if ok:
                    error = _max_nodal_distance(problem, problem.u.x.array, u_coarse)
                    if error > stepping.tolerance:
                        ok = False
                        reason = f"error {error:.3g} > tolerance {stepping.tolerance:g}"
            if ok:
                break
            if np.isnan(error):
                reason = f"SNES {rec.reason_name}, min J {rec.min_J:.3g}"
            problem.restore(state)
            rejected += 1
            streak = 0
            h = h / 2
            dt = h
            if h < stepping.min_step:
                raise ConvergenceError(
                    f"time stepping failed at t = {t:g}: step {h:g} below dt_min {stepping.min_step:g} ({reason})",
                    t,
                    history,
                )
        streak += 1
        if streak >= stepping.grow_after and (stepping.adaptive or dt < stepping.max_step):
            dt = min(2 * dt, stepping.max_step)
            streak = 0
        record = TimeStepRecord(
            step=len(history) + 1,
            time=problem.time,
            dt=h,
            iterations=sum(r.iterations for r in accepted),
            solves=solves,
            rejected=rejected,
            error=error,
            min_J=accepted[-1].min_J,
            wall_time=_time.perf_counter() - start,
            solve_records=accepted,
        )
        history.append(record)
        if on_step is not None:
            on_step(record)
    return history
