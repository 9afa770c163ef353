"""Generalized-alpha with contact: the contact force's alpha offset, with and without the force interpolation.

The light block of ``tests/test_contact_dynamics.py``: a Neo-Hookean unit cube
(3 x 3 x 3 boxes, E = 1, rho = 1e-4: nearly quasi-static), rollers on x = 0 and
y = 0, the top held in z, pushed up by 0.1 over t in [0, 1] s by a plane
(dhat = 1e-3, kappa = 1) that starts ``gap`` below the bottom. Per time step and
start gap, one JSON object with the final contact force of

* ``quasi_static``: the quasi-static solve (the light body's limit),
* ``newmark``: Newmark (average acceleration, no alpha),
* ``alpha_interpolated``: generalized-alpha (rho_inf = 0.8) with the contact
  force interpolated between the step's ends (``hyperfem.contact.interpolation``),
* ``alpha_end_state``: generalized-alpha with the contact force at u_{n+1} alone
  (as before the interpolation),

and each one's relative offset from the quasi-static force.

    python benchmarks/contact_alpha.py [--dts 0.05 0.1] [--gaps 0.5 2]
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import numpy as np  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.contact import PlaneContact  # noqa: E402
from hyperfem.simulation import Simulation  # noqa: E402

DHAT, PUSH = 1e-3, 0.1
TIGHT = {"snes_rtol": 1e-10, "snes_atol": 1e-12}


def held_cube(comm: MPI.Comm) -> hf.HyperelasticProblem:
    mesh = dmesh.create_unit_cube(comm, 3, 3, 3)
    groups = {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], 1.0),
              "x0": lambda x: np.isclose(x[0], 0.0), "y0": lambda x: np.isclose(x[1], 0.0)}
    domain = hf.Domain.from_locators(mesh, groups, source="cube(3)")
    bcs = [hf.PrescribedDisplacement(name, [0.0], components=[k]) for name, k in (("x0", 0), ("y0", 1), ("top", 2))]
    params = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
    return hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params), bcs=bcs)


def plane(problem: object, gap: float) -> PlaneContact:
    return PlaneContact("bottom", point=(0.0, 0.0, -gap), normal=(0.0, 0.0, 1.0), dhat=DHAT, stiffness=1.0,
                        motion=(0.0, 0.0, PUSH))


def quasi_static(comm: MPI.Comm, gap: float) -> float:
    base = held_cube(comm)
    contact = plane(base, gap).bind(base)
    hf.solve_quasistatic(hf.NewtonSolver(base, TIGHT, external_energies=[contact]))
    return float(contact.force()[2])


def dynamic(comm: MPI.Comm, scheme: dyn.TimeIntegrator, dt: float, gap: float, interpolate: bool = True) -> dict:
    problem = dyn.IncrementalProblem(held_cube(comm), scheme, dyn.MassDensity(1e-4))
    if not interpolate:  # the contact force at u_{n+1} alone: no generalized-alpha step seen by the contact
        problem.force_interpolation = lambda: None  # type: ignore[method-assign]
    contact = plane(problem, gap).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
    summary = Simulation(problem, solver, dyn.TimeStepping(dt=dt, t_end=1.0), []).run()
    return {"force": float(contact.force()[2]), "rejected": summary["rejected"], "min_distance": contact.min_distance()}


def main() -> list[dict]:
    p = argparse.ArgumentParser()
    p.add_argument("--dts", type=float, nargs="+", default=[0.05, 0.1])
    p.add_argument("--gaps", type=float, nargs="+", default=[0.5, 2.0], help="start gaps in units of dhat")
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    results = []
    for gap in args.gaps:
        reference = quasi_static(comm, gap * DHAT)
        for dt in args.dts:
            runs = {
                "newmark": dynamic(comm, dyn.Newmark(), dt, gap * DHAT),
                "alpha_interpolated": dynamic(comm, dyn.GeneralizedAlpha(rho_inf=0.8), dt, gap * DHAT),
                "alpha_end_state": dynamic(comm, dyn.GeneralizedAlpha(rho_inf=0.8), dt, gap * DHAT, False),
            }
            entry: dict = {"gap_over_dhat": gap, "dt": dt, "ranks": comm.size, "quasi_static": reference}
            for name, run in runs.items():
                entry[name] = run["force"]
                entry[f"{name}_offset"] = run["force"] / reference - 1.0
                entry[f"{name}_rejected"] = run["rejected"]
                entry[f"{name}_min_distance"] = run["min_distance"]
            entry["alpha_interpolated_vs_newmark"] = runs["alpha_interpolated"]["force"] / runs["newmark"]["force"] - 1
            entry["alpha_end_state_vs_newmark"] = runs["alpha_end_state"]["force"] / runs["newmark"]["force"] - 1
            results.append(entry)
            if comm.rank == 0:
                print(json.dumps(entry), flush=True)
    return results


if __name__ == "__main__":
    main()
