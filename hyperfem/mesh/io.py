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
from hyperfem.mesh.gmsh_session import gmsh_session

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
    # Read on rank 0 and report failure to every rank *before* the collective
    # distribution, so a bad file cannot leave the other ranks waiting.
    error = ""
    if comm.rank == 0:
        with gmsh_session() as gmsh:
            try:
                gmsh.model.add("hyperfem")
                gmsh.merge(str(path))
                if gmsh.model.getDimension() < 1:
                    error = "no mesh in file"
            except Exception as exc:  # gmsh raises a bare Exception with its log line
                error = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            error = comm.bcast(error, root=0)
            if not error:
                data = dgmsh.model_to_mesh(gmsh.model, comm, 0, gdim=gdim)
    else:
        error = comm.bcast(error, root=0)
        if not error:
            data = dgmsh.model_to_mesh(None, comm, 0, gdim=gdim)
    if error:
        raise MeshError(f"{path}: could not read gmsh mesh ({error})")
    if not data.physical_groups:
        raise MeshError(f"{path}: the mesh has no physical groups; name boundaries and regions in gmsh")
    return domain_from_meshdata(data, str(path))
