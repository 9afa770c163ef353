"""Outputs of a :class:`~hyperfem.simulation.Simulation`: observers of every accepted step.

An output overrides what it needs of :class:`Output`:

* :meth:`~Output.start` — once, before any solve (open files, compile forms;
  an unwritable folder fails here, on every rank);
* :meth:`~Output.measure` — after the initial state and every accepted step:
  columns for the row of that state;
* :meth:`~Output.write` — after the row is complete: write files;
* :meth:`~Output.summary` — entries for the run's summary;
* :meth:`~Output.close` — once, at the end or after a failure;
* :meth:`~Output.state` and :meth:`~Output.restart` — what a checkpoint
  keeps of the output, and how it continues from it
  (:mod:`hyperfem.simulation.checkpoint`): on a restart
  :meth:`~Output.restart` replaces the recording of the initial state.

Everything is on disk when :meth:`~Output.write` returns, so a run killed at
any moment (SIGKILL) leaves every completed step readable: the CSV line is
appended and the file closed, the JSON summary replaced atomically, the VTX
frame indexed (:func:`~hyperfem.io.vtx_steps`), the convergence line appended.

Writers here: :class:`VTX` (ParaView time series), :class:`XDMF` (the same
as XDMF, P1/DG0), :class:`CSVLog` (one line per state), :class:`JSONSummary`
(the whole summary, rewritten after every step), :class:`ConvergenceLog`
(the Newton residual norms of every step, one JSON line each),
:class:`Progress` (a line on rank 0). Adapters: :class:`Quantity` (a
column from a callable), :class:`Recorder` (an object with ``record(step)``,
e.g. :class:`~hyperfem.dynamics.Diagnostics`, which measures and writes
nothing: its rows reach files through :class:`CSVLog` and
:class:`JSONSummary`), :class:`Derived` (a summary entry computed from the
others), :class:`OnStep` (a callback per accepted step). The measures of
mechanics (probes, reaction forces, bulge, cell fields) are in
:mod:`hyperfem.simulation.measures` and :mod:`hyperfem.simulation.reactions`,
derived fields (stress, J, fibre stretch) in :mod:`hyperfem.simulation.fields`.

A restarted run cannot append to the VTX/XDMF files of the first one
(DOLFINx writers start a new file), so it writes its frames to
:func:`continuation_path` (``bend.bp`` → ``bend.restart-000012.bp``, 12 the
step it continues from) and the summary lists both (``vtx_parts``). CSV,
JSON and convergence files are rewritten with the rows kept in the
checkpoint, then appended as before.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.io.results import VTXWriter, XDMFWriter, ensure_output_dir, flatten_row, on_rank0, write_json
from hyperfem.solver.stepping import StepRecord

if TYPE_CHECKING:
    from mpi4py import MPI

    from hyperfem.simulation.runner import Simulation
    from hyperfem.solver.newton import SolveRecord

__all__ = [
    "XDMF",
    "CSVLog",
    "ConvergenceLog",
    "Derived",
    "JSONSummary",
    "OnStep",
    "Output",
    "Progress",
    "Quantity",
    "Recorder",
    "VTX",
    "continuation_path",
    "format_summary",
    "read_convergence",
]


class Output:
    """Base of the observers of a simulation; every hook does nothing by default."""

    def start(self, sim: Simulation) -> None:
        """Before the first solve (the initial state is not recorded yet)."""

    def measure(self, sim: Simulation, step: StepRecord | None) -> dict:
        """Columns for the row of the current state (``step`` is ``None`` for the initial state)."""
        return {}

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Write the current state; ``sim.rows[-1]`` is its complete row."""

    def summary(self, sim: Simulation, summary: dict) -> dict:
        """Entries for the summary (``summary`` holds the entries collected so far)."""
        return {}

    def close(self, sim: Simulation) -> None:
        """After the last step, or after a failure (``sim.completed`` tells which)."""

    def state(self, sim: Simulation) -> dict | None:
        """What a checkpoint keeps of this output (JSON-serialisable), or ``None``."""
        return None

    def restart(self, sim: Simulation, state: dict | None) -> None:
        """Continue from a checkpoint: ``sim.rows`` holds the rows so far, ``state`` what :meth:`state` returned."""


def _check_every(where: str, every: int) -> int:
    if not (isinstance(every, int) and not isinstance(every, bool) and every >= 1):
        raise ParameterError(f"{where}: every must be an integer >= 1, got {every!r}")
    return every


def _due(step: StepRecord | None, every: int) -> bool:
    """Whether an output with ``every`` acts on this state: the initial one, and every n-th step."""
    return step is None or step.step % every == 0


def continuation_path(path: str | Path, step: int) -> Path:
    """Where a run restarted after step ``step`` writes a time series: ``name.restart-000012.bp``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.restart-{int(step):06d}{path.suffix}")


class _TimeSeries(Output):
    """Frames of functions at the initial state and at every step (or at given times); see :class:`VTX`."""

    def __init__(
        self,
        path: str | Path,
        functions: Sequence[fem.Function] | None,
        times: Sequence[float] | None,
        role: str,
    ):
        self.path = Path(path)
        self.functions = None if functions is None else list(functions)
        self._pending = None if times is None else sorted(float(t) for t in times)
        self.role = role
        self._file: VTXWriter | XDMFWriter | None = None
        self._parts: list[str] = []

    def _open(self, comm: MPI.Comm, path: Path, functions: list[fem.Function]) -> VTXWriter | XDMFWriter:
        raise NotImplementedError

    def start(self, sim: Simulation) -> None:
        """Open the file (on a restart: the continuation file, see :func:`continuation_path`)."""
        functions = self.functions if self.functions is not None else sim.fields.output()
        path = self.path if sim.restarted_from is None else continuation_path(self.path, sim.step)
        self._file = self._open(sim.comm, path, functions)
        self._parts = [str(path)]
        sim.files[self.role] = str(path)

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Append a frame (at the initial state, at every step or when passing the next output time)."""
        due = step is None or self._pending is None
        while self._pending and self._pending[0] <= sim.time + 1e-9 * max(1.0, abs(sim.time)):
            self._pending.pop(0)
            due = True
        if due:
            self._refresh()
            assert self._file is not None  # opened by start
            self._file.write(sim.time)

    def _refresh(self) -> None:
        """Bring the functions up to date before a frame (for subclasses that compute them)."""

    def close(self, sim: Simulation) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def state(self, sim: Simulation) -> dict:
        """The output times still to come and the files written so far."""
        return {"pending": self._pending, "parts": list(self._parts)}

    def restart(self, sim: Simulation, state: dict | None) -> None:
        """Keep the remaining output times; the first frame of the new file is the restart state."""
        if state is not None:
            if state.get("pending") is not None and self._pending is not None:
                self._pending = [float(t) for t in state["pending"]]
            self._parts = [*state.get("parts", []), *self._parts]
        self._refresh()
        assert self._file is not None  # opened by start
        self._file.write(sim.time)

    def summary(self, sim: Simulation, summary: dict) -> dict:
        """The files of a restarted run (``<role>_parts``, in order)."""
        return {f"{self.role}_parts": list(self._parts)} if len(self._parts) > 1 else {}


class VTX(_TimeSeries):
    """A VTX (``.bp``) time series for ParaView: the initial state and then every step (or given times).

    Every frame is indexed when it is written (BP4), so a killed run leaves
    every complete frame readable.

    Args:
        path: The ``.bp`` folder.
        functions: What to write; default the simulation's
            :meth:`~hyperfem.simulation.StateFunctions.output` (displacement; pressure
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
        super().__init__(path, functions, times, role)

    def _open(self, comm: MPI.Comm, path: Path, functions: list[fem.Function]) -> VTXWriter:
        return VTXWriter(comm, path, functions)


class XDMF(_TimeSeries):
    """An XDMF (``.xdmf`` + ``.h5``) time series, for tools that read XDMF only.

    Nodal fields are interpolated to the geometry's Lagrange degree (P1),
    cell-wise constant ones written per cell (:class:`~hyperfem.io.XDMFWriter`);
    prefer :class:`VTX`, which keeps the degree of the fields.

    Args:
        path: The ``.xdmf`` file.
        functions: What to write (default as for :class:`VTX`).
        times: As for :class:`VTX`.
        role: Key in ``sim.files`` (default ``"xdmf"``).
    """

    def __init__(
        self,
        path: str | Path,
        functions: Sequence[fem.Function] | None = None,
        *,
        times: Sequence[float] | None = None,
        role: str = "xdmf",
    ):
        super().__init__(path, functions, times, role)

    def _open(self, comm: MPI.Comm, path: Path, functions: list[fem.Function]) -> XDMFWriter:
        return XDMFWriter(comm, path, functions)


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

    def start(self, sim: Simulation) -> None:
        """Check the folder (on every rank) before any solve."""
        ensure_output_dir(self.path.parent, sim.comm)
        sim.files["summary"] = str(self.path)

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Rewrite the file."""
        write_json(self.path, sim.summary(rows=self.rows), sim.comm)

    def close(self, sim: Simulation) -> None:
        """The final summary (``completed`` and ``error`` set)."""
        self.write(sim, None)


class CSVLog(Output):
    """One CSV line per recorded state, appended as it is recorded.

    The header is the first row's columns (lists spread over ``name_0``,
    ``name_1``, ...); later rows fill the same columns.

    Args:
        path: The ``.csv`` file (overwritten at the start).
        every: Write the initial state and every n-th step only (as
            :class:`Recorder` with the same ``every`` measures them).
    """

    def __init__(self, path: str | Path, *, every: int = 1):
        self.path = Path(path)
        self.every = _check_every("CSVLog", every)
        self._columns: list[str] | None = None

    def start(self, sim: Simulation) -> None:
        """Check the folder (on every rank) before any solve."""
        ensure_output_dir(self.path.parent, sim.comm)
        sim.files["csv"] = str(self.path)
        self._columns = None

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Append the current row (if it is due)."""
        if not _due(step, self.every):
            return
        row = flatten_row(sim.rows[-1])
        first = self._columns is None
        if first:
            self._columns = list(row)
        columns = self._columns  # set above for the first row

        def append() -> None:
            with self.path.open("w" if first else "a", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=columns or [], extrasaction="ignore")
                if first:
                    writer.writeheader()
                writer.writerow(row)

        on_rank0(sim.comm, append, f"cannot write {self.path}")

    def restart(self, sim: Simulation, state: dict | None) -> None:
        """Rewrite the file with the rows kept in the checkpoint (those that were due)."""
        rows = [flatten_row(row) for row in sim.rows if int(row.get("step", 0)) % self.every == 0]
        self._columns = list(rows[0]) if rows else None
        columns = self._columns

        def rewrite() -> None:
            with self.path.open("w", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=columns or [], extrasaction="ignore")
                if columns:
                    writer.writeheader()
                writer.writerows(rows)

        on_rank0(sim.comm, rewrite, f"cannot write {self.path}")


def _norms(records: Sequence[SolveRecord]) -> list[list[float]]:
    return [[float(x) for x in r.residual_norms] for r in records]


class ConvergenceLog(Output):
    """The Newton residual norms of every recorded state, one JSON line each (appended, flushed).

    A line is ``{"step", "time", "dt", "accepted": [[|r_0|, |r_1|, ...], ...],
    "rejected": [[...], ...], "reasons": [...]}``: the residual 2-norm at each
    Newton iterate of the solves that produced the accepted state (two with
    step doubling), of the attempts that were cut back, and the SNES reasons
    of the accepted solves. Read it with :func:`read_convergence`; plot it with
    :func:`hyperfem.simulation.plots.newton_convergence`.

    Args:
        path: The ``.jsonl`` file (overwritten at the start).
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)

    def start(self, sim: Simulation) -> None:
        """Check the folder and empty the file (on every rank) before any solve."""
        ensure_output_dir(self.path.parent, sim.comm)
        sim.files["convergence"] = str(self.path)
        if sim.restarted_from is None:
            on_rank0(sim.comm, lambda: self.path.write_text(""), f"cannot write {self.path}")

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Append the line of the current state."""
        if step is None:
            initial = [sim.initial_solve] if sim.initial_solve is not None else []
            line = {"step": 0, "time": sim.time, "dt": 0.0, "accepted": _norms(initial), "rejected": []}
            line["reasons"] = [r.reason_name for r in initial]
        else:
            line = {
                "step": step.step,
                "time": step.time,
                "dt": step.dt,
                "accepted": _norms(step.solve_records),
                "rejected": _norms(step.failed),
                "reasons": [r.reason_name for r in step.solve_records],
            }
        text = json.dumps(line, allow_nan=True) + "\n"

        def append() -> None:
            with self.path.open("a") as fh:
                fh.write(text)

        on_rank0(sim.comm, append, f"cannot write {self.path}")

    def restart(self, sim: Simulation, state: dict | None) -> None:
        """Keep the lines of the steps up to the restart (those of later, lost steps are dropped)."""
        upto = sim.step

        def trim() -> None:
            kept = [line for line in read_convergence(self.path) if line["step"] <= upto] if self.path.is_file() else []
            self.path.write_text("".join(json.dumps(line) + "\n" for line in kept))

        on_rank0(sim.comm, trim, f"cannot write {self.path}")


def read_convergence(path: str | Path) -> list[dict]:
    """The lines of a :class:`ConvergenceLog` file (an incomplete last line, from a killed run, is skipped)."""
    lines = []
    for text in Path(path).read_text().splitlines():
        try:
            lines.append(json.loads(text))
        except ValueError:
            continue
    return lines


class Progress(Output):
    """Print a line per recorded state on rank 0, or a progress bar on a terminal.

    Args:
        line: Makes the line from the row.
        every: Print every n-th step only.
        initial: Print the initial state too.
        bar: Redraw one line with a bar of the time reached (``[#####.....] 50 %``)
            instead of printing a line per state. ``None``: when standard output
            is a terminal and the ``CI`` environment variable is unset (log files
            and CI get plain lines).
    """

    def __init__(
        self, line: Callable[[dict], str], *, every: int = 1, initial: bool = True, bar: bool | None = None
    ):
        self.line = line
        self.every = every
        self.initial = initial
        self.bar = bar
        self._drawn = False

    def start(self, sim: Simulation) -> None:
        """Print the mesh-quality line before the first solve (rank 0)."""
        super().start(sim)
        if self.bar is None:
            # Boundary: sys.stdout may be replaced by any stream (pytest, notebooks) without isatty.
            self.bar = bool(getattr(sys.stdout, "isatty", lambda: False)()) and not os.environ.get("CI")
        self._drawn = False
        self._t0 = sim.time
        if sim.mesh_quality is not None and sim.comm.rank == 0:
            print(sim.mesh_quality.summary_line(), flush=True)

    def _bar_line(self, sim: Simulation, text: str) -> str:
        span = sim.policy.end - self._t0
        fraction = 1.0 if span == 0 else min(max((sim.time - self._t0) / span, 0.0), 1.0)
        width = 20
        filled = int(round(fraction * width))
        head = f"[{'#' * filled}{'.' * (width - filled)}] {100 * fraction:3.0f} %  "
        columns = shutil.get_terminal_size((100, 24)).columns
        return (head + text)[: max(columns - 1, len(head))]

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Print (or redraw the bar)."""
        due = self.initial if step is None else step.step % self.every == 0
        if not (due and sim.comm.rank == 0):
            return
        text = self.line(sim.rows[-1])
        if self.bar:
            line = self._bar_line(sim, text)
            print("\r" + line + "\x1b[K", end="", flush=True)
            self._drawn = True
        else:
            print(text, flush=True)

    def close(self, sim: Simulation) -> None:
        """End the bar's line."""
        if self._drawn and sim.comm.rank == 0:
            print(flush=True)
        self._drawn = False
        super().close(sim)


class Quantity(Output):
    """A column from a callable (e.g. the activation level ``lambda: activation.value``).

    Args:
        name: Column name.
        value: Called after every accepted step; a number or a list of numbers.
    """

    def __init__(self, name: str, value: Callable[[], object]):
        self.name = name
        self.value = value

    def measure(self, sim: Simulation, step: StepRecord | None) -> dict:
        """``{name: value()}``."""
        return {self.name: self.value()}


class RowRecorder(Protocol):
    """What :class:`Recorder` reads: ``record(step)`` (``summary()`` and ``rows`` are optional)."""

    def record(self, step: StepRecord | None) -> Mapping[str, object]:
        """The columns of the current state (``step`` is ``None`` for the initial state)."""


class Recorder(Output):
    """Columns from an object with ``record(step) -> dict`` and, optionally, ``summary() -> dict``.

    E.g. :class:`~hyperfem.dynamics.Diagnostics` (energies, volume, probe
    positions of a dynamic run).

    Args:
        recorder: The object.
        every: Record the initial state and every n-th step only (the rows
            of the other steps lack the recorder's columns; the recorder's
            summary covers the states it recorded).
    """

    def __init__(self, recorder: RowRecorder, *, every: int = 1) -> None:
        self.recorder = recorder
        self.every = _check_every("Recorder", every)

    def measure(self, sim: Simulation, step: StepRecord | None) -> dict:
        """The recorder's row (if it is due)."""
        return dict(self.recorder.record(step)) if _due(step, self.every) else {}

    def summary(self, sim: Simulation, summary: dict) -> dict:
        """The recorder's summary, if it has one; a table several recorders give (``contact``) is merged."""
        make = getattr(self.recorder, "summary", None)  # boundary: a user recorder may not summarize
        out = dict(make()) if callable(make) else {}
        for key, value in out.items():
            if isinstance(value, dict) and isinstance(summary.get(key), dict):
                out[key] = {**summary[key], **value}
        return out

    def state(self, sim: Simulation) -> dict | None:
        """The recorder's ``rows`` list, if it keeps one (e.g. :class:`~hyperfem.dynamics.Diagnostics`)."""
        rows = getattr(self.recorder, "rows", None)  # boundary: a user recorder may keep no rows
        return {"rows": list(rows)} if isinstance(rows, list) else None

    def restart(self, sim: Simulation, state: dict | None) -> None:
        """Give the recorder back its rows."""
        rows = getattr(self.recorder, "rows", None)  # boundary: a user recorder may keep no rows
        if state is not None and isinstance(rows, list):
            rows[:] = state["rows"]


class OnStep(Output):
    """Call ``callback(record)`` with the :class:`~hyperfem.solver.stepping.StepRecord` of every accepted step.

    The ``on_step`` argument of :func:`~hyperfem.dynamics.integrate_explicit` and
    :func:`~hyperfem.dynamics.integrate_semi_implicit`; not called for the initial state.
    """

    def __init__(self, callback: Callable[[StepRecord], None]):
        self.callback = callback

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Call the callback (after the row is complete)."""
        if step is not None:
            self.callback(step)


class Derived(Output):
    """A summary entry computed from the entries before it (e.g. a convergence statement).

    Args:
        name: Summary key.
        value: ``value(summary) -> entry``; not called before the first accepted step.
    """

    def __init__(self, name: str, value: Callable[[dict], object]):
        self.name = name
        self.value = value

    def summary(self, sim: Simulation, summary: dict) -> dict:
        """``{name: value(summary)}`` once a step is accepted."""
        return {self.name: self.value(summary)} if sim.step > 0 else {}


def format_summary(summary: dict) -> str:
    """Short human-readable form of :meth:`Simulation.summary <hyperfem.simulation.Simulation.summary>`."""
    kinds = {
        "quasi-static": "load steps", "arc-length": "continuation steps", "buckling": "load steps to the reference"
    }
    steps = kinds.get(summary.get("stage", ""), "time steps")
    lines = [
        f"{summary['name']}: {summary['dofs']} dofs, {summary['cells']} cells, {summary['ranks']} rank(s)",
        f"  {steps}: {summary['steps']}, Newton iterations per step: {summary['newton_iterations']}",
    ]
    if summary.get("stage") == "arc-length":
        limits = ", ".join(f"{v:.6g}" for v in summary.get("limit_points", [])) or "none"
        bifurcations = ", ".join(f"{v:.6g}" for v in summary.get("bifurcations", [])) or "none"
        lines.append(f"  limit points at load factor: {limits}; bifurcations near load factor: {bifurcations}")
    if summary.get("stage") == "buckling":
        b = summary["buckling"]
        factors = ", ".join(f"{v:.6g}" for v in b["load_factors"]) or "none found"
        lines.append(f"  critical load factors: {factors} (reference {b['reference_time']:g}, increment "
                     f"{b['increment']:g}, {b['prestress']} prestress)")
    if "probe_displacement" in summary:
        for p, d in zip(summary["probe_points"], summary["probe_displacement"], strict=True):
            lines.append(f"  displacement at {tuple(p)}: {np.array2string(np.asarray(d), precision=6)} m")
    if "convergence" in summary:
        lines.append(f"  convergence: {summary['convergence']}")
    if not summary.get("completed", True):
        lines.append(f"  stopped at t = {summary['time']:g}: {summary.get('error')}")
    if summary.get("restarted_from"):
        lines.append(f"  restarted from {summary['restarted_from']}")
    lines.append(f"  wall time (stepping, after form compilation): {summary['wall_time']:.2f} s")
    files = summary.get("files", {})
    if files:
        shown: list[str] = []
        for role, path in files.items():
            parts = summary.get(f"{role}_parts") or [path]  # a restarted time series: every file, in order
            shown.extend(_file_text(p) for p in parts)
        lines.append(f"  output: {', '.join(shown)}")
    return "\n".join(lines)


def _file_text(path: str) -> str:
    """A file of the summary's output line (ParaView time series marked)."""
    return f"{path} (ParaView)" if path.endswith((".bp", ".xdmf")) else path
