"""Moving a problem's unknown to a PETSc vector (the solver's trial states)."""

from __future__ import annotations

from mpi4py import MPI  # noqa: F401  (before dolfinx/petsc4py)
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem
from dolfinx.la.petsc import _ghost_update

__all__ = ["assign_state"]


def assign_state(x: PETSc.Vec, u: fem.Function) -> None:
    """Copy ``x`` (owned and ghost entries, after a forward ghost update of ``x``) into ``u``.

    Args:
        x: A ghosted vector of ``u``'s layout (a SNES iterate or trial state).
        u: The unknown to move.
    """
    _ghost_update(x, PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD)  # type: ignore[arg-type]  # petsc4py: enums typed int
    fpetsc.assign(x, u)  # type: ignore[arg-type]  # dolfinx: singledispatch, the (Vec, Function) variant
