"""Quasi-static load stepping with automatic cutback.

The load factor ``s`` goes from its current value to ``target``. A step that
fails (SNES diverged, or an inverted element) is undone and retried with half
the increment; after an easy step (few Newton iterations) the increment grows.
Below ``min_increment`` a :class:`~hyperfem.errors.ConvergenceError` names the
last load factor reached; completed steps have already been handed to the
``on_step`` callback, so their results are never lost.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable
from dataclasses import dataclass, field

from hyperfem.errors import ConvergenceError, ParameterError
from hyperfem.materials.parameters import check_positive
from hyperfem.solver.newton import NewtonSolver, SolveRecord

__all__ = ["LoadStepping", "StepRecord", "solve_quasistatic"]


@dataclass(frozen=True)
class LoadStepping:
    """Parameters of the load-stepping loop.

    Attributes:
        initial_increment: First increment of the load factor.
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
            value = getattr(self, name)
            if not (isinstance(value, numbers.Integral) and not isinstance(value, bool) and value >= 1):
                raise ParameterError(f"LoadStepping: {name} must be an integer >= 1, got {value!r}")
        if not 0 < self.min_increment <= self.initial_increment <= self.max_increment:
            raise ParameterError(
                "LoadStepping: need 0 < min_increment <= initial_increment <= max_increment, got "
                f"{self.min_increment}, {self.initial_increment}, {self.max_increment}"
            )
        if self.growth < 1:
            raise ParameterError(f"LoadStepping: growth must be >= 1, got {self.growth}")


@dataclass
class StepRecord:
    """A converged load step.

    Attributes:
        load_factor: Load factor reached.
        increment: Increment used for this step.
        cutbacks: Failed attempts before this step converged.
        solve: The converged :class:`SolveRecord`.
        failed: Records of the failed attempts.
    """

    load_factor: float
    increment: float
    cutbacks: int
    solve: SolveRecord
    failed: list[SolveRecord] = field(default_factory=list)

    def as_dict(self) -> dict:
        """JSON-serialisable form."""
        return {
            "load_factor": self.load_factor,
            "increment": self.increment,
            "cutbacks": self.cutbacks,
            "solve": self.solve.as_dict(),
            "failed": [f.as_dict() for f in self.failed],
        }


def solve_quasistatic(
    solver: NewtonSolver,
    target: float = 1.0,
    stepping: LoadStepping | None = None,
    on_step: Callable[[StepRecord], None] | None = None,
) -> list[StepRecord]:
    """Ramp the load factor of ``solver.problem`` to ``target``.

    Args:
        solver: The Newton solver (its problem holds the state).
        target: Final load factor.
        stepping: Increment control (default :class:`LoadStepping`).
        on_step: Called after every converged step (e.g. to write output).

    Returns:
        The converged steps.

    Raises:
        ConvergenceError: When the increment falls below ``min_increment``;
            ``load_factor`` and ``history`` tell how far it got.
    """
    stepping = LoadStepping() if stepping is None else stepping
    problem = solver.problem
    u = problem.u
    s = problem.load_factor
    inc = min(stepping.initial_increment, stepping.max_increment)
    history: list[StepRecord] = []
    failed: list[SolveRecord] = []
    saved = u.x.array.copy()
    attempts = 0
    while s < target - 1e-12 * max(1.0, abs(target)):
        attempts += 1
        if attempts > stepping.max_steps:
            raise ConvergenceError(
                f"load stepping exceeded {stepping.max_steps} steps at load factor {s:g}", s, history
            )
        step = min(inc, target - s)
        problem.set_load_factor(s + step)
        record = solver.solve()
        if record.converged:
            s += step
            saved[:] = u.x.array
            entry = StepRecord(s, step, len(failed), record, failed)
            history.append(entry)
            failed = []
            if on_step is not None:
                on_step(entry)
            if record.iterations <= stepping.easy_iterations:
                inc = min(inc * stepping.growth, stepping.max_increment)
            continue
        failed.append(record)
        u.x.array[:] = saved
        problem.set_load_factor(s)
        inc = step / 2
        if inc < stepping.min_increment:
            raise ConvergenceError(
                f"load stepping failed: reached load factor {s:g} of {target:g}; "
                f"increment {inc:g} below minimum {stepping.min_increment:g} "
                f"(last SNES reason {record.reason_name})",
                s,
                history,
            )
    return history
