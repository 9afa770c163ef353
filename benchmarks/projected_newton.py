"""Projected Newton (PSD-projected material tangent, seed 004) against plain Newton.

Solvers, all with hyperfem's energy line search (for conservative loads),
inversion guard and default tolerances:

* ``plain``: :class:`~hyperfem.solver.NewtonSolver` with the consistent tangent;
* ``projected``: :func:`~hyperfem.solver.projected.projected_newton_solver`,
  negative eigenvalues of the material tangent clamped at 0 at every
  quadrature point (seed 004);
* ``abs``: the same with the absolute-value filter (negative modes flipped);
* ``hybrid``: projected until the residual is below ``--switch`` (1e-2) of the
  initial one, consistent after that.

Cases on ``meshes/beam_h2.msh`` (Erleben's cantilever, seed 003 §5.7),
compressible Neo-Hookean, E = 1 MPa, nu = 0.3, the full load in one step:

* ``bend_x5`` / ``bend_x5_p2``: 5 x the bend traction (P1 / P2);
* ``twist_x5``: 5 x the twist traction (a follower load: no energy line
  search, the follower tangent is added unprojected);
* ``column_50kPa`` / ``column_100kPa``: a dead axial compression of the
  free end, 50 / 100 kPa, with a 1 % lateral imperfection (0, -1, 0) %;
  the Euler load of the clamped-free column is about 33 kPa
  (pi^2 E I / (4 L^2) / A; less with shear on this stubby beam), so both
  are beyond buckling.

Each (case, solver) is run twice from rest: one ``solve()`` at the full load
(``single``) and :func:`~hyperfem.solve_quasistatic` with the default
stepping, which starts at the full load and cuts the step back on failure
(``stepped``). Printed per run, one JSON object: convergence, Newton
iterations (all solves of the stepped run, failed ones included), cutbacks
(rejected steps), inversion-guard cutbacks, wall time, the time spent
refreshing the projected tangent, the share of quadrature points whose
material tangent was indefinite at the end, the total potential, the
test-point displacement and, serially, the smallest eigenvalue of the
consistent tangent on the free dofs at the end (negative: an unstable
equilibrium or not an equilibrium).

    python benchmarks/projected_newton.py [--output benchmarks/results/projected_newton.jsonl]
    mpiexec -n 2 python benchmarks/projected_newton.py
    python benchmarks/projected_newton.py --smoke   # one case, quick
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import numpy as np  # noqa: E402
from dolfinx import fem  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load, twist_load  # noqa: E402
from hyperfem.io import PointProbe  # noqa: E402
from hyperfem.solver.projected import ProjectedTangent, projected_newton_solver  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
MESH = ROOT / "meshes" / "beam_h2.msh"
IMPERFECTION = 0.01


def column_load(pressure: float) -> hf.DeadTraction:
    """Axial compression ``pressure`` (Pa) of the free end with a lateral imperfection."""
    return hf.DeadTraction("free_end", (-pressure, -IMPERFECTION * pressure, 0.0))


CASES = {
    "bend_x5": (1, lambda: bend_load(5.0)),
    "bend_x5_p2": (2, lambda: bend_load(5.0)),
    "twist_x5": (1, lambda: twist_load(5.0)),
    "column_50kPa": (1, lambda: column_load(5.0e4)),
    "column_100kPa": (1, lambda: column_load(1.0e5)),
}
SOLVERS = ("plain", "projected", "abs", "hybrid")


class TimedTangent:
    """A :class:`ProjectedTangent` whose refreshes are timed."""

    def __init__(self, tangent: ProjectedTangent):
        self.tangent = tangent
        self.seconds = 0.0
        inner = tangent.refresh

        def refresh(force: bool = False) -> None:
            start = time.perf_counter()
            inner(force)
            self.seconds += time.perf_counter() - start

        tangent.refresh = refresh  # what projected_newton_solver installs as the state hook


def build(case: str, solver_name: str, switch: float):
    degree, load = CASES[case]
    domain = hf.read_mesh(MESH)
    problem = hf.HyperelasticProblem(
        domain,
        lambda F: hf.materials.neo_hookean(F, CantileverSpec().lame),
        bcs=[hf.Clamp("clamped")],
        loads=[load()],
        degree=degree,
    )
    if solver_name == "plain":
        return problem, hf.NewtonSolver(problem), None
    tangent = ProjectedTangent(problem, mode="abs" if solver_name == "abs" else "clamp")
    timed = TimedTangent(tangent)
    solver = projected_newton_solver(
        problem, tangent=tangent, consistent_below=switch if solver_name == "hybrid" else None
    )
    return problem, solver, timed


def free_min_eigenvalue(problem) -> float | None:
    """Smallest eigenvalue of the consistent tangent on the free dofs over the largest (serial only)."""
    if problem.domain.comm.size > 1:
        return None
    K = fem.assemble_matrix(fem.form(problem.jacobian), bcs=problem.bcs).to_dense()
    off = np.abs(K).sum(axis=1) - np.abs(np.diag(K))
    free = ~((off == 0.0) & (np.diag(K) == 1.0))  # Dirichlet rows: identity
    lam = np.linalg.eigvalsh(0.5 * (K + K.T)[np.ix_(free, free)])
    return float(lam[0] / np.abs(lam).max())


def run(case: str, solver_name: str, mode: str, switch: float) -> dict:
    comm = MPI.COMM_WORLD
    problem, solver, timed = build(case, solver_name, switch)
    probe = PointProbe(problem.domain.mesh, [TEST_POINT])
    start = time.perf_counter()
    if mode == "single":
        problem.set_time(1.0)
        records = [solver.solve()]
        converged, steps, rejected = records[0].converged, 1, 0
    else:
        try:
            history = hf.solve_quasistatic(solver)
            records = [r for s in history for r in (*s.failed, *s.solve_records)]
            converged, steps, rejected = True, len(history), sum(s.rejected for s in history)
        except hf.ConvergenceError as exc:
            history = list(getattr(exc, "history", []) or [])
            records = [r for s in history for r in (*s.failed, *s.solve_records)]
            converged, steps, rejected = False, len(history), sum(s.rejected for s in history)
    wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    last = records[-1] if records else None
    row = {
        "case": case,
        "solver": solver_name,
        "run": mode,
        "ranks": comm.size,
        "dofs": problem.V.dofmap.index_map.size_global * problem.V.dofmap.index_map_bs,
        "converged": bool(converged),
        "reason": last.reason_name if last else "",
        "iterations": int(sum(r.iterations for r in records)),
        "solves": len(records),
        "steps": steps,
        "cutbacks": int(rejected),
        "inversion_cutbacks": int(sum(r.inversion_cutbacks for r in records)),
        "filtered_steps": int(sum(getattr(r, "filtered_steps", 0) for r in records)),
        "time_s": wall,
        "refresh_time_s": None,
        "refreshes": None,
        "indefinite_fraction": None,
        "total_potential": float(solver.energy()) if problem.conservative else None,
        "test_point_displacement": probe(problem.u)[0].tolist(),
        "min_eigenvalue_free_K": free_min_eigenvalue(problem),
        "residual_norms_last_solve": [float(x) for x in last.residual_norms] if last else [],
    }
    if timed is not None:
        stats = timed.tangent.statistics()
        row["refresh_time_s"] = comm.allreduce(timed.seconds, op=MPI.MAX)
        row["refreshes"] = stats.refreshes
        if timed.tangent.active:
            row["indefinite_fraction"] = stats.projected_fraction
    if row["indefinite_fraction"] is None:  # plain, or a hybrid that ended consistent: measure it
        probe_tangent = ProjectedTangent(problem)
        probe_tangent.refresh()
        row["indefinite_fraction"] = probe_tangent.statistics().projected_fraction
    return row


def main() -> list[dict]:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    p.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=list(SOLVERS))
    p.add_argument("--runs", nargs="+", default=["single", "stepped"], choices=["single", "stepped"])
    p.add_argument("--switch", type=float, default=1e-2, help="relative residual of the hybrid's switch")
    p.add_argument("--smoke", action="store_true", help="one case (bend_x5), single solve: a quick check")
    p.add_argument("--output", type=Path, default=None, help="append the JSON lines to this file")
    args = p.parse_args()
    if args.smoke:
        args.cases, args.runs = ["bend_x5"], ["single"]
    comm = MPI.COMM_WORLD
    rows = []
    for case in args.cases:
        for mode in args.runs:
            for solver_name in args.solvers:
                row = run(case, solver_name, mode, args.switch)
                rows.append(row)
                if comm.rank == 0:
                    print(json.dumps(row), flush=True)
                    if args.output is not None:
                        with open(args.output, "a") as f:
                            f.write(json.dumps(row) + "\n")
    return rows


if __name__ == "__main__":
    main()
