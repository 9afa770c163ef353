"""Tool on tissue in real time: a rigid spherical tool indenting and dragging across a soft slab, RealtimeStepper.

The stretch goal of issue 19 (seed 000's own): the tool-on-tissue demo through
:class:`~hyperfem.dynamics.RealtimeStepper` with the barrier, at
:math:`\\Delta t = 1/30` s on a few thousand tetrahedra, no step accepted with
penetration. The slab: 1 x 1 x 0.25 m, clamped at the bottom, Neo-Hookean
(E = 10 kPa, nu = 0.45, rho = 1000 kg/m^3), P1 on ``create_box`` with
(n, n, n/4) boxes of 6 tetrahedra; backward Euler. The tool: a
:class:`~hyperfem.contact.SphereContact` of radius 0.15 starting 2 mm above the
middle of the top, moved by (0.3, 0, -0.1) m over 2 s (indenting 40 % of the
slab while dragging), optional Coulomb friction. Per mesh size and
configuration one JSON object: tetrahedra, unknowns, steps/s sustained over
the timed steps (after ``--warmup``), the fraction of steps within the frame, the inversion guard's cutbacks,
the per-step breakdown (assembly with the barrier's terms, solve, other: the
collision filters and the rest; ms), Newton iterations, steps above ``rtol``,
collision-filter cutbacks, the smallest contact distance over all steps (> 0:
no step accepted with penetration), the final contact force, and at the final
state the cost of one Newton iteration's parts: the elastic tangent assembly,
the residual, and the contact's own terms.

    python benchmarks/contact_realtime.py [--sizes 2000 6000] [--config cg-icc-modified mumps-modified] [--dhat 3e-3]
    mpiexec -n 2 python benchmarks/contact_realtime.py
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
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.contact import SphereContact  # noqa: E402

DT = 1.0 / 30.0
RADIUS, GAP = 0.15, 2e-3
MOTION = (0.3, 0.0, -0.1)  # over DURATION: indent 0.1 of the 0.25 slab while dragging 0.3
DURATION = 2.0


def slab(comm: MPI.Comm, tets: int) -> dyn.IncrementalProblem:
    n = max(4, round((tets / 1.5) ** (1.0 / 3.0)))  # 6 n * n * n/4 = 1.5 n^3 tetrahedra
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([1.0, 1.0, 0.25])], [n, n, max(1, n // 4)],
                            dmesh.CellType.tetrahedron)
    groups = {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], 0.25)}
    domain = hf.Domain.from_locators(mesh, groups, source=f"slab({n})")
    params = hf.materials.LameParameters.from_youngs(E=1e4, nu=0.45)
    base = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("bottom")])
    return dyn.IncrementalProblem(base, dyn.BackwardEuler(), dyn.MassDensity(1000.0))


def run(
    tets: int, config: str, budget: int, steps: int, warmup: int, friction: float, contact: bool = True,
    dhat: float | None = None,
) -> dict:
    comm = MPI.COMM_WORLD
    problem = slab(comm, tets)
    contacts = []
    if contact:
        extra = {"friction": friction, "friction_epsilon": 1e-4} if friction else {}
        above = 0.25 + RADIUS + GAP + (dhat or 0.0)  # out of the barrier's reach at the start
        tool = SphereContact("top", center=(0.35, 0.5, above), radius=RADIUS, motion=MOTION,
                             profile=lambda t: t / DURATION, dhat=dhat, **extra).bind(problem)
        contacts = [tool]
    start = time.perf_counter()
    stepper = dyn.RealtimeStepper(problem, DT, budget, config=config, contacts=contacts)
    setup = time.perf_counter() - start
    stepper.run(warmup + steps)
    summary = stepper.summary(skip=warmup)
    records = stepper.history
    entry = {
        "tetrahedra": problem.domain.mesh.topology.index_map(3).size_global,
        "unknowns": problem.V.dofmap.index_map.size_global * 3,
        "ranks": comm.size,
        "config": config,
        "budget": budget,
        "contact": contact,
        "friction": friction if contact else None,
        "dhat": contacts[0].dhat if contact else None,  # type: ignore[attr-defined]
        "steps": summary.steps,
        "steps_per_second": summary.steps_per_second,
        "realtime_fraction": summary.realtime_fraction,
        "max_step_ms": 1e3 * summary.max_step_time,
        "assembly_ms": 1e3 * summary.assembly_time,
        "solve_ms": 1e3 * summary.solve_time,
        "other_ms": 1e3 * summary.other_time,
        "mean_iterations": summary.mean_iterations,
        "tangents": summary.tangents,
        "unconverged": summary.unconverged,
        "relative_residual_max": summary.relative_residual_max,
        "setup_s": setup,
        "load_average": os.getloadavg()[0],
    }
    entry.update(per_iteration(stepper))
    if contact:
        entry["min_distance"] = min(r.min_distance for r in records)
        entry["contact_cutbacks"] = sum(r.contact_cutbacks for r in records)
        entry["inversion_cutbacks"] = sum(r.inversion_cutbacks for r in records)
        entry["contact_force"] = [float(v) for v in contacts[0].force()]  # type: ignore[attr-defined]
        entry["active_nodes"] = contacts[0].active_count()  # type: ignore[attr-defined]
    return entry


def _best(fn, repeat: int = 5) -> float:
    """The fastest of ``repeat`` calls of ``fn`` (s), the slowest rank."""
    times = []
    for _ in range(repeat):
        MPI.COMM_WORLD.Barrier()
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return MPI.COMM_WORLD.allreduce(min(times), op=MPI.MAX)


def per_iteration(stepper: dyn.RealtimeStepper) -> dict:
    """At the final state: the elastic tangent assembly, the residual (with the contact's gradient), and the
    contact's own terms (gradient into the residual, Hessian blocks into the tangent) of one Newton iteration (ms)."""
    out = {
        "tangent_assembly_ms": 1e3 * _best(stepper._matrices.assemble),
        "residual_ms": 1e3 * _best(stepper._assemble_residual),
    }
    contact = stepper._contact
    if contact is not None:
        b, A = stepper._b, stepper.A
        out["contact_terms_ms"] = 1e3 * _best(lambda: (contact.add_residual(b), contact.add_tangent(A)))
    return out


def main() -> list[dict]:
    p = argparse.ArgumentParser()
    p.add_argument("--sizes", type=int, nargs="+", default=[2000, 6000])
    p.add_argument("--config", nargs="+", default=["cg-icc-modified", "mumps-modified"])
    p.add_argument("--budget", type=int, default=6)
    p.add_argument("--steps", type=int, default=int(round(DURATION / DT)) - 5)
    p.add_argument("--warmup", type=int, default=5)
    p.add_argument("--friction", type=float, default=0.0)
    p.add_argument("--dhat", type=float, default=None, help="barrier width (default: from the mesh size)")
    args = p.parse_args()
    results = []
    for tets in args.sizes:
        for config in args.config:
            entry = run(tets, config, args.budget, args.steps, args.warmup, args.friction, True, args.dhat)
            results.append(entry)
            if MPI.COMM_WORLD.rank == 0:
                print(json.dumps(entry), flush=True)
    return results


if __name__ == "__main__":
    main()
