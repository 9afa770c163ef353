"""Generalized-alpha with a tie (glued halves): the tie force's alpha offset, with and without the force interpolation.

The conforming split bar of ``tests/test_contact_tie.py`` ([0, 2] x [0, 1]^2 as two
halves, N x N x N boxes each, their nodes at x = 1 duplicated and glued by a
:class:`~hyperfem.contact.TieContact`; Neo-Hookean, E = 1, nu = 0.3), light
(rho = 1e-4: nearly quasi-static), the left end held, the right end pulled by
(0.1, 0, 0.2) t over t in [0, 1] s. Per time step and tie stiffness (``--stiffness``:
the default penalty, 1e8 times the mean tangent diagonal, or a soft one), one JSON
object with the final tie force (x component) and the right end's reaction of

* ``quasi_static``: the quasi-static solve (the light body's limit),
* ``alpha_interpolated``: generalized-alpha (rho_inf = 0.8) with the tie force
  interpolated between the step's ends (``hyperfem.contact.interpolation``),
* ``alpha_end_state``: generalized-alpha with the tie force at u_{n+1} alone,

each one's relative offset from the quasi-static values, and the largest gap of the cut.

    python benchmarks/contact_tie_alpha.py [--dts 0.05 0.1] [--stiffness default 0.1] [--n 2]
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import hyperfem as hf  # noqa: E402
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.contact import TieContact  # noqa: E402
from hyperfem.simulation import Simulation  # noqa: E402
from hyperfem.simulation.reactions import ReactionForce  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import test_contact_tie as bar  # noqa: E402  (the split bar)

TIGHT = {"snes_rtol": 1e-10, "snes_atol": 1e-9}


def base(comm: MPI.Comm) -> hf.HyperelasticProblem:
    bcs = [hf.PrescribedDisplacement("left_end", [0.0, 0.0, 0.0]), hf.PrescribedDisplacement("right_end", bar.PULL)]
    return hf.HyperelasticProblem(bar._split_bar(comm), lambda F: hf.materials.neo_hookean(F, bar.PARAMS), bcs=bcs)


def quasi_static(comm: MPI.Comm, stiffness: float | None) -> dict:
    problem = base(comm)
    tie = TieContact("right_cut", "left_cut", stiffness=stiffness).bind(problem)
    hf.solve_quasistatic(hf.NewtonSolver(problem, TIGHT, external_energies=[tie]),
                         stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    return {"tie": float(tie.force()[0]), "reaction": float(ReactionForce(problem, "right_end")()[0]),
            "gap": tie.max_gap()}


def dynamic(comm: MPI.Comm, dt: float, stiffness: float | None, interpolate: bool) -> dict:
    problem = dyn.IncrementalProblem(base(comm), dyn.GeneralizedAlpha(rho_inf=0.8), dyn.MassDensity(1e-4))
    if not interpolate:  # the tie force at u_{n+1} alone: no generalized-alpha step seen by the tie
        problem.force_interpolation = lambda: None  # type: ignore[method-assign]
    tie = TieContact("right_cut", "left_cut", stiffness=stiffness).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[tie])
    summary = Simulation(problem, solver, dyn.TimeStepping(dt=dt, t_end=1.0), []).run()
    return {"tie": float(tie.force()[0]), "reaction": float(ReactionForce(problem, "right_end")()[0]),
            "gap": tie.max_gap(), "rejected": summary["rejected"]}


def main() -> list[dict]:
    p = argparse.ArgumentParser()
    p.add_argument("--dts", type=float, nargs="+", default=[0.05, 0.1])
    p.add_argument("--stiffness", nargs="+", default=["default", "0.1"])
    p.add_argument("--n", type=int, default=2)
    args = p.parse_args()
    bar.N = args.n
    comm = MPI.COMM_WORLD
    results = []
    for value in args.stiffness:
        stiffness = None if value == "default" else float(value)
        reference = quasi_static(comm, stiffness)
        for dt in args.dts:
            entry: dict = {"stiffness": value, "dt": dt, "n": args.n, "ranks": comm.size, "quasi_static": reference}
            for name, interpolate in (("alpha_interpolated", True), ("alpha_end_state", False)):
                run = dynamic(comm, dt, stiffness, interpolate)
                run["tie_offset"] = run["tie"] / reference["tie"] - 1.0
                run["reaction_offset"] = run["reaction"] / reference["reaction"] - 1.0
                entry[name] = run
            results.append(entry)
            if comm.rank == 0:
                print(json.dumps(entry), flush=True)
    return results


if __name__ == "__main__":
    main()
