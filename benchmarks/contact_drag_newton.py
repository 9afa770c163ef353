"""Newton iterations of the surgery demo's drag, per iteration: what limits each step (issue 19).

The probe of ``demos/surgery.py`` (a triangulated ball, R = 0.2) indents the tissue slab
(2 x 1 x 0.5, 2n x n x n/2 boxes) by 0.1, then drags 0.4 along x (half the steps each). Every
Newton iteration is logged: the residual norm, the step length the line search kept
(``lam_ls``: |x_k - x_{k-1}| over the filtered direction), the fraction each step filter
allowed (``ExactInversionFilter``, ``MeshCollisionFilter`` = the CCD, ``JacobianBisectionFilter``),
the largest move of a surface node, the active pairs and how many entered or left since the
last iterate, whether the barrier's tangent was exact or projected, the total potential and
the smallest pair distance. Per step: the iterations of the accepted solve split into phases,

* ``A``: the step was shortened by a filter or moved a surface node by more than d-hat
  (the iterates still travel),
* ``C``: the final run of iterations each cutting the residual by 5x or more (Newton's rate),
* ``B``: the rest (the plateau),

the failed attempts (reason, iterations), and how far the predicted start, the last state
(the anchor) and the secant extrapolation lie from the solution (max norm).

    python benchmarks/contact_drag_newton.py [--n 12] [--steps 8] [--friction 0.3] [--verbose] [--json out.json]

Serial (it gathers nothing; on 2 ranks the counts are the same, the per-node columns are rank 0's).

Measured (serial, ``benchmarks/results/contact_drag_newton.jsonl``), indentation / drag iterations:
n = 10: 36 / 97 (drag phases A 41, B 41, C 15; the CCD shortened 15 steps, all in the first 2-3
iterations of a step); n = 12: 32 / 167 (A 61, B 78, C 28; the first drag step refused once);
n = 12 frictionless: 34 / 145; n = 14: 90 / 822 (5 steps refused at their start, 9 attempts, all
0-iteration "the surfaces intersect" / "sweeps through" after the predictor: the increment falls to
1/256 and the drag takes 90 steps of about 9 iterations). What it shows:

* the predicted start of a drag step is farther from the solution than the last state (n = 12:
  0.05-0.10 vs 0.03-0.05, max norm; in the indentation 0.02 vs 0.03): the predictor carries the
  overrun nodes ahead of the ball rigidly with it (+0.1 along x) where they are pushed down, and the
  tangent solve spreads that to some 100 surface nodes;
* the plateau (B) is not the CCD (it caps only the first iterations): the active pairs churn (tens
  in, tens out per iteration while the nodes slide over the ball's facets), and near the solution the
  exact barrier tangent is indefinite there (nodes pressed on the ball's edges and vertices), its
  direction not a descent one, so the projected tangent takes over, whose steps creep (residual
  flat or growing while the potential falls) until the set settles;
* smaller increments do not remove it (n = 12, 32 steps: about 16 iterations per drag step, with
  or without friction).

Tried, not adopted (n = 10 / 12 drag iterations, 97 / 167 before): kappa / 10: 174 (n = 10); ABS
instead of CLAMP projection: 158; always projected: 471; always exact: fails; the exact tangent
from moves below 0.3 / 3 / 10 / 30 d-hat (1 now): 93 / 100 / 77 / 89, n = 12 with 10: 166
(noise); a finer probe (icosphere(4)): 187; the Newton direction reversed where it ascends: 97 /
176; the cp line search: worse; a secant start: refused (the tool overlaps it; the carried
predictor starts from the last state); carrying the overrun nodes by the normal part of the
tool's move only (relative to a convex tool they slide on its supporting plane, so the sweep stays
collision-free): drag 78 / 103 with the same forces, but the indentation worse (43 / 52 vs 36 /
32) and at n = 14 17 refused steps instead of 5 (1194 iterations in all vs 912).

The refused starts at n = 14 were the predictor's: at 10^4 unknowns the solver runs CG + GAMG, and
the lift's Krylov solve (the carried nodes prescribed, the barrier's stiff block in the tangent) ended
with KSP_DIVERGED_INDEFINITE_PC; the lift was dropped, the start stayed refused ("the surfaces
intersect") and the step was cut back, down to 1/256. The lift now falls back to one LU solve, as a
Newton direction does (``BoundaryPredictor._direct_fallback``): n = 14, friction 0.3: 912 -> 230
iterations (indent 90 -> 31, drag 822 -> 199; 8 steps and 1 refused start instead of 98 steps and 9);
frictionless: 1035 -> 134 (drag 953 -> 101; 8 steps instead of 113). n <= 12 (MUMPS) is unchanged,
bit for bit. The forces differ where the baseline's step sequence did (the lagged friction's and the
ploughing's dependence on the increments): n = 14 at t = 0.5 (end of the indentation) -0.03447 vs
-0.03318 after 12 cut-back steps (n = 10, 12: -0.0385, -0.0348 with 4 steps), at t = 1 (-0.0353,
0.0109) vs (-0.0361, 0.0129).

Also tried, not adopted: lifting with the elastic tangent alone (``NewtonSolver._predict`` without the
energies' Hessians when nodes are carried) measured, drag iterations before -> after: n = 10: 97 ->
94, n = 12: 167 -> 129, n = 14: 822 -> 536 (71 steps instead of 98), frictionless n = 10: 137 -> 68,
n = 12: 145 -> 153, with the same forces where the step sequence stayed the same; but n = 6 (the
demo's default): 53 -> 88 and the end force 1.3 % off (another step sequence), and the demo test
(n = 4, 4 steps) then drags in one step instead of two halves: its end force 10 % off (the lagged
friction's step-size error). Not adopted.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import numpy as np  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.contact import ToolContact, icosphere  # noqa: E402
from hyperfem.simulation import Recorder, Simulation  # noqa: E402
from hyperfem.simulation.outputs import Output  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "demos"))
import surgery  # noqa: E402  (the demo's material, probe and path)


def build(comm: MPI.Comm, n: int, friction: float, dhat: float, depth: float = 0.1, drag: float = 0.4):
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([2.0, 1.0, 0.5])], [2 * n, n, max(1, n // 2)])
    groups = {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], 0.5)}
    domain = hf.Domain.from_locators(mesh, groups, source=f"tissue slab, n = {n}")
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, surgery.PARAMS),
                                     bcs=[hf.PrescribedDisplacement("bottom", [0.0, 0.0, 0.0])])
    points, triangles = icosphere(3)
    probe = points * surgery.RADIUS + np.array([0.6, 0.5, 0.5 + surgery.LIFT + surgery.RADIUS])
    tool = ToolContact.from_arrays(["top"], probe, triangles, motion=surgery.path(depth, drag), dhat=dhat,
                                   friction=friction).bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-9}, external_energies=[tool])
    return problem, tool, solver


class IterationLog:
    """The per-iteration records of the solver's SNES (module docstring)."""

    def __init__(self, problem, tool, solver):
        self.problem, self.tool, self.solver = problem, tool, solver
        self.records: list[dict] = []
        self._fractions: dict[str, float] = {}
        self._filtered_norm = 0.0
        self._previous: tuple[np.ndarray, set] | None = None
        self.start: np.ndarray | None = None
        for step_filter in solver.step_filters.filters:
            self._wrap(step_filter)
        apply = solver.step_filters.apply

        def logged_apply(x, y):
            self._fractions = {}
            total = apply(x, y)
            self._filtered_norm = y.norm()
            return total

        solver.step_filters.apply = logged_apply
        solver.snes.setMonitor(self._monitor)

    def _wrap(self, step_filter) -> None:
        fraction_of = step_filter.step_fraction
        name = type(step_filter).__name__

        def logged(x, y):
            fraction = fraction_of(x, y)
            self._fractions[name] = min(fraction, self._fractions.get(name, 1.0))
            return fraction

        step_filter.step_fraction = logged

    def _pairs(self, u: np.ndarray) -> set:
        tool = self.tool
        collisions = tool._collisions(tool.vertices(u))
        return {tuple(int(v) for v in collisions[k].vertex_ids(tool.mesh.edges, tool.mesh.faces))
                for k in range(len(collisions))}

    def _monitor(self, snes, it: int, norm: float) -> None:
        self.solver._set_state(snes.getSolution())  # the unknown with its ghosts (the surface is gathered from it)
        u = self.problem.u.x.array.copy()
        pairs = self._pairs(u)
        record: dict = {"it": it, "residual": norm, "active": len(pairs),
                        "exact_tangent": bool(self.tool.exact_tangent), "min_distance": self.tool.min_distance(u)}
        if it > 0 and self._previous is not None:
            before, previous_pairs = self._previous
            record["added"] = len(pairs - previous_pairs)
            record["removed"] = len(previous_pairs - pairs)
            moved = self.tool.surface.displacements(u) - self.tool.surface.displacements(before)
            record["max_move"] = float(np.abs(moved).max())
            record["lam_ls"] = float(np.linalg.norm(u - before) / self._filtered_norm) if self._filtered_norm else 0.0
            record["filters"] = dict(self._fractions)
        internal, external = self.solver._energies()
        record["potential"] = internal - external
        if it == 0:
            self.start = u
        self._previous = (u, pairs)
        self.records.append(record)

    def take(self) -> list[dict]:
        records, self.records, self._previous = self.records, [], None
        return records


def phases(records: list[dict], dhat: float) -> dict:
    """The accepted solve's iterations split into A (travel), B (plateau), C (Newton's rate): module docstring."""
    starts = [i for i, r in enumerate(records) if r["it"] == 0]
    solve = [r for r in records[starts[-1]:] if r["it"] > 0] if starts else []
    residuals = [r["residual"] for r in solve]
    quadratic, k = 0, len(solve) - 1
    while k >= 1 and residuals[k] < 0.2 * residuals[k - 1]:
        quadratic, k = quadratic + 1, k - 1
    travel = sum(1 for r in solve[: len(solve) - quadratic]
                 if min(r.get("filters", {}).values(), default=1.0) < 1.0 or r.get("max_move", 0.0) > dhat)
    return {"A": travel, "B": len(solve) - quadratic - travel, "C": quadratic,
            "ccd_limited": sum(1 for r in solve if r.get("filters", {}).get("MeshCollisionFilter", 1.0) < 1.0),
            "pair_churn": sum(r.get("added", 0) + r.get("removed", 0) for r in solve)}


def main() -> dict:
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=12)
    p.add_argument("--steps", type=int, default=8)
    p.add_argument("--friction", type=float, default=0.3)
    p.add_argument("--dhat", type=float, default=5e-3)
    p.add_argument("--verbose", action="store_true")
    p.add_argument("--json", type=Path, default=None)
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    problem, tool, solver = build(comm, args.n, args.friction, args.dhat)
    log = IterationLog(problem, tool, solver)
    accepted: list[np.ndarray] = []
    steps: list[dict] = []

    class Steps(Output):
        def write(self, sim, step) -> None:
            records = log.take()
            u = problem.u.x.array.copy()
            if step is None:
                accepted.append(u)
                return
            entry = {"t": sim.time, "iterations": [r.iterations for r in step.solve_records],
                     "failed": [(r.reason_name, r.iterations) for r in step.failed],
                     "force": [float(v) for v in tool.force()],
                     "friction_force": [float(v) for v in tool.friction_force()],
                     "intersecting": tool.intersecting(), **phases(records, tool.dhat)}
            start = next((r for r in reversed(records) if r["it"] == 0), None)
            if start is not None and len(accepted) >= 2:
                entry["anchor_to_solution"] = float(np.abs(accepted[-1] - u).max())
                entry["predicted_to_solution"] = float(np.abs(log.start - u).max())
                entry["secant_to_solution"] = float(np.abs(2 * accepted[-1] - accepted[-2] - u).max())
            if args.verbose:
                entry["records"] = records
            accepted.append(u)
            steps.append(entry)

    summary = Simulation(problem, solver, hf.StepPolicy(increment=1.0 / args.steps), [Recorder(tool), Steps()],
                         name="drag-newton").run()
    drag = [s for s in steps if s["t"] > 0.5 + 1e-12]
    result = {"n": args.n, "steps": args.steps, "friction": args.friction, "dhat": args.dhat, "ranks": comm.size,
              "completed": summary["completed"], "indent_iterations": sum(sum(s["iterations"]) for s in steps) -
              sum(sum(s["iterations"]) for s in drag), "drag_iterations": sum(sum(s["iterations"]) for s in drag),
              "drag_phases": {k: sum(s[k] for s in drag) for k in ("A", "B", "C", "ccd_limited")},
              "rejected": sum(len(s["failed"]) for s in steps), "steps_log": steps}
    if comm.rank == 0:
        for s in steps:
            print(f"t = {s['t']:.4f}: {s['iterations']} its (A {s['A']}, B {s['B']}, C {s['C']}; CCD-limited "
                  f"{s['ccd_limited']}; pair churn {s['pair_churn']}), failed {s['failed']}, force "
                  f"{np.round(np.add(s['force'], s['friction_force']), 6).tolist()}"
                  + (f", from the solution: predicted start {s['predicted_to_solution']:.3g}, last state "
                     f"{s['anchor_to_solution']:.3g}" if "anchor_to_solution" in s else ""))
        print(json.dumps({k: v for k, v in result.items() if k != "steps_log"}))
        if args.json is not None:
            args.json.write_text(json.dumps(result, indent=1))
    return result


if __name__ == "__main__":
    main()
