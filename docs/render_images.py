"""Draw the README pictures of the cantilever bend and twist: ``docs/images/bend.png``, ``docs/images/twist.png``.

Runs both cases of seed 003 §5.7 as ``demos/bend.py`` and ``demos/twist.py``
do (P2 tetrahedra on the committed ``meshes/beam_h1.msh``, the whole load in
one step; about 5 s for both) and draws the deformed beam, true scale,
coloured by the von Mises stress (DG1, averaged at the vertices), with the
outline of the undeformed beam, through the
:class:`~hyperfem.simulation.render.Render` output (800 x 500 pixels, under
200 kB each). Needs pyvista (``pip install 'hyperfem[render]'``)::

    python docs/render_images.py                 # or: mpiexec -n 2 python docs/render_images.py
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.cases import CantileverSpec, bend_load, twist_load  # noqa: E402
from hyperfem.simulation import Simulation  # noqa: E402
from hyperfem.simulation.render import Render  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
MESH = ROOT / "meshes" / "beam_h1.msh"
IMAGES = ROOT / "docs" / "images"

VIEWS = {
    "bend": {"view": (0.35, 0.3, 1.0), "title": "bend: dead end traction (0, -5, 0) kPa, P2, h = 1 m"},
    "twist": {"view": (1.0, 0.5, 0.8), "title": "twist: follower end traction 5 kPa/m (0, z, -y), P2, h = 1 m"},
}


def picture(name: str, load, comm) -> dict:
    """Run one case and draw ``docs/images/<name>.png``."""
    domain = hf.read_mesh(MESH, comm)
    params = CantileverSpec().lame
    energy = lambda F: hf.materials.neo_hookean(F, params)  # noqa: E731
    problem = hf.HyperelasticProblem(domain, energy, bcs=[hf.Clamp("clamped")], loads=[load], degree=2)
    render = Render(
        IMAGES / f"{name}.png",
        scalars="von_mises",
        materials=energy,
        window_size=(800, 500),
        scalar_bar_title="von Mises stress (Pa)",
        zoom=1.15,
        **VIEWS[name],
    )
    stepping = hf.LoadStepping(initial_increment=1.0)
    return Simulation(problem, hf.NewtonSolver(problem), stepping, [render], name=name).run()


def main() -> None:
    comm = MPI.COMM_WORLD
    for name, load in (("bend", bend_load()), ("twist", twist_load())):
        picture(name, load, comm)
        if comm.rank == 0:
            print(f"{IMAGES / name}.png", flush=True)


if __name__ == "__main__":
    main()
