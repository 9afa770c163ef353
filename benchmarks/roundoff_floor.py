"""Where the residual floor sits, and what ending a solve there saves.

For the cantilever bend/twist (P1 and P2, full load in one step) the solve
is run with a tolerance far below the floating-point floor (rtol = atol =
1e-15), once with hyperfem's round-off stop and once without it (plain SNES
tolerances: it wanders until ``snes_max_it``). Printed per case, one JSON
object: the residual history, the estimate eps*|| |K| |x| || at the end, the
noise band (the residual norms after the floor was reached, divided by the
estimate), Newton iterations with and without the stop, and the largest
difference of the two solutions.

    python benchmarks/roundoff_floor.py [--output benchmarks/results/roundoff_floor.jsonl]
    mpiexec -n 2 python benchmarks/roundoff_floor.py
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
from hyperfem.cases import CantileverSpec, bend_load, twist_load  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TIGHT = {"snes_rtol": 1e-15, "snes_atol": 1e-15, "snes_max_it": 30}


def solve(mesh: str, degree: int, case: str, roundoff_factor: float):
    domain = hf.read_mesh(ROOT / "meshes" / mesh)
    params = CantileverSpec().lame
    load = bend_load() if case == "bend" else twist_load()
    problem = hf.HyperelasticProblem(
        domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("clamped")], loads=[load], degree=degree
    )
    solver = hf.NewtonSolver(problem, TIGHT, roundoff_factor=roundoff_factor)
    problem.set_time(1.0)
    record = solver.solve()
    return problem, solver, record


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--output", type=Path, default=None, help="append the JSON lines to this file")
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    for mesh, degree in (("beam_h2.msh", 1), ("beam_h1.msh", 1), ("beam_h2.msh", 2), ("beam_h1.msh", 2)):
        for case in ("bend", "twist"):
            problem, solver, stop = solve(mesh, degree, case, hf.ROUNDOFF_FACTOR)
            u_stop = problem.u.x.array.copy()
            floor = solver.roundoff_floor()
            problem2, _, plain = solve(mesh, degree, case, 0.0)
            norms = np.array(plain.residual_norms)
            # The noise phase: from the first norm within 3x of the median of the last five on
            # (only when the plain run wandered to snes_max_it; cp may stop by itself earlier).
            wandered = plain.reason_name == "DIVERGED_MAX_IT"
            band = norms[int(np.argmax(norms <= 3 * np.median(norms[-5:]))):] if wandered else None
            diff = comm.allreduce(float(np.abs(problem2.u.x.array - u_stop).max()), op=MPI.MAX)
            rows.append(
                {
                    "mesh": mesh,
                    "degree": degree,
                    "case": case,
                    "ranks": comm.size,
                    "estimate": floor,
                    "noise_band_over_estimate": None if band is None else [float(band.min() / floor),
                                                                           float(band.max() / floor)],
                    "with_stop": {"reason": stop.reason_name, "iterations": stop.iterations,
                                  "residual_norms": stop.residual_norms},
                    "without_stop": {"reason": plain.reason_name, "iterations": plain.iterations,
                                     "residual_norms": plain.residual_norms},
                    "max_solution_difference": diff,
                }
            )
            if comm.rank == 0:
                print(json.dumps(rows[-1]), flush=True)
    if comm.rank == 0 and args.output is not None:
        with open(args.output, "a") as f:
            for row in rows:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
