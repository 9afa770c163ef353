"""Reading gmsh meshes with named physical groups.

The file is read on rank 0 and distributed by :func:`dolfinx.io.gmsh.read_from_msh`;
the physical-group names stored in the file become the names used by
boundary conditions and material regions.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

from mpi4py import MPI

import numpy as np
from dolfinx.io import gmsh as dgmsh

from hyperfem.errors import MeshError, MeshFileNotFoundError
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.gmsh_session import distribute_model

__all__ = ["domain_from_meshdata", "read_mesh"]


def domain_from_meshdata(data: dgmsh.MeshData, source: str) -> Domain:
    """Wrap :class:`dolfinx.io.gmsh.MeshData` in a :class:`Domain`."""
    tdim = data.mesh.topology.dim
    cells, facets = {}, {}
    for name, group in data.physical_groups.items():
        if group.dim == tdim:
            cells[name] = int(group.tag)
        elif group.dim == tdim - 1:
            facets[name] = int(group.tag)
    return Domain(data.mesh, data.cell_tags, data.facet_tags, cells, facets, source)


DUPLICATE_TOLERANCE = 1e-10
"""Nodes closer than this times the mesh's extent count as duplicates (exactly equal ones always do)."""


def _point(x: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:g}" for v in x) + ")"


def _element_name(gmsh: ModuleType, etype: int, count: int = 1) -> str:
    """``tetrahedron``, or the plural (``tetrahedra``, ``triangles``) for ``count != 1``."""
    name = str(gmsh.model.mesh.getElementProperties(etype)[0]).split()[0].lower()
    if count == 1:
        return name
    return name[:-2] + "a" if name.endswith("hedron") else name + "s"


def _check_coordinates(gmsh: ModuleType) -> None:
    """Every node coordinate must be finite (rank 0)."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    x = np.asarray(coords, dtype=float).reshape(-1, 3)
    bad = np.flatnonzero(~np.all(np.isfinite(x), axis=1))
    if bad.size:
        first = bad[0]
        raise MeshError(
            f"{bad.size} node(s) have coordinates that are not finite numbers (node {int(tags[first])} at "
            f"{_point(x[first])}); fix the mesh file"
        )


def _check_cells(gmsh: ModuleType, tdim: int, needed: int) -> None:
    """The cells must be volume cells of one type (rank 0).

    ``tdim`` is the highest dimension of a physical group, ``needed`` the
    dimension the coordinates span.
    """
    higher = [(d, t) for d in range(tdim + 1, 4) for t in gmsh.model.mesh.getElementTypes(d)]
    if higher:
        d, etype = higher[0]
        count = len(gmsh.model.mesh.getElementsByType(etype)[0])
        raise MeshError(
            f"{count} {_element_name(gmsh, etype, count)} are in no physical group (the groups stop at dimension "
            f"{tdim}); add a physical group of dimension {d} (gmsh: Physical Volume) so they are read"
        )
    types = list(gmsh.model.mesh.getElementTypes(tdim))
    counts = [(len(gmsh.model.mesh.getElementsByType(t)[0]), t) for t in types]
    names = ", ".join(f"{n} {_element_name(gmsh, t, n)}" for n, t in counts) or "none"
    if needed > tdim:
        raise MeshError(
            f"no volume cells: the mesh has only {tdim}D cells ({names}) with coordinates in {needed}D "
            f"(a surface mesh); mesh the volume (gmsh: Mesh {needed}) and name it with a physical group"
        )
    if len(types) > 1:
        raise MeshError(
            f"the {tdim}D cells mix {len(types)} types ({names}); hyperfem needs one cell type: remesh with one "
            "(gmsh: tetrahedra only, no Mesh.RecombineAll)"
        )


def _check_duplicate_nodes(gmsh: ModuleType, tdim: int) -> None:
    """No two nodes of the cells may share coordinates (rank 0): such cells are not connected."""
    used = [gmsh.model.mesh.getElementsByType(t)[1] for t in gmsh.model.mesh.getElementTypes(tdim)]
    if not used:
        return
    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, dtype=np.int64)
    x = np.asarray(coords, dtype=float).reshape(-1, 3)
    keep = np.isin(tags, np.unique(np.concatenate(used)))
    tags, x = tags[keep], x[keep]
    if len(tags) < 2:
        return
    low, extent = x.min(axis=0), float(np.ptp(x, axis=0).max())
    keys = np.round((x - low) / (DUPLICATE_TOLERANCE * extent if extent > 0 else 1.0)).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    shared = counts[inverse.reshape(-1)] > 1
    if shared.any():
        first = np.flatnonzero(shared)
        group = first[inverse.reshape(-1)[first] == inverse.reshape(-1)[first[0]]]
        a, b = sorted(int(t) for t in tags[group[:2]])
        raise MeshError(
            f"{int(shared.sum())} nodes share coordinates (node {a} and node {b} at {_point(x[group[0]])}); "
            "remove duplicates (gmsh: Geometry.Tolerance / Coherence; fragment volumes that touch)"
        )


def _geometric_dimension(gmsh: ModuleType, tdim: int) -> int:
    """Smallest dimension >= ``tdim`` whose trailing coordinates are all zero (rank 0)."""
    _, coords, _ = gmsh.model.mesh.getNodes()
    x = np.asarray(coords, dtype=float).reshape(-1, 3)
    if x.size == 0:
        raise MeshError("the file has no mesh nodes")
    scale = max(1.0, float(np.abs(x).max()))
    used = [bool(np.any(np.abs(x[:, k]) > 1e-14 * scale)) for k in range(3)]
    last = max((k + 1 for k in range(3) if used[k]), default=1)
    return max(tdim, last)


def read_mesh(path: str | Path, comm: MPI.Comm = MPI.COMM_WORLD, gdim: int | None = None) -> Domain:
    """Read a gmsh ``.msh`` file with physical groups.

    Args:
        path: The ``.msh`` file.
        comm: Communicator to distribute the mesh over.
        gdim: Geometric dimension. By default it is inferred from the file:
            the topological dimension of the highest physical groups, raised to
            cover every coordinate that is not zero (a planar mesh of triangles
            with all :math:`z = 0` gets ``gdim = 2``; a surface in space gets 3).

    Returns:
        The distributed :class:`Domain`.

    Raises:
        MeshFileNotFoundError: If the file does not exist.
        MeshError: If gmsh cannot read it, it has no physical groups, or
            ``gdim`` is too small for its cells or coordinates; if a node
            coordinate is NaN or infinite, two nodes of the cells share
            coordinates, the cells mix types, or there are no cells of the
            dimension the coordinates span (a surface mesh in 3D). Checked on
            rank 0 before DOLFINx reads the file; every rank raises.
    """
    path = Path(path)
    if gdim is not None and gdim not in (1, 2, 3):
        raise MeshError(f"{path}: gdim must be 1, 2, 3 or None (infer from the file), got {gdim!r}")
    exists = comm.allreduce(int(path.is_file()), op=MPI.MIN)
    if not exists:
        raise MeshFileNotFoundError(f"mesh file not found: {path}")

    # Other formats (.vtu, .inp, .mesh, ...) carry their groups in ways gmsh does not read: point to convert.
    hint = "" if path.suffix.lower() == ".msh" else (
        f" ({path.suffix or 'no suffix'}: not a gmsh .msh file; convert it with "
        f"`hyperfem convert {path.name} {path.stem}.msh`)"
    )

    def load(gmsh: ModuleType) -> int:
        gmsh.model.add("hyperfem")
        try:
            gmsh.merge(str(path))
        except Exception as exc:  # gmsh raises bare Exceptions
            reason = str(exc).splitlines()[0] if str(exc) else repr(exc)
            raise MeshError(f"could not read gmsh mesh: {reason}{hint}") from None
        if gmsh.model.getDimension() < 1:
            raise MeshError(f"could not read gmsh mesh: no mesh in file{hint}")
        groups = gmsh.model.getPhysicalGroups()
        if not groups:
            raise MeshError(f"the mesh has no physical groups; name its boundaries and regions in gmsh{hint}")
        tdim = max(dim for dim, _ in groups)
        _check_coordinates(gmsh)
        needed = _geometric_dimension(gmsh, tdim)
        _check_cells(gmsh, tdim, needed)
        _check_duplicate_nodes(gmsh, tdim)
        if gdim is None:
            return needed
        if gdim < needed:
            raise MeshError(
                f"gdim={gdim} is too small: the mesh has {tdim}D cells and coordinates in {needed} dimensions"
            )
        return gdim

    # Read on rank 0; a failure reaches every rank before the collective distribution.
    data = distribute_model(comm, load, None, str(path))
    return domain_from_meshdata(data, str(path))
