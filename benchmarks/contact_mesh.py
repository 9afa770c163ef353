"""Mesh contact (``ipctk``): what the barrier's terms cost per Newton iteration, against the elastic iteration.

A unit cube of ``n`` x ``n`` x ``n`` boxes (6 P1 tetrahedra each) whose
*whole* boundary is the collision surface (``6 n^2 + 2`` vertices: 9,602 at
``n = 40``), resting at ``dhat/2`` on a rigid two-triangle plate
(``ToolContact``; ``n^2 + ...`` bottom vertices in contact, every pair of the
bottom face active). Per mesh size, one JSON object with the seconds of one
evaluation of each contact term at that state (best of ``--repeat``):

* ``gather``: the surface positions (one ``allgather``),
* ``pairs``: the broad phase (``HashGrid`` candidates) and the active pairs,
* ``energy``, ``gradient`` (added to a residual), ``hessian`` (the projected
  Hessian from ``ipctk`` and its insertion into the tangent),
* ``ccd``: the collision filter of a Newton step (``AdditiveCCD``),

against the elastic terms of the same iteration: ``residual`` and
``tangent`` assembly and one ``linear_solve`` with the solver's own linear
solver (MUMPS LU below 10^4 unknowns, CG + GAMG above; a random right-hand
side), and ``newton_iteration``: a solve of one Newton iteration after a
first (set-up) solve (the top pushed from 0.5 % to 1 % of the height down):
the predictor's tangent solve, the iteration's assembly, solve, energy line
search, filters and contact terms.
``ratio`` is the contact terms (pairs + energy + gradient + hessian + ccd,
the pairs counted once since they are cached per state) over the elastic
ones.

``--shape plate`` takes a plate of one layer of ``n x n`` boxes (``1/n``
thick) instead: every node is on the surface (``2 (n + 1)^2`` vertices:
100,352 at ``n = 223``) and the bottom's half of them in contact, the
surface-heavy end of the scale.

Measured (``benchmarks/results/contact_mesh_s38.jsonl``, quiet machine; contact terms / elastic terms, s):

========================  =========  ==============  =================  ======
mesh                      unknowns   surface verts.  ranks              ratio
========================  =========  ==============  =================  ======
cube, n = 40              206,763    9,602           1: 0.066 / 1.19    0.056
plate, n = 71             31,104     10,368          1: 0.122 / 0.080   1.5
plate, n = 223            301,056    100,352         1: 1.45 / 0.90     1.6
plate, n = 223            301,056    100,352         2: 2.28 / 0.42     5.4
========================  =========  ==============  =================  ======

Where the contact time goes at 10^5 vertices (51,515 active pairs, the plate's whole bottom): the broad
phase and the active set (``pairs``, 0.69 s serially) and the CCD (0.62 s); the Hessian 0.10 s, the gradient
0.03 s. Both grow about linearly with the surface (0.054 and 0.057 s at 10^4). On 2 ranks every rank
evaluates the whole gathered surface (:mod:`hyperfem.contact.surface`), so the contact terms do not shrink
while the elastic ones halve; the two ranks' ``ipctk`` calls also share the 2 cores (1.1 and 1.0 s).
For a solid body, whose surface is a small part of its nodes, the contact terms are 6 % of the elastic
iteration at 10^4 surface vertices.

``--degree 2`` takes P2 tetrahedra, whose surface goes through the collision
proxy (:mod:`hyperfem.contact.proxy`; ``--subdivision``, default the
library's): ``collision_vertices`` against ``surface_vertices`` (the nodes).

    python benchmarks/contact_mesh.py [--sizes 10 20 40] [--repeat 3] [--degree 2] [--subdivision 1]
    mpiexec -n 2 python benchmarks/contact_mesh.py
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import numpy as np  # noqa: E402
import dolfinx.fem.petsc as fpetsc  # noqa: E402
from dolfinx import fem  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.contact import ToolContact  # noqa: E402

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
DHAT = 1e-3


def _best(function, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        MPI.COMM_WORLD.Barrier()
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return MPI.COMM_WORLD.allreduce(best, op=MPI.MAX)


def measure(n: int, repeat: int, degree: int = 1, subdivision: int | None = None, shape: str = "cube") -> dict:
    comm = MPI.COMM_WORLD
    height = 1.0 if shape == "cube" else 1.0 / n  # a plate: one layer of n x n boxes, every node on the surface
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([1.0, 1.0, height])], [n, n, n if shape == "cube" else 1])
    groups = {"surface": lambda x: np.full(x.shape[1], True), "top": lambda x: np.isclose(x[2], height)}
    domain = hf.Domain.from_locators(mesh, groups, source=f"{shape}({n})")
    bcs = [hf.PrescribedDisplacement("top", [0.0, 0.0, -0.01 * height])]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs, degree=degree)
    plate = np.array([[-1.0, -1.0, -DHAT / 2], [3.0, -1.0, -DHAT / 2], [3.0, 3.0, -DHAT / 2], [-1.0, 3.0, -DHAT / 2]])
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    tool = ToolContact.from_arrays(["surface"], plate, triangles, dhat=DHAT, subdivision=subdivision).bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[tool])
    u = problem.u.x.array
    nlp = solver._nlp
    A, b = nlp.A, nlp.b
    step = problem.u.x.petsc_vec.duplicate()
    step.array_w[:] = 0.0
    step.array_w[tool.surface.dofs[:, 2]] = 0.5 * DHAT  # every surface node 0.5 dhat down: the filter cuts it

    def pairs():
        tool._cache = None
        tool._collisions(tool.vertices(u))

    residual_form = fem.form(problem.residual)

    def elastic_residual():
        with b.localForm() as local:
            local.set(0.0)
        fpetsc.assemble_vector(b, residual_form)

    def tangent():
        A.zeroEntries()
        fpetsc.assemble_matrix(A, nlp.J, bcs=problem.bcs)
        A.assemble()

    tangent()
    solver.external.add_tangent(A)
    ksp = solver.snes.getKSP()
    ksp.setOperators(A, A)
    du = step.duplicate()

    def solve():
        ksp.setOperators(A, A)
        ksp.solve(b, du)

    elastic_residual()
    timings = {
        "gather": _best(lambda: tool.vertices(u), repeat),
        "pairs": _best(pairs, repeat),
        "energy": _best(lambda: tool.energy(u), repeat),
        "gradient": _best(lambda: solver.external.add_residual(b), repeat),
        "hessian": _best(lambda: solver.external.add_tangent(A), repeat),
        "ccd": _best(lambda: tool.step_filter.step_fraction(problem.u.x.petsc_vec, step), repeat),
        "residual": _best(elastic_residual, repeat),
        "tangent": _best(tangent, repeat),
    }
    tangent()
    solver.external.add_tangent(A)
    rng = np.random.default_rng(0)
    b.array_w[:] = rng.standard_normal(len(b.array_r))  # a right-hand side with every mode in it
    fpetsc.set_bc(b, problem.bcs)
    solver.snes.setUp()  # the solver's own linear solver, as configured for the Newton solve
    timings["linear_solve"] = _best(solve, repeat)
    # One whole Newton iteration of the solver (the top pushed 1 % of the height), contact terms included.
    solver.snes.setTolerances(max_it=1)
    problem.set_time(0.5)
    solver.solve()  # the first solve sets up (forms, preconditioner, round-off estimate)
    problem.set_time(1.0)
    start = time.perf_counter()
    solver.solve()
    timings["newton_iteration"] = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    contact = sum(timings[k] for k in ("pairs", "energy", "gradient", "hessian", "ccd"))
    elastic = timings["residual"] + timings["tangent"] + timings["linear_solve"]
    W = problem.u.function_space
    return {
        "n": n,
        "shape": shape,
        "degree": degree,
        "ranks": comm.size,
        "unknowns": W.dofmap.index_map.size_global * W.dofmap.index_map_bs,
        "surface_vertices": tool.surface.size,
        "collision_vertices": tool.surface.collision_size,
        "active_pairs": tool.active_count(),
        "seconds": {k: round(v, 5) for k, v in timings.items()},
        "contact": round(contact, 5),
        "elastic": round(elastic, 5),
        "ratio": round(contact / elastic, 3),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--degree", type=int, default=1)
    parser.add_argument("--subdivision", type=int, default=None)
    parser.add_argument("--shape", choices=("cube", "plate"), default="cube")
    args = parser.parse_args()
    for n in args.sizes:
        result = measure(n, args.repeat, args.degree, args.subdivision, args.shape)
        if MPI.COMM_WORLD.rank == 0:
            print(json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
