r"""Plots of a finished (or stopped) run, from its output files, as PNG.

Each function takes what a run left on disk — its output folder, its JSON
summary or its CSV — and writes one PNG (matplotlib with the Agg backend,
imported only when a plot is made):

* :func:`load_displacement` — a load column against a displacement column of
  the rows (by default the largest reaction force against the largest probe
  or boundary displacement);
* :func:`newton_convergence` — the residual norm at every Newton iterate of
  every step, semilog (from the :class:`~hyperfem.simulation.outputs.ConvergenceLog`);
* :func:`dynamics_time_series` — the motion of the test point, the energies
  and the volume ratio of dynamic runs (the diagnostics CSV of
  ``demos/dynamics.py``, several runs overlaid);
* :func:`plot_run` — every plot that the files of a run allow.

Under MPI pass ``comm``: rank 0 plots and the others return ``None``.
"""

from __future__ import annotations

import csv
import json
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hyperfem.errors import OutputError, ParameterError
from hyperfem.simulation.outputs import _flatten, read_convergence

__all__ = [
    "dynamics_time_series",
    "load_displacement",
    "newton_convergence",
    "plot_run",
    "read_rows",
]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _number(value) -> float | None:
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
            raw = [_flatten(row) for row in data["rows"]]
    except (OSError, ValueError) as exc:
        raise OutputError(f"cannot read {source}: {exc}") from None
    if not raw:
        raise OutputError(f"{source}: no rows")
    keys = [k for k in raw[0] if all(_number(r.get(k)) is not None for r in raw)]
    return [{k: float(r[k]) for k in keys} for r in raw]


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
    comm=None,
) -> Path | None:
    """Plot a load column against a displacement column of a run's rows.

    Args:
        source: Output folder, JSON summary with rows, or CSV (:func:`read_rows`).
        load: Column on the vertical axis; default the reaction force
            component (``reaction_*_F?``, not the total) largest at the end,
            else ``time`` (the load factor).
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
    forces = [k for k in rows[0] if k.startswith("reaction_") and "_F" in k and not k.startswith("reaction_total_")]
    load = load or _largest(rows, forces) or "time"
    candidates = _columns(rows, "probe_displacement") + [k for k in rows[0] if re.match(r"u\d+_", k)]
    displacement = displacement or _largest(rows, candidates)
    for name, what in ((load, "load"), (displacement, "displacement")):
        if name is None:
            raise ParameterError(f"load_displacement: no displacement column in {source}; pass displacement=")
        if name not in rows[0]:
            raise ParameterError(
                f"load_displacement: no {what} column {name!r} in {source} (columns: {', '.join(rows[0])})"
            )
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot([r[displacement] for r in rows], [r[load] for r in rows], "o-", ms=3)
    ax.set_xlabel(displacement)
    ax.set_ylabel("load factor" if load == "time" else load)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    out = Path(output) if output is not None else _default_output(source, "load_displacement")
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def _convergence_file(source: Path) -> Path:
    if source.is_file():
        return source
    found = sorted(source.glob("*.jsonl"))
    if not found:
        raise OutputError(f"{source}: no convergence log (*.jsonl; add a ConvergenceLog output)")
    return found[0]


def newton_convergence(source: str | Path, *, output: str | Path | None = None, comm=None) -> Path | None:
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
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.set_xlabel("Newton iteration")
    ax.set_ylabel("residual norm")
    ax.grid(True, which="both", alpha=0.3)
    mappable = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(min(steps), top))
    fig.colorbar(mappable, ax=ax, label="step")
    fig.tight_layout()
    out = Path(output) if output is not None else path.with_name(f"{path.stem}_newton.png")
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def dynamics_time_series(
    sources: str | Path | Sequence[str | Path], *, output: str | Path | None = None, comm=None
) -> Path | None:
    """Motion of the test point, energies and volume ratio of dynamic runs, one panel each.

    Reads the diagnostics CSV (or any rows with the columns of
    :class:`~hyperfem.dynamics.Diagnostics`: ``time``, ``p0_x``..., ``kinetic_energy``,
    ``elastic_energy``, ``total_energy``, ``volume_ratio``, ``min_J``);
    several runs are overlaid, labelled by their folder.

    Args:
        sources: One or more CSV files (or folders / summaries, :func:`read_rows`).
        output: PNG file (default next to the first source).
        comm: Communicator; only rank 0 plots.

    Returns:
        The PNG path (``None`` on other ranks).
    """
    if comm is not None and comm.rank != 0:
        return None
    paths = [Path(sources)] if isinstance(sources, (str, Path)) else [Path(s) for s in sources]
    plt = _pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(7, 9), sharex=True)
    for path in paths:
        rows = read_rows(path)
        d = {k: [r[k] for r in rows] for k in rows[0]}
        label = path.name if path.is_dir() else path.parent.name
        t = d["time"]
        for comp, style in zip("xyz", ("-", "--", ":"), strict=True):
            if f"p0_{comp}" in d:
                axes[0].plot(t, d[f"p0_{comp}"], style, label=f"{label}: {comp}")
        for key, style, name in (
            ("kinetic_energy", "-", "kinetic"),
            ("elastic_energy", "-", "elastic"),
            ("total_energy", "k--", "total"),
        ):
            if key in d:
                axes[1].plot(t, d[key], style, lw=1 if key == "total_energy" else 1.5, label=f"{label}: {name}")
        if "volume_ratio" in d:
            axes[2].plot(t, d["volume_ratio"], label=f"{label}: V/V0")
        if "min_J" in d:
            axes[2].plot(t, d["min_J"], ":", label=f"{label}: min J")
    axes[0].set_ylabel("test point position (m)")
    axes[1].set_ylabel("energy (J)")
    axes[2].set_ylabel("volume ratio, min J")
    axes[2].set_xlabel("time (s)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    first = paths[0]
    if output is not None:
        out = Path(output)
    else:
        out = first / "run_dynamics.png" if first.is_dir() else first.with_suffix(".png")
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def plot_run(folder: str | Path, *, comm=None) -> list[Path]:
    """Every plot the files in a run's output folder allow; returns the PNG paths (rank 0; ``[]`` elsewhere).

    Load–displacement when the rows have a displacement column, the Newton
    history when there is a convergence log, the time series when the rows
    are those of a dynamic run (``kinetic_energy``).
    """
    if comm is not None and comm.rank != 0:
        return []
    folder = Path(folder)
    made = []
    rows = read_rows(folder)
    if "kinetic_energy" in rows[0]:
        made.append(dynamics_time_series(folder))
    try:
        made.append(load_displacement(folder))
    except ParameterError:
        pass
    if list(folder.glob("*.jsonl")):
        made.append(newton_convergence(folder))
    return made
