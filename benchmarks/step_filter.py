"""Exact inversion-free step filter vs quadrature-point bisection: Newton on large loads in one step.

Erleben's cantilever (seed 003) with P1 tetrahedra, the full load applied in a
single solve, scaled 2x to 200x so that Newton's first directions would
invert cells. For each mesh, case and load scale the same problem is solved
with ``NewtonSolver(step_filter="exact")`` (seed 004: the largest step at which
no cell shrinks below 0.1 of its volume, times ``STEP_SAFETY``) and with
``step_filter="bisection"`` (halve until J > 1e-6 at every quadrature point).
One JSON object per run: Newton iterations, line-search trial evaluations
(objective evaluations of the energy line search, residual evaluations for
the follower-load twist), the guard's own counts (steps filtered, halvings),
wall time, test-point displacement; then one summary object per
(mesh, case, scale) with the displacement difference of the two.

``--safety`` reruns the exact filter with other values of ``STEP_SAFETY``.

    python benchmarks/step_filter.py [--meshes meshes/beam_h2.msh meshes/beam_h1.msh] \
        [--scales 2 5 20 50 100 200] [--safety 0.9]
    mpiexec -n 2 python benchmarks/step_filter.py
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import numpy as np  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.solver.filters import STEP_SAFETY, ExactInversionFilter  # noqa: E402
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load, twist_load  # noqa: E402
from hyperfem.io import PointProbe  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def run(mesh: Path, case: str, scale: float, step_filter: str, safety: float) -> tuple[dict, np.ndarray]:
    domain = hf.read_mesh(mesh)
    params = CantileverSpec().lame
    load = bend_load(scale) if case == "bend" else twist_load(scale)
    problem = hf.HyperelasticProblem(
        domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("clamped")], loads=[load]
    )
    solver = hf.NewtonSolver(problem, step_filter=step_filter)
    snes = solver.snes
    count = [0]
    if solver.energy_line_search:
        objective, _, _ = snes.getObjective()

        def counted(snes_, x):
            count[0] += 1
            return objective(snes_, x)

        snes.setObjective(counted)
    for step_filter_ in solver.step_filters.filters:
        if isinstance(step_filter_, ExactInversionFilter):
            step_filter_.safety = safety
    problem.set_time(1.0)
    rec = solver.solve()
    displacement = PointProbe(domain.mesh, [TEST_POINT])(problem.u)[0]
    comm = domain.comm
    entry = {
        "mesh": mesh.name,
        "case": case,
        "scale": scale,
        "step_filter": rec.step_filter,
        "safety": safety if step_filter == "exact" else None,
        "ranks": comm.size,
        "cells": domain.mesh.topology.index_map(3).size_global,
        "converged": rec.converged,
        "reason": rec.reason_name,
        "iterations": rec.iterations,
        "objective_evaluations": count[0],
        "function_evaluations": int(snes.getFunctionEvaluations()),
        "filtered_steps": rec.filtered_steps,
        "min_step_fraction": rec.min_step_fraction,
        "inversion_cutbacks": rec.inversion_cutbacks,
        "time_s": comm.allreduce(rec.wall_time, op=MPI.MAX),
        "min_J": rec.min_J,
        "test_point_displacement": displacement.tolist(),
        "message": rec.message,
    }
    return entry, displacement


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--meshes", nargs="+", default=[ROOT / "meshes" / "beam_h2.msh", ROOT / "meshes" / "beam_h1.msh"])
    p.add_argument("--cases", nargs="+", default=["bend", "twist"])
    p.add_argument("--scales", type=float, nargs="+", default=[2.0, 5.0, 20.0, 50.0, 100.0, 200.0])
    p.add_argument("--safety", type=float, nargs="+", default=[STEP_SAFETY])
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    results = []

    def emit(entry):
        results.append(entry)
        if comm.rank == 0:
            print(json.dumps(entry), flush=True)

    for mesh in map(Path, args.meshes):
        for case in args.cases:
            for scale in args.scales:
                base, d_bis = run(mesh, case, scale, "bisection", STEP_SAFETY)
                emit(base)
                for safety in args.safety:
                    ours, d_ex = run(mesh, case, scale, "exact", safety)
                    emit(ours)
                    emit(
                        {
                            "summary": True,
                            "mesh": mesh.name,
                            "case": case,
                            "scale": scale,
                            "safety": safety,
                            "ranks": comm.size,
                            "both_converged": base["converged"] and ours["converged"],
                            "iterations_exact_vs_bisection": [ours["iterations"], base["iterations"]],
                            "time_ratio_exact_over_bisection": ours["time_s"] / base["time_s"],
                            "max_displacement_difference": float(np.max(np.abs(d_ex - d_bis))),
                        }
                    )
    return results


if __name__ == "__main__":
    main()
