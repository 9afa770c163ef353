"""Newton iterations and time: hyperfem's energy line search vs the textbook NonlinearProblem.

The baseline is the set-up of the DOLFINx hyperelasticity demo: a
``NonlinearProblem`` with SNES ``newtonls``, backtracking on the residual norm
and MUMPS. hyperfem uses the same SNES with Π as the line-search objective.
Both solve the cantilever bend (full load, one step) on the same mesh; the
script prints one JSON object per mesh and the speed-up.

    python benchmarks/energy_line_search.py [--h 1.0 0.5] [--degree 1]
    mpiexec -n 2 python benchmarks/energy_line_search.py
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import numpy as np  # noqa: E402
import ufl  # noqa: E402
from dolfinx import fem  # noqa: E402
from dolfinx.fem.petsc import NonlinearProblem  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load  # noqa: E402
from hyperfem.io import PointProbe  # noqa: E402


def textbook(domain, degree):
    """The DOLFINx-demo way: hand-written forms, residual-norm backtracking."""
    spec = CantileverSpec()
    mu, lmbda = spec.lame.mu, spec.lame.lmbda
    V = fem.functionspace(domain.mesh, ("Lagrange", degree, (3,)))
    u, v = fem.Function(V), ufl.TestFunction(V)
    F = ufl.variable(ufl.Identity(3) + ufl.grad(u))
    J = ufl.det(F)
    psi = mu / 2 * (ufl.tr(F.T * F) - 3) - mu * ufl.ln(J) + lmbda / 2 * ufl.ln(J) ** 2
    P = ufl.diff(psi, F)
    t = fem.Constant(domain.mesh, np.array([0.0, -5e3, 0.0]))
    md = {"quadrature_degree": hf.problem.default_quadrature_degree(degree)}
    R = ufl.inner(P, ufl.grad(v)) * ufl.dx(metadata=md) - ufl.dot(t, v) * domain.ds("free_end", metadata=md)
    dofs = fem.locate_dofs_topological(V, 2, domain.facets("clamped"))
    bc = fem.dirichletbc(np.zeros(3), dofs, V)
    opts = {
        "snes_type": "newtonls",
        "snes_linesearch_type": "bt",
        "snes_rtol": 1e-9,
        "snes_atol": 1e-10,
        "snes_max_it": 50,
        "ksp_type": "preonly",
        "pc_type": "lu",
        "pc_factor_mat_solver_type": "mumps",
    }
    problem = NonlinearProblem(R, u, bcs=[bc], petsc_options_prefix="textbook_", petsc_options=opts)
    start = time.perf_counter()
    problem.solve()
    wall = time.perf_counter() - start
    snes = problem.solver
    return u, {
        "iterations": snes.getIterationNumber(),
        "reason": int(snes.getConvergedReason()),
        "time_s": wall,
    }


def hyperfem_run(domain, degree):
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(
        domain,
        lambda F: hf.materials.neo_hookean(F, params),
        bcs=[hf.Clamp("clamped")],
        loads=[bend_load()],
        degree=degree,
    )
    solver = hf.NewtonSolver(problem)
    problem.set_time(1.0)
    rec = solver.solve()
    return problem.u, {"iterations": rec.iterations, "reason": rec.reason, "time_s": rec.wall_time}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--h", type=float, nargs="+", default=[1.0, 0.5])
    p.add_argument("--degree", type=int, default=1)
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    results = []
    for h in args.h:
        domain = hf.beam_mesh(h=h, comm=comm)
        probe = PointProbe(domain.mesh, [TEST_POINT])
        u0, base = textbook(domain, args.degree)
        u1, ours = hyperfem_run(domain, args.degree)
        d0, d1 = probe(u0)[0], probe(u1)[0]
        for r in (base, ours):
            r["time_s"] = comm.allreduce(r["time_s"], op=MPI.MAX)
        entry = {
            "h": h,
            "degree": args.degree,
            "ranks": comm.size,
            "dofs": u1.function_space.dofmap.index_map.size_global * 3,
            "textbook": {**base, "test_point_displacement": d0.tolist()},
            "hyperfem": {**ours, "test_point_displacement": d1.tolist()},
            "iteration_ratio": base["iterations"] / max(ours["iterations"], 1),
            "speedup": base["time_s"] / ours["time_s"],
            "max_displacement_difference": float(np.max(np.abs(d0 - d1))),
        }
        results.append(entry)
        if comm.rank == 0:
            print(json.dumps(entry), flush=True)
    return results


if __name__ == "__main__":
    main()
