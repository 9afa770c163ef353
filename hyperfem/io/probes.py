"""Point probes: finite-element functions evaluated at fixed reference points, in parallel.

:class:`PointProbe` evaluates each point on the lowest rank that owns a cell
containing it; the values are summed over ranks so every rank gets the
result. (The minimum over quadrature points, :math:`\\min J`, is a measure of
the state: :class:`hyperfem.problem.inversion.QuadratureMinimum`.)
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem, geometry
from dolfinx import mesh as dmesh
from numpy.typing import ArrayLike
from mpi4py import MPI

from hyperfem.errors import ParameterError

__all__ = ["PointProbe"]


class PointProbe:
    """Evaluate functions at fixed reference points (cells located once).

    Args:
        mesh: The mesh.
        points: Array of shape ``(n, 3)`` (or ``(3,)``, or ``(n, 1..2)``
            padded with zeros) in reference coordinates.

    Raises:
        ParameterError: If a point is not 1 to 3 finite coordinates or lies outside the mesh.
    """

    def __init__(self, mesh: dmesh.Mesh, points: ArrayLike) -> None:
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
