"""Where the residual floor sits, and what ending a solve there saves.

For the cantilever bend/twist (P1 and P2, full load in one step) the solve
is run with a tolerance far below the floating-point floor (rtol = atol =
1e-15), once with hyperfem's round-off stop and once without it (plain SNES
tolerances: it wanders until ``snes_max_it``). Printed per case, one JSON
object: the residual history, the estimate eps*|| |K| |x| || at the end, the
noise band (the residual norms after the floor was reached, divided by the
estimate), Newton iterations with and without the stop, and the largest
difference of the two solutions.

``--mixed``: the three-field (u, p, theta) problem (P2/P1/P1, neo-Hookean
isochoric part, log volumetric law, mu = 1) instead, at K/mu = 1e2, 1e4 and
1e8: the unit cube (2 x 2 x 2 boxes) on rollers pulled to stretch 1.5, and a
bar 1 x 0.3 x 0.3 (4 x 2 x 2 boxes) clamped at x = 0 and pulled by 0.3 (not
homogeneous), each in 4 load steps; the noise band of every step, against the
estimate and against the one without the identity part of theta
(``estimate_without_theta``, what the stop used before).

    python benchmarks/roundoff_floor.py [--mixed] [--output benchmarks/results/roundoff_floor.jsonl]
    mpiexec -n 2 python benchmarks/roundoff_floor.py [--mixed]
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import numpy as np  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402
from petsc4py import PETSc  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.cases import CantileverSpec, bend_load, twist_load  # noqa: E402
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube  # noqa: E402
from hyperfem.kinematics import isochoric_invariants  # noqa: E402
from hyperfem.problem import MixedHyperelasticProblem, SplitEnergy  # noqa: E402
from hyperfem.solver.roundoff import reference_scale  # noqa: E402

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


def mixed_problem(case: str, ratio: float) -> MixedHyperelasticProblem:
    """The three-field cube or gripped bar of ``--mixed``, K/mu = ``ratio``."""
    material = SplitEnergy(lambda F: 0.5 * (isochoric_invariants(F)[0] - 3.0), ratio, "log")
    if case == "cube":
        return MixedHyperelasticProblem(unit_cube(2), material, bcs=uniaxial_rollers(1.5))
    mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([1.0, 0.3, 0.3])], [4, 2, 2])
    domain = hf.Domain.from_locators(
        mesh, {"left": lambda x: np.isclose(x[0], 0.0), "right": lambda x: np.isclose(x[0], 1.0)}, source="bar"
    )
    bcs = [hf.Clamp("left"), hf.PrescribedDisplacement("right", [0.3, 0.0, 0.0])]
    return MixedHyperelasticProblem(domain, material, bcs=bcs)


def estimate_without_theta(problem: MixedHyperelasticProblem, solver: hf.NewtonSolver) -> float:
    """eps || |K| (|x| + h) || with h in the displacement dofs only (the estimate before the identity of theta)."""
    A = solver.snes.getJacobian()[0].duplicate(copy=True)
    ai, aj, av = A.getValuesCSR()
    A.setValuesCSR(ai, aj, np.abs(av))
    A.assemble()
    x = solver.snes.getSolution().copy()
    x.abs()
    h = reference_scale(problem, x)
    volume = problem.field_dofs()["volume"]
    h.array[volume[volume < h.getLocalSize()]] = 0.0
    x.axpy(1.0, h)
    y = A.createVecLeft()
    A.mult(x, y)
    return float(np.finfo(float).eps * y.norm(PETSc.NormType.NORM_2))


def mixed_rows(comm: MPI.Comm) -> list[dict]:
    """The ``--mixed`` rows: per load step, the noise band of the plain solve over both estimates."""
    rows = []
    for case in ("cube", "bar"):
        for ratio in (1e2, 1e4, 1e8):
            runs = {}
            for label, factor in (("with_stop", hf.ROUNDOFF_FACTOR), ("without_stop", 0.0)):
                problem = mixed_problem(case, ratio)
                solver = hf.NewtonSolver(problem, TIGHT, roundoff_factor=factor)
                steps = []
                for t in (0.25, 0.5, 0.75, 1.0):
                    problem.set_time(t)
                    record = solver.solve()
                    steps.append((record, solver.roundoff_floor(), estimate_without_theta(problem, solver)))
                runs[label] = (problem.u.x.array.copy(), steps)
            (u_stop, stop), (u_plain, plain) = runs["with_stop"], runs["without_stop"]
            diff = comm.allreduce(float(np.abs(u_plain - u_stop).max()), op=MPI.MAX)
            bands, bands_old = [], []
            for record, floor, old in plain:
                norms = np.array(record.residual_norms)
                if record.reason_name != "DIVERGED_MAX_IT":  # ended by a tolerance: no noise band
                    bands.append(None)
                    bands_old.append(None)
                    continue
                band = norms[int(np.argmax(norms <= 3 * np.median(norms[-5:]))):]
                bands.append([float(band.min() / floor), float(band.max() / floor)])
                bands_old.append([float(band.min() / old), float(band.max() / old)])
            rows.append(
                {
                    "mixed": case,
                    "K_over_mu": ratio,
                    "ranks": comm.size,
                    "estimate": [floor for _, floor, _ in stop],
                    "estimate_without_theta": [old for _, _, old in stop],
                    "noise_band_over_estimate": bands,
                    "noise_band_over_estimate_without_theta": bands_old,
                    "with_stop": [{"reason": r.reason_name, "iterations": r.iterations,
                                   "residual_norms": r.residual_norms} for r, _, _ in stop],
                    "without_stop": [{"reason": r.reason_name, "iterations": r.iterations} for r, _, _ in plain],
                    "max_solution_difference": diff,
                }
            )
            if comm.rank == 0:
                print(json.dumps(rows[-1]), flush=True)
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--output", type=Path, default=None, help="append the JSON lines to this file")
    p.add_argument("--mixed", action="store_true", help="the three-field problem instead of the cantilever")
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    rows = mixed_rows(comm) if args.mixed else []
    cantilevers = (("beam_h2.msh", 1), ("beam_h1.msh", 1), ("beam_h2.msh", 2), ("beam_h1.msh", 2))
    for mesh, degree in () if args.mixed else cantilevers:
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
