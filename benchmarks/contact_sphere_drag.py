"""An analytic ball dragged across the surgery demo's tissue slab: Newton iterations per variant (issue 19).

The slab of ``demos/surgery.py`` (2 x 1 x 0.5, 2n x n x n/2 boxes, compressible Neo-Hookean, clamped
bottom) and its probe's path (down 0.11 over t <= 1/2, then 0.4 along x), with the probe as an analytic
ball (``SphereContact``, R = 0.2, d-hat 5e-3) instead of a triangulated one. 8 steps, ``snes_rtol`` 1e-9.
The variants switch off what stop 38 added, one at a time:

* ``default``: the ball's tangent exact once the nodes settle
  (:data:`~hyperfem.contact.nodal.SETTLED_MOVE`), and a carried lift that pushes a node into the ball
  carrying that node too (:data:`~hyperfem.solver.newton.CARRY_ROUNDS`);
* ``projected``: the tangent always projected (the barrier blocks clipped to PSD, as before);
* ``no-carry-rounds``: ``CARRY_ROUNDS = 0`` (a refused start is cut back, as before);
* ``before``: both off.

    python benchmarks/contact_sphere_drag.py [--n 10 14] [--friction 0 0.3] [--variants default projected ...]

Prints one JSON line per run: the Newton iterations of all solves (failed ones included), the refused
(cut-back) solves, the steps, the force at the end (normal and friction), the wall time.

Measured (serial, ``benchmarks/results/contact_sphere_drag_s38.jsonl``; iterations, refused solves in
brackets), frictionless / mu = 0.3:

=========  ====================  ====================
variant    n = 10                n = 14
=========  ====================  ====================
before     149 (0) / 139 (0)     842 (4) / 140 (0)
projected  149 (0) / 139 (0)     146 (0) / 140 (0)
default    78 (0) / 85 (0)       81 (0) / 91 (0)
=========  ====================  ====================

The end force is the same in every variant (frictionless: the equilibrium does not depend on the
steps; with friction the same steps were taken).
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import numpy as np  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402

import hyperfem as hf  # noqa: E402
import hyperfem.solver.newton as newton  # noqa: E402
from hyperfem.contact import SphereContact  # noqa: E402
from hyperfem.contact.sphere import SphereBarrier  # noqa: E402
from hyperfem.simulation import Recorder, Simulation  # noqa: E402

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
VARIANTS = {"default": (True, newton.CARRY_ROUNDS), "projected": (False, newton.CARRY_ROUNDS),
            "no-carry-rounds": (True, 0), "before": (False, 0)}


def drag(comm: MPI.Comm, n: int, friction: float, steps: int = 8) -> dict:
    """One run of the ball dragged across the slab; its counts and end force."""
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([2.0, 1.0, 0.5])], [2 * n, n, max(1, n // 2)])
    groups = {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], 0.5)}
    domain = hf.Domain.from_locators(mesh, groups, source=f"tissue slab, n = {n}")
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS),
                                     bcs=[hf.PrescribedDisplacement("bottom", [0.0, 0.0, 0.0])])
    path = hf.loading.Waypoints(times=(0.0, 0.5, 1.0), points=((0, 0, 0), (0, 0, -0.11), (0.4, 0, -0.11)))
    ball = SphereContact("top", center=(0.6, 0.5, 0.71), radius=0.2, motion=path, dhat=5e-3,
                         friction=friction).bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-9}, external_energies=[ball])
    start = time.perf_counter()
    summary = Simulation(problem, solver, hf.StepPolicy(increment=1.0 / steps), [Recorder(ball)], name="drag").run()
    wall = time.perf_counter() - start
    rows = summary["rows"][1:]
    force = np.array(rows[-1]["contact_force"]) + (np.array(rows[-1]["contact_friction_force"]) if friction else 0.0)
    return {"completed": bool(summary["completed"]), "steps": len(rows),
            "newton_iterations": int(sum(row["newton_iterations"] for row in rows)),
            "refused": int(sum(row["rejected"] for row in rows)), "force": force.tolist(), "wall_s": wall}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, nargs="+", default=[10, 14])
    p.add_argument("--friction", type=float, nargs="+", default=[0.0, 0.3])
    p.add_argument("--variants", nargs="+", choices=sorted(VARIANTS), default=["before", "projected", "default"])
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    for n in args.n:
        for friction in args.friction:
            for variant in args.variants:
                SphereBarrier.curved, newton.CARRY_ROUNDS = VARIANTS[variant]
                result = {"n": n, "friction": friction, "variant": variant, "ranks": comm.size,
                          **drag(comm, n, friction)}
                if comm.rank == 0:
                    print(json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
