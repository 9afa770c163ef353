"""What the command line prints: progress lines, the mesh-quality table, warnings.

Everything here formats; printing happens on rank 0 (:func:`say`, :func:`warn`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from mpi4py import MPI

from hyperfem.mesh.quality import MEASURES, MeshQuality

__all__ = ["progress_line", "quality_table", "say", "warn"]


def say(text: str, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Print ``text`` on rank 0 (stdout, flushed)."""
    if comm.rank == 0:
        print(text, flush=True)


def warn(text: str, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Print ``hyperfem: warning: text`` on rank 0 (stderr)."""
    if comm.rank == 0:
        print(f"hyperfem: warning: {text}", file=sys.stderr, flush=True)


def _vector(value: Sequence[float]) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in value) + ")"


def progress_line(row: dict) -> str:
    """One line per recorded state: step, time, increment, Newton iterations, residual, min J, reactions, probes."""
    dynamic = "kinetic_energy" in row  # a time integration: times in s; else load factors (no unit)
    unit = " s" if dynamic else ""
    parts = [
        f"step {row['step']:>3}",
        f"t = {row['time']:.6g}{unit}" if dynamic else f"load factor {row['time']:.6g}",
        f"dt = {row['dt']:.4g}{unit}" if dynamic else f"increment {row['dt']:.4g}",
        f"newton {row['newton_iterations']}",
    ]
    if row.get("residual") == row.get("residual"):  # not nan
        parts.append(f"|r| {row['residual']:.2e}")
    if row.get("rejected"):
        parts.append(f"rejected {row['rejected']}")
    if row.get("min_J") == row.get("min_J"):  # not nan
        parts.append(f"min J {row['min_J']:.4g}")
    if row.get("negative_pivots", -1) >= 0:  # a continuation: the stability of the state, what the step passed
        parts.append(f"neg. pivots {row['negative_pivots']}" + ("" if row.get("stable", True) else " (unstable)"))
    if "negative_eigenvalues" in row:  # the Stability output: the lowest eigenvalue of the tangent
        lowest = row["lowest_eigenvalues"][0] if row.get("lowest_eigenvalues") else float("nan")
        parts.append(f"mu_min {lowest:.4g}" + ("" if row.get("stable_state", True) else " UNSTABLE"))
    if row.get("limit_point"):
        parts.append(f"LIMIT POINT at load factor {row['limit_load']:.6g}")
    if row.get("bifurcation"):
        parts.append("BIFURCATION (pivot count changed)")
    if row.get("switched"):
        parts.append("switched branch")
    forces: dict[str, list[float]] = {}
    for key, value in row.items():
        if key.startswith("reaction_") and key[-3:-1] == "_F":
            forces.setdefault(key[len("reaction_") : -3], []).append(value)
    for name, force in forces.items():
        if name != "total":
            parts.append(f"F[{name}] = {_vector(force)} N")
    for key in row:
        if key.endswith("_min_distance") and f"{key[:-13]}_force" in row:  # a contact: pairs, gap, force
            name = key[: -len("_min_distance")]
            force = row[f"{name}_force"]
            parts.append(f"{name}: {row.get(name + '_active', 0)} active, d_min {row[key]:.3g}, F = {_vector(force)} N")
        elif key.endswith("_max_gap") and f"{key[:-8]}_force" in row:  # a tie
            parts.append(f"{key[:-8]}: gap {row[key]:.2g} m")
    if "probe_displacement" in row and row["probe_displacement"]:
        parts.append(f"u(probe 0) = {_vector(row['probe_displacement'][0])} m")
    if "kinetic_energy" in row:
        parts.append(f"K = {row['kinetic_energy']:.4g} J")
    return "  ".join(parts)


def quality_table(quality: MeshQuality) -> str:
    """The seed 003 §5.6 measures as a table: min, p1, p5, median, mean, max (1 = regular)."""
    columns = ("min", "p1", "p5", "p50", "mean", "max")
    width = max(len(label) for label in MEASURES.values())
    lines = [f"{'measure':<{width}}  " + "  ".join(f"{c:>6}" for c in columns)]
    for key, stats in quality.stats.items():
        lines.append(f"{MEASURES[key]:<{width}}  " + "  ".join(f"{stats[c]:6.3f}" for c in columns))
    return "\n".join(lines)
