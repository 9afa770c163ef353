"""gmsh generator for Erleben's cantilever beam (seed 003, §5.7).

A 10 × 4 × 4 m box centred at the origin, :math:`x \\in [-5, 5]`,
:math:`y, z \\in [-2, 2]`, meshed with tetrahedra. Physical groups:

* ``clamped``  — the face :math:`x = -5`,
* ``free_end`` — the face :math:`x = +5`,
* ``surface``  — the four remaining faces,
* ``beam``     — the volume.

gmsh runs on rank 0 only; the mesh is distributed by DOLFINx.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.io.results import ensure_output_dir
from hyperfem.mesh.budget import check_mesh_size
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.gmsh_session import distribute_model, gmsh_session
from hyperfem.mesh.io import domain_from_meshdata
from hyperfem.validation import is_finite_number

__all__ = ["BEAM_GROUPS", "beam_mesh", "write_beam_mesh"]

BEAM_GROUPS = {"beam": 1, "clamped": 1, "free_end": 2, "surface": 3}
LENGTH, WIDTH, HEIGHT = 10.0, 4.0, 4.0
VOLUME = LENGTH * WIDTH * HEIGHT


def _check(h: float, order: int) -> None:
    if not (is_finite_number(h) and h > 0):
        raise ParameterError(f"beam mesh: element size h must be a finite number > 0, got {h!r}")
    if order not in (1, 2):
        raise ParameterError(f"beam mesh: order must be 1 or 2, got {order!r}")


def _build_beam_model(gmsh: ModuleType, h: float, order: int) -> None:
    gmsh.model.add("beam")
    gmsh.model.occ.addBox(-LENGTH / 2, -WIDTH / 2, -HEIGHT / 2, LENGTH, WIDTH, HEIGHT)
    gmsh.model.occ.synchronize()
    clamped, free_end, surface = [], [], []
    for dim, tag in gmsh.model.getEntities(2):
        x = gmsh.model.occ.getCenterOfMass(dim, tag)[0]
        if abs(x + LENGTH / 2) < 1e-8:
            clamped.append(tag)
        elif abs(x - LENGTH / 2) < 1e-8:
            free_end.append(tag)
        else:
            surface.append(tag)
    volumes = [tag for _, tag in gmsh.model.getEntities(3)]
    gmsh.model.addPhysicalGroup(3, volumes, BEAM_GROUPS["beam"], name="beam")
    gmsh.model.addPhysicalGroup(2, clamped, BEAM_GROUPS["clamped"], name="clamped")
    gmsh.model.addPhysicalGroup(2, free_end, BEAM_GROUPS["free_end"], name="free_end")
    gmsh.model.addPhysicalGroup(2, surface, BEAM_GROUPS["surface"], name="surface")
    gmsh.option.setNumber("Mesh.MeshSizeMin", h)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay: deterministic
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.setOrder(order)


def beam_mesh(
    h: float = 1.0, order: int = 1, comm: MPI.Comm = MPI.COMM_WORLD, *, allow_large: bool | None = None
) -> Domain:
    """Generate the cantilever beam in memory and distribute it.

    Args:
        h: Target element size in metres.
        order: Geometric order of the tetrahedra (1 or 2).
        comm: Communicator; gmsh runs on rank 0 only.
        allow_large: Mesh even if the estimate exceeds the available memory
            (:mod:`hyperfem.mesh.budget`); ``None``: the ``HYPERFEM_ALLOW_LARGE`` environment variable.

    Returns:
        The distributed :class:`~hyperfem.mesh.Domain`.

    Raises:
        ParameterError: A bad size or order.
        ProblemSizeError: Meshing at ``h`` would not fit in memory (on every rank).
    """
    _check(h, order)  # on every rank, before any collective call
    check_mesh_size("beam mesh", VOLUME, h, comm, allow_large)
    data = distribute_model(comm, lambda gmsh: _build_beam_model(gmsh, h, order), 3, "beam mesh")
    return domain_from_meshdata(data, f"beam_mesh(h={h}, order={order})")


def write_beam_mesh(path: str | Path, h: float = 1.0, order: int = 1, *, allow_large: bool | None = None) -> Path:
    """Write the beam mesh to a gmsh ``.msh`` (format 4.1) file. Serial; call on one rank.

    Args:
        path: Output file.
        h: Target element size in metres.
        order: Geometric order (1 or 2).
        allow_large: As for :func:`beam_mesh`.

    Returns:
        The path written.

    Raises:
        ProblemSizeError: Meshing at ``h`` would not fit in memory.
    """
    path = Path(path)
    _check(h, order)
    check_mesh_size("beam mesh", VOLUME, h, MPI.COMM_SELF, allow_large)
    ensure_output_dir(path.parent, MPI.COMM_SELF)  # OutputError if the folder cannot be written
    with gmsh_session() as gmsh:
        _build_beam_model(gmsh, h, order)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    return path
