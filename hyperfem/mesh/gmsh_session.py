"""A quiet gmsh session for rank 0."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from hyperfem.errors import MeshError

__all__ = ["distribute_model", "gmsh_session"]


@contextmanager
def gmsh_session() -> Iterator[object]:
    """Yield the ``gmsh`` module, initialised without terminal output; cleared afterwards.

    An already-initialised gmsh (e.g. by the user) is reused and left initialised.
    """
    try:
        import gmsh
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise MeshError("the gmsh Python module is required to read or generate meshes") from exc
    initialized = gmsh.isInitialized()
    if not initialized:
        gmsh.initialize(interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        yield gmsh
    finally:
        gmsh.clear()
        if not initialized:
            gmsh.finalize()


def distribute_model(comm, build, gdim: int = 3, what: str = "gmsh model"):
    """Build a gmsh model on rank 0 and distribute it as a DOLFINx mesh.

    A failure while building is broadcast before the collective distribution,
    so every rank raises the same :class:`~hyperfem.errors.MeshError` instead of
    waiting for rank 0.

    Args:
        comm: Communicator.
        build: ``build(gmsh)`` that adds and meshes the model (rank 0 only).
        gdim: Geometric dimension.
        what: Name used in error messages.

    Returns:
        :class:`dolfinx.io.gmsh.MeshData`.
    """
    from dolfinx.io import gmsh as dgmsh

    if comm.rank == 0:
        with gmsh_session() as gmsh:
            error = ""
            try:
                build(gmsh)
            except Exception as exc:  # gmsh raises bare Exceptions
                error = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            comm.bcast(error, root=0)
            if error:
                raise MeshError(f"{what}: {error}")
            return dgmsh.model_to_mesh(gmsh.model, comm, 0, gdim=gdim)
    error = comm.bcast(None, root=0)
    if error:
        raise MeshError(f"{what}: {error}")
    return dgmsh.model_to_mesh(None, comm, 0, gdim=gdim)
