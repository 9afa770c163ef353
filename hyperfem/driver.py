"""A quasi-static run with output: load stepping, VTX per step, probes, JSON summary.

Demos and the CLI use :func:`run_quasistatic` so that every run reports the
same things: degrees of freedom, steps, Newton iterations per step, probe
values, wall time and where the files are. Each converged step is written
before the next one starts, so a later failure loses nothing.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from mpi4py import MPI

from hyperfem.errors import ConvergenceError
from hyperfem.io.probes import PointProbe
from hyperfem.io.results import VTXOutput, ensure_output_dir, write_json
from hyperfem.solver.newton import NewtonSolver
from hyperfem.solver.stepping import LoadStepping, StepRecord, solve_quasistatic

__all__ = ["format_summary", "run_quasistatic"]


def run_quasistatic(
    solver: NewtonSolver,
    name: str,
    output_dir: str | Path,
    probe_points: Sequence[Sequence[float]] = (),
    stepping: LoadStepping | None = None,
    target: float = 1.0,
    extra: dict | None = None,
) -> dict:
    """Ramp the load to ``target``, writing ``<name>.bp`` and ``<name>.json``.

    Args:
        solver: Newton solver of the problem.
        name: Base name of the output files.
        output_dir: Folder for the output files.
        probe_points: Reference points whose displacement is recorded per step.
        stepping: Load-step control.
        target: Final load factor.
        extra: Additional entries for the summary.

    Returns:
        The summary dictionary (also written as JSON). On
        :class:`~hyperfem.errors.ConvergenceError` the summary of the completed
        steps is written with ``"completed": false`` before re-raising.

    Raises:
        OutputError: If ``output_dir`` cannot be created or written (every
            rank, before the first step).
    """
    problem = solver.problem
    comm = problem.domain.comm
    output_dir = ensure_output_dir(Path(output_dir), comm)
    u = problem.u
    probe = PointProbe(problem.domain.mesh, probe_points) if len(probe_points) else None
    vtx_path = output_dir / f"{name}.bp"
    json_path = output_dir / f"{name}.json"
    steps: list[dict] = []
    summary = {
        "name": name,
        "dofs": int(u.function_space.dofmap.index_map.size_global * u.function_space.dofmap.index_map_bs),
        "cells": int(problem.domain.mesh.topology.index_map(problem.domain.tdim).size_global),
        "ranks": comm.size,
        "mesh": problem.domain.source,
        "degree": problem.degree,
        "petsc_options": {k: str(v) for k, v in solver.options.items()},
        "energy_line_search": solver.energy_line_search,
        "probe_points": [list(map(float, p)) for p in probe_points],
        "files": {"vtx": str(vtx_path), "summary": str(json_path)},
        **(extra or {}),
    }

    start = time.perf_counter()
    with VTXOutput(comm, vtx_path, [u]) as vtx:
        vtx.write(problem.load_factor)

        def on_step(step: StepRecord) -> None:
            vtx.write(step.load_factor)
            entry = {
                "load_factor": step.load_factor,
                "newton_iterations": step.solve.iterations,
                "cutbacks": step.cutbacks,
                "reason": step.solve.reason_name,
                "residual_norms": step.solve.residual_norms,
                "min_J": step.solve.min_J,
            }
            if probe is not None:
                entry["probe_displacement"] = probe(u).tolist()
            steps.append(entry)

        try:
            solve_quasistatic(solver, target, stepping or LoadStepping(), on_step)
            completed, error = True, None
        except ConvergenceError as exc:
            completed, error = False, str(exc)
        finally:
            summary.update(
                completed=False,
                steps=steps,
                load_steps=len(steps),
                newton_iterations=[s["newton_iterations"] for s in steps],
                total_newton_iterations=int(sum(s["newton_iterations"] for s in steps)),
                wall_time=comm.allreduce(time.perf_counter() - start, op=MPI.MAX),
            )
    summary["completed"] = completed
    summary["load_factor"] = problem.load_factor if completed else (steps[-1]["load_factor"] if steps else 0.0)
    if probe is not None and steps:
        summary["probe_displacement"] = steps[-1]["probe_displacement"]
    if error:
        summary["error"] = error
    write_json(json_path, summary, comm)
    if error:
        raise ConvergenceError(f"{name}: {error} (completed steps written to {json_path})", summary["load_factor"])
    return summary


def format_summary(summary: dict) -> str:
    """Short human-readable summary of :func:`run_quasistatic`'s result."""
    lines = [
        f"{summary['name']}: {summary['dofs']} dofs, {summary['cells']} cells, {summary['ranks']} rank(s)",
        f"  load steps: {summary['load_steps']}, Newton iterations per step: {summary['newton_iterations']}",
    ]
    if "probe_displacement" in summary:
        for p, d in zip(summary["probe_points"], summary["probe_displacement"], strict=True):
            lines.append(f"  displacement at {tuple(p)}: {np.array2string(np.asarray(d), precision=6)} m")
    if "convergence" in summary:
        lines.append(f"  convergence: {summary['convergence']}")
    lines.append(f"  wall time (load stepping, after form compilation): {summary['wall_time']:.2f} s")
    lines.append(f"  output: {summary['files']['vtx']} (ParaView), {summary['files']['summary']}")
    return "\n".join(lines)
