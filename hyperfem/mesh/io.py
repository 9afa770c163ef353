"""Reading gmsh meshes with named physical groups.

The file is read on rank 0 and distributed by :func:`dolfinx.io.gmsh.read_from_msh`;
the physical-group names stored in the file become the names used by
boundary conditions and material regions.
"""

from __future__ import annotations

from pathlib import Path

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


def _geometric_dimension(gmsh, tdim: int) -> int:
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
            ``gdim`` is too small for its cells or coordinates.
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

    def load(gmsh) -> int:
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
        needed = _geometric_dimension(gmsh, tdim)
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
