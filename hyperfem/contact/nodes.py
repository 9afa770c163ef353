r"""Contact points: the displacement nodes of a named boundary that a rank owns.

The contact points of a boundary group are the nodes of the displacement's
Lagrange space on its facets: the vertices for P1, every P2 boundary node
(vertices and edge midpoints) for P2. Each MPI rank keeps the nodes whose
displacement dofs it owns, so every node is evaluated exactly once and a
point–obstacle term needs no communication but the reductions of its sums.

The dofs are local indices into the unknown's array (``u.x.array``, the same
indices as the owned part of a SNES vector), one per displacement component,
so the same code serves the displacement problem and the three-field
:math:`(u, p, \theta)` problem (whose displacement is the first block).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from dolfinx import fem
from dolfinx import mesh as dmesh

from hyperfem.errors import ParameterError
from hyperfem.mesh.domain import Domain
from hyperfem.problem.protocol import SolidProblem

__all__ = ["BoundaryNodes", "boundary_nodes", "facet_size"]


@dataclass(frozen=True)
class BoundaryNodes:
    """The owned displacement nodes of a boundary group.

    Attributes:
        boundary: The group's name.
        dofs: Local dofs, shape ``(m, gdim)``: row ``k`` holds the components of node ``k``.
        X: Reference coordinates of the nodes, shape ``(m, gdim)``.
        total: Number of nodes over all ranks.
    """

    boundary: str
    dofs: np.ndarray
    X: np.ndarray
    total: int

    def positions(self, u: np.ndarray) -> np.ndarray:
        """Current positions :math:`X + u` of the nodes, for the unknown's local array ``u`` (or a SNES vector's)."""
        return self.X + u[self.dofs]


def boundary_nodes(problem: SolidProblem, boundary: str) -> BoundaryNodes:
    """The owned displacement nodes of ``boundary`` (collective).

    Raises:
        UnknownGroupError: No boundary group of that name (the message lists those that exist).
        ParameterError: The group has no facets on any rank.
    """
    domain = problem.domain
    facets = domain.facets(boundary)
    fdim = domain.tdim - 1
    domain.mesh.topology.create_connectivity(fdim, domain.tdim)
    W = problem.u.function_space
    owned = W.dofmap.index_map.size_local * W.dofmap.index_map_bs
    V = problem.displacement_space()
    gdim = domain.gdim
    columns, coordinates = [], []
    for i in range(gdim):
        sub = V.sub(i)
        collapsed = sub.collapse()[0]
        parent, local = fem.locate_dofs_topological((sub, collapsed), fdim, facets)
        X = collapsed.tabulate_dof_coordinates()[local, :gdim]
        # The same node has bitwise equal coordinates in every component's space: sorting matches them.
        order = np.lexsort(X.T[::-1])
        columns.append(parent[order])
        coordinates.append(X[order])
    for X in coordinates[1:]:
        if X.shape != coordinates[0].shape or not np.array_equal(X, coordinates[0]):
            raise ParameterError(f"contact on {boundary!r}: the displacement components have different nodes")
    dofs = np.stack(columns, axis=1).astype(np.int64) if columns[0].size else np.zeros((0, gdim), np.int64)
    mine = np.all(dofs < owned, axis=1)
    total = domain.comm.allreduce(int(mine.sum()), op=MPI.SUM)
    if total == 0:
        raise ParameterError(f"contact on {boundary!r}: the boundary group has no facets")
    return BoundaryNodes(boundary, dofs[mine], coordinates[0][mine], total)


def facet_size(domain: Domain, boundary: str) -> float:
    """The mean diameter of the owned facets of ``boundary`` in the reference configuration (collective)."""
    mesh = domain.mesh
    fdim = domain.tdim - 1
    facets = domain.facets(boundary)
    mesh.topology.create_connectivity(fdim, 0)
    facets = facets[facets < mesh.topology.index_map(fdim).size_local]
    total, count = 0.0, len(facets)
    if count:
        x = mesh.geometry.x[dmesh.entities_to_geometry(mesh, fdim, facets)]
        gaps = x[:, :, None, :] - x[:, None, :, :]
        total = float(np.sqrt((gaps**2).sum(axis=-1)).max(axis=(1, 2)).sum())
    total, count = domain.comm.allreduce(np.array([total, count], dtype=float), op=MPI.SUM)
    return float(total / count) if count else float("nan")
