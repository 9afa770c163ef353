r"""Orientation of the cells of a mesh: inverted (negatively oriented) and degenerate cells.

The signed volume of a tetrahedron with vertices :math:`x_0 \dots x_3` is
:math:`V = \tfrac16 (x_1 - x_0)\cdot\big((x_2 - x_0)\times(x_3 - x_0)\big)`
(of a triangle in the plane, :math:`\tfrac12 (x_1 - x_0)\times(x_2 - x_0)`);
gmsh writes cells with :math:`V > 0`. A cell with :math:`V < 0` lists its
vertices in the mirrored order; one with :math:`|V|` at round-off of
:math:`\ell^3` (:math:`\ell` its longest edge) has no volume.

What hyperfem does with them (documented in the CLI help):

* degenerate cells are an error everywhere: their stiffness is singular;
* inverted cells are harmless to a run — DOLFINx integrates with
  :math:`|\det J|` and keeps the vertex order, and the results on a mesh with
  some cells mirrored equal those on the original — so ``hyperfem run`` and
  ``hyperfem mesh-quality`` only warn, while ``hyperfem convert`` refuses to
  write them unless asked to reorient (``--reorient`` swaps two vertices),
  because other tools (gmsh's own checks, Abaqus) reject such files.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI

from hyperfem.errors import MeshError

if TYPE_CHECKING:
    from hyperfem.mesh.domain import Domain

__all__ = [
    "DEGENERATE_TOLERANCE",
    "Orientation",
    "check_cell_volumes",
    "domain_orientation",
    "orientation",
    "signed_volumes",
]

DEGENERATE_TOLERANCE = 1e-12
r"""A cell with :math:`|V| \le` this times :math:`\ell^3` (:math:`\ell^2` for triangles) has no volume."""


def signed_volumes(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed volumes (areas) of simplices and their scale :math:`\\ell^d`.

    Args:
        points: Vertex coordinates, ``(n, 4, 3)`` tetrahedra or ``(n, 3, 2|3)`` triangles
            (triangles in 3D get the :math:`z` component of the normal).

    Returns:
        ``(volumes, scales)``, both of shape ``(n,)``.
    """
    p = np.asarray(points, dtype=float)
    edges = p[:, 1:] - p[:, :1]
    if p.shape[1] == 4:
        volume = np.einsum("ij,ij->i", edges[:, 0], np.cross(edges[:, 1], edges[:, 2])) / 6.0
        dim = 3
    else:
        e = edges[..., :2]
        volume = 0.5 * (e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
        dim = 2
    n = p.shape[1]
    lengths = [np.linalg.norm(p[:, j] - p[:, i], axis=1) for i in range(n) for j in range(i + 1, n)]
    longest = np.max(np.stack(lengths, axis=1), axis=1) if len(p) else np.zeros(0)
    return volume, longest**dim


@dataclass(frozen=True)
class Orientation:
    """Counts of inverted and degenerate cells.

    Attributes:
        cells: Number of cells checked.
        inverted: Cells with negative signed volume (not degenerate).
        degenerate: Cells without volume.
    """

    cells: int
    inverted: int
    degenerate: int


def orientation(points: np.ndarray) -> tuple[Orientation, np.ndarray, np.ndarray]:
    """Orientation of simplices given by their vertex coordinates (see :func:`signed_volumes`).

    Returns:
        The counts, and boolean masks of the inverted and of the degenerate cells.
    """
    volume, scale = signed_volumes(points)
    degenerate = np.abs(volume) <= DEGENERATE_TOLERANCE * scale
    inverted = (volume < 0) & ~degenerate
    return Orientation(len(volume), int(inverted.sum()), int(degenerate.sum())), inverted, degenerate


def domain_orientation(domain: Domain) -> Orientation | None:
    """The counts over the owned cells of a :class:`~hyperfem.mesh.Domain`, reduced over ranks (collective).

    Returns:
        ``None`` for cells other than triangles (in the plane) and tetrahedra.
    """
    mesh = domain.mesh
    tdim = mesh.topology.dim
    name = mesh.topology.cell_type.name
    if not (name == "tetrahedron" or (name == "triangle" and mesh.geometry.dim == 2)):
        return None
    owned = mesh.topology.index_map(tdim).size_local
    nodes = mesh.geometry.dofmaps[0][:owned, : tdim + 1]  # vertices come first in every Lagrange geometry
    counts, _, _ = orientation(mesh.geometry.x[nodes])
    comm = domain.comm
    total = comm.allreduce(np.array([counts.cells, counts.inverted, counts.degenerate]), op=MPI.SUM)
    return Orientation(*(int(v) for v in total))


def check_cell_volumes(domain: Domain) -> Orientation | None:
    """Refuse a mesh with cells without volume (collective; the same message as ``hyperfem run``).

    A flat mesh (every node in one plane) would otherwise surface much later as
    a singular tangent ("rigid-body motion unconstrained").

    Returns:
        The counts (``None`` for cells :func:`domain_orientation` does not measure).

    Raises:
        MeshError: ``MESH: 2 of 2 cells have no volume (degenerate); fix the mesh (...)``.
    """
    counts = domain_orientation(domain)
    if counts is not None and counts.degenerate:
        raise MeshError(
            f"{domain.source}: {counts.degenerate} of {counts.cells} cells have no volume (degenerate); fix the mesh "
            "(hyperfem mesh-quality shows the measures)"
        )
    return counts
