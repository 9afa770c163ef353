# %% [markdown]
# # Self-contact: a strip folded onto itself on a table
#
# A strip of compressible Neo-Hookean rubber ($E = 1$, $\nu = 0.3$),
# $L \times w \times t = 1 \times 0.1 \times 0.05$, lies on a rigid table and
# is clamped at $x = 0$. Its free end is turned over: first along the arc of
# pure bending, by a prescribed rotation $\theta$ about the $y$ axis, until the
# strip is a half circle with its end upside down above the clamp
# ($\theta = \pi$, load factor $1/2$); then the end is brought down onto the
# strip's first half, at $x = 0.15$, tilted back by $\varphi = 0.5$ so that the
# folded half comes down on the lying half. The strip's top face touches
# itself (the fold), and its bottom face rests on the table.
#
# Contact is one more term of the total potential: the IPC barrier over the
# point–triangle and edge–edge pairs of the top face closer than $\hat d$
# (``SurfaceContact`` with one boundary group: **self-contact**, pairs of the
# same surface; neighbouring triangles are not pairs), and the barrier
# between the table and the nodes of the bottom face (``PlaneContact``).
# Every Newton step is shortened by a continuous collision detection of both,
# so no accepted iterate has the strip pass through itself or the table.
#
# Checked at every step: the self-contact's forces are internal (they sum to
# zero), the table's force balances the reactions of the clamp and of the
# turned end, and no two triangles intersect (``ipctk.has_intersections``);
# at the end the fold carries pairs closer than $\hat d$, all at a positive
# distance.
#
# Run with `python demos/fold.py` or `mpiexec -n 2 python demos/fold.py`
# (needs the contact extra: `pip install 'hyperfem[contact]'`).

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # threaded BLAS slows MUMPS ~10x
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
import math  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_float, positive_int, run  # noqa: E402
from hyperfem.contact import PlaneContact, SurfaceContact  # noqa: E402
from hyperfem.io import ensure_output_dir  # noqa: E402
from hyperfem.simulation import Recorder, Simulation  # noqa: E402
from hyperfem.simulation.measures import Reaction  # noqa: E402

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
LENGTH, WIDTH, THICKNESS = 1.0, 0.1, 0.05
TURN = 0.5  # the load factor at which the end is upside down above the clamp


def parse(argv=None):
    p = ArgumentParser(description="Self-contact: a strip folded onto itself on a table")
    p.add_argument("--n", type=positive_int, default=2, help="cells through the thickness (20n along, 2n across)")
    p.add_argument("--at", type=float, default=0.15, help="where the end comes down (x)")
    p.add_argument("--tilt", type=float, default=0.5, help="the end's tilt back, in radians")
    p.add_argument("--gap", type=positive_float, default=2e-3, help="the end's lowest corner above the lying half")
    p.add_argument("--steps", type=positive_int, default=16, help="load steps (half turning, half folding)")
    p.add_argument("--dhat", type=positive_float, default=1e-3, help="barrier width")
    p.add_argument("--output", type=Path, default=Path("output"), help="output folder (fold.json)")
    return p.parse_args(argv)


# %% [markdown]
# ## The end's path
# Pure bending by an end rotation $\theta$ bends the strip's mid-plane
# ($z = t/2$) into an arc of radius $L/\theta$: the end section's centre goes
# to $c(\theta) = \bigl((L/\theta)\sin\theta,\ t/2 + (L/\theta)(1 - \cos\theta)\bigr)$
# in the $(x, z)$ plane and the section turns with it ($s \le 1/2$). Then
# ($s > 1/2$) the centre moves on a straight line to $x_e$, at the height
# where the end's lowest corner is the gap $g$ above the lying half
# ($z_e = t + g + \tfrac t2\cos\varphi$), while $\theta$ goes from $\pi$ to
# $\pi - \varphi$. The end's prescribed displacement is that rigid motion of
# its reference points (a callable ``value(x, s)`` of ``PrescribedDisplacement``).


# %%
def end_path(at: float, tilt: float, gap: float):
    top = THICKNESS / 2 + 2.0 * LENGTH / math.pi  # the centre's height at theta = pi
    low = THICKNESS + gap + THICKNESS / 2 * math.cos(tilt)

    def displacement(x: np.ndarray, s: float) -> np.ndarray:
        if s <= TURN:
            theta = math.pi * s / TURN
            if theta == 0.0:
                return np.zeros_like(x)
            radius = LENGTH / theta
            centre = (radius * math.sin(theta), THICKNESS / 2 + radius * (1.0 - math.cos(theta)))
        else:
            f = (s - TURN) / (1.0 - TURN)
            theta = math.pi - f * tilt
            centre = (f * at, top + f * (low - top))
        dz = x[2] - THICKNESS / 2  # the offset across the thickness, turned by theta
        new_x = centre[0] - dz * math.sin(theta)
        new_z = centre[1] + dz * math.cos(theta)
        return np.vstack([new_x - x[0], np.zeros_like(x[1]), new_z - x[2]])

    return displacement


# %% [markdown]
# ## The run


# %%
class IntersectionCheck:
    def __init__(self, contact):
        self.contact = contact

    def record(self, step: object = None) -> dict:
        return {"intersecting": self.contact.intersecting()}


def fold(comm, n: int, at: float, tilt: float, gap: float, steps: int, dhat: float) -> dict:
    box = [np.zeros(3), np.array([LENGTH, WIDTH, THICKNESS])]
    mesh = dmesh.create_box(comm, box, [20 * n, 2 * n, n])
    groups = {
        "clamp": lambda x: np.isclose(x[0], 0.0),
        "end": lambda x: np.isclose(x[0], LENGTH),
        "top": lambda x: np.isclose(x[2], THICKNESS),
        "bottom": lambda x: np.isclose(x[2], 0.0),
    }
    domain = hf.Domain.from_locators(mesh, groups, source=f"strip, n = {n}")
    bcs = [hf.Clamp("clamp"), hf.PrescribedDisplacement("end", end_path(at, tilt, gap))]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)
    self_contact = SurfaceContact(["top"], dhat=dhat, name="fold").bind(problem)
    # The table lies 2 d-hat below the strip: no force at rest (a force on the clamped nodes is not in a reaction).
    table = PlaneContact("bottom", point=(0.0, 0.0, -2 * dhat), normal=(0.0, 0.0, 1.0), dhat=dhat,
                         name="table").bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10}, external_energies=[self_contact, table])
    outputs = [Recorder(self_contact), Recorder(table), Reaction("clamp"), Reaction("end"),
               Recorder(IntersectionCheck(self_contact))]
    policy = hf.StepPolicy(increment=1.0 / steps, max_increment=1.0 / steps, must_hit=[TURN])
    summary = Simulation(problem, solver, policy, outputs, name="fold").run()
    rows = summary["rows"][1:]
    table_force = np.array([row["table_force"] for row in rows])
    reactions = np.array([np.add(row["reaction_clamp"], row["reaction_end"]) for row in rows])
    internal = np.array([row["fold_force"] for row in rows])
    scale = float(np.abs(table_force).max())
    touching = [i for i, row in enumerate(rows) if row["fold_active"] > 0]
    u = problem.u.x.array
    on_lying_half = _force_on(self_contact, u, lambda X: X[:, 0] < LENGTH / 2)
    return {
        "completed": bool(summary["completed"]),
        "steps": len(rows),
        "time": [row["time"] for row in rows],
        "table_force": table_force.tolist(),
        "end_reaction": rows[-1]["reaction_end"],
        "balance": float(np.abs(table_force + reactions).max() / scale),
        "self_force_sum": float(np.abs(internal).max() / scale),
        "fold_force_on_lying_half": on_lying_half.tolist(),
        "self_contact_from": rows[touching[0]]["time"] if touching else None,
        "self_pairs": rows[-1]["fold_active"],
        "min_distance": min(row["fold_min_distance"] for row in rows),
        "table_min_distance": min(row["table_min_distance"] for row in rows),
        "intersecting": any(row["intersecting"] for row in rows),
    }


def _force_on(contact, u: np.ndarray, where) -> np.ndarray:
    """The self-contact's force on the surface nodes whose reference positions pass ``where`` (collective)."""
    _, values = contact.gradient(u)  # at this rank's owned surface nodes
    mine = where(contact.surface.X[contact.surface.rows])
    local = -values[mine].sum(axis=0) if mine.any() else np.zeros(3)
    return contact.comm.allreduce(local)


# %%
def main(argv=None):
    args = parse(argv)
    comm = MPI.COMM_WORLD
    ensure_output_dir(args.output, comm)
    result = fold(comm, args.n, args.at, args.tilt, args.gap, args.steps, args.dhat)
    if comm.rank == 0:
        (args.output / "fold.json").write_text(json.dumps(result, indent=2))
        print(
            f"fold: {result['steps']} steps, self-contact from load factor {result['self_contact_from']} "
            f"({result['self_pairs']} pairs at the end, force on the lying half "
            f"{np.round(result['fold_force_on_lying_half'], 7).tolist()}); table force at the end "
            f"{np.round(result['table_force'][-1], 7).tolist()}; table + reactions {result['balance']:.1e} of it; "
            f"sum of the self-contact forces {result['self_force_sum']:.1e}; "
            f"smallest gaps {result['min_distance']:.3g} (fold), {result['table_min_distance']:.3g} (table); "
            f"intersecting: {result['intersecting']}"
        )
    comm.Barrier()  # the file exists on every rank's return
    return result


if __name__ == "__main__":
    run(main)
