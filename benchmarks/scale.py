"""Scaling of a nonlinear solve with the number of unknowns: hyperfem vs plain DOLFINx + MUMPS.

The cantilever bend (or twist) of seed 003 on ``create_box`` meshes of the
10 x 4 x 4 beam with (2N, N, N) boxes of 6 tetrahedra, full load in one step.
For each size it runs, each in a fresh process (clean peak memory), on 1 and
2 ranks:

* ``hyperfem``: :class:`~hyperfem.NewtonSolver` with its automatic linear
  solver (MUMPS below the threshold, CG + GAMG with rigid-body modes above);
* ``hyperfem-iterative`` / ``hyperfem-direct``: the same with the linear
  solver forced (to measure the crossover of the automatic choice);
* ``baseline``: the best plain-DOLFINx set-up, ``NonlinearProblem`` with SNES
  ``newtonls``/``basic`` (full Newton steps) and MUMPS LU, skipped above
  ``--max-lu`` unknowns (memory).

Printed per run, one JSON object: unknowns, ranks, Newton and Krylov
iterations, time in residual assembly, tangent assembly, preconditioner set-up
and Krylov solve (PETSc log events), total solve time, peak RSS (summed over
ranks), the test-point displacement. At the end: the fitted exponent of time
and memory vs unknowns, the 2-rank parallel efficiency and the speed-up over
the baseline at each size; ``--plot`` writes time and memory vs unknowns (PNG).

    python benchmarks/scale.py --sizes 8 12 16 24 32 48 64 --ranks 1 2 \
        --output benchmarks/results/scale.jsonl --plot benchmarks/results/scale.png
    python benchmarks/scale.py --smoke          # tiny sizes; what the test suite runs

``--formulation mixed`` runs the three-field (u, p, θ) P2/P1/P1 problem of a
nearly incompressible Neo-Hookean beam (ν = 0.4995, K/μ ≈ 10³, same E and
loads): ``hyperfem-iterative`` is then the Schur field split (its
displacement block by the two-level p-multigrid, ``hyperfem-gamg-u`` by GAMG
on the P2 block as before), and the baseline is ``NonlinearProblem`` (SNES ``basic``, MUMPS) on the same
residual and tangent forms.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
EVENTS = ("SNESFunctionEval", "SNESJacobianEval", "PCSetUp", "PCSetUpOnBlocks", "KSPSolve")


def _box(N: int, comm):
    import numpy as np
    from dolfinx import mesh as dmesh

    import hyperfem as hf

    mesh = dmesh.create_box(comm, [[-5.0, -2.0, -2.0], [5.0, 2.0, 2.0]], [2 * N, N, N], dmesh.CellType.tetrahedron)
    return hf.Domain.from_locators(
        mesh, {"clamped": lambda x: np.isclose(x[0], -5.0), "free_end": lambda x: np.isclose(x[0], 5.0)}
    )


HAND_TUNED = {
    "ksp_type": "cg", "pc_type": "gamg", "mg_levels_ksp_type": "chebyshev", "mg_levels_pc_type": "jacobi",
    "pc_gamg_reuse_interpolation": True, "ksp_rtol": 1e-6, "ksp_atol": 1e-30, "ksp_max_it": 1000,
}
"""An expert's hand-tuned set-up (issue 20): CG + GAMG with the rigid-body near-nullspace, reused interpolation,
``ksp_rtol 1e-6``, PETSc's defaults otherwise (what hyperfem's automatic choice was before issue 20)."""


def _hand_tuned(problem):
    """hyperfem's NewtonSolver with :data:`HAND_TUNED` and the rigid-body modes on the matrix.

    GMRES (PETSc's default restart) in place of CG for a follower load's non-symmetric tangent, as an expert would:
    CG there stops at ``ksp_max_it`` in every Newton iteration.
    """
    from hyperfem.solver.linear import LinearSolver, _near_nullspace_hook

    options = dict(HAND_TUNED) if problem.conservative else {**HAND_TUNED, "ksp_type": "gmres"}
    return LinearSolver(options, near_nullspace=_near_nullspace_hook(problem.displacement_space()))


def _parse_options(pairs: list[str]) -> dict[str, object]:
    """``["key=value", ...]`` (``--petsc``) as a PETSc options dictionary (a bare ``key`` means true)."""
    return dict((p.split("=", 1) if "=" in p else (p, True)) for p in pairs)


def _events():
    from petsc4py import PETSc

    return {name: PETSc.Log.Event(name).getPerfInfo()["time"] for name in EVENTS}


def single(args) -> None:
    """One run in this process (called through a subprocess by :func:`main`)."""
    from mpi4py import MPI
    from petsc4py import PETSc

    import numpy as np

    import hyperfem as hf
    from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load, twist_load
    from hyperfem.io import PointProbe

    PETSc.Log.begin()
    comm = MPI.COMM_WORLD
    domain = _box(args.N, comm)
    params = CantileverSpec().lame
    load = bend_load() if args.case == "bend" else twist_load()
    row = {"variant": args.variant, "case": args.case, "N": args.N, "degree": args.degree, "ranks": comm.size}
    if args.formulation == "mixed":
        row["formulation"] = "mixed"
    t0 = time.perf_counter()
    if args.formulation == "mixed":
        from hyperfem.kinematics import isochoric_invariants
        from hyperfem.problem import MixedHyperelasticProblem, SplitEnergy
        from hyperfem.solver.linear import DIRECT, choose_linear_solver

        E, nu = CantileverSpec().E, 0.4995
        mu, K = E / (2 * (1 + nu)), E / (3 * (1 - 2 * nu))
        material = SplitEnergy(lambda F: 0.5 * mu * (isochoric_invariants(F)[0] - 3.0), K)
        problem = MixedHyperelasticProblem(
            domain, material, bcs=[hf.Clamp("clamped")], loads=[load], degree=max(args.degree, 2)
        )
        problem.set_time(1.0)
        if args.variant.startswith("hyperfem"):
            forced = {"hyperfem-iterative": 0, "hyperfem-gamg-u": 0, "hyperfem-direct": 2**62}.get(args.variant)
            linear = None if forced is None else choose_linear_solver(problem, mixed_threshold=forced)
            if args.variant == "hyperfem-gamg-u":  # the split's u block by GAMG on P2 (before the p-multigrid)
                from hyperfem.solver.pmultigrid import GAMG_U

                own = {k: v for k, v in linear.options.items() if not k.startswith("fieldsplit_u_")}
                linear = replace(linear, options={**own, **GAMG_U})
            linear = _with_petsc(linear, problem, args.petsc, row)
            solver = hf.NewtonSolver(problem, linear_solver=linear)
            setup = time.perf_counter() - t0
            before = _events()
            t1 = time.perf_counter()
            rec = solver.solve(raise_on_failure=True)
            row.update(
                linear_solver=rec.linear_solver, newton_iterations=rec.iterations,
                krylov_iterations=rec.linear_iterations, early_rebuilds=solver._lag.early_rebuilds,
            )
        else:
            from dolfinx.fem.petsc import NonlinearProblem

            opts = {"snes_type": "newtonls", "snes_linesearch_type": "basic", "snes_rtol": 1e-9, "snes_atol": 1e-10,
                    "snes_max_it": 50, **DIRECT}
            nlp = NonlinearProblem(problem.residual, problem.u, bcs=problem.bcs, J=problem.jacobian,
                                   petsc_options_prefix="baseline_", petsc_options=opts)
            setup = time.perf_counter() - t0
            before = _events()
            t1 = time.perf_counter()
            nlp.solve()
            snes = nlp.solver
            assert snes.getConvergedReason() > 0, snes.getConvergedReason()
            row.update(
                linear_solver="preonly+lu(mumps)", newton_iterations=snes.getIterationNumber(),
                krylov_iterations=snes.getLinearSolveIterations(),
            )
        solve = time.perf_counter() - t1
        after = _events()
        W = problem.u.function_space
        row["unknowns"] = int(W.dofmap.index_map.size_global * W.dofmap.index_map_bs)
        u, _ = problem.update_fields()
    elif args.variant.startswith("hyperfem"):
        from hyperfem.solver.linear import choose_linear_solver

        problem = hf.HyperelasticProblem(
            domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("clamped")], loads=[load],
            degree=args.degree,
        )
        forced = {"hyperfem-iterative": 0, "hyperfem-direct": 2**62}.get(args.variant)
        linear = None if forced is None else choose_linear_solver(problem, threshold=forced)
        if args.variant == "hyperfem-hand-tuned":
            linear = _hand_tuned(problem)
        linear = _with_petsc(linear, problem, args.petsc, row)
        solver = hf.NewtonSolver(problem, linear_solver=linear)
        problem.set_time(1.0)
        setup = time.perf_counter() - t0
        before = _events()
        t1 = time.perf_counter()
        rec = solver.solve(raise_on_failure=True)
        solve = time.perf_counter() - t1
        u = problem.u
        row.update(
            linear_solver=rec.linear_solver, newton_iterations=rec.iterations, krylov_iterations=rec.linear_iterations,
            early_rebuilds=solver._lag.early_rebuilds,
        )
    else:
        import ufl
        from dolfinx import fem
        from dolfinx.fem.petsc import NonlinearProblem

        mu, lmbda = params.mu, params.lmbda
        V = fem.functionspace(domain.mesh, ("Lagrange", args.degree, (3,)))
        u, v = fem.Function(V), ufl.TestFunction(V)
        F = ufl.variable(ufl.Identity(3) + ufl.grad(u))
        J = ufl.det(F)
        psi = mu / 2 * (ufl.tr(F.T * F) - 3) - mu * ufl.ln(J) + lmbda / 2 * ufl.ln(J) ** 2
        md = {"quadrature_degree": 1 if args.degree == 1 else 2 * args.degree}
        X = ufl.SpatialCoordinate(domain.mesh)
        if args.case == "bend":
            t_load = ufl.as_vector((0.0, -5e3, 0.0))
        else:
            x = X + u
            t_load = 5e3 * ufl.as_vector((0.0, x[2], -x[1]))
        ds = domain.ds("free_end", metadata={"quadrature_degree": 2 * args.degree})
        R = ufl.inner(ufl.diff(psi, F), ufl.grad(v)) * ufl.dx(metadata=md) - ufl.dot(t_load, v) * ds
        dofs = fem.locate_dofs_topological(V, 2, domain.facets("clamped"))
        bc = fem.dirichletbc(np.zeros(3), dofs, V)
        opts = {
            "snes_type": "newtonls", "snes_linesearch_type": "basic", "snes_rtol": 1e-9, "snes_atol": 1e-10,
            "snes_max_it": 50, "ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps",
        }
        nlp = NonlinearProblem(R, u, bcs=[bc], petsc_options_prefix="baseline_", petsc_options=opts)
        setup = time.perf_counter() - t0
        before = _events()
        t1 = time.perf_counter()
        nlp.solve()
        solve = time.perf_counter() - t1
        snes = nlp.solver
        assert snes.getConvergedReason() > 0, snes.getConvergedReason()
        row.update(
            linear_solver="preonly+lu(mumps)", newton_iterations=snes.getIterationNumber(),
            krylov_iterations=snes.getLinearSolveIterations(),
        )
    if args.formulation != "mixed":
        after = _events()
        V = u.function_space
        row["unknowns"] = int(V.dofmap.index_map.size_global * V.dofmap.index_map_bs)
    row.update({f"time_{k}": comm.allreduce(after[k] - before[k], op=MPI.MAX) for k in EVENTS})
    row["time_setup"] = comm.allreduce(setup, op=MPI.MAX)
    row["time_solve"] = comm.allreduce(solve, op=MPI.MAX)
    row["peak_rss_gb"] = comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, op=MPI.SUM) / 1024**2
    row["test_point"] = [float(c) for c in PointProbe(domain.mesh, [TEST_POINT])(u)[0]]
    if comm.rank == 0:
        print("RESULT " + json.dumps(row), flush=True)


def _with_petsc(linear, problem, petsc: list[str], row: dict):
    """``linear`` (``None``: the automatic choice) with the ``--petsc`` options over its own; noted in ``row``."""
    if not petsc:
        return linear
    from hyperfem.solver.linear import choose_linear_solver

    base = linear if linear is not None else choose_linear_solver(problem)
    row["petsc"] = petsc
    return replace(base, options={**base.options, **_parse_options(petsc)})


def _launch(N, degree, case, variant, ranks, timeout, formulation="displacement", petsc=()):
    mpiexec = Path(sys.executable).parent / "mpiexec"
    mpiexec = str(mpiexec) if mpiexec.exists() else "mpiexec"
    cmd = [sys.executable, __file__, "--single", str(N), "--degree", str(degree), "--case", case, "--variant", variant,
           "--formulation", formulation, *(["--petsc", *petsc] if petsc else [])]
    if ranks > 1:
        cmd = [mpiexec, "-n", str(ranks), *cmd]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    for line in out.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    return {"variant": variant, "N": N, "ranks": ranks, "error": (out.stderr or out.stdout).strip().splitlines()[-1:]}


def _relative_difference(p: list[float], q: list[float]) -> float:
    """:math:`|p - q| / |q|` of two test-point displacements."""
    return float(sum((a - b) ** 2 for a, b in zip(p, q, strict=True)) ** 0.5 / sum(b**2 for b in q) ** 0.5)


def _fit(rows, key):
    import numpy as np

    pts = [(r["unknowns"], r[key]) for r in rows if "error" not in r and r["unknowns"] >= 1e4 and r[key] > 0]
    if len(pts) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[4, 8, 12, 16, 24, 32])
    p.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    p.add_argument("--degree", type=int, default=1)
    p.add_argument("--case", choices=("bend", "twist"), default="bend")
    p.add_argument("--formulation", choices=("displacement", "mixed"), default="displacement")
    p.add_argument("--max-lu", type=int, default=250_000, help="largest size the MUMPS baseline runs at")
    p.add_argument("--timeout", type=float, default=1200.0, help="seconds per run")
    p.add_argument("--output", type=Path, default=None, help="append JSON lines here")
    p.add_argument("--plot", type=Path, default=None, help="PNG of time and memory vs unknowns")
    p.add_argument("--smoke", action="store_true", help="two tiny sizes, 1 rank (for the test suite)")
    p.add_argument(
        "--variants", nargs="+", default=["hyperfem", "baseline"],
        choices=["hyperfem", "hyperfem-iterative", "hyperfem-direct", "hyperfem-hand-tuned", "hyperfem-gamg-u",
                 "baseline"],
        help="hyperfem (automatic linear solver), with the iterative or direct solver forced, with the hand-tuned "
        "expert set-up of issue 20 (CG + GAMG + rigid modes, PETSc defaults otherwise), the mixed field split with "
        "GAMG on its P2 displacement block instead of the p-multigrid, plain DOLFINx",
    )
    p.add_argument(
        "--petsc", nargs="*", default=[], metavar="KEY=VALUE",
        help="PETSc options added to a hyperfem variant's linear solver (its 'snes_' options reach SNES), "
        "e.g. --petsc snes_lag_preconditioner=3 ksp_rtol=1e-4",
    )
    p.add_argument("--single", type=int, default=None, help=argparse.SUPPRESS)
    p.add_argument("--variant", default="hyperfem", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.single is not None:
        args.N = args.single
        single(args)
        return
    if args.smoke:
        args.sizes, args.ranks = [2, 3], [1]
    rows = []
    for N in args.sizes:
        for ranks in args.ranks:
            for variant in args.variants:
                k = max(args.degree, 2) if args.formulation == "mixed" else args.degree
                approx = 3 * (2 * N * k + 1) * (N * k + 1) ** 2
                if variant in ("baseline", "hyperfem-direct") and approx > args.max_lu:
                    continue
                petsc = args.petsc if variant.startswith("hyperfem") else ()
                row = _launch(N, args.degree, args.case, variant, ranks, args.timeout, args.formulation, petsc)
                rows.append(row)
                print(json.dumps(row), flush=True)
                if args.output is not None:
                    with open(args.output, "a") as f:
                        f.write(json.dumps(row) + "\n")
    summary = {"summary": True, "case": args.case, "degree": args.degree, "formulation": args.formulation}
    for variant in ("hyperfem", "baseline"):
        for ranks in args.ranks:
            sel = [r for r in rows if r.get("variant") == variant and r.get("ranks") == ranks]
            summary[f"time_exponent_{variant}_{ranks}"] = _fit(sel, "time_solve")
            summary[f"memory_exponent_{variant}_{ranks}"] = _fit(sel, "peak_rss_gb")
    by = {(r.get("variant"), r.get("ranks"), r.get("N")): r for r in rows if "error" not in r}
    summary["speedup_over_baseline_1rank"] = {
        N: by[("baseline", 1, N)]["time_solve"] / by[("hyperfem", 1, N)]["time_solve"]
        for N in args.sizes if ("baseline", 1, N) in by and ("hyperfem", 1, N) in by
    }
    summary["test_point_rel_diff_vs_baseline"] = {
        N: max(
            _relative_difference(by[("hyperfem", r, N)]["test_point"], by[("baseline", r, N)]["test_point"])
            for r in args.ranks if ("hyperfem", r, N) in by and ("baseline", r, N) in by
        )
        for N in args.sizes if any(("hyperfem", r, N) in by and ("baseline", r, N) in by for r in args.ranks)
    }
    summary["parallel_efficiency_2ranks"] = {
        N: by[("hyperfem", 1, N)]["time_solve"] / (2 * by[("hyperfem", 2, N)]["time_solve"])
        for N in args.sizes if ("hyperfem", 1, N) in by and ("hyperfem", 2, N) in by
    }
    print(json.dumps(summary), flush=True)
    if args.output is not None:
        with open(args.output, "a") as f:
            f.write(json.dumps(summary) + "\n")
    if args.plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        for variant in ("hyperfem", "baseline"):
            for ranks in args.ranks:
                sel = sorted(
                    (r for r in rows if r.get("variant") == variant and r.get("ranks") == ranks and "error" not in r),
                    key=lambda r: r["unknowns"],
                )
                if not sel:
                    continue
                n = [r["unknowns"] for r in sel]
                label = f"{variant}, {ranks} rank(s)"
                axes[0].loglog(n, [r["time_solve"] for r in sel], "o-", label=label)
                axes[1].loglog(n, [r["peak_rss_gb"] for r in sel], "o-", label=label)
        axes[0].set(xlabel="unknowns", ylabel="solve time (s)", title=f"{args.case}, P{args.degree}")
        axes[1].set(xlabel="unknowns", ylabel="peak RSS, all ranks (GB)")
        for ax in axes:
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)


if __name__ == "__main__":
    main()
