"""The iterative path against MUMPS for the Newton solve of the bend (or the twist), by displacement degree.

Where the automatic choice switches from LU to the iterative path for P3 and above
(:data:`hyperfem.solver.linear.HIGH_ORDER_DIRECT_THRESHOLDS`): high-order tangents
need many more Krylov iterations. Each
case solves the full load in one Newton solve, once to compile and once
timed from u = 0, with each linear solver forced; one JSON line per case.

    python benchmarks/linear_degree.py [--cases 1:0.35 2:0.5 3:1 3:0.7 4:1 5:1] [--output FILE]

On degree 2 and up the iterative path is CG (GMRES for the twist) + the two-level p-multigrid
(:mod:`hyperfem.solver.pmultigrid`: P_k smoothed, GAMG with the rigid-body
modes on the Galerkin P1 operator); ``--variants gamg`` forces CG + GAMG on
the P_k tangent, the path before. Measured, serial, quiet machine,
p-multigrid / GAMG (/ MUMPS), ``results/linear_degree_pmg_s35.jsonl``: P2
30.8k 2.60 / 3.01 s, 86.8k 6.79 / 8.15 s; P3 16k 1.84 / 3.15 / 2.75 s (89 /
138 CG iterations), P4 35.8k 13.9 / 13.1 / 13.0 s (174 / 189; 5 Newton
iterations against 4), P5 67k 47.8 / 58.7 / 41.0 s (270 / 324). An earlier
run (``results/linear_degree_pmg_rigid_s34.jsonl``): P3 1.83 / 2.18 / 2.64,
P4 11.3 / 12.2 / 13.1, P5 45.5 / 60.8 / 45.4 s.
The thresholds to MUMPS (:data:`hyperfem.solver.linear.HIGH_ORDER_DIRECT_THRESHOLDS`),
measured with GAMG first, were lowered with the p-multigrid to 10k (P3) and 20k (P4)
(``results/linear_degree_thresholds_s36.jsonl``; the table is in their docstring).

``--load twist`` runs the follower twist instead (GMRES; the p-multigrid or, ``gamg``, GAMG
on P_k). Measured, serial, quiet machine, two interleaved runs,
``results/linear_degree_twist_pmg_s36.jsonl``, p-multigrid / GAMG / MUMPS: P2 30.8k
3.01, 3.76 / 4.16, 4.32 / 8.50, 8.25 s; 86.8k 8.86, 7.58 / 13.56, 11.25 / 52.2, 47.9 s; P3 45k
9.37, 7.12 / 12.27, 11.12 / 19.8, 17.9 s; the same 6 Newton iterations each.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import hyperfem as hf  # noqa: E402
from hyperfem.cases import CantileverSpec, bend_load, twist_load  # noqa: E402
from hyperfem.solver.linear import choose_linear_solver  # noqa: E402


def run(domain, degree: int, variant: str, load: str = "bend") -> dict:
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(
        domain,
        lambda F: hf.materials.neo_hookean(F, params),
        degree=degree,
        bcs=[hf.Clamp("clamped")],
        loads=[bend_load() if load == "bend" else twist_load()],
    )
    # Each variant forced through the automatic choice's threshold, so that it takes that path's whole
    # configuration (the iterative path's lag would otherwise lag the factorisation too).
    threshold = 2**62 if variant == "direct" else 0
    linear = choose_linear_solver(problem, threshold=threshold)
    if variant == "gamg":  # CG (GMRES) + GAMG on the P_k tangent (the iterative path before the p-multigrid)
        from dataclasses import replace

        from hyperfem.solver.linear import SYMMETRIC_ITERATIVE

        own = {k: v for k, v in linear.options.items() if not k.startswith(("pc_", "mg_"))}
        linear = replace(
            linear,
            options={**own, **{k: v for k, v in SYMMETRIC_ITERATIVE.items() if k.startswith(("pc_", "mg_"))}},
            configure=None,
        )
    solver = hf.NewtonSolver(problem, linear_solver=linear)
    problem.set_time(1.0)
    solver.solve(raise_on_failure=True)
    problem.u.x.array[:] = 0.0
    start = time.perf_counter()
    rec = solver.solve(raise_on_failure=True)
    wall = domain.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    return {
        "degree": degree,
        "variant": variant,
        "linear_solver": rec.linear_solver,
        "unknowns": problem.V.dofmap.index_map.size_global * problem.V.dofmap.index_map_bs,
        "newton": rec.iterations,
        "krylov": rec.linear_iterations,
        "wall_s": round(wall, 3),
        "pc_setup_s": round(rec.pc_setup_time, 3),
        "ranks": domain.comm.size,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--cases",
        nargs="+",
        default=["1:0.35", "2:0.5", "3:1", "3:0.7", "4:1", "5:1"],
        help="DEGREE:H pairs (beam element size h)",
    )
    p.add_argument("--output", type=Path, default=None, help="append the JSON lines to this file")
    p.add_argument(
        "--variants",
        nargs="+",
        default=["iterative", "direct"],
        choices=["iterative", "direct", "gamg"],
        help="the automatic iterative path, MUMPS, CG (GMRES) + GAMG on the P_k tangent",
    )
    p.add_argument("--load", choices=["bend", "twist"], default="bend", help="the dead bend or the follower twist")
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    for case in args.cases:
        degree, h = int(case.split(":")[0]), float(case.split(":")[1])
        committed = Path(__file__).resolve().parent.parent / "meshes" / "beam_h1.msh"
        domain = hf.read_mesh(committed, comm) if h == 1.0 else hf.beam_mesh(h=h, comm=comm)
        for variant in args.variants:
            row = {**run(domain, degree, variant, args.load), "h": h, "load": args.load}
            if comm.rank == 0:
                line = json.dumps(row)
                print(line, flush=True)
                if args.output is not None:
                    with open(args.output, "a") as f:
                        f.write(line + "\n")


if __name__ == "__main__":
    main()
