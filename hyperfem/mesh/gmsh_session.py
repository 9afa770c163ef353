"""A quiet gmsh session for rank 0."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from hyperfem.errors import MeshError

__all__ = ["gmsh_session"]


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
