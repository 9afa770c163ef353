# %% [markdown]
# # Virtual surgery: a rigid probe indents a tissue slab and drags across it
#
# Seed 000's application is a surgical simulator: tissue pushed, pulled and
# dragged by rigid tools. Here a ball-ended probe (a triangulated sphere of
# radius $R = 0.2$, the tool surface as a surgical instrument's STL would give
# it) is pressed into a slab of soft tissue ($2 \times 1 \times 0.5$,
# compressible Neo-Hookean, $E = 1$, $\nu = 0.3$, clamped at the bottom) to a
# depth $\delta$, then dragged along $x$ by $L$ while pressed. Contact is one
# more term of the total potential (issue 19),
#
# $$
# \Pi(u) = \int_\Omega \psi(I + \nabla u)\,dX + \kappa \sum_{k} b\bigl(d_k^2(u), \hat d^2\bigr),
# $$
#
# the IPC barrier over the point–triangle and edge–edge pairs $k$ between the
# probe's triangles and the slab's top surface closer than $\hat d$
# (``ToolContact``; the pairs, distances, barrier and its derivatives come from
# the IPC Toolkit, ``ipctk``). Every Newton step is shortened by a continuous
# collision detection of the probe against the surface, so no accepted
# iterate ever has the probe inside the tissue. The probe moves by a
# prescribed path: at the start of each step, the surface nodes it would
# overrun are carried with it by the predictor (a tangent solve that lifts
# their increment into the slab), and the sweep from the last state to the
# new one is checked to be collision-free.
#
# Checked here, at every step: the contact force equals minus the reaction
# of the clamped bottom (equilibrium of the slab, to round-off), and no
# triangle of the probe and the tissue intersect (``ipctk.has_intersections``).
# With friction ($\mu = 0.3$ by default, smoothed Coulomb, lagged per step as
# in IPC) the dragged probe also pulls the tissue's surface along: the
# horizontal force is the friction plus the resistance of the tissue ahead of
# it (``--friction 0`` for a frictionless probe, which only ploughs).
#
# Run with `python demos/surgery.py` or `mpiexec -n 2 python demos/surgery.py`
# (needs the contact extra: `pip install 'hyperfem[contact]'`). The default
# mesh (`--n 6`) takes seconds; `--n 30` (90.8k unknowns) took 9 min 45 s on
# 2 ranks of a quiet 2-core machine, in 19 steps. The indentation alone (the
# run stopped at the deepest point, t = 0.5: 4 steps, the same force) took
# 35–41 s; the rest is the Newton
# iterations of the drag (`benchmarks/contact_drag_newton.py`; 14 min 51 s
# before a failed lagged preconditioner was rebuilt rather than replaced by
# MUMPS, `benchmarks/contact_recovery.py`).

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # threaded BLAS slows MUMPS ~10x
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_float, positive_int, run  # noqa: E402
from hyperfem.contact import ToolContact, icosphere  # noqa: E402
from hyperfem.io import ensure_output_dir  # noqa: E402
from hyperfem.simulation import Recorder, Simulation  # noqa: E402
from hyperfem.simulation.measures import Reaction  # noqa: E402

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
RADIUS, LIFT = 0.2, 0.01  # the probe's radius, its height above the tissue at the start


def parse(argv=None):
    p = ArgumentParser(description="Virtual surgery: a rigid probe indents a tissue slab and drags across it")
    p.add_argument("--n", type=positive_int, default=6, help="cells across the slab's width (2n x n x n/2)")
    p.add_argument("--depth", type=positive_float, default=0.1, help="indentation depth")
    p.add_argument("--drag", type=positive_float, default=0.4, help="how far the probe is dragged along x")
    p.add_argument("--steps", type=positive_int, default=8, help="load steps (half indenting, half dragging)")
    p.add_argument("--dhat", type=positive_float, default=5e-3, help="barrier width")
    p.add_argument("--friction", type=float, default=0.3, help="Coulomb coefficient between probe and tissue")
    p.add_argument("--output", type=Path, default=Path("output"), help="output folder (surgery.json)")
    return p.parse_args(argv)


# %% [markdown]
# ## The probe's path
# Down by $\delta + $ its lift over the first half of the run ($t \le 1/2$),
# then along $x$ by $L$: a path $t \mapsto$ translation through waypoints
# (piecewise linear), given to ``ToolContact`` as its ``motion``.


# %%
def path(depth: float, drag: float) -> hf.loading.Waypoints:
    down = -(depth + LIFT)
    return hf.loading.Waypoints(times=(0.0, 0.5, 1.0), points=((0.0, 0.0, 0.0), (0.0, 0.0, down), (drag, 0.0, down)))


# %% [markdown]
# ## The slab and the probe
# An output column of our own: whether any two triangles intersect after the step.


# %%
class IntersectionCheck:
    def __init__(self, tool):
        self.tool = tool

    def record(self, step: object = None) -> dict:
        return {"intersecting": self.tool.intersecting()}



# %%
def surgery(comm, n: int, depth: float, drag: float, steps: int, dhat: float, friction: float) -> dict:
    box = [np.zeros(3), np.array([2.0, 1.0, 0.5])]
    mesh = dmesh.create_box(comm, box, [2 * n, n, max(1, n // 2)])
    groups = {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], 0.5)}
    domain = hf.Domain.from_locators(mesh, groups, source=f"tissue slab, n = {n}")
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS),
                                     bcs=[hf.PrescribedDisplacement("bottom", [0.0, 0.0, 0.0])])
    points, triangles = icosphere(3)
    probe = points * RADIUS + np.array([0.6, 0.5, 0.5 + LIFT + RADIUS])
    tool = ToolContact.from_arrays(
        ["top"], probe, triangles, motion=path(depth, drag), dhat=dhat, friction=friction
    ).bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-9}, external_energies=[tool])
    outputs = [Recorder(tool), Reaction("bottom"), Recorder(IntersectionCheck(tool))]
    policy = hf.StepPolicy(increment=1.0 / steps)
    summary = Simulation(problem, solver, policy, outputs, name="surgery").run()
    rows = summary["rows"][1:]
    force = np.array([row["tool_force"] for row in rows])
    if friction > 0.0:  # the total force of the probe on the tissue: normal (barrier) and friction parts
        force = force + np.array([row["tool_friction_force"] for row in rows])
    reaction = np.array([row["reaction_bottom"] for row in rows])
    balance = float(np.abs(force + reaction).max() / np.abs(force).max())
    return {
        "completed": bool(summary["completed"]),
        "steps": len(rows),
        "time": [row["time"] for row in rows],
        "force": force.tolist(),
        "balance": balance,
        "min_distance": min(row["tool_min_distance"] for row in rows),
        # The collision filter sees every Newton iterate but each solve's last (the step's own, in the rows).
        "min_iterate_distance": tool.step_filter.min_distance,
        "intersecting": any(row["intersecting"] for row in rows),
        "surface_nodes": tool.surface.size,
        "probe_triangles": len(triangles),
    }


# %%
def main(argv=None):
    args = parse(argv)
    comm = MPI.COMM_WORLD
    ensure_output_dir(args.output, comm)
    result = surgery(comm, args.n, args.depth, args.drag, args.steps, args.dhat, args.friction)
    if comm.rank == 0:
        (args.output / "surgery.json").write_text(json.dumps(result, indent=2))
        print(
            f"surgery: {result['steps']} steps, probe force at the deepest point "
            f"{result['force'][int(np.argmin(np.abs(np.array(result['time']) - 0.5)))][2]:.4g}, at the end of the drag "
            f"{np.round(result['force'][-1], 4).tolist()}; force + reaction {result['balance']:.1e} of the force; "
            f"smallest gap {result['min_distance']:.3g}; intersecting: {result['intersecting']}"
        )
    comm.Barrier()  # the file exists on every rank's return
    return result


if __name__ == "__main__":
    run(main)
