"""Evaluation of finite-element quantities in parallel: at points, and minima over quadrature points.

* :class:`PointProbe` — a function at fixed reference points. Each point is
  evaluated on the lowest rank that owns a cell containing it; the values are
  summed over ranks so every rank gets the result.
* :class:`QuadratureMinimum` — the smallest value of a scalar expression over
  the quadrature points of the owned cells (e.g. :math:`\\min J`, the
  inversion measure of the solver and of the dynamics diagnostics), and how
  many cells fall below a threshold.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem, geometry
from mpi4py import MPI

from hyperfem.errors import ParameterError

__all__ = ["PointProbe", "QuadratureMinimum"]


class PointProbe:
    """Evaluate functions at fixed reference points (cells located once).

    Args:
        mesh: The mesh.
        points: Array of shape ``(n, 3)`` (or ``(3,)``, or ``(n, 1..2)``
            padded with zeros) in reference coordinates.

    Raises:
        ParameterError: If a point is not 1 to 3 finite coordinates or lies outside the mesh.
    """

    def __init__(self, mesh, points):
        try:
            pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        except (TypeError, ValueError):
            raise ParameterError(f"PointProbe: points must be an (n, 3) array of numbers, got {points!r}") from None
        if pts.ndim != 2 or not 1 <= pts.shape[1] <= 3 or pts.shape[0] == 0:
            raise ParameterError(f"PointProbe: points must have shape (n, 1..3), got {pts.shape}")
        if not np.all(np.isfinite(pts)):
            bad = pts[~np.all(np.isfinite(pts), axis=1)][0]
            raise ParameterError(
                f"PointProbe: point {bad.tolist()} has a non-finite coordinate (points must be finite)"
            )
        if pts.shape[1] < 3:
            pts = np.hstack([pts, np.zeros((pts.shape[0], 3 - pts.shape[1]))])
        self.points = pts
        self.mesh = mesh
        tdim = mesh.topology.dim
        tree = geometry.bb_tree(mesh, tdim)
        candidates = geometry.compute_collisions_points(tree, pts)
        colliding = geometry.compute_colliding_cells(mesh, candidates, pts)
        size_local = mesh.topology.index_map(tdim).size_local
        owner = np.full(len(pts), -1, dtype=np.int32)
        for i in range(len(pts)):
            cells = colliding.links(i)
            owned = cells[cells < size_local]
            if len(owned):
                owner[i] = owned[0]
        found = np.where(owner >= 0, mesh.comm.rank, mesh.comm.size).astype(np.int32)
        # One rank (the lowest that found it) evaluates each point.
        self._rank = np.empty_like(found)
        mesh.comm.Allreduce(found, self._rank, op=MPI.MIN)  # elementwise over the points
        missing = np.where(self._rank == mesh.comm.size)[0]
        if len(missing):
            raise ParameterError(f"PointProbe: point {pts[missing[0]].tolist()} is outside the mesh")
        self._mine = np.where(self._rank == mesh.comm.rank)[0]
        self._cells = owner[self._mine]

    def __call__(self, u: fem.Function) -> np.ndarray:
        """Values of ``u`` at the points, shape ``(n, value_size)``, on every rank."""
        size = int(np.prod(u.function_space.value_shape)) if u.function_space.value_shape else 1
        values = np.zeros((len(self.points), size))
        if len(self._mine):
            values[self._mine] = u.eval(self.points[self._mine], self._cells).reshape(len(self._mine), size)
        return self.mesh.comm.allreduce(values, op=MPI.SUM)


class QuadratureMinimum:
    """The minimum of a scalar UFL expression over the quadrature points of the mesh (compiled once).

    Args:
        mesh: The mesh.
        expr: Scalar UFL expression (e.g. :math:`J = \\det F`).
        points: Reference quadrature points (e.g. ``problem.quadrature_points()``).
    """

    def __init__(self, mesh, expr: ufl.core.expr.Expr, points: np.ndarray):
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
