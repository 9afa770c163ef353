"""The nearly-incompressible cube of issue 8: uniaxial stretch to 2, rollers on three faces.

Unit cube of tetrahedra, u_x = 0, u_y = 0, u_z = 0 on x = 0, y = 0, z = 0,
u_x = 1 on x = 1, lateral faces free; psi = mu/2 (J^(-2/3) tr C - 3) + U(J)
with mu = 1. Exact incompressible answer: lateral displacement
1/sqrt(2) - 1 = -0.29289 at every free-face node, axial force mu (l - 1/l^2) = 1.75.
Prints one JSON object per row (corner lateral displacement, axial force,
int J dX, load steps, Newton iterations, wall time), with the solver's
boundary-increment predictor on and off.

    python benchmarks/incompressible_cube.py [--quick]
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import ufl  # noqa: E402
from dolfinx import fem  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube  # noqa: E402
from hyperfem.io import PointProbe  # noqa: E402
from hyperfem.kinematics import isochoric_invariants  # noqa: E402
from hyperfem.problem import SplitEnergy, solid_problem  # noqa: E402
from hyperfem.simulation.reactions import ReactionForce  # noqa: E402

ROWS = [  # (formulation, law, K/mu, cells per side)
    ("mixed", "log", 1e3, 4),
    ("mixed", "log", 1e4, 4),
    ("mixed", "log", 1e3, 8),
    ("mixed", "quadratic", 1e3, 4),
    ("mixed", "log", 1e3, 2),
    ("displacement", "log", 1e3, 4),
    ("displacement", "log", 1e4, 4),
]


def run(formulation: str, law: str, K: float, n: int, predictor: bool) -> dict:
    comm = MPI.COMM_WORLD
    domain = unit_cube(n, comm)
    mesh = domain.mesh
    material = SplitEnergy(lambda F: 0.5 * (isochoric_invariants(F)[0] - 3.0), K, law)
    bcs = uniaxial_rollers(2.0)
    problem = solid_problem(domain, material, bcs=bcs, formulation=formulation)
    reaction = ReactionForce(problem, "x1")
    start = time.perf_counter()
    row = {"formulation": formulation, "law": law, "K_over_mu": K, "cells_per_side": n, "predictor": predictor}
    try:
        steps = hf.solve_quasistatic(
            hf.NewtonSolver(problem, predictor=predictor), stepping=hf.LoadStepping(initial_increment=0.25)
        )
        row.update(
            load_steps=len(steps),
            newton_iterations=int(sum(s.solve.iterations + sum(f.iterations for f in s.failed) for s in steps)),
        )
    except hf.ConvergenceError as exc:
        row["error"] = str(exc)
    row["wall_time"] = time.perf_counter() - start
    u = problem.update_fields()[0] if formulation == "mixed" else problem.u
    row["corner_lateral"] = float(PointProbe(mesh, [(1.0, 1.0, 1.0)])(u)[0][1])
    row["axial_force"] = float(reaction()[0])
    J = ufl.det(ufl.Identity(3) + ufl.grad(u))
    row["volume"] = comm.allreduce(fem.assemble_scalar(fem.form(J * ufl.dx(metadata={"quadrature_degree": 4}))))
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="predictor on only (the off rows take ~30 s)")
    args = p.parse_args()
    for formulation, law, K, n in ROWS:
        for predictor in (True,) if args.quick else (True, False):
            row = run(formulation, law, K, n, predictor)
            if MPI.COMM_WORLD.rank == 0:
                print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
