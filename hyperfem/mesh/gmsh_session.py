"""A quiet gmsh session for rank 0."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from types import ModuleType
from typing import TYPE_CHECKING

from mpi4py import MPI

from hyperfem.errors import MeshError

if TYPE_CHECKING:
    from dolfinx.io.gmsh import MeshData

__all__ = ["distribute_model", "gmsh_session"]


@contextmanager
def gmsh_session() -> Iterator[ModuleType]:
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


def _first_line(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return text or type(exc).__name__


def distribute_model(
    comm: MPI.Comm, build: Callable[[ModuleType], int | None], gdim: int | None = 3, what: str = "gmsh model"
) -> MeshData:
    """Build a gmsh model on rank 0 and distribute it as a DOLFINx mesh.

    Everything rank 0 does alone (importing and starting gmsh, building or
    reading the model) is guarded: its failure is broadcast before the
    collective distribution, so every rank raises the same
    :class:`~hyperfem.errors.MeshError` instead of waiting for rank 0. The
    errors DOLFINx raises collectively while distributing (no physical groups,
    cells tagged twice) become a :class:`~hyperfem.errors.MeshError` too.

    Args:
        comm: Communicator.
        build: ``build(gmsh)`` that adds and meshes the model (rank 0 only). It
            may return the geometric dimension, used when ``gdim`` is ``None``.
        gdim: Geometric dimension, or ``None`` for the one ``build`` returns (default 3).
        what: Name used in error messages.

    Returns:
        :class:`dolfinx.io.gmsh.MeshData`.
    """
    from dolfinx.io import gmsh as dgmsh

    def distribute(model: object, dim: int) -> MeshData:
        try:
            return dgmsh.model_to_mesh(model, comm, 0, gdim=dim)
        except RuntimeError as exc:  # raised on every rank (DOLFINx broadcasts its checks)
            raise MeshError(f"{what}: {_first_line(exc)}") from None

    if comm.rank == 0:
        with ExitStack() as stack:
            error, dim, gmsh = "", None, None  # dim and gmsh are set when error stays ""
            try:  # importing/starting gmsh and building the model happen on rank 0 alone
                gmsh = stack.enter_context(gmsh_session())
                found = build(gmsh)
                dim = gdim if gdim is not None else (found or 3)
            except Exception as exc:  # gmsh raises bare Exceptions
                error = _first_line(exc)
            comm.bcast((error, dim), root=0)
            if error:
                raise MeshError(f"{what}: {error}")
            assert gmsh is not None and dim is not None
            return distribute(gmsh.model, dim)
    error, dim = comm.bcast(None, root=0)
    if error:
        raise MeshError(f"{what}: {error}")
    return distribute(None, dim)
