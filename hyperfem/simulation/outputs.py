"""Outputs of a :class:`~hyperfem.simulation.Simulation`: observers of every accepted step.

An output overrides what it needs of :class:`Output`:

* :meth:`~Output.start` — once, before any solve (open files, compile forms;
  an unwritable folder fails here, on every rank);
* :meth:`~Output.measure` — after the initial state and every accepted step:
  columns for the row of that state;
* :meth:`~Output.write` — after the row is complete: write files;
* :meth:`~Output.summary` — entries for the run's summary;
* :meth:`~Output.close` — once, at the end or after a failure.

Writers here: :class:`VTX` (ParaView time series), :class:`CSVLog` (one line
per state), :class:`JSONSummary` (the whole summary, rewritten after every
step), :class:`Progress` (a line on rank 0). Adapters: :class:`Quantity` (a
column from a callable), :class:`Recorder` (an object with ``record(step)``,
e.g. :class:`~hyperfem.dynamics.Diagnostics`), :class:`Derived` (a summary
entry computed from the others). The measures of mechanics (probes, reaction
forces, bulge, cell fields) are in :mod:`hyperfem.simulation.measures`.
"""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from dolfinx import fem

from hyperfem.io.results import VTXOutput, ensure_output_dir, on_rank0, write_json
from hyperfem.solver.stepping import StepRecord

__all__ = [
    "CSVLog",
    "Derived",
    "JSONSummary",
    "Output",
    "Progress",
    "Quantity",
    "Recorder",
    "VTX",
    "format_summary",
]


class Output:
    """Base of the observers of a simulation; every hook does nothing by default."""

    def start(self, sim) -> None:
        """Before the first solve (the initial state is not recorded yet)."""

    def measure(self, sim, step: StepRecord | None) -> dict:
        """Columns for the row of the current state (``step`` is ``None`` for the initial state)."""
        return {}

    def write(self, sim, step: StepRecord | None) -> None:
        """Write the current state; ``sim.rows[-1]`` is its complete row."""

    def summary(self, sim, summary: dict) -> dict:
        """Entries for the summary (``summary`` holds the entries collected so far)."""
        return {}

    def close(self, sim) -> None:
        """After the last step, or after a failure (``sim.completed`` tells which)."""


class VTX(Output):
    """A VTX (``.bp``) time series for ParaView: the initial state and then every step (or given times).

    Args:
        path: The ``.bp`` folder.
        functions: What to write; default the simulation's
            :meth:`~hyperfem.simulation.Fields.output` (displacement; pressure
            of the three-field problem; velocity of a dynamic run).
        times: Write only when a step reaches or passes the next of these
            times (use must-hit times to land on them); ``None``: every step.
        role: Key in ``sim.files`` (default ``"vtx"``).
    """

    def __init__(
        self,
        path: str | Path,
        functions: Sequence[fem.Function] | None = None,
        *,
        times: Sequence[float] | None = None,
        role: str = "vtx",
    ):
        self.path = Path(path)
        self.functions = None if functions is None else list(functions)
        self._pending = None if times is None else sorted(float(t) for t in times)
        self.role = role
        self._file: VTXOutput | None = None

    def start(self, sim) -> None:
        """Open the file."""
        functions = self.functions if self.functions is not None else sim.fields.output()
        self._file = VTXOutput(sim.comm, self.path, functions)
        sim.files[self.role] = str(self.path)

    def write(self, sim, step: StepRecord | None) -> None:
        """Append a frame (at the initial state, at every step or when passing the next output time)."""
        due = step is None or self._pending is None
        while self._pending and self._pending[0] <= sim.time + 1e-9 * max(1.0, abs(sim.time)):
            self._pending.pop(0)
            due = True
        if due:
            self._refresh()
            self._file.write(sim.time)

    def _refresh(self) -> None:
        """Bring the functions up to date before a frame (for subclasses that compute them)."""

    def close(self, sim) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None


class JSONSummary(Output):
    """The run's summary as JSON, rewritten (once) after every accepted step and at the end.

    A failure therefore loses nothing: the file holds every completed step and
    ``"completed": false``.

    Args:
        path: The ``.json`` file.
        rows: Include every row (for long runs, keep them in a :class:`CSVLog` instead).
    """

    def __init__(self, path: str | Path, *, rows: bool = True):
        self.path = Path(path)
        self.rows = rows

    def start(self, sim) -> None:
        """Check the folder (on every rank) before any solve."""
        ensure_output_dir(self.path.parent, sim.comm)
        sim.files["summary"] = str(self.path)

    def write(self, sim, step: StepRecord | None) -> None:
        """Rewrite the file."""
        write_json(self.path, sim.summary(rows=self.rows), sim.comm)

    def close(self, sim) -> None:
        """The final summary (``completed`` and ``error`` set)."""
        self.write(sim, None)


def _flatten(row: dict) -> dict:
    """Scalars as they are; lists of numbers as ``name_0, name_1, ...`` (nested: ``name_0_1``)."""
    flat = {}
    for key, value in row.items():
        if isinstance(value, (list, tuple, np.ndarray)):
            array = np.asarray(value, dtype=float)
            for index in np.ndindex(array.shape):
                flat["_".join([key, *map(str, index)])] = float(array[index])
        else:
            flat[key] = value
    return flat


class CSVLog(Output):
    """One CSV line per recorded state, appended as it is recorded.

    The header is the first row's columns (lists spread over ``name_0``,
    ``name_1``, ...); later rows fill the same columns.

    Args:
        path: The ``.csv`` file (overwritten at the start).
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._columns: list[str] | None = None

    def start(self, sim) -> None:
        """Check the folder (on every rank) before any solve."""
        ensure_output_dir(self.path.parent, sim.comm)
        sim.files["csv"] = str(self.path)
        self._columns = None

    def write(self, sim, step: StepRecord | None) -> None:
        """Append the current row."""
        row = _flatten(sim.rows[-1])
        first = self._columns is None
        if first:
            self._columns = list(row)
        columns = self._columns

        def append() -> None:
            with self.path.open("w" if first else "a", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
                if first:
                    writer.writeheader()
                writer.writerow(row)

        on_rank0(sim.comm, append, f"cannot write {self.path}")


class Progress(Output):
    """Print a line per recorded state on rank 0.

    Args:
        line: Makes the line from the row.
        every: Print every n-th step only.
        initial: Print the initial state too.
    """

    def __init__(self, line: Callable[[dict], str], *, every: int = 1, initial: bool = True):
        self.line = line
        self.every = every
        self.initial = initial

    def write(self, sim, step: StepRecord | None) -> None:
        """Print."""
        due = self.initial if step is None else step.step % self.every == 0
        if due and sim.comm.rank == 0:
            print(self.line(sim.rows[-1]), flush=True)


class Quantity(Output):
    """A column from a callable (e.g. the activation level ``lambda: activation.value``).

    Args:
        name: Column name.
        value: Called after every accepted step; a number or a list of numbers.
    """

    def __init__(self, name: str, value: Callable[[], object]):
        self.name = name
        self.value = value

    def measure(self, sim, step: StepRecord | None) -> dict:
        """``{name: value()}``."""
        return {self.name: self.value()}


class Recorder(Output):
    """Columns from an object with ``record(step) -> dict`` and, optionally, ``summary() -> dict``.

    E.g. :class:`~hyperfem.dynamics.Diagnostics` (energies, volume, probe
    positions of a dynamic run).
    """

    def __init__(self, recorder):
        self.recorder = recorder

    def measure(self, sim, step: StepRecord | None) -> dict:
        """The recorder's row."""
        return dict(self.recorder.record(step))

    def summary(self, sim, summary: dict) -> dict:
        """The recorder's summary, if it has one."""
        make = getattr(self.recorder, "summary", None)
        return dict(make()) if callable(make) else {}


class Derived(Output):
    """A summary entry computed from the entries before it (e.g. a convergence statement).

    Args:
        name: Summary key.
        value: ``value(summary) -> entry``; not called before the first accepted step.
    """

    def __init__(self, name: str, value: Callable[[dict], object]):
        self.name = name
        self.value = value

    def summary(self, sim, summary: dict) -> dict:
        """``{name: value(summary)}`` once a step is accepted."""
        return {self.name: self.value(summary)} if sim.steps else {}


def format_summary(summary: dict) -> str:
    """Short human-readable form of :meth:`Simulation.summary <hyperfem.simulation.Simulation.summary>`."""
    steps = "load steps" if summary.get("stage") == "quasi-static" else "time steps"
    lines = [
        f"{summary['name']}: {summary['dofs']} dofs, {summary['cells']} cells, {summary['ranks']} rank(s)",
        f"  {steps}: {summary['steps']}, Newton iterations per step: {summary['newton_iterations']}",
    ]
    if "probe_displacement" in summary:
        for p, d in zip(summary["probe_points"], summary["probe_displacement"], strict=True):
            lines.append(f"  displacement at {tuple(p)}: {np.array2string(np.asarray(d), precision=6)} m")
    if "convergence" in summary:
        lines.append(f"  convergence: {summary['convergence']}")
    if not summary.get("completed", True):
        lines.append(f"  stopped at t = {summary['time']:g}: {summary.get('error')}")
    lines.append(f"  wall time (stepping, after form compilation): {summary['wall_time']:.2f} s")
    files = summary.get("files", {})
    if files:
        shown = [f"{path} (ParaView)" if path.endswith(".bp") else path for path in files.values()]
        lines.append(f"  output: {', '.join(shown)}")
    return "\n".join(lines)
