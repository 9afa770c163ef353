"""Reading gmsh meshes with named physical groups.

The file is read on rank 0 and distributed by :func:`dolfinx.io.gmsh.read_from_msh`;
the physical-group names stored in the file become the names used by
boundary conditions and material regions.
"""

from __future__ import annotations

from pathlib import Path

from mpi4py import MPI

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


def read_mesh(path: str | Path, comm: MPI.Comm = MPI.COMM_WORLD, gdim: int = 3) -> Domain:
    """Read a gmsh ``.msh`` file with physical groups.

    Args:
        path: The ``.msh`` file.
        comm: Communicator to distribute the mesh over.
        gdim: Geometric dimension (2 for planar meshes).

    Returns:
        The distributed :class:`Domain`.

    Raises:
        MeshFileNotFoundError: If the file does not exist.
        MeshError: If gmsh cannot read it or it has no physical groups.
    """
    path = Path(path)
    exists = comm.allreduce(int(path.is_file()), op=MPI.MIN)
    if not exists:
        raise MeshFileNotFoundError(f"mesh file not found: {path}")
    def load(gmsh) -> None:
        gmsh.model.add("hyperfem")
        gmsh.merge(str(path))
        if gmsh.model.getDimension() < 1:
            raise MeshError("no mesh in file")

    # Read on rank 0; a failure reaches every rank before the collective distribution.
    data = distribute_model(comm, load, gdim, f"{path}: could not read gmsh mesh")
    if not data.physical_groups:
        raise MeshError(f"{path}: the mesh has no physical groups; name boundaries and regions in gmsh")
    return domain_from_meshdata(data, str(path))
