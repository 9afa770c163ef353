"""A run: a problem, its solver, a step policy and the outputs that observe every accepted step.

:class:`Simulation` is the same for statics and dynamics: it wraps the
problem in a :class:`~hyperfem.solver.stepping.QuasiStaticStage`, or in a
:class:`~hyperfem.solver.stepping.DynamicStage` when the problem is a time
step (:class:`~hyperfem.dynamics.IncrementalProblem`), or in the stage it is
given (``stage=``: :class:`~hyperfem.dynamics.SemiImplicitStage` for one
linearization per step, :class:`~hyperfem.dynamics.ExplicitStage` for the
central differences of :class:`~hyperfem.dynamics.ExplicitDynamics`, which
steps itself and takes no Newton solver), and steps it with
:func:`~hyperfem.solver.stepping.run_steps`. After the initial state and
after every accepted step it

1. refreshes :class:`StateFunctions` (the displacement, pressure and velocity as
   plain functions, for the three-field problem too),
2. builds one *row*: step, time, increment, Newton iterations, rejected
   attempts, min J, the solver's consistency indicators, and the columns
   the outputs measure (:meth:`~hyperfem.simulation.outputs.Output.measure`),
3. lets the outputs write (:meth:`~hyperfem.simulation.outputs.Output.write`):
   VTX frames, the CSV line, the JSON summary.

So every accepted step is on disk before the next one starts. When a step
fails after all cutbacks the outputs are closed (a
:class:`~hyperfem.simulation.checkpoint.Checkpoint` among them writes the
last converged state), the summary says ``"completed": false`` and the
:class:`~hyperfem.errors.ConvergenceError` is raised again, naming where the
completed steps and the checkpoint are.

``run(restart=path)`` continues from a checkpoint instead of the initial
state (:mod:`hyperfem.simulation.checkpoint`): same problem, solver, outputs
and policy as the run that wrote it (the end time may differ) and the same
mesh, on any number of ranks. Steps are numbered on from the checkpoint, and the rows,
summary and files continue those of the first run.

The real-time stepper (:class:`~hyperfem.dynamics.RealtimeStepper`) is the
one time stepper that does not run here; its module says why.
"""

from __future__ import annotations

import signal
import time as _time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from hyperfem.io.probes import PointProbe
from hyperfem.errors import ConvergenceError, Interrupted, ParameterError
from hyperfem.mesh.quality import MeshQuality, mesh_quality
from hyperfem.problem.protocol import MixedProblemProtocol, SolidProblem, TimeStepProblem, TimeStepState
from hyperfem.simulation import checkpoint as _checkpoint
from hyperfem.simulation.interrupt import InterruptGuard
from hyperfem.solver.newton import NewtonSolver, SolveRecord
from hyperfem.simulation.outputs import Output
from hyperfem.solver.arc_length import ArcLength, ArcLengthStage
from hyperfem.solver.stepping import DynamicStage, QuasiStaticStage, Stage, StepPolicy, StepRecord, run_steps

if TYPE_CHECKING:
    from hyperfem.dynamics.explicit import ExplicitDynamics

__all__ = ["LARGE_DISPLACEMENT", "LargeDisplacementWarning", "Simulation", "StateFunctions"]

LARGE_DISPLACEMENT = 10.0
"""A displacement this many times the body's size draws a :class:`LargeDisplacementWarning`."""


class LargeDisplacementWarning(UserWarning):
    """The displacement is far larger than the body: probably a load or unit error."""


class StageType(Protocol):
    """A :class:`~hyperfem.solver.stepping.Stage` class: ``kind`` and ``stage(problem, solver)``."""

    kind: str

    def __call__(self, problem: Any, solver: Any, /) -> Stage[Any]:
        """The stage of ``problem`` stepped by ``solver`` (``None`` for a problem that steps itself)."""


class StepPreset(Protocol):
    """A step-control preset: :class:`~hyperfem.solver.LoadStepping`, :class:`~hyperfem.dynamics.TimeStepping`."""

    def policy(self) -> StepPolicy:
        """The step control it stands for."""


@runtime_checkable
class _Stepper(Protocol):
    """What moves the state, seen by the summary: a Newton solver, or a problem that steps itself."""

    linear_solver_name: str

    def min_J(self) -> float:
        """The smallest volume ratio at the quadrature points."""


def _is_time_step(problem: SolidProblem | ExplicitDynamics) -> bool:
    return isinstance(problem, TimeStepProblem)


def _matched_states(outputs: Sequence[Output], saved: list[dict]) -> list[dict | None]:
    """The saved state of each output: the k-th output of a type gets the k-th saved state of that type."""
    by_type: dict[str, list] = {}
    for entry in saved:
        by_type.setdefault(entry["type"], []).append(entry["state"])
    out = []
    for output in outputs:
        states = by_type.get(type(output).__name__, [])
        out.append(states.pop(0) if states else None)
    return out


class StateFunctions:
    """The state of a problem as plain functions for output and measurement (``Simulation.fields``).

    For the displacement problem :attr:`displacement` is the unknown itself;
    for the three-field problem the collapsed displacement and pressure of
    ``update_fields()``. A time step (``problem.base`` and ``problem.v``: an
    :class:`~hyperfem.dynamics.IncrementalProblem` or an
    :class:`~hyperfem.dynamics.ExplicitDynamics`) adds the velocity, collapsed
    the same way.

    Args:
        problem: A problem, or a time step wrapping one.

    Attributes:
        base: The problem of the body (``problem.base`` for a time step).
        displacement: Displacement function.
        pressure: Pressure function of the three-field problem, else ``None``.
        velocity: Velocity of a time step, else ``None``.
    """

    def __init__(self, problem: SolidProblem | TimeStepState) -> None:
        self.base = problem.base if isinstance(problem, TimeStepState) else problem
        self._mixed = self.base if isinstance(self.base, MixedProblemProtocol) else None
        self.pressure: fem.Function | None
        if self._mixed is not None:
            self.displacement, self.pressure = self._mixed.update_fields()
        else:
            self.displacement, self.pressure = self.base.u, None
        self._v = problem.v if isinstance(problem, TimeStepState) else None
        self._v_dofs: np.ndarray | None = None
        self.velocity = self._v
        space = self.base.displacement_space()
        if self._v is not None and space.component():  # the velocity has the state's blocks
            collapsed, dofs = space.collapse()
            self._v_dofs = np.asarray(dofs, dtype=np.int32).reshape(-1)
            self.velocity = fem.Function(collapsed, name="velocity")

    def refresh(self) -> None:
        """Copy the current state into the functions (nothing to do for the displacement problem)."""
        if self._mixed is not None:
            self._mixed.update_fields()
        if self._v_dofs is not None:
            assert self.velocity is not None and self._v is not None  # set with _v_dofs
            self.velocity.x.array[:] = self._v.x.array[self._v_dofs]

    def output(self) -> list[fem.Function]:
        """What a VTX file shows by default: displacement, pressure, velocity (those that exist)."""
        return [f for f in (self.displacement, self.pressure, self.velocity) if f is not None]


class Simulation:
    """One run of a problem, observed by outputs after every accepted step.

    Args:
        problem: A :class:`~hyperfem.problem.protocol.SolidProblem`, or an
            :class:`~hyperfem.dynamics.IncrementalProblem` for a dynamic run,
            or an :class:`~hyperfem.dynamics.ExplicitDynamics` (with
            ``stage=ExplicitStage`` and no solver).
        solver: The :class:`~hyperfem.solver.NewtonSolver` built on ``problem``;
            ``None`` for a problem that steps itself (the explicit scheme: it
            has ``min_J()`` and ``linear_solver_name`` in its place).
        stepper: The :class:`~hyperfem.solver.stepping.StepPolicy`, or a preset
            (:class:`~hyperfem.solver.LoadStepping` to 1,
            :class:`~hyperfem.dynamics.TimeStepping`) turned into one, or
            :class:`~hyperfem.solver.ArcLength` for a continuation (an
            :class:`~hyperfem.solver.ArcLengthStage` under its policy: the
            load factor is the time, each row gets the step's events —
            ``negative_pivots``, ``stable``, ``limit_point``, ``limit_load``,
            ``bifurcation``, ``switched``, ``arc_length`` — and the summary
            the ``limit_points`` and ``bifurcations`` found).
        outputs: Observers (:mod:`hyperfem.simulation.outputs`,
            :mod:`hyperfem.simulation.measures`), called in this order.
        stage: The :class:`~hyperfem.solver.stepping.Stage` class that takes
            the steps, built as ``stage(problem, solver)`` when the run starts
            (after a restart's state is loaded); its ``kind`` is the run's.
            Default: :class:`~hyperfem.solver.stepping.DynamicStage` for a time
            step, else :class:`~hyperfem.solver.stepping.QuasiStaticStage`.
            :class:`~hyperfem.dynamics.SemiImplicitStage` takes one
            linearization per step, :class:`~hyperfem.dynamics.ExplicitStage`
            the explicit scheme's steps.
        name: Name of the run (summary, messages).
        info: Extra summary entries (case, parameters).
        solve_initial: Solve for equilibrium at the start time before the
            first step (a preloaded or passive initial state); it is row 0.
        case: JSON-serialisable description of the model that a restart must
            match (e.g. the mesh, material, boundary-condition and load
            sections of a case file); its hash is part of every checkpoint's
            fingerprint. Default: ``info``. Plain data only (numbers, strings,
            lists, dicts): anything else is hashed by ``str()``, which may
            name memory addresses that differ between processes.

    Raises:
        ParameterError: ``solve_initial`` without a solver.

    Attributes:
        rows: One dict per recorded state (row 0: the initial state), those
            before a restart included.
        steps: The :class:`~hyperfem.solver.stepping.StepRecord` accepted in
            this process (after a restart: since the restart).
        files: Files the outputs write, by role (``"summary"``, ``"csv"``, VTX names).
        completed: Whether the run reached the end.
        error: Why it stopped, or ``None``.
        stage: The stage of the current (or last) :meth:`run`, ``None`` before.
        stepper: The step-size control's state after the last accepted step
            (:class:`~hyperfem.simulation.checkpoint.StepperState`).
        restarted_from: The checkpoint this run continued from, or ``None``.
        initial_solve: The record of the initial solve (``solve_initial``), or ``None``.
        mesh_quality: The seed 003 §5.6 quality measures of the mesh
            (:class:`~hyperfem.mesh.quality.MeshQuality`), computed when the run
            starts; a :class:`~hyperfem.mesh.quality.MeshQualityWarning` is
            issued for a poor mesh, and the summary holds the statistics.
        state_converged: After a failure: whether the problem holds the last
            converged state (a failed step after all cutbacks), so that it
            may be checkpointed.
    """

    def __init__(
        self,
        problem: SolidProblem | ExplicitDynamics,
        solver: NewtonSolver | None,
        stepper: StepPolicy | StepPreset | ArcLength,
        outputs: Sequence[Output] = (),
        *,
        stage: StageType | None = None,
        name: str = "run",
        info: dict | None = None,
        solve_initial: bool = False,
        case: object = None,
    ) -> None:
        if solver is None and solve_initial:
            raise ParameterError(f"{name}: solve_initial needs a solver (the problem steps itself)")
        if solver is None and stage is None:
            raise ParameterError(
                f"{name}: no solver and no stage: the default stages solve with a NewtonSolver; a problem that "
                "steps itself needs its stage (e.g. stage=hyperfem.dynamics.ExplicitStage for ExplicitDynamics)"
            )
        self.problem = problem
        self.solver = solver
        if stage is None:
            stage = DynamicStage if _is_time_step(problem) else QuasiStaticStage
        self._stage_type = stage
        self.continuation = stepper if isinstance(stepper, ArcLength) else None
        if self.continuation is not None:
            if solver is None or _is_time_step(problem):
                raise ParameterError(f"{name}: arc-length continuation needs a quasi-static problem and its solver")
            self.policy = self.continuation.policy(float(problem.time))
        else:
            self.policy = stepper if isinstance(stepper, StepPolicy) else stepper.policy()
        self.outputs = list(outputs)
        self.name = name
        self.info = dict(info or {})
        self.solve_initial = solve_initial
        self.case = self.info if case is None else case
        self.comm = problem.domain.comm
        self.fields = StateFunctions(problem)
        self.stage: Stage[Any] | None = None
        self.rows: list[dict] = []
        self.steps: list[StepRecord] = []
        self.files: dict[str, str] = {}
        self.completed = False
        self.error: str | None = None
        self.stepper = _checkpoint.StepperState.start(self.policy)
        self.restarted_from: str | None = None
        self.initial_solve: SolveRecord | None = None
        self.state_converged = False
        self.mesh_quality: MeshQuality | None = None
        self._offset = 0
        self._start: float | None = None
        self._wall = 0.0
        self._wall_before = 0.0
        self._warned_size = False
        self._size: float | None = None
        self._guard: InterruptGuard | None = None

    # -- state -----------------------------------------------------------------------
    @property
    def kind(self) -> str:
        """The stage's kind: ``"dynamic"`` (a time step), ``"arc-length"`` (a continuation) or ``"quasi-static"``."""
        return ArcLengthStage.kind if self.continuation is not None else self._stage_type.kind

    @property
    def time(self) -> float:
        """Time of the accepted state."""
        return self.stage.time if self.stage is not None else float(self.problem.time)

    @property
    def step(self) -> int:
        """Accepted steps so far (those before a restart included)."""
        return self._offset + len(self.steps)

    @property
    def wall_time(self) -> float:
        """Seconds spent stepping so far, on the slowest rank (collective; forms are compiled before).

        After a restart: the first run's time up to its checkpoint plus this one's.
        """
        local = self._wall if self._start is None else _time.perf_counter() - self._start
        return self._wall_before + self.comm.allreduce(local, op=MPI.MAX)

    @property
    def dofs(self) -> int:
        """Global number of unknowns (all fields of a mixed space, every component)."""
        dofmap = self.problem.u.function_space.dofmap
        return int(dofmap.index_map.size_global * dofmap.index_map_bs)

    # -- running ---------------------------------------------------------------------
    def run(self, restart: str | Path | None = None) -> dict:
        """Record the initial state (or continue from a checkpoint), step to the policy's end, return the summary.

        Args:
            restart: A checkpoint to continue from: a
                :class:`~hyperfem.simulation.checkpoint.Checkpoint` folder (its
                latest) or one of its step folders. The run must be built as
                the one that wrote it (same mesh, problem and case; any
                number of ranks).

        Raises:
            ConvergenceError: A step failed after all cutbacks (the summary,
                with ``"completed": false``, and a checkpoint of the last
                converged state, if a :class:`~hyperfem.simulation.checkpoint.Checkpoint`
                is among the outputs, are written first; the message names them).
            CheckpointError: ``restart`` is not a readable checkpoint of this run
                (before any output is opened).
            OutputError: An output folder cannot be written (before any solve).
        """
        policy = self.policy
        meta = None
        if restart is not None:
            meta = _checkpoint.load_checkpoint(self, restart)
            self.restarted_from = meta["path"]
            self.rows = [dict(row) for row in meta["rows"]]
            self._offset = int(meta["step"])
            self.stepper = _checkpoint.StepperState(**meta["stepper"])
            self._wall_before = float(meta.get("wall_time", 0.0))
            policy = self.stepper.resumed(self.policy)
            self.fields.refresh()
        if self.continuation is not None:
            assert self.solver is not None and isinstance(self.problem, SolidProblem)  # __init__
            self.stage = ArcLengthStage(self.problem, self.solver, self.continuation)
            if meta is not None and meta.get("stage_state"):
                self.stage.resume(meta["stage_state"])
        else:
            self.stage = self._stage_type(self.problem, self.solver)
        domain = self.fields.base.domain
        if self.mesh_quality is None and domain.mesh.topology.cell_type.name in ("triangle", "tetrahedron"):
            # seed 003 §5.6: look at the mesh before solving on it (a warning, not an error, when poor);
            # the measures are those of simplices (hexahedral meshes run without them)
            self.mesh_quality = mesh_quality(domain)
            self.mesh_quality.warn_if_poor()
        started = []
        self._guard = InterruptGuard(self.comm)
        try:
            self._guard.__enter__()
            for output in self.outputs:
                output.start(self)
                started.append(output)
            self._start = _time.perf_counter()
            if meta is None:
                solver = self.solver if self.solve_initial else None  # __init__: solve_initial needs a solver
                self.initial_solve = solver.solve(raise_on_failure=True) if solver is not None else None
                self._accept(None, self.initial_solve)
            else:
                states = _matched_states(self.outputs, meta.get("outputs", []))
                for output, state in zip(self.outputs, states, strict=True):
                    output.restart(self, state)
            resume = {}
            if meta is not None:  # the step-size control carries on its counts
                resume = {"streak": min(self.stepper.streak, policy.grow_after - 1), "attempts": self.stepper.attempts}
            finished = self._finished()
            run_steps(self.stage, policy, lambda record: self._accept(record, None), stop=finished, **resume)
            self.completed = True
        except ConvergenceError as exc:
            self.error = str(exc)
            self.state_converged = bool(self.rows)
            self._close(started)
            detail = self._kept("last converged state checkpointed in")
            raise ConvergenceError(f"{self.name}: {exc}{detail}", exc.time, exc.history) from exc
        except Interrupted as exc:
            self.error = str(exc)
            self.state_converged = True
            self._close(started)
            detail = self._kept("continue with --restart from")
            if "checkpoint" not in self.files:
                note = "no checkpoint output: the run cannot be continued"
                detail = f"{detail[:-1]}; {note})" if detail else f" ({note})"
            raise Interrupted(f"{self.name}: {exc}{detail}", exc.time) from None
        except Exception as exc:
            self.error = f"{type(exc).__name__}: {exc}"
            raise
        finally:
            self._guard.__exit__(None, None, None)
            self._close(started)
        return self.summary()

    def _finished(self) -> Callable[[StepRecord], bool] | None:
        """When the run ends before its end time: the stage's own test (a continuation's) and its probe stop."""
        stage_test = getattr(self.stage, "finished", None)
        probe_stop = None if self.continuation is None else self.continuation.probe_stop
        if probe_stop is None:
            return stage_test
        point, component, value = probe_stop
        probe = PointProbe(self.fields.base.domain.mesh, [list(point)])
        start = float(probe(self.fields.displacement)[0, component])

        def finished(record: StepRecord) -> bool:
            now = float(probe(self.fields.displacement)[0, component])  # fields are refreshed by _accept
            return bool(stage_test is not None and stage_test(record)) or (now - value) * (start - value) <= 0

        return finished

    def _kept(self, checkpoint_words: str) -> str:
        """`` (completed steps written to ...; <checkpoint_words> CHECKPOINT)`` for the message of a stopped run."""
        where = []
        if "summary" in self.files:
            where.append(f"completed steps written to {self.files['summary']}")
        if "checkpoint" in self.files and Path(self.files["checkpoint"]).name.startswith("step-"):
            where.append(f"{checkpoint_words} {self.files['checkpoint']}")
        return f" ({'; '.join(where)})" if where else ""

    def _body_size(self) -> float:
        """Diagonal of the body's bounding box (reference configuration; collective)."""
        x = self.fields.base.domain.mesh.geometry.x
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        self.comm.Allreduce(x.min(axis=0, initial=np.inf), lo, op=MPI.MIN)
        self.comm.Allreduce(x.max(axis=0, initial=-np.inf), hi, op=MPI.MAX)
        return float(np.linalg.norm(hi - lo))

    def _check_displacement_size(self) -> None:
        """Warn once when the displacement exceeds :data:`LARGE_DISPLACEMENT` times the body's size (collective).

        A load a million times too large (a unit slip: kPa for Pa) "converges" to a state no
        hyperelastic answer is meant to describe (the bend case went 123 km); the run goes on,
        but says so.
        """
        if self._warned_size:
            return
        u = self.fields.displacement
        gdim = self.fields.base.domain.gdim
        values = u.x.array.reshape(-1, gdim)
        largest = self.comm.allreduce(float(np.max(np.linalg.norm(values, axis=1), initial=0.0)), op=MPI.MAX)
        if self._size is None:  # the reference configuration does not change: measured once
            self._size = self._body_size()
        size = self._size
        if largest > LARGE_DISPLACEMENT * size:
            self._warned_size = True
            if self.comm.rank == 0:
                warnings.warn(
                    f"{self.name}: the displacement reaches {largest:.3g} at t = {self.time:g}, "
                    f"{largest / size:.3g} times the body's size ({size:.3g}, the diagonal of its bounding box); "
                    "check the loads, the material constants and their units",
                    LargeDisplacementWarning,
                    stacklevel=2,
                )

    def _check_interrupt(self) -> None:
        """Raise :class:`~hyperfem.errors.Interrupted` on every rank if any rank was signalled (collective)."""
        guard = self._guard
        if guard is None:
            return
        signum = guard.requested()
        if signum:
            what = "interrupted (Ctrl-C)" if signum == signal.SIGINT else f"stopped by {signal.Signals(signum).name}"
            raise Interrupted(f"{what} after step {self.step}, t = {self.time:g}", self.time)

    def _close(self, started: list) -> None:
        """Stop the clock and close the outputs still open (in order; each once).

        Every output is closed even when one fails (a full disk: the summary cannot be
        written, but the field files must still be closed or abandoned); the first
        failure is raised after the others are closed.
        """
        if self._start is not None:
            self._wall, self._start = _time.perf_counter() - self._start, None
        first: Exception | None = None
        while started:
            try:
                started.pop(0).close(self)
            except Exception as exc:  # noqa: BLE001 - re-raised below, after the other outputs are closed
                first = first or exc
        if first is not None:
            raise first

    def _accept(self, record: StepRecord | None, initial: SolveRecord | None) -> None:
        if record is not None:
            record.step += self._offset
            self.steps.append(record)
            self.stepper = self.stepper.after(record, self.policy)
        self.fields.refresh()
        self._check_displacement_size()
        solve = record.solve if record is not None else initial
        row = {
            "step": 0 if record is None else record.step,
            "time": self.time,
            "dt": 0.0 if record is None else record.dt,
            "newton_iterations": record.iterations if record is not None else (solve.iterations if solve else 0),
            "solves": record.solves if record is not None else int(solve is not None),
            "rejected": 0 if record is None else record.rejected,
            "error_estimate": float("nan") if record is None else record.error,
            "min_J": solve.min_J if solve is not None else self._solver_or_problem().min_J(),
            "residual": (solve.residual_norms[-1] if solve is not None and solve.residual_norms else float("nan")),
            "reason": solve.reason_name if solve is not None else "",
            "krylov_iterations": sum(r.linear_iterations for r in record.solve_records) if record is not None
            else (solve.linear_iterations if solve else 0),
            "pc_setup_time": sum(r.pc_setup_time for r in record.solve_records) if record is not None
            else (solve.pc_setup_time if solve else 0.0),
            **(solve.indicators if solve is not None else {}),
        }
        measure = getattr(self.stage, "measure", None)  # a stage's own entries (a continuation's events)
        if measure is not None:
            row.update(measure())
        for output in self.outputs:
            row.update(output.measure(self, record))
        self.rows.append(row)
        for output in self.outputs:
            output.write(self, record)
        self._check_interrupt()

    def _solver_or_problem(self) -> _Stepper:
        """What moves the state: the Newton solver, or the problem that steps itself (``solver=None``)."""
        if self.solver is not None:
            return self.solver
        assert isinstance(self.problem, _Stepper)  # without a solver the problem steps itself (explicit)
        return self.problem

    # -- summary ---------------------------------------------------------------------
    def summary(self, rows: bool = True) -> dict:
        """What the run did so far: size, steps, Newton iterations, outputs' entries, files.

        Args:
            rows: Include every row (``"rows"``).
        """
        base = self.fields.base
        stepped = self.rows[1:]
        its = [int(r["newton_iterations"]) for r in stepped]
        summary = {
            "name": self.name,
            "stage": self.kind,
            "completed": self.completed,
            "error": self.error,
            "time": self.time,
            "end": self.policy.end,
            "dofs": self.dofs,
            "cells": int(base.domain.mesh.topology.index_map(base.domain.tdim).size_global),
            "ranks": self.comm.size,
            "mesh": base.domain.source,
            "degree": base.degree,
            "petsc_options": {} if self.solver is None else {k: str(v) for k, v in self.solver.options.items()},
            "energy_line_search": self.solver is not None and self.solver.energy_line_search,
            "linear_solver": self._solver_or_problem().linear_solver_name,
            "steps": self.step,
            "newton_iterations": its,
            "total_newton_iterations": int(sum(its)),
            "total_krylov_iterations": int(sum(r.get("krylov_iterations", 0) for r in self.rows)),
            "pc_setup_time": float(sum(r.get("pc_setup_time", 0.0) for r in self.rows)),
            "rejected": int(sum(r["rejected"] for r in stepped)),
            "solves": int(sum(r["solves"] for r in stepped)),
            "wall_time": self.wall_time,
            "files": dict(self.files),
            "restarted_from": self.restarted_from,
            "mesh_quality": None if self.mesh_quality is None else self.mesh_quality.stats,
            **self.info,
        }
        if self.continuation is not None:
            if self.continuation.end is None:
                summary["end"] = None
            summary["limit_points"] = [r["limit_load"] for r in stepped if r.get("limit_point")]
            summary["bifurcations"] = [r["time"] for r in stepped if r.get("bifurcation")]
        if self.kind == "quasi-static":
            summary["load_steps"] = summary["steps"]  # the older name of the count, kept for readers of old summaries
        for output in self.outputs:
            summary.update(output.summary(self, summary))
        if rows:
            summary["rows"] = list(self.rows)
        return summary
