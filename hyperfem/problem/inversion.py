r"""The inversion measure of a state: the smallest :math:`J = \det F` over the quadrature points.

:class:`QuadratureMinimum` evaluates a scalar expression (the problem's
:meth:`~hyperfem.problem.base.EnergyProblem.volume_jacobian` at its
:meth:`~hyperfem.problem.base.EnergyProblem.quadrature_points`) on the owned
cells and reduces over the ranks: the smallest value, and how many cells fall
below a threshold. The solver's inversion guard and its step filters
(:mod:`hyperfem.solver.filters`) and the dynamics diagnostics measure the
state with it.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

__all__ = ["QuadratureMinimum"]


class QuadratureMinimum:
    """The minimum of a scalar UFL expression over the quadrature points of the mesh (compiled once).

    Args:
        mesh: The mesh.
        expr: Scalar UFL expression (e.g. :math:`J = \\det F`).
        points: Reference quadrature points (e.g. ``problem.quadrature_points()``).
    """

    def __init__(self, mesh: dmesh.Mesh, expr: ufl.core.expr.Expr, points: np.ndarray) -> None:
        self.mesh = mesh
        self._expr = fem.Expression(expr, points)
        tdim = mesh.topology.dim
        self._cells = np.arange(mesh.topology.index_map(tdim).size_local, dtype=np.int32)

    def _per_cell(self) -> np.ndarray:
        values = self._expr.eval(self.mesh, self._cells)
        return values.reshape(len(self._cells), -1).min(axis=1) if values.size else np.zeros(0)

    def __call__(self) -> float:
        """The global minimum (every rank gets it; ``inf`` on an empty mesh)."""
        per_cell = self._per_cell()
        local = float(per_cell.min()) if per_cell.size else np.inf
        return self.mesh.comm.allreduce(local, op=MPI.MIN)

    def with_count(self, threshold: float = 0.0) -> tuple[float, int]:
        """``(global minimum, number of cells with a value <= threshold at some quadrature point)``."""
        per_cell = self._per_cell()
        local_min = float(per_cell.min()) if per_cell.size else np.inf
        local_count = int((per_cell <= threshold).sum())
        comm = self.mesh.comm
        return comm.allreduce(local_min, op=MPI.MIN), comm.allreduce(local_count, op=MPI.SUM)
