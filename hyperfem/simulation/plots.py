r"""Plots of a finished (or stopped) run, from its output files, as PNG.

Each function takes what a run left on disk — its output folder, its JSON
summary or its CSV — and writes one PNG (matplotlib with the Agg backend,
imported only when a plot is made):

* :func:`load_displacement` — a load column against a displacement column of
  the rows (by default the largest reaction force against the largest probe
  or boundary displacement) of a quasi-static run;
* :func:`response_history` — displacement and reaction force against time
  (what a dynamic run gets instead: its reaction oscillates);
* :func:`newton_convergence` — the residual norm at every Newton iterate of
  every step, semilog (from the :class:`~hyperfem.simulation.outputs.ConvergenceLog`);
* :func:`dynamics_time_series` — the motion of the test point, the energies
  and the volume ratio of dynamic runs (the diagnostics CSV of
  ``demos/dynamics.py`` or the CSV of ``hyperfem run``, several runs overlaid);
* :func:`plot_run` — every plot that the files of a run allow.

Axes are labelled with the quantity, where it is taken and its unit
(:func:`quantity`: ``probe_displacement_0_1`` → "displacement u_y at (4.5,
1.5, 1.5) [m]", ``reaction_clamped_Fy`` → "reaction force F_y on 'clamped'
[N]"); the probe points and the run's name come from its JSON summary.

Under MPI pass ``comm``: rank 0 plots and the others return ``None``.
"""

from __future__ import annotations

import csv
import json
import re
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from hyperfem.errors import OutputError, ParameterError
from hyperfem.io.results import flatten_row
from hyperfem.simulation.outputs import read_convergence

if TYPE_CHECKING:
    from mpi4py import MPI

__all__ = [
    "dynamics_time_series",
    "load_displacement",
    "newton_convergence",
    "plot_run",
    "quantity",
    "read_rows",
    "response_history",
]

AXES = "xyz"
ENERGY_TOTAL = "total = kinetic + elastic − external work"
"""Legend of the total energy of a dynamic run (constant without damping: the external work is in it)."""


def _pyplot() -> ModuleType:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


_FLAGS = {"True": 1.0, "False": 0.0}
"""Booleans as the CSV writes them (a continuation's ``stable``, ``limit_point``, ``bifurcation``)."""


def _number(value: str | float | None) -> float | None:
    if value is None:
        return None
    if isinstance(value, str) and value in _FLAGS:
        return _FLAGS[value]
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _summary_file(folder: Path) -> Path | None:
    """The JSON summary in ``folder`` (a ``.json`` with ``rows``); the newest if several."""
    found = []
    for path in sorted(folder.glob("*.json")):
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(data, dict) and "rows" in data:
            found.append((path.stat().st_mtime, path))
    return max(found)[1] if found else None


def _rows_file(source: Path) -> Path:
    """The file :func:`read_rows` reads for ``source`` (in a folder: the JSON summary, else the first CSV)."""
    if not source.is_dir():
        return source
    summary = _summary_file(source)
    csvs = sorted(source.glob("*.csv"))
    if summary is None and not csvs:
        raise OutputError(f"{source}: no JSON summary with rows and no CSV file")
    return summary if summary is not None else csvs[0]


def read_rows(source: str | Path) -> list[dict[str, float]]:
    """The numeric columns of a run's rows, from a CSV, a JSON summary (with rows) or an output folder.

    Lists are spread over ``name_0, name_1, ...`` as in the CSV; columns with a
    non-number in any row (the SNES reason) are left out.

    Raises:
        OutputError: If there is nothing to read there.
    """
    source = _rows_file(Path(source))
    try:
        if source.suffix == ".csv":
            with source.open() as fh:
                raw = list(csv.DictReader(fh))
        else:
            data = json.loads(source.read_text())
            if "rows" not in data:
                raise OutputError(f"{source}: the summary has no rows (written with rows=False; use the CSV)")
            raw = [flatten_row(row) for row in data["rows"]]
    except (OSError, ValueError) as exc:
        raise OutputError(f"cannot read {source}: {exc}") from None
    if not raw:
        raise OutputError(f"{source}: no rows")
    keys = [k for k in raw[0] if all(_number(r.get(k)) is not None for r in raw)]
    return [{k: float(_number(r[k])) for k in keys} for r in raw]  # type: ignore[arg-type]  # checked above


def _run_summary(source: Path) -> dict:
    """The JSON summary of the run whose rows ``source`` holds ({} if none): same stem first, then any in the folder."""
    folder = source if source.is_dir() else source.parent
    stem = None if source.is_dir() else source.stem
    candidates = sorted(folder.glob("*.json"), key=lambda p: (p.stem != stem, p.name))
    for path in candidates:
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(data, dict) and "name" in data and "steps" in data:
            return data
    return {}


def _point(values: Sequence[float]) -> str:
    return "(" + ", ".join(f"{float(v):g}" for v in values) + ")"


def _dynamic(rows: list[dict], meta: dict) -> bool:
    return meta.get("stage", "quasi-static") == "dynamic" or "kinetic_energy" in rows[0]


ENERGIES = {
    "kinetic_energy": "kinetic energy [J]",
    "elastic_energy": "elastic energy [J]",
    "external_work": "external work [J]",
    "total_energy": f"energy, {ENERGY_TOTAL} [J]",
    "volume_ratio": "volume ratio V/V0",
    "min_J": "smallest J = det F",
}


def quantity(column: str, meta: dict | None = None, *, unit: bool = True) -> str:
    """The axis label of a column: quantity, where, unit.

    Args:
        column: A column of the rows (``probe_displacement_0_1``, ``reaction_clamped_Fy``, ``u1_free_end``, ...).
        meta: The run's summary (``probe_points``, ``stage``), if known.
        unit: Append the unit (``[m]``); without it, the text of a legend entry.
    """
    meta = meta or {}

    def done(text: str, u: str) -> str:
        return f"{text} [{u}]" if unit and u else text

    if column == "time":
        return done("time t", "s") if meta.get("stage", "quasi-static") != "quasi-static" else "load factor"
    if m := re.fullmatch(r"probe_displacement_(\d+)_(\d)", column):
        i, c = int(m[1]), int(m[2])
        points = meta.get("probe_points") or []
        where = _point(points[i]) if i < len(points) else f"probe {i}"
        return done(f"displacement u_{AXES[c]} at {where}", "m")
    if m := re.fullmatch(r"reaction_(.+)_([FM])([xyz])", column):
        name, kind, axis = m[1], m[2], m[3]
        what = "reaction force" if kind == "F" else "reaction moment"
        where = "on all supports" if name == "total" else f"on {name!r}"
        return done(f"{what} {kind}_{axis} {where}", "N" if kind == "F" else "N m")
    if m := re.fullmatch(r"u(\d)_(.+)", column):
        return done(f"mean displacement u_{AXES[int(m[1])]} on {m[2]!r}", "m")
    if m := re.fullmatch(r"p(\d+)_([xyz])", column):
        return done(f"test point {int(m[1])}: position {m[2]}", "m")
    if column in ENERGIES:
        text = ENERGIES[column]
        return text if unit else text.split(" [")[0]
    return column


def _title(meta: dict, what: str) -> str:
    return f"{meta['name']}: {what}" if meta.get("name") else what


def _columns(rows: list[dict], start: str) -> list[str]:
    return [k for k in rows[0] if k.startswith(start)]


def _largest(rows: list[dict], names: list[str]) -> str | None:
    if not names:
        return None
    return max(names, key=lambda k: abs(rows[-1][k]))


def _default_output(source: Path, suffix: str) -> Path:
    read = _rows_file(source)
    return read.with_name(f"{read.stem}_{suffix}.png")


def load_displacement(
    source: str | Path,
    *,
    load: str | None = None,
    displacement: str | None = None,
    output: str | Path | None = None,
    comm: MPI.Comm | None = None,
) -> Path | None:
    """Plot a load column against a displacement column of a run's rows.

    Args:
        source: Output folder, JSON summary with rows, or CSV (:func:`read_rows`).
        load: Column on the vertical axis; default the reaction force
            component (``reaction_*_F?``, not the total) largest at the end,
            else ``time`` (the load factor); for an arc-length run ``time``
            (the path in the load factor, with its limit points starred,
            its bifurcations marked and its unstable states hollow).
        displacement: Column on the horizontal axis; default the probe or
            boundary-average displacement largest at the end.
        output: PNG file (default ``<name>_load_displacement.png`` beside the file read).
        comm: Communicator; only rank 0 plots.

    Returns:
        The PNG path (``None`` on other ranks).

    Raises:
        ParameterError: A named column does not exist, or no displacement column is found.
    """
    if comm is not None and comm.rank != 0:
        return None
    source = Path(source)
    rows = read_rows(source)
    meta = _run_summary(source)
    continuation = meta.get("stage") == "arc-length" or "limit_point" in rows[0]
    forces = [k for k in rows[0] if k.startswith("reaction_") and "_F" in k and not k.startswith("reaction_total_")]
    load = load or ("time" if continuation else _largest(rows, forces)) or "time"
    candidates = _columns(rows, "probe_displacement") + [k for k in rows[0] if re.match(r"u\d+_", k)]
    displacement = displacement or _largest(rows, candidates)
    for name, what in ((load, "load"), (displacement, "displacement")):
        if name is None:
            raise ParameterError(f"load_displacement: no displacement column in {source}; pass displacement=")
        if name not in rows[0]:
            raise ParameterError(
                f"load_displacement: no {what} column {name!r} in {source} (columns: {', '.join(rows[0])})"
            )
    assert displacement is not None  # checked above
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.8))
    label = meta.get("name", "run")
    x, y = [r[displacement] for r in rows], [r[load] for r in rows]
    ax.plot(x, y, "o-", ms=3, label=f"{label} (one point per step)")
    if continuation:
        _continuation_marks(ax, rows, x, y, load)
    ax.set_xlabel(quantity(displacement, meta))
    ax.set_ylabel(quantity(load, {**meta, "stage": "quasi-static"}))
    ax.set_title(_title(meta, "load–displacement"))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    out = Path(output) if output is not None else _default_output(source, "load_displacement")
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def _continuation_marks(ax: Any, rows: list[dict], x: list[float], y: list[float], load: str) -> None:
    """Hollow markers on unstable states, a star at each limit point (its located load), a cross at bifurcations."""
    unstable = [i for i, r in enumerate(rows) if r.get("stable") == 0.0]
    if unstable:
        ax.plot([x[i] for i in unstable], [y[i] for i in unstable], "o", ms=6, mfc="white", mec="C0",
                label="unstable under load control")
    limits = [i for i, r in enumerate(rows) if r.get("limit_point")]
    if limits:
        located = [rows[i]["limit_load"] if load == "time" else y[i] for i in limits]
        ax.plot([x[i] for i in limits], located, "k*", ms=11, label="limit point (located load)")
    bifurcations = [i for i, r in enumerate(rows) if r.get("bifurcation")]
    if bifurcations:
        ax.plot([x[i] for i in bifurcations], [y[i] for i in bifurcations], "rx", ms=10, mew=2, label="bifurcation")


def _convergence_file(source: Path) -> Path:
    if source.is_file():
        return source
    found = sorted(source.glob("*.jsonl"))
    if not found:
        raise OutputError(f"{source}: no convergence log (*.jsonl; add a ConvergenceLog output)")
    return found[0]


def newton_convergence(
    source: str | Path, *, output: str | Path | None = None, comm: MPI.Comm | None = None
) -> Path | None:
    """Plot the residual norm of every Newton iterate of every step (semilog; colour = step).

    Solves of rejected attempts are dotted grey.

    Args:
        source: The ``.jsonl`` of a :class:`~hyperfem.simulation.outputs.ConvergenceLog`, or its folder.
        output: PNG file (default ``<log>_newton.png`` beside it).
        comm: Communicator; only rank 0 plots.

    Returns:
        The PNG path (``None`` on other ranks).
    """
    if comm is not None and comm.rank != 0:
        return None
    path = _convergence_file(Path(source))
    lines = read_convergence(path)
    if not lines:
        raise OutputError(f"{path}: no steps recorded")
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    steps = [line["step"] for line in lines]
    cmap = plt.get_cmap("viridis")
    top = max(1, max(steps))
    for line in lines:
        for norms in line.get("rejected", []):
            if norms:
                ax.semilogy(range(len(norms)), norms, ":", color="0.6", lw=1)
        for norms in line["accepted"]:
            positive = [n if n > 0 else np.nan for n in norms]
            if positive:
                ax.semilogy(range(len(norms)), positive, "o-", ms=3, lw=1, color=cmap(line["step"] / top))
    if any(line.get("rejected") for line in lines):
        ax.plot([], [], ":", color="0.6", lw=1, label="rejected attempts (step cut back)")
    ax.plot([], [], "o-", ms=3, lw=1, color=cmap(1.0), label="accepted solve of a step")
    ax.legend(fontsize=8, loc="best")
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.set_xlabel("Newton iteration")
    ax.set_ylabel("residual norm |r| (SNES function norm)")
    ax.set_title(_title(_run_summary(path), "Newton convergence per step"))
    ax.grid(True, which="both", alpha=0.3)
    mappable = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(min(steps), top))
    bar = fig.colorbar(mappable, ax=ax, label="step")
    bar.locator = plt.MaxNLocator(integer=True)  # steps are counted, not measured
    bar.update_ticks()
    fig.tight_layout()
    out = Path(output) if output is not None else path.with_name(f"{path.stem}_newton.png")
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def _test_point(d: dict[str, list[float]], meta: dict) -> tuple[list[tuple[str, str]], str]:
    """The columns of the test point's panel (``(column, legend)``) and its axis label.

    The current position ``p0_x``... of :class:`~hyperfem.dynamics.Diagnostics` if recorded,
    else the displacement of the first probe (``probe_displacement_0_*``, the CSV of ``hyperfem run``).
    """
    position = [(f"p0_{c}", c) for c in AXES if f"p0_{c}" in d]
    if position:
        return position, "test point position [m]"
    shown = [(f"probe_displacement_0_{i}", f"u_{c}") for i, c in enumerate(AXES) if f"probe_displacement_0_{i}" in d]
    points = meta.get("probe_points") or []
    where = f" at {_point(points[0])}" if points else ""
    return shown, f"test point displacement{where} [m]"


def dynamics_time_series(
    sources: str | Path | Sequence[str | Path], *, output: str | Path | None = None, comm: MPI.Comm | None = None
) -> Path | None:
    """Motion of the test point, energies and volume ratio of dynamic runs, one panel each.

    Reads the diagnostics CSV (or any rows with the columns of
    :class:`~hyperfem.dynamics.Diagnostics`: ``time``, ``p0_x``..., ``kinetic_energy``,
    ``elastic_energy``, ``total_energy``, ``volume_ratio``, ``min_J``), or the
    rows of ``hyperfem run`` (the test point is then the first probe's
    displacement); several runs are overlaid, labelled by their folder.

    Args:
        sources: One or more CSV files (or folders / summaries, :func:`read_rows`).
        output: PNG file (default ``<name>_dynamics.png`` beside the first file read).
        comm: Communicator; only rank 0 plots.

    Returns:
        The PNG path (``None`` on other ranks).
    """
    if comm is not None and comm.rank != 0:
        return None
    paths = [Path(sources)] if isinstance(sources, (str, Path)) else [Path(s) for s in sources]
    plt = _pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(7.5, 9.5), sharex=True)
    point_label, names = "test point [m]", []
    for path in paths:
        rows = read_rows(path)
        meta = _run_summary(path)
        d = {k: [r[k] for r in rows] for k in rows[0]}
        label = meta.get("name") or (path.name if path.is_dir() else path.parent.name)
        names.append(label)
        t = d["time"]
        shown, point_label = _test_point(d, meta)
        for (key, comp), style in zip(shown, ("-", "--", ":"), strict=False):
            axes[0].plot(t, d[key], style, label=f"{label}: {comp}")
        for key, style, name in (
            ("kinetic_energy", "-", "kinetic"),
            ("elastic_energy", "-", "elastic"),
            ("external_work", "-.", "external work"),
            ("total_energy", "k--", ENERGY_TOTAL),
        ):
            if key in d:
                axes[1].plot(t, d[key], style, lw=1 if key == "total_energy" else 1.5, label=f"{label}: {name}")
        if "volume_ratio" in d:
            axes[2].plot(t, d["volume_ratio"], label=f"{label}: V/V0")
        if "min_J" in d:
            axes[2].plot(t, d["min_J"], ":", label=f"{label}: min J")
    axes[0].set_ylabel(point_label)
    axes[1].set_ylabel("energy [J]")
    axes[2].set_ylabel("volume ratio V/V0, min J [-]")
    axes[2].set_xlabel("time t [s]")
    axes[0].set_title(f"{', '.join(dict.fromkeys(names))}: dynamic run")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    out = Path(output) if output is not None else _default_output(paths[0], "dynamics")
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def response_history(
    source: str | Path, *, output: str | Path | None = None, comm: MPI.Comm | None = None
) -> Path | None:
    """Displacement and reaction force against time, one panel each (the load–displacement plot of a dynamic run).

    Args:
        source: Output folder, JSON summary with rows, or CSV (:func:`read_rows`).
        output: PNG file (default ``<name>_history.png`` beside the file read).
        comm: Communicator; only rank 0 plots.

    Returns:
        The PNG path (``None`` on other ranks).

    Raises:
        ParameterError: The rows have neither a displacement nor a reaction column.
    """
    if comm is not None and comm.rank != 0:
        return None
    source = Path(source)
    rows = read_rows(source)
    meta = {"stage": "dynamic", **_run_summary(source)}
    moved = _columns(rows, "probe_displacement") + [k for k in rows[0] if re.fullmatch(r"u\d_.+", k)]
    forces = [k for k in rows[0] if re.fullmatch(r"reaction_.+_F[xyz]", k) and not k.startswith("reaction_total_")]
    if not moved and not forces:
        raise ParameterError(f"response_history: no displacement or reaction column in {source}")
    t = [r["time"] for r in rows]
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 7), sharex=True)
    for ax, columns, what in ((axes[0], moved, "displacement [m]"), (axes[1], forces, "reaction force [N]")):
        for key in columns:
            ax.plot(t, [r[key] for r in rows], lw=1.2, label=quantity(key, meta, unit=False))
        ax.set_ylabel(what)
        ax.grid(True, alpha=0.3)
        if columns:
            ax.legend(fontsize=7, loc="best")
    axes[1].set_xlabel(quantity("time", meta))
    axes[0].set_title(_title(meta, "displacement and reaction force against time"))
    fig.tight_layout()
    out = Path(output) if output is not None else _default_output(source, "history")
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def plot_run(folder: str | Path, *, comm: MPI.Comm | None = None) -> list[Path]:
    """Every plot the files in a run's output folder allow; returns the PNG paths (rank 0; ``[]`` elsewhere).

    Quasi-static runs: load–displacement when the rows have a displacement
    column. Dynamic runs (``kinetic_energy`` in the rows): the time series
    (:func:`dynamics_time_series`) and displacement and reaction against time
    (:func:`response_history`; a reaction oscillating against the
    displacement says little). The Newton history when there is a convergence log.
    """
    if comm is not None and comm.rank != 0:
        return []
    folder = Path(folder)
    made: list[Path | None] = []  # None only on ranks other than 0 (these calls have no comm)
    rows = read_rows(folder)
    dynamic = _dynamic(rows, _run_summary(folder))
    if dynamic:
        made.append(dynamics_time_series(folder))
    try:
        made.append(response_history(folder) if dynamic else load_displacement(folder))
    except ParameterError:
        pass
    if list(folder.glob("*.jsonl")):
        made.append(newton_convergence(folder))
    return [path for path in made if path is not None]
