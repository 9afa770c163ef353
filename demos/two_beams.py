# %% [markdown]
# # Two bodies: one cantilever bent into another
#
# Two cantilevers of compressible Neo-Hookean rubber ($E = 1$, $\nu = 0.3$),
# $4 \times 0.5 \times 0.5$ each, side by side with a gap $g = 0.1$ between
# them, are clamped at $x = 0$. The free end of the first is moved sideways by
# $\delta = 0.4$ toward the second: it bends, touches the second and pushes it
# aside. The two beams are two cell groups of **one mesh** (two bodies of one
# problem: one function space, one Newton system), meshed independently, and
# their facing sides may touch (``SurfaceContact``, the IPC barrier between
# the surface triangles from ``ipctk``); every Newton step is shortened by a
# continuous collision detection, so they never pass through each other.
#
# Checked at every step: the second beam has no load but the contact, so the
# force the first exerts on it equals minus the reaction of its clamp (to the
# solver's tolerance: 6e-7 of this small force), and no two triangles
# intersect (``ipctk.has_intersections``). Contact begins with cut-backs (the
# pushed end must not jump through the gap); then the solver's predictor
# carries the nodes of the second beam that the prescribed end touches, and
# the increment grows back.
#
# Run with `python demos/two_beams.py` or `mpiexec -n 2 python demos/two_beams.py`
# (needs the contact extra: `pip install 'hyperfem[contact]'`).

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # threaded BLAS slows MUMPS ~10x
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

import basix.ufl  # noqa: E402
import ufl  # noqa: E402

import hyperfem as hf  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_float, positive_int, run  # noqa: E402
from hyperfem.contact import SurfaceContact  # noqa: E402
from hyperfem.io import ensure_output_dir  # noqa: E402
from hyperfem.simulation import Recorder, Simulation  # noqa: E402
from hyperfem.simulation.measures import Reaction  # noqa: E402

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
LENGTH, WIDTH = 4.0, 0.5


def parse(argv=None):
    p = ArgumentParser(description="Two bodies: one cantilever bent into another (SurfaceContact)")
    p.add_argument("--n", type=positive_int, default=2, help="cells across a beam (8n along it)")
    p.add_argument("--gap", type=positive_float, default=0.1, help="the gap between the beams")
    p.add_argument("--push", type=positive_float, default=0.4, help="sideways move of the first beam's free end")
    p.add_argument("--steps", type=positive_int, default=8, help="load steps")
    p.add_argument("--dhat", type=positive_float, default=5e-3, help="barrier width")
    p.add_argument("--output", type=Path, default=Path("output"), help="output folder (two_beams.json)")
    return p.parse_args(argv)


# %% [markdown]
# ## The mesh: two boxes, one mesh
# Each beam is a box of tetrahedra built on rank 0 and put in one mesh
# (DOLFINx distributes it); the cell groups ``first`` and ``second`` and the
# facet groups (the clamped ends, the facing sides) are tagged by where the
# facets lie and which beam their cell belongs to.


# %%
def two_beams_mesh(comm, n: int, gap: float) -> hf.Domain:
    parts = []
    for y0 in (0.0, WIDTH + gap):
        box = [np.array([0.0, y0, 0.0]), np.array([LENGTH, y0 + WIDTH, WIDTH])]
        beam = dmesh.create_box(MPI.COMM_SELF, box, [8 * n, n, n])
        dofmap = beam.geometry.dofmaps[0] if hasattr(beam.geometry, "dofmaps") else beam.geometry.dofmap
        parts.append((beam.geometry.x.copy(), np.asarray(dofmap).copy()))
    if comm.rank == 0:
        x = np.vstack([parts[0][0], parts[1][0]])
        cells = np.vstack([parts[0][1], parts[1][1] + len(parts[0][0])]).astype(np.int64)
    else:
        x, cells = np.zeros((0, 3)), np.zeros((0, 4), dtype=np.int64)
    mesh = dmesh.create_mesh(comm, cells, ufl.Mesh(basix.ufl.element("Lagrange", "tetrahedron", 1, shape=(3,))), x)
    tdim = 3
    mesh.topology.create_connectivity(tdim - 1, tdim)
    facets = dmesh.exterior_facet_indices(mesh.topology)
    middle = dmesh.compute_midpoints(mesh, tdim - 1, facets)
    f2c = mesh.topology.connectivity(tdim - 1, tdim)
    owner_y = dmesh.compute_midpoints(mesh, tdim, np.array([f2c.links(f)[0] for f in facets], dtype=np.int32))[:, 1]
    second = owner_y > WIDTH + gap / 2
    values = np.full(len(facets), 6, dtype=np.int32)  # the other faces
    values[np.isclose(middle[:, 0], 0.0) & ~second] = 1  # first_clamp
    values[np.isclose(middle[:, 0], 0.0) & second] = 2  # second_clamp
    values[np.isclose(middle[:, 0], LENGTH) & ~second] = 3  # first_tip
    values[np.isclose(middle[:, 1], WIDTH) & ~second] = 4  # first_side (facing the second)
    values[np.isclose(middle[:, 1], WIDTH + gap) & second] = 5  # second_side (facing the first)
    cells_all = np.arange(mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts,
                          dtype=np.int32)
    regions = np.where(dmesh.compute_midpoints(mesh, tdim, cells_all)[:, 1] > WIDTH + gap / 2, 2, 1).astype(np.int32)
    groups = {"first_clamp": 1, "second_clamp": 2, "first_tip": 3, "first_side": 4, "second_side": 5, "other": 6}
    cell_tags = dmesh.meshtags(mesh, tdim, cells_all, regions)
    facet_tags = dmesh.meshtags(mesh, tdim - 1, facets, values)
    return hf.Domain(mesh, cell_tags, facet_tags, {"first": 1, "second": 2}, groups, source=f"two beams, n = {n}")


# %% [markdown]
# ## The run


# %%
class IntersectionCheck:
    def __init__(self, contact):
        self.contact = contact

    def record(self, step: object = None) -> dict:
        return {"intersecting": self.contact.intersecting()}


def two_beams(comm, n: int, gap: float, push: float, steps: int, dhat: float) -> dict:
    domain = two_beams_mesh(comm, n, gap)
    bcs = [
        hf.Clamp("first_clamp"),
        hf.Clamp("second_clamp"),
        hf.PrescribedDisplacement("first_tip", [push], components=[1]),
    ]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)
    contact = SurfaceContact(["first_side", "second_side"], dhat=dhat).bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-11}, external_energies=[contact])
    outputs = [Recorder(contact), Reaction("second_clamp"), Recorder(IntersectionCheck(contact))]
    # Contact begins with cut-backs (the pushed end must not jump through the gap); growth after every two steps,
    # however many Newton iterations they took, brings the increment back.
    policy = hf.StepPolicy(increment=1.0 / steps, max_increment=1.0 / steps, grow_after=2, easy_iterations=None)
    summary = Simulation(problem, solver, policy, outputs, name="two_beams").run()
    rows = summary["rows"][1:]
    on_second = np.array([[-f for f in row["contact_force"]] for row in rows])  # the force on first_side, negated
    reaction = np.array([row["reaction_second_clamp"] for row in rows])
    touching = [i for i, row in enumerate(rows) if row["contact_active"] > 0]
    balance = float(np.abs(on_second + reaction)[touching].max() / np.abs(on_second).max()) if touching else 0.0
    return {
        "completed": bool(summary["completed"]),
        "steps": len(rows),
        "time": [row["time"] for row in rows],
        "force_on_second": on_second.tolist(),
        "balance": balance,
        "first_contact_at": rows[touching[0]]["time"] if touching else None,
        "min_distance": min(row["contact_min_distance"] for row in rows),
        "intersecting": any(row["intersecting"] for row in rows),
        "surface_nodes": contact.surface.size,
    }


# %%
def main(argv=None):
    args = parse(argv)
    comm = MPI.COMM_WORLD
    ensure_output_dir(args.output, comm)
    result = two_beams(comm, args.n, args.gap, args.push, args.steps, args.dhat)
    if comm.rank == 0:
        (args.output / "two_beams.json").write_text(json.dumps(result, indent=2))
        print(
            f"two beams: {result['steps']} steps, first contact at load factor {result['first_contact_at']}, "
            f"force on the second beam at the end {np.round(result['force_on_second'][-1], 5).tolist()}; "
            f"force + clamp reaction {result['balance']:.1e} of the force; smallest gap {result['min_distance']:.3g}; "
            f"intersecting: {result['intersecting']}"
        )
    comm.Barrier()  # the file exists on every rank's return
    return result


if __name__ == "__main__":
    run(main)
