"""gmsh generator for two bodies in one mesh: two unit cubes stacked with a gap, meshed independently.

The ``lower`` cube is :math:`[0, 1]^2 \\times [-1, 0]`, the ``upper`` one
:math:`[0, 1]^2 \\times [g, 1 + g]`; each is meshed with tetrahedra of its
own size, so the facing faces do not match (the contact patch test, and two
bodies for :class:`~hyperfem.contact.SurfaceContact`); or, with
``cell="hexahedron"``, each in equal boxes of its own size. Physical groups:

* volumes ``lower``, ``upper``;
* faces ``lower_top`` (:math:`z = 0`), ``lower_bottom`` (:math:`z = -1`),
  ``upper_bottom`` (:math:`z = g`), ``upper_top`` (:math:`z = 1 + g`),
  ``x0`` and ``y0`` (the faces :math:`x = 0`, :math:`y = 0` of both cubes),
  ``sides`` (the other lateral faces).

gmsh runs on rank 0 only; the mesh is distributed by DOLFINx.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.io.results import ensure_output_dir
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.gmsh_session import distribute_model, gmsh_session
from hyperfem.mesh.io import domain_from_meshdata
from hyperfem.validation import is_finite_number

__all__ = ["BLOCKS_GROUPS", "stacked_blocks_mesh", "write_stacked_blocks_mesh"]

BLOCKS_GROUPS = {
    "lower": 1, "upper": 2,
    "lower_top": 1, "lower_bottom": 2, "upper_bottom": 3, "upper_top": 4, "x0": 5, "y0": 6, "sides": 7,
}


CELLS = ("tetrahedron", "hexahedron")


def _check(h_lower: float, h_upper: float, gap: float, order: int, cell: str = "tetrahedron") -> None:
    for key, value in (("h_lower", h_lower), ("h_upper", h_upper), ("gap", gap)):
        if not (is_finite_number(value) and value > 0):
            raise ParameterError(f"stacked blocks mesh: {key} must be a finite number > 0, got {value!r}")
    if order not in (1, 2):
        raise ParameterError(f"stacked blocks mesh: order must be 1 or 2, got {order!r}")
    if cell not in CELLS:
        raise ParameterError(f"stacked blocks mesh: cell must be one of {', '.join(CELLS)}, got {cell!r}")


def _structured(gmsh: ModuleType, volume: int, h: float) -> None:
    """Hexahedra on a cube: every edge in round(1/h) equal parts, transfinite faces recombined into quadrilaterals."""
    divisions = max(1, round(1.0 / h))
    surfaces = [tag for _, tag in gmsh.model.getBoundary([(3, volume)], oriented=False)]
    curves = {abs(c) for s in surfaces for _, c in gmsh.model.getBoundary([(2, s)], oriented=False)}
    for curve in sorted(curves):
        gmsh.model.mesh.setTransfiniteCurve(curve, divisions + 1)
    for surface in surfaces:
        gmsh.model.mesh.setTransfiniteSurface(surface)
        gmsh.model.mesh.setRecombine(2, surface)
    gmsh.model.mesh.setTransfiniteVolume(volume)


def _build(gmsh: ModuleType, h_lower: float, h_upper: float, gap: float, order: int, cell: str = "tetrahedron") -> None:
    gmsh.model.add("stacked_blocks")
    lower = gmsh.model.occ.addBox(0.0, 0.0, -1.0, 1.0, 1.0, 1.0)
    upper = gmsh.model.occ.addBox(0.0, 0.0, gap, 1.0, 1.0, 1.0)
    gmsh.model.occ.synchronize()
    faces: dict[str, list[int]] = {name: [] for name in ("lower_top", "lower_bottom", "upper_bottom", "upper_top",
                                                          "x0", "y0", "sides")}
    for volume, prefix in ((lower, "lower"), (upper, "upper")):
        for _, tag in gmsh.model.getBoundary([(3, volume)], oriented=False):
            x, y, z = gmsh.model.occ.getCenterOfMass(2, tag)
            z0, z1 = (-1.0, 0.0) if prefix == "lower" else (gap, 1.0 + gap)
            if abs(z - z1) < 1e-9:
                faces[f"{prefix}_top"].append(tag)
            elif abs(z - z0) < 1e-9:
                faces[f"{prefix}_bottom"].append(tag)
            elif abs(x) < 1e-9:
                faces["x0"].append(tag)
            elif abs(y) < 1e-9:
                faces["y0"].append(tag)
            else:
                faces["sides"].append(tag)
        h = h_lower if prefix == "lower" else h_upper
        if cell == "hexahedron":
            _structured(gmsh, volume, h)
        else:
            points = gmsh.model.getBoundary([(3, volume)], recursive=True)
            gmsh.model.mesh.setSize(points, h)
    gmsh.model.addPhysicalGroup(3, [lower], BLOCKS_GROUPS["lower"], name="lower")
    gmsh.model.addPhysicalGroup(3, [upper], BLOCKS_GROUPS["upper"], name="upper")
    for name, tags in faces.items():
        gmsh.model.addPhysicalGroup(2, tags, BLOCKS_GROUPS[name], name=name)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay: deterministic
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.setOrder(order)


def stacked_blocks_mesh(
    h_lower: float = 0.5,
    h_upper: float = 0.34,
    gap: float = 5e-4,
    order: int = 1,
    comm: MPI.Comm = MPI.COMM_WORLD,
    cell: str = "tetrahedron",
) -> Domain:
    """Generate the two stacked cubes in memory and distribute them (module docstring).

    Args:
        h_lower: Element size of the lower cube.
        h_upper: Element size of the upper cube.
        gap: The distance between them.
        order: Geometric order of the cells (1 or 2).
        comm: Communicator; gmsh runs on rank 0 only.
        cell: ``"tetrahedron"`` (unstructured, Delaunay) or ``"hexahedron"`` (structured: each cube
            in ``round(1/h)^3`` equal boxes).

    Raises:
        ParameterError: A size or gap that is not a number > 0, an order other than 1 or 2, or another cell.
    """
    _check(h_lower, h_upper, gap, order, cell)
    data = distribute_model(
        comm, lambda gmsh: _build(gmsh, h_lower, h_upper, gap, order, cell), 3, "stacked blocks mesh"
    )
    return domain_from_meshdata(
        data, f"stacked_blocks_mesh(h_lower={h_lower}, h_upper={h_upper}, gap={gap}, cell={cell!r})"
    )


def write_stacked_blocks_mesh(
    path: str | Path,
    h_lower: float = 0.5,
    h_upper: float = 0.34,
    gap: float = 5e-4,
    order: int = 1,
    cell: str = "tetrahedron",
) -> Path:
    """Write the two stacked cubes to a gmsh ``.msh`` (format 4.1) file. Serial; call on one rank."""
    path = Path(path)
    _check(h_lower, h_upper, gap, order, cell)
    ensure_output_dir(path.parent, MPI.COMM_SELF)
    with gmsh_session() as gmsh:
        _build(gmsh, h_lower, h_upper, gap, order, cell)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    return path
