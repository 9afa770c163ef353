"""Contact with a rigid plane: what the barrier costs per Newton iteration, and Newton iterations with and without it.

The block of ``tests/test_contact.py``: a unit cube of ``n`` x ``n`` x ``n``
boxes (6 P1 tetrahedra each), rollers on x = 0 and y = 0, the top pushed down
by 20 % in 4 load steps, the bottom on the plane z = -dhat/2
(``PlaneContact``, dhat = 1e-3). Per mesh size, one JSON object:

* ``iterations_contact`` / ``iterations_roller``: Newton iterations of the 4
  steps with contact, and with the plane replaced by a roller (u_z = 0 on the
  bottom: the same frictionless support as a Dirichlet condition);
* per Newton iteration, at the final state (mean of ``--repeat`` runs): the
  contact terms (``energy`` + ``gradient`` added to the residual + ``hessian``
  added to the tangent + the collision ``filter`` of a Newton step) against the
  elastic residual and tangent assembly and the linear solve of the same
  iteration (the solver's own: MUMPS LU below 10^4 unknowns, refactorised as in every
  Newton iteration; CG + GAMG above);
* ``contact_force_z`` and the closed-form comparison, the smallest distance.

    python benchmarks/contact.py [--sizes 8 20] [--repeat 5]
    mpiexec -n 2 python benchmarks/contact.py
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402
import dolfinx.fem.petsc as fpetsc  # noqa: E402
from dolfinx import fem  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402

import hyperfem as hf  # noqa: E402

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
DELTA = 0.2
DHAT = 1e-3


def _problem(n: int, roller: bool) -> hf.HyperelasticProblem:
    mesh = dmesh.create_unit_cube(MPI.COMM_WORLD, n, n, n)
    groups = {
        "bottom": lambda x: np.isclose(x[2], 0.0),
        "top": lambda x: np.isclose(x[2], 1.0),
        "x0": lambda x: np.isclose(x[0], 0.0),
        "y0": lambda x: np.isclose(x[1], 0.0),
    }
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("top", [-DELTA], components=[2]),
    ]
    if roller:
        bcs.append(hf.PrescribedDisplacement("bottom", [0.0], components=[2]))
    domain = hf.Domain.from_locators(mesh, groups, source=f"cube({n})")
    return hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)


def _ramp(solver: hf.NewtonSolver) -> tuple[int, float]:
    start = time.perf_counter()
    steps = hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.25, max_increment=0.25))
    wall = MPI.COMM_WORLD.allreduce(time.perf_counter() - start, op=MPI.MAX)
    return sum(r.iterations for s in steps for r in s.solve_records), wall


def _mean_seconds(work, repeat: int) -> float:
    comm = MPI.COMM_WORLD
    comm.Barrier()
    start = time.perf_counter()
    for _ in range(repeat):
        work()
    comm.Barrier()
    return comm.allreduce(time.perf_counter() - start, op=MPI.MAX) / repeat


def _costs(problem, solver, repeat: int) -> dict:
    """Seconds per Newton iteration at the current state: the contact terms and the elastic assembly + solve."""
    external = solver.external
    contact_filter = external.step_filters[0]
    residual, tangent = fem.form(problem.residual), fem.form(problem.jacobian)
    A = fpetsc.create_matrix(tangent)
    b = fpetsc.create_vector(problem.u.function_space)
    x = problem.u.x.petsc_vec.copy()
    step = x.duplicate()
    ksp = solver.snes.getKSP()

    def assemble():
        with b.localForm() as local:
            local.set(0.0)
        fpetsc.assemble_vector(b, residual)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        A.zeroEntries()
        fpetsc.assemble_matrix(A, tangent, bcs=problem.bcs)
        A.assemble()

    def solve():
        A.assemble()  # a new state of A: MUMPS factorises again, as in a Newton iteration
        ksp.setOperators(A)
        ksp.solve(b, step)

    assemble()
    solve()
    out = {
        "energy_s": _mean_seconds(external.energy, repeat),
        "gradient_s": _mean_seconds(lambda: external.add_residual(b), repeat),
        "hessian_s": _mean_seconds(lambda: external.add_tangent(A), repeat),
        "filter_s": _mean_seconds(lambda: contact_filter.step_fraction(x, step), repeat),
        "elastic_assembly_s": _mean_seconds(assemble, repeat),
        "linear_solve_s": _mean_seconds(solve, repeat),
    }
    out["contact_s"] = out["energy_s"] + out["gradient_s"] + out["hessian_s"] + out["filter_s"]
    out["contact_over_elastic"] = out["contact_s"] / (out["elastic_assembly_s"] + out["linear_solve_s"])
    for vec in (b, x, step):
        vec.destroy()
    A.destroy()
    return out


def run(n: int, repeat: int) -> dict:
    comm = MPI.COMM_WORLD
    problem = _problem(n, roller=False)
    contact = hf.contact.PlaneContact("bottom", point=(0, 0, -DHAT / 2), normal=(0, 0, 1), dhat=DHAT).bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[contact])
    iterations, wall = _ramp(solver)
    force = contact.force()
    z = contact.nodes.positions(problem.u.x.array)[:, 2]
    height = 1.0 - DELTA - comm.allreduce(float(z.sum()), op=MPI.SUM) / contact.nodes.total
    entry = {
        "n": n,
        "ranks": comm.size,
        "unknowns": problem.u.function_space.dofmap.index_map.size_global * 3,
        "contact_nodes": contact.nodes.total,
        "iterations_contact": iterations,
        "wall_contact_s": wall,
        "contact_force_z": float(force[2]),
        "closed_form_relative_error": abs(force[2] + _uniaxial_stress(height)) / abs(_uniaxial_stress(height)),
        "min_distance": contact.min_distance(),
        "active": contact.active_count(),
        "displacement_norm": float(problem.u.x.petsc_vec.norm()),
        "stiffness": contact.stiffness,
        "linear_solver": solver.linear_solver_name,
    }
    entry.update(_costs(problem, solver, repeat))
    roller = _problem(n, roller=True)
    entry["iterations_roller"], entry["wall_roller_s"] = _ramp(hf.NewtonSolver(roller))
    return entry


def _uniaxial_stress(stretch: float) -> float:
    """P_zz of Neo-Hookean uniaxial stress (lateral faces free; see tests/test_contact.py)."""
    mu, lam = PARAMS.mu, PARAMS.lmbda
    lt = 1.0
    for _ in range(50):
        J = stretch * lt * lt
        g = mu * lt + (lam * np.log(J) - mu) / lt
        lt -= g / (mu + 2.0 * lam / lt**2 - (lam * np.log(J) - mu) / lt**2)
    J = stretch * lt * lt
    return mu * stretch + (lam * np.log(J) - mu) / stretch


def main() -> list[dict]:
    p = argparse.ArgumentParser()
    p.add_argument("--sizes", type=int, nargs="+", default=[8, 20])
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args()
    results = []
    for n in args.sizes:
        entry = run(n, args.repeat)
        results.append(entry)
        if MPI.COMM_WORLD.rank == 0:
            print(json.dumps(entry), flush=True)
    return results


if __name__ == "__main__":
    main()
