"""Real-time stepping: sustained steps per second vs mesh size (seed 000: a step in under 1/30 s).

The dynamic cantilever of seed 003 (default: the bend case, backward Euler,
:math:`\\Delta t = 1/30` s, viscous damping) on ``create_box`` meshes of the
10 x 4 x 4 beam, (nx, ny, ny) boxes of 6 tetrahedra sized to the requested
tetrahedron counts. For each size, configuration and rank count one fresh
process builds the problem, takes ``--warmup`` steps (not counted: the first
preconditioner or factorisation set-up) and then ``--steps`` timed steps;
with ``--repeat`` each point runs that often and the fastest run is kept (load
on a shared machine only slows runs down).

Configurations (``--config``):

* the presets of :data:`hyperfem.dynamics.realtime.CONFIGS` run by
  :class:`~hyperfem.dynamics.realtime.RealtimeStepper` (``cg-jacobi``,
  ``cg-icc``, ``cg-gamg``, ``mumps``, ``cg-icc-modified``, ``mumps-modified``);
* ``newton-solver``: the ordinary path for comparison — the
  :class:`~hyperfem.dynamics.IncrementalProblem` step (``prepare``, solve,
  ``commit``) with :class:`~hyperfem.NewtonSolver` cut down to a real-time
  solver (``snes_max_it`` = budget, line search ``basic``, no predictor,
  inversion guard, round-off stop or energy line search; CG + block-Jacobi
  ICC(0)); its breakdown comes from PETSc's log events.

Printed per run, one JSON object: tetrahedra, unknowns, ranks, configuration,
budget, sustained steps/s (timed steps over their wall time, slowest rank),
fraction of steps within the frame time, the 1-minute load average of the machine
at the start, the per-step breakdown (assembly,
solve, other; ms), Newton and Krylov iterations, tangent assemblies, residual
statistics (:math:`\\|r\\|/\\|r_0\\|` left per step), set-up time, the test-point
displacement at the end. Then a summary: per configuration and rank count the
largest mesh that sustains ``--target`` steps/s.

    python benchmarks/realtime.py --sizes 1000 4000 6000 10000 15000 20000 \\
        --config cg-icc cg-icc-modified mumps-modified newton-solver --ranks 1 2 --repeat 2 \\
        --output benchmarks/results/realtime.jsonl
    python benchmarks/realtime.py --smoke          # tiny, 1 rank (for the test suite)

Timings on a shared machine are indicative only; rerun on a quiet one.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

BASELINE = "newton-solver"
EVENTS = ("SNESFunctionEval", "SNESJacobianEval", "KSPSolve")


def box_divisions(tets: int) -> tuple[int, int, int]:
    """(nx, ny, ny) with 6 nx ny^2 close to ``tets`` and nx/ny close to 10/4."""
    ny = max(2, round((tets / 15.0) ** (1.0 / 3.0)))
    nx = max(2, round(tets / (6.0 * ny * ny)))
    return nx, ny, ny


def _box(divisions, comm):
    import numpy as np
    from dolfinx import mesh as dmesh

    import hyperfem as hf

    mesh = dmesh.create_box(comm, [[-5.0, -2.0, -2.0], [5.0, 2.0, 2.0]], list(divisions), dmesh.CellType.tetrahedron)
    return hf.Domain.from_locators(
        mesh, {"clamped": lambda x: np.isclose(x[0], -5.0), "free_end": lambda x: np.isclose(x[0], 5.0)}
    )


class NewtonSolverSteps:
    """The ordinary step (``IncrementalProblem.prepare`` + ``NewtonSolver.solve`` + ``commit``) at a fixed budget."""

    def __init__(self, problem, dt: float, budget: int, rtol: float):
        import hyperfem as hf
        from petsc4py import PETSc

        from hyperfem.solver.linear import LinearSolver

        self.problem, self.dt = problem, dt
        options = {"snes_max_it": budget, "snes_linesearch_type": "basic", "snes_rtol": rtol, "snes_atol": 1e-10}
        icc = {"ksp_type": "cg", "pc_type": "bjacobi", "sub_pc_type": "icc", "ksp_rtol": 1e-4, "ksp_atol": 0.0}
        self.solver = hf.NewtonSolver(
            problem,
            options,
            energy_line_search=False,
            min_jacobian=None,
            predictor=False,
            roundoff_factor=0.0,
            linear_solver=LinearSolver(icc),
        )
        self.events = {name: PETSc.Log.Event(name) for name in EVENTS}
        self.rows = []

    def step(self):
        p = self.problem
        start = time.perf_counter()
        before = {k: e.getPerfInfo()["time"] for k, e in self.events.items()}
        inputs = p.step_inputs()
        p.prepare(self.dt)
        rec = self.solver.solve()
        p.commit(self.dt, *inputs)
        wall = time.perf_counter() - start
        after = {k: e.getPerfInfo()["time"] for k, e in self.events.items()}
        d = {k: after[k] - before[k] for k in EVENTS}
        norms = rec.residual_norms
        asm = d["SNESFunctionEval"] + d["SNESJacobianEval"]
        self.rows.append(
            {
                "wall": wall,
                "assembly": asm,
                "solve": d["KSPSolve"],
                "iterations": rec.iterations,
                "linear": rec.linear_iterations,
                "relative": norms[-1] / norms[0] if norms and norms[0] > 0 else 0.0,
                "residual": norms[-1] if norms else float("nan"),
            }
        )

    def summary(self, skip: int, comm) -> dict:
        import numpy as np
        from mpi4py import MPI

        rows = self.rows[skip:]
        times = np.array([[r["wall"], r["assembly"], r["solve"]] for r in rows])
        slowest = np.empty_like(times)
        comm.Allreduce(times, slowest, op=MPI.MAX)
        walls = slowest[:, 0]
        rel = np.array([r["relative"] for r in rows])
        return {
            "steps": len(rows),
            "wall_time": float(walls.sum()),
            "steps_per_second": len(rows) / float(walls.sum()),
            "realtime_fraction": float(np.mean(walls <= self.dt)),
            "max_step_time": float(walls.max()),
            "mean_iterations": float(np.mean([r["iterations"] for r in rows])),
            "tangents": int(sum(r["iterations"] for r in rows)),
            "linear_iterations": float(np.mean([r["linear"] for r in rows])),
            "relative_residual_mean": float(rel.mean()),
            "relative_residual_median": float(np.median(rel)),
            "relative_residual_max": float(rel.max()),
            "residual_max": float(max(r["residual"] for r in rows)),
            "assembly_time": float(slowest[:, 1].mean()),
            "solve_time": float(slowest[:, 2].mean()),
            "other_time": float((walls - slowest[:, 1] - slowest[:, 2]).clip(min=0).mean()),
        }


def single(args) -> None:
    """One run in this process (called through a subprocess by :func:`main`)."""
    from mpi4py import MPI
    from petsc4py import PETSc

    from hyperfem import dynamics as dyn
    from hyperfem.cases.cantilever_dynamics import TEST_POINT, CantileverDynamics, cantilever_problem
    from hyperfem.dynamics.realtime import RealtimeStepper
    from hyperfem.io import PointProbe

    PETSc.Log.begin()
    comm = MPI.COMM_WORLD
    load = os.getloadavg()[0]  # how busy the machine was (timings on a shared machine are indicative)
    divisions = box_divisions(args.single)
    t0 = time.perf_counter()
    domain = _box(divisions, comm)
    spec = CantileverDynamics()
    base, _ = cantilever_problem(args.case, domain, spec)
    problem = dyn.IncrementalProblem(
        base, dyn.BackwardEuler(), dyn.MassDensity(spec.rho), dyn.viscous_damping(spec.damping)
    )
    if args.config == BASELINE:
        stepper = NewtonSolverSteps(problem, args.dt, args.budget, args.rtol)
    else:
        stepper = RealtimeStepper(problem, args.dt, args.budget, config=args.config, rtol=args.rtol)
    setup = time.perf_counter() - t0
    for _ in range(args.warmup + args.steps):
        stepper.step()
    if args.config == BASELINE:
        summary = stepper.summary(args.warmup, comm)
    else:
        summary = stepper.summary(skip=args.warmup).as_dict()
        summary["unconverged"] = summary.get("unconverged")
    V = problem.V
    tets = domain.mesh.topology.index_map(3).size_global
    row = {
        "config": args.config,
        "case": args.case,
        "divisions": list(divisions),
        "tets": int(tets),
        "unknowns": int(V.dofmap.index_map.size_global * V.dofmap.index_map_bs),
        "ranks": comm.size,
        "budget": args.budget,
        "rtol": args.rtol,
        "dt": args.dt,
        "warmup": args.warmup,
        **summary,
        "assembly_ms": 1e3 * summary["assembly_time"],
        "solve_ms": 1e3 * summary["solve_time"],
        "other_ms": 1e3 * summary["other_time"],
        "step_ms": 1e3 * summary["wall_time"] / summary["steps"],
        "setup_s": comm.allreduce(setup, op=MPI.MAX),
        "load_average": load,
        "test_point": [float(c) for c in PointProbe(domain.mesh, [TEST_POINT])(problem.u)[0]],
    }
    if comm.rank == 0:
        print("RESULT " + json.dumps(row), flush=True)


def _launch(args, tets, config, ranks):
    mpiexec = Path(sys.executable).parent / "mpiexec"
    mpiexec = str(mpiexec) if mpiexec.exists() else "mpiexec"
    cmd = [
        sys.executable, __file__, "--single", str(tets), "--config", config, "--case", args.case,
        "--budget", str(args.budget), "--rtol", repr(args.rtol), "--dt", repr(args.dt),
        "--steps", str(args.steps), "--warmup", str(args.warmup),
    ]
    if ranks > 1:
        cmd = [mpiexec, "-n", str(ranks), *cmd]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout)
    for line in out.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    error = (out.stderr or out.stdout).strip().splitlines()[-1:]
    return {"config": config, "tets": tets, "ranks": ranks, "error": error}


def main() -> None:
    from hyperfem.cases.cantilever_dynamics import CASES
    from hyperfem.dynamics.realtime import CONFIGS

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[1000, 4000, 6000, 10000, 15000, 20000],
                   help="approximate tetrahedron counts")
    p.add_argument("--config", nargs="+", default=["cg-icc", "mumps-modified"], choices=[*CONFIGS, BASELINE])
    p.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    p.add_argument("--budget", type=int, default=6, help="Newton iterations per step")
    p.add_argument("--rtol", type=float, default=1e-4, help="a step stops early at |r| <= rtol |r0|")
    p.add_argument("--dt", type=float, default=1.0 / 30.0)
    p.add_argument("--steps", type=int, default=60, help="timed steps")
    p.add_argument("--warmup", type=int, default=3, help="untimed first steps")
    p.add_argument("--case", choices=CASES, default="bend")
    p.add_argument("--target", type=float, default=30.0, help="steps per second to sustain")
    p.add_argument("--repeat", type=int, default=1, help="runs per point; the fastest is kept")
    p.add_argument("--timeout", type=float, default=900.0, help="seconds per run")
    p.add_argument("--output", type=Path, default=None, help="append JSON lines here")
    p.add_argument("--smoke", action="store_true", help="one tiny size, 1 rank, few steps (for the test suite)")
    p.add_argument("--single", type=int, default=None, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.single is not None:
        args.config = args.config[0]
        single(args)
        return
    if args.smoke:
        args.sizes, args.ranks, args.steps, args.warmup = [300], [1], 5, 1
        args.config = ["cg-icc", "mumps-modified", BASELINE]
    rows = []
    for tets in args.sizes:
        for ranks in args.ranks:
            for config in args.config:
                runs = [_launch(args, tets, config, ranks) for _ in range(args.repeat)]
                good = [r for r in runs if "error" not in r]
                # Load on a shared machine only slows a run down: keep the fastest.
                row = max(good, key=lambda r: r["steps_per_second"]) if good else runs[-1]
                if good:
                    row["repeats_steps_per_second"] = [r["steps_per_second"] for r in good]
                rows.append(row)
                print(json.dumps(row), flush=True)
                if args.output is not None:
                    with open(args.output, "a") as f:
                        f.write(json.dumps(row) + "\n")
    ok = [r for r in rows if "error" not in r]
    summary = {
        "summary": True, "case": args.case, "budget": args.budget, "rtol": args.rtol, "dt": args.dt,
        "target": args.target,
    }
    largest = {}
    for config in args.config:
        for ranks in args.ranks:
            fast = [
                r for r in ok
                if r["config"] == config and r["ranks"] == ranks and r["steps_per_second"] >= args.target
            ]
            best = max(fast, key=lambda r: r["tets"], default=None)
            largest[f"{config}/{ranks}"] = None if best is None else {
                "tets": best["tets"], "steps_per_second": best["steps_per_second"],
                "relative_residual_max": best["relative_residual_max"],
            }
    summary["largest_mesh_at_target"] = largest
    # How far each run's test point is from the most converged run of its size (inexact steps drift).
    drift = {}
    for tets in {r["tets"] for r in ok}:
        for ranks in args.ranks:
            sel = [r for r in ok if r["tets"] == tets and r["ranks"] == ranks]
            if len(sel) < 2:
                continue
            ref = min(sel, key=lambda r: r["relative_residual_max"])
            scale = sum(c * c for c in ref["test_point"]) ** 0.5
            for r in sel:
                diff = sum((a - b) ** 2 for a, b in zip(r["test_point"], ref["test_point"], strict=True)) ** 0.5
                drift[f'{r["config"]}/{tets}/{ranks}'] = diff / scale if scale > 0 else 0.0
    summary["test_point_rel_diff_vs_most_converged"] = drift
    summary["fastest_config_per_size"] = {
        f"{tets}/{ranks}": max(sel, key=lambda r: r["steps_per_second"])["config"]
        for tets in args.sizes for ranks in args.ranks
        if (sel := [r for r in ok if r["ranks"] == ranks and abs(r["tets"] - tets) <= 0.2 * tets])
    }
    print(json.dumps(summary), flush=True)
    if args.output is not None:
        with open(args.output, "a") as f:
            f.write(json.dumps(summary) + "\n")


if __name__ == "__main__":
    main()
