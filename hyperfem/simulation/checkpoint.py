r"""Checkpoint and restart of a :class:`~hyperfem.simulation.Simulation`.

A checkpoint holds everything a run needs to continue as if it had never
stopped:

* the state: the unknown ``u`` (for the three-field problem the whole mixed
  vector :math:`(u, p, \theta - 1)`), and for a dynamic run the velocity
  ``v`` and acceleration ``a`` (time :math:`t_n`); stored by
  :mod:`hyperfem.io.checkpoint` (one ``.npz`` per rank, owned dof values
  keyed by global dof index); and the fields of every updater of the problem
  that keeps a state of its own (:class:`StatefulUpdater`, e.g. the history
  of :class:`~hyperfem.materials.viscoelastic.Viscoelastic`), and of every
  external energy of the solver that keeps one (under generalized-:math:`\alpha`
  a contact's frozen force of the step's start, :mod:`hyperfem.contact.interpolation`);
* the time (load factor) and the count of accepted steps;
* the state of the step-size control (:class:`StepperState`): the nominal
  increment, the run of easy steps towards the next growth, the attempts spent;
* the rows recorded so far and what each output keeps
  (:meth:`~hyperfem.simulation.outputs.Output.state`; on a restart the k-th
  output of a class gets the state of the k-th output of that class, so
  outputs may be added or removed); the rows, and the lists in an output's
  state that only grow, are written once per run to the checkpoint folder's
  history file (:class:`~hyperfem.io.checkpoint.History`), each checkpoint
  appending the steps since the last, so ``meta.json`` does not grow with the run;
* a fingerprint of the run (:func:`fingerprint`): mesh, spaces, ranks, stage
  and a hash of the case description. A restart that does not match raises
  :class:`~hyperfem.io.CheckpointError` naming the first difference.

:class:`Checkpoint` is the output that writes them: every ``every`` steps, at
the end, and after a failed step (after all cutbacks) of the last converged
state. ``Simulation.run(restart=path)`` continues from one; the restarted run
repeats the arithmetic of the uninterrupted one, so on the same number of
ranks its rows and final state agree bit for bit; on another number of ranks
(the state is then found by partition-independent dof keys,
:mod:`hyperfem.io.checkpoint`) they agree as closely as two uninterrupted runs
on different numbers of ranks do.

The step-size control continues where it stopped: the nominal increment,
the count of easy steps towards the next growth (``grow_after``) and the
attempts spent are passed back to :func:`~hyperfem.solver.stepping.run_steps`,
so a checkpoint can be taken after any accepted step, every ``every`` steps
exactly.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.io.checkpoint import (
    CheckpointError,
    History,
    read_functions,
    read_meta,
    step_folder_name,
    write_checkpoint,
)
from hyperfem.io.results import ensure_output_dir, jsonable
from hyperfem.problem.protocol import SolidProblem
from hyperfem.simulation.outputs import Output
from hyperfem.solver.stepping import StepPolicy, StepRecord

if TYPE_CHECKING:
    from dolfinx import mesh as dmesh

    from hyperfem.dynamics.incremental import DynamicState
    from hyperfem.simulation.runner import Simulation

__all__ = [
    "Checkpoint",
    "CheckpointError",
    "StatefulUpdater",
    "StepperState",
    "case_hash",
    "checkpoint_functions",
    "fingerprint",
    "load_checkpoint",
    "save_checkpoint",
]


@dataclasses.dataclass(frozen=True)
class StepperState:
    """The state of the increment control of :func:`~hyperfem.solver.stepping.run_steps` between two steps.

    :meth:`after` replays the control's rules on an accepted step: a rejected
    attempt makes the shortened step the nominal increment and resets the
    count of easy steps; an easy step (no solve above ``easy_iterations``)
    adds one; after ``grow_after`` of them the increment grows by ``growth``,
    up to ``max_increment``.

    Attributes:
        increment: Nominal increment of the next step (> 0).
        streak: Consecutive easy steps since the last growth or reset.
        attempts: Attempts spent so far (accepted and rejected).
    """

    increment: float
    streak: int = 0
    attempts: int = 0

    @classmethod
    def start(cls, policy: StepPolicy) -> StepperState:
        """The state before the first step."""
        return cls(min(policy.increment, policy.max_step))

    def after(self, record: StepRecord, policy: StepPolicy) -> StepperState:
        """The state after the accepted step ``record``."""
        dt, streak = self.increment, self.streak
        if record.rejected:
            dt, streak = abs(record.dt), 0
        easy = policy.easy_iterations is None or max(
            (r.iterations for r in record.solve_records), default=0
        ) <= policy.easy_iterations
        streak = streak + 1 if easy else 0
        if streak >= policy.grow_after:
            dt, streak = min(dt * policy.growth, policy.max_step), 0
        return StepperState(dt, streak, self.attempts + record.rejected + 1)

    def resumed(self, policy: StepPolicy) -> StepPolicy:
        """``policy`` continued from this state: its increment and effective bounds.

        Pass :attr:`streak` and :attr:`attempts` to
        :func:`~hyperfem.solver.stepping.run_steps` along with it.
        """
        return dataclasses.replace(
            policy,
            increment=min(max(self.increment, policy.min_step), policy.max_step),
            min_increment=policy.min_step,
            max_increment=policy.max_step,
        )


@runtime_checkable
class _DynamicRun(Protocol):
    """The problem of a dynamic run as a checkpoint sees it: the state ``u, v, a`` and ``restore``."""

    u: fem.Function
    v: fem.Function
    a: fem.Function

    def restore(self, state: DynamicState) -> None:
        """Back to the state ``(t, u, v, a)``."""


@runtime_checkable
class StatefulUpdater(Protocol):
    """An updater of the problem with a state of its own that a checkpoint holds (e.g. a viscoelastic history)."""

    def state_functions(self) -> dict[str, fem.Function]:
        """Its state at the accepted state now in the unknown, by name (collective)."""

    def restart(self, t: float) -> None:
        """The functions were read back: they are the state at the accepted time ``t``."""


@runtime_checkable
class _Updated(Protocol):
    """A problem that names its updaters (:class:`~hyperfem.problem.base.EnergyProblem`)."""

    @property
    def updaters(self) -> tuple[Any, ...]:
        """What ``set_time`` moves besides loads and boundary values."""


def _stateful_updaters(sim: Simulation) -> list[StatefulUpdater]:
    """The updaters of the run's problem that keep a state (none for a problem that names no updaters)."""
    base = sim.fields.base
    updaters = base.updaters if isinstance(base, _Updated) else ()
    return [u for u in updaters if isinstance(u, StatefulUpdater)]


def _stateful_energies(sim: Simulation) -> list[StatefulUpdater]:
    """The solver's external energies that keep a state (a contact's frozen force under generalized-alpha)."""
    external = getattr(sim.solver, "external", None)
    energies = external.energies if external else ()
    return [e for e in energies if isinstance(e, StatefulUpdater)]


def case_hash(case: object) -> str:
    """SHA-256 of the canonical JSON of a case description (sorted keys; non-JSON values by ``str``)."""
    text = json.dumps(jsonable(case), sort_keys=True, default=str, allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def checkpoint_functions(sim: Simulation) -> dict[str, fem.Function]:
    """What a checkpoint of ``sim`` stores: ``u``, ``v``, ``a`` for a dynamic run, the updaters' states."""
    problem = sim.problem
    functions = {"u": problem.u}
    if sim.kind == "dynamic":
        assert isinstance(problem, _DynamicRun)  # the time step of a dynamic run
        functions.update(v=problem.v, a=problem.a)
    for k, updater in enumerate(_stateful_updaters(sim)):
        functions.update({f"updater{k}_{name}": f for name, f in updater.state_functions().items()})
    for k, energy in enumerate(_stateful_energies(sim)):
        functions.update({f"external{k}_{name}": f for name, f in energy.state_functions().items()})
    return functions


def _geometry_sums(mesh: dmesh.Mesh) -> list[float]:
    """Partition-independent sums over the owned vertices: coordinates and their squares."""
    n = mesh.geometry.index_map().size_local
    x = mesh.geometry.x[:n]
    local = np.array([x.sum(), (x**2).sum()], dtype=float)
    return [float(v) for v in mesh.comm.allreduce(local, op=MPI.SUM)]


def fingerprint(sim: Simulation) -> dict:
    """What must agree between a run and the checkpoint it restarts from (collective).

    Returns:
        ``stage``, ``ranks``, ``cells``, ``vertices``, ``geometry`` (sums of
        the vertex coordinates and their squares), ``dofs``, ``element`` (of
        the unknown), ``degree`` and ``case`` (:func:`case_hash` of the
        simulation's ``case``).
    """
    base = sim.fields.base
    mesh = base.domain.mesh
    tdim = mesh.topology.dim
    return {
        "stage": sim.kind,
        "ranks": sim.comm.size,
        "cells": int(mesh.topology.index_map(tdim).size_global),
        "vertices": int(mesh.topology.index_map(0).size_global),
        "geometry": _geometry_sums(mesh),
        "dofs": sim.dofs,
        "element": str(sim.problem.u.function_space.ufl_element()),
        "degree": int(base.degree),
        "case": case_hash(sim.case),
    }


def _mismatch(stored: dict, current: dict) -> str:
    labels = {
        "stage": "stage",
        "cells": "mesh cells",
        "vertices": "mesh vertices",
        "geometry": "mesh coordinates",
        "dofs": "unknowns",
        "element": "element",
        "degree": "displacement degree",
        "case": "case (hash of the case description)",
    }
    for key, label in labels.items():
        a, b = stored.get(key), current[key]
        if key == "geometry":
            same = a is not None and np.allclose(a, b, rtol=1e-12, atol=1e-12 * max(1.0, abs(b[1])) ** 0.5)
        else:
            same = a == b
        if not same:
            if key in ("geometry", "case"):
                return f"the {label} differs"
            return f"{label}: {a} in the checkpoint, {b} in this run"
    return ""


def _output_state(history: History, k: int, state: Any) -> Any:
    """An output's state with its list entries referred to ``history`` (those that only grow)."""
    if not isinstance(state, dict):
        return state
    return {
        key: history.refer(f"outputs/{k}/{key}", value) if isinstance(value, list) else value
        for key, value in state.items()
    }


def save_checkpoint(
    sim: Simulation, folder: str | Path, *, keep: int | None = 2, history: History | None = None
) -> Path:
    """Write a checkpoint of the accepted state of ``sim`` (collective).

    Args:
        sim: The simulation.
        folder: The checkpoint folder.
        keep: Checkpoints kept (:func:`~hyperfem.io.checkpoint.write_checkpoint`).
        history: The run's history file (the same object for every checkpoint
            of a run into ``folder``: each appends only what is new); ``None``
            writes a new one with every row.

    Returns:
        The checkpoint's step folder.
    """
    history = History(sim.comm) if history is None else history
    meta = {
        "name": sim.name,
        "fingerprint": fingerprint(sim),
        "time": sim.time,
        "completed": sim.completed,
        "stepper": dataclasses.asdict(sim.stepper),
        "stage_state": _stage_state(sim),
        "policy": {f.name: getattr(sim.policy, f.name) for f in dataclasses.fields(sim.policy)},
        "wall_time": sim.wall_time,
        "rows": history.refer("rows", sim.rows),
        "outputs": [
            {"type": type(o).__name__, "state": _output_state(history, k, o.state(sim))}
            for k, o in enumerate(sim.outputs)
        ],
    }
    return write_checkpoint(folder, sim.step, checkpoint_functions(sim), meta, sim.comm, keep=keep, history=history)


def _stage_state(sim: Simulation) -> dict | None:
    """What the stage of ``sim`` keeps for a restart (a continuation's direction and pivots), or ``None``."""
    state = getattr(sim.stage, "checkpoint_state", None)
    return None if state is None else state()


def load_checkpoint(sim: Simulation, path: str | Path) -> dict:
    """Bring ``sim`` to the state of a checkpoint (collective); returns its record.

    Sets the state functions, the time (loads, boundary values and updaters
    follow), the rows, the step count and the step-size control. The outputs'
    states are in the record (``"outputs"``), for
    :meth:`~hyperfem.simulation.outputs.Output.restart`.

    Raises:
        CheckpointError: On every rank, when there is no readable checkpoint
            at ``path`` or it does not match the run (:func:`fingerprint`).
    """
    meta = read_meta(path, sim.comm)
    where = meta["path"]
    mismatch = _mismatch(meta.get("fingerprint", {}), fingerprint(sim))
    if mismatch:
        raise CheckpointError(f"cannot restart from {where}: it does not match this run: {mismatch}")
    read_functions(where, checkpoint_functions(sim), sim.comm)
    t = float(meta["time"])
    for updater in [*_stateful_updaters(sim), *_stateful_energies(sim)]:
        updater.restart(t)
    if sim.kind == "dynamic":
        from hyperfem.dynamics.incremental import DynamicState

        p = sim.problem
        assert isinstance(p, _DynamicRun)  # the time step of a dynamic run
        p.restore(DynamicState(t, p.u.x.array, p.v.x.array, p.a.x.array))
    else:
        assert isinstance(sim.problem, SolidProblem)  # a quasi-static run's problem
        sim.problem.set_time(t)
    if sim.solver is not None:  # the explicit scheme runs its hooks before every force assembly
        sim.solver.refresh()  # state hooks (e.g. a material's rotation field) at the loaded state
        if sim.solver.external:  # contact pulls a penetrating start guess back towards the loaded state
            sim.solver.external.update(sim.problem.time)  # obstacles where they were: the friction lag is taken there
            sim.solver.external.remember()
    return meta


class Checkpoint(Output):
    """Checkpoints of a run: every ``every`` accepted steps, at the end, and of the last converged state on failure.

    Each is a folder ``step-NNNNNN`` under ``folder`` (:mod:`hyperfem.io.checkpoint`),
    ``folder/latest.json`` names the newest; continue with
    ``Simulation.run(restart=folder)``.

    Args:
        folder: Where to write.
        every: Steps between checkpoints; ``None``: only at the end and on failure.
        keep: Checkpoints kept (older ones are removed); ``None``: all.
        final: Write one at the end of a completed run.

    Raises:
        ParameterError: ``every`` or ``keep`` is not an integer >= 1 (or ``None``).
    """

    def __init__(self, folder: str | Path, *, every: int | None = 10, keep: int | None = 2, final: bool = True):
        for name, value in (("every", every), ("keep", keep)):
            if value is not None and not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
                raise ParameterError(f"Checkpoint: {name} must be an integer >= 1 or None, got {value!r}")
        self.folder = Path(folder)
        self.every = every
        self.keep = keep
        self.final = final
        self.last: int | None = None
        self.path: Path | None = None
        self._completed = False
        self._history: History | None = None

    def start(self, sim: Simulation) -> None:
        """Check the folder (on every rank) before any solve; a history file for this run."""
        ensure_output_dir(self.folder, sim.comm)
        sim.files["checkpoint"] = str(self.folder)
        self.last = 0
        self._history = History(sim.comm)

    def _save(self, sim: Simulation) -> None:
        self.path = save_checkpoint(sim, self.folder, keep=self.keep, history=self._history)
        self.last, self._completed = sim.step, sim.completed
        sim.files["checkpoint"] = str(self.path)

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Save when ``every`` steps have passed since the last checkpoint."""
        if step is None or self.every is None:
            return
        assert self.last is not None  # set by start
        if sim.step - self.last >= self.every:
            self._save(sim)

    def close(self, sim: Simulation) -> None:
        """At the end, or after a failed step: the last converged state (not after other errors)."""
        if sim.step == self.last and self.path is not None and self._completed == sim.completed:
            return  # this state is checkpointed already, with the same outcome
        if (sim.completed and self.final) or (not sim.completed and sim.state_converged and sim.rows):
            self._save(sim)

    def restart(self, sim: Simulation, state: dict | None) -> None:
        """Count the steps from the restart."""
        self.last = sim.step

    def path_of(self, step: int) -> Path:
        """The folder of the checkpoint after ``step``."""
        return self.folder / step_folder_name(step)
