r"""Homogeneous uniaxial stretch of the unit cube: the reference case for nearly incompressible solids.

Rollers on :math:`x = 0, y = 0, z = 0` (one component each), :math:`u_x = \lambda - 1`
on :math:`x = 1`, lateral faces free. For any isotropic material the exact
solution is homogeneous, :math:`u = (\lambda - 1)x\,e_x + (\lambda_t - 1)(y\,e_y + z\,e_z)`,
so every formulation must reproduce it at every node; in the incompressible
limit :math:`\lambda_t = \lambda^{-1/2}`.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from dolfinx import mesh as dmesh

from hyperfem.mesh.domain import Domain
from hyperfem.problem.boundary_conditions import PrescribedDisplacement

__all__ = ["unit_cube", "uniaxial_rollers"]


def unit_cube(n: int, comm: MPI.Comm = MPI.COMM_WORLD) -> Domain:
    """The unit cube of ``n`` x ``n`` x ``n`` boxes (6 tetrahedra each), faces ``x0, x1, y0, z0``."""
    mesh = dmesh.create_unit_cube(comm, n, n, n)
    return Domain.from_locators(
        mesh,
        {
            "x0": lambda x: np.isclose(x[0], 0.0),
            "x1": lambda x: np.isclose(x[0], 1.0),
            "y0": lambda x: np.isclose(x[1], 0.0),
            "z0": lambda x: np.isclose(x[2], 0.0),
        },
        source=f"unit_cube({n})",
    )


def uniaxial_rollers(stretch: float) -> list[PrescribedDisplacement]:
    """The symmetry rollers and the prescribed end displacement ``stretch - 1`` (ramped with t)."""
    return [
        PrescribedDisplacement("x0", [0.0], components=[0]),
        PrescribedDisplacement("y0", [0.0], components=[1]),
        PrescribedDisplacement("z0", [0.0], components=[2]),
        PrescribedDisplacement("x1", [stretch - 1.0], components=[0]),
    ]
