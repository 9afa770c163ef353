"""First bending frequency of cantilevers from simulated free vibration vs Timoshenko.

Small-amplitude launch v_y = v0 (x/L)^2, Newmark (1/4, 1/2), dt = T/60; the period is
the second zero crossing of the tip deflection. Cases: the slender 10 x 1 x 1 beam on
refined box meshes (P2), and Erleben's 10 x 4 x 4 beam (seed 003) on the gmsh beam
(P1 and P2). Prints a table and writes benchmarks/results/dynamics_frequency.json.

    PYTHONPATH=. python benchmarks/dynamics_frequency.py
"""

import json
import math
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.cases.beam_theory import euler_bernoulli_cantilever, timoshenko_cantilever  # noqa: E402

E, NU, RHO = 1e6, 0.3, 1000.0


def measure(domain, L, H, degree, tip, steps_per_period=60):
    params = hf.materials.LameParameters.from_youngs(E, NU)
    base = hf.HyperelasticProblem(
        domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("clamped")], degree=degree
    )
    problem = dyn.IncrementalProblem(base, dyn.Newmark(), dyn.MassDensity(RHO))
    omega = timoshenko_cantilever(E, NU, RHO, L, H, H)
    T = 2 * math.pi / omega
    x0 = tip[0] - L
    v0 = 1e-3 * L * omega
    problem.v.interpolate(lambda x: np.vstack([0 * x[0], v0 * ((x[0] - x0) / L) ** 2, 0 * x[0]]))
    diag = dyn.Diagnostics(problem, [tip])
    diag.record()
    solver = hf.NewtonSolver(problem, energy_line_search=False)
    start = time.perf_counter()
    dyn.integrate(problem, solver, dyn.TimeStepping(dt=T / steps_per_period, t_end=1.1 * T), on_step=diag.record)
    t, y = diag.column("time"), diag.column("p0_y") - tip[1]
    cross = [
        t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])
        for i in range(1, len(y) - 1)
        if (y[i] > 0 >= y[i + 1]) or (y[i] < 0 <= y[i + 1])
    ]
    omega_fe = 2 * math.pi / cross[1]
    return {
        "omega_fe": omega_fe,
        "omega_timoshenko": omega,
        "omega_euler_bernoulli": euler_bernoulli_cantilever(E, RHO, L, H, H),
        "ratio_timoshenko": omega_fe / omega,
        "dofs": 3 * base.V.dofmap.index_map.size_global,
        "wall_time": time.perf_counter() - start,
    }


def main() -> list[dict]:
    comm = MPI.COMM_WORLD
    results = []
    for n in (10, 20, 40):
        m = dmesh.create_box(comm, [[0, 0, 0], [10, 1, 1]], [n, n // 10, n // 10], dmesh.CellType.tetrahedron)
        domain = hf.Domain.from_locators(m, {"clamped": lambda x: np.isclose(x[0], 0.0)})
        r = measure(domain, 10.0, 1.0, 2, (10.0, 0.5, 0.5))
        results.append({"beam": "10x1x1", "mesh": f"box {n}x{n // 10}x{n // 10}", "degree": 2, **r})
    for h, degree in ((1.0, 1), (0.5, 1), (1.0, 2)):
        domain = hf.beam_mesh(h=h, comm=comm)
        r = measure(domain, 10.0, 4.0, degree, (5.0, 0.0, 0.0))
        results.append({"beam": "10x4x4 (seed 003)", "mesh": f"gmsh h={h}", "degree": degree, **r})
    if comm.rank == 0:
        print(f"{'beam':18s} {'mesh':14s} deg {'dofs':>6s} {'w_FE':>8s} {'w_Timo':>8s} {'w_EB':>8s} {'FE/Timo':>8s}")
        for r in results:
            print(
                f"{r['beam']:18s} {r['mesh']:14s} {r['degree']:3d} {r['dofs']:6d} {r['omega_fe']:8.4f} "
                f"{r['omega_timoshenko']:8.4f} {r['omega_euler_bernoulli']:8.4f} {r['ratio_timoshenko']:8.4f}"
            )
        out = Path(__file__).parent / "results" / "dynamics_frequency.json"
        out.parent.mkdir(exist_ok=True)
        out.write_text(json.dumps(results, indent=2))
    return results


if __name__ == "__main__":
    main()
