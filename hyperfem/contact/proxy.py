r"""The collision proxy: finer linear triangles on a surface facet, their vertices interpolated from the facet's nodes.

The barrier of :mod:`~hyperfem.contact.mesh_barrier` acts on the vertices of
a linear collision mesh. On the nodes alone (``subdivision = 1``, the default
of P1 tetrahedra and of degree-1 edges in 2D) its vertices are the
displacement nodes themselves (:mod:`~hyperfem.contact.surface`): a P2 facet
is four linear triangles on its six nodes. Every vertex in contact then carries about the
same force, where the consistent nodal loads of a uniform pressure on a P2
triangle are 0 at the corners and a third of the load at each midside node
(the reason Abaqus has its modified C3D10M tetrahedron for contact): the
interface warps, and the stacked-block patch test misses the uniform pressure
by 3.3 % at h = (1, 0.6), converging only as O(h).

With ``subdivision`` :math:`s > 1` each facet is cut into a finer lattice of
linear triangles (a degree-:math:`k` facet edge into :math:`k s` segments),
whose vertices :math:`y_j = \sum_i N_i(\xi_j)\,x_i` follow the facet's own
shape functions :math:`N_i` (high-order IPC's collision proxy, Ferguson et
al. 2023): a sparse linear map :math:`y = W x`. The barrier and its
continuous collision detection act on :math:`y`; the gradient is
:math:`W^T g_y` and the Hessian :math:`W^T H_y W` (per component). A lattice
of equal vertex forces then integrates the pressure against each :math:`N_i`
by the lattice's piecewise-linear rule, which tends to the consistent loads
as :math:`s` grows. The proxy's triangles are what is kept
intersection-free; between its vertices the curved P2 surface can differ from
them by :math:`O(h^2/s^2)`.

A Q1 face has the same trouble in another form: its two triangles on the
four corners are not the bilinear face (they fold along a diagonal), and a
uniform pressure on them is not carried by the face's consistent loads
either.

Measured on the stacked-block patch test (``tests/test_contact_surfaces.py``,
the top reaction against :math:`|P_{zz}|`), on the nodes / :math:`s = 2`
(the default there, :func:`default_subdivision`) / :math:`s = 4`:

* P2 tetrahedra, h = (1, 0.6), 10 % compression: 3.3 % / 0.42 % / 0.14 %
  (P1 on the nodes: 0.031 %; with :math:`s = 2`: 0.019 %, not worth its
  cost, so P1 stays on the nodes); h = (0.5, 0.34): 1.08 % / 0.17 % / 0.048 %;
* Q2 hexahedra, h = (0.5, 1), 20 %: 5.9 % / 0.39 %;
* Q1 hexahedra, h = (1, 0.6), 10 %: 1.7 % / 0.015 % (the warp 11 / 1.3
  d-hat); h = (1/3, 1/2), 20 %: 0.006 % / 0.007 % (the warp 2.4 / 0.5 d-hat);
* 2D, P2 triangles / Q2 quadrilaterals: 2.2 % / 0.15 %, 3.0 % / 0.14 %
  (degree 1 on the nodes: 0.004 %, 0.002 %: a linear edge is its segment).

The interface's warp (the spread of the contact nodes' heights, 5 d-hat on
the nodes for P2) falls to below one d-hat. IPC's area weighting
(``NormalCollisions.use_area_weighting``, with the stiffness rescaled)
changed none of these warps (tried). The proxy has about :math:`s^2` times
the vertices of the nodes (a P2 triangle: 8 vertices and 16 triangles at
:math:`s = 2`, against 2 and 4), and ``ipctk``'s costs grow with it; the
solve times of these tests did not change (0.9 s at h = (1, 0.6) either
way). The default stiffness is scaled by nodes per vertex
(:func:`~hyperfem.contact.bodies.surface_defaults`), so that a pressure
gives the same gap with or without the proxy.

Ties (:mod:`~hyperfem.contact.tie`) go through the same proxy: its points are
tied to the other group's proxy triangles, and the glued P2/Q1/Q2 patch test
passes to 2e-10–6e-10 (on the nodes 0.074–3.7 % off).

Lattice points on a facet edge or corner are shared with the neighbouring
facets (found by their rows of :math:`W`), so the proxy is a closed
surface wherever the facets are. Its vertices are ordered by their rest
positions: the same on any number of ranks.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["DEFAULT_SUBDIVISION", "collision_proxy", "default_subdivision", "reference_lattice"]

DEFAULT_SUBDIVISION = 2
"""The proxy of a surface whose facets are not linear triangles or segments, by default (module docstring)."""


def default_subdivision(facet: str, degree: int) -> int:
    """:data:`DEFAULT_SUBDIVISION` for degree-2 facets and quadrilateral faces (Q1 too), else 1 (on the nodes).

    Args:
        facet: ``"triangle"``, ``"quadrilateral"`` or ``"interval"`` (:func:`reference_lattice`).
        degree: The displacement's degree.
    """
    return DEFAULT_SUBDIVISION if degree == 2 or facet == "quadrilateral" else 1


_EXACT = 2**30  # weights are compared on this grid (the lattice's are dyadic or rational with small denominators)


def _interval(k: int, t: np.ndarray) -> np.ndarray:
    """1D Lagrange shape functions at ``t``: degree 1 ``[1 - t, t]``, degree 2 ``[end 0, end 1, middle]``."""
    if k == 1:
        return np.stack([1.0 - t, t], axis=1)
    return np.stack([(1.0 - t) * (1.0 - 2.0 * t), t * (2.0 * t - 1.0), 4.0 * t * (1.0 - t)], axis=1)


def _triangle_points(n: int) -> list[tuple[int, int]]:
    """The lattice points :math:`(i, j)`, :math:`i + j \\le n`, of a triangle cut into :math:`n^2`, row by row."""
    return [(i, j) for j in range(n + 1) for i in range(n + 1 - j)]


def reference_lattice(facet: str, degree: int, resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """The lattice of a reference facet: the nodes' shape values at its points and its linear sub-facets.

    Node orders (as :mod:`~hyperfem.contact.surface` lists a facet's nodes):

    * ``"triangle"``: ``[v0, v1, v2]``, degree 2 ``+ [m01, m12, m02]``;
    * ``"quadrilateral"`` (vertices at (0, 0), (1, 0), (0, 1), (1, 1)): ``[a, b, c, d]``, degree 2
      ``+ [m_ab, m_ac, centre, m_bd, m_cd]``;
    * ``"interval"``: ``[a, b]``, degree 2 ``+ [middle]``.

    Args:
        facet: ``"triangle"``, ``"quadrilateral"`` or ``"interval"``.
        degree: 1 or 2.
        resolution: Segments per facet edge, :math:`n \\ge 1`.

    Returns:
        ``(S, sub)``: shape values ``(p, m)`` at the ``p`` lattice points, and the sub-facets ``(t, 3)``
        (``(t, 2)`` on an interval) as lattice point indices.
    """
    n = int(resolution)
    if facet == "interval":
        t = np.arange(n + 1) / n
        return _interval(degree, t), np.stack([np.arange(n), np.arange(1, n + 1)], axis=1)
    if facet == "quadrilateral":
        t = np.arange(n + 1) / n
        index = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)  # [j, i]: the point (t_i, t_j)
        s_values, t_values = _interval(degree, t), _interval(degree, t)
        if degree == 1:
            S = np.einsum("ia,jb->jiab", s_values, t_values)[..., [0, 1, 0, 1], [0, 0, 1, 1]]
        else:  # [a, b, c, d, ab, ac, centre, bd, cd]: (s node, t node) with 0, 1 the ends and 2 the middle
            pairs = [(0, 0), (1, 0), (0, 1), (1, 1), (2, 0), (0, 2), (2, 2), (1, 2), (2, 1)]
            S = np.stack([np.einsum("i,j->ji", s_values[:, a], t_values[:, b]) for a, b in pairs], axis=-1)
        p, q, r, w = index[:-1, :-1], index[:-1, 1:], index[1:, :-1], index[1:, 1:]
        sub = np.concatenate([np.stack([p, q, w], -1).reshape(-1, 3), np.stack([p, w, r], -1).reshape(-1, 3)])
        return S.reshape(-1, S.shape[-1]), sub
    points = _triangle_points(n)
    where = {ij: k for k, ij in enumerate(points)}
    xi = np.array(points, dtype=float) / n
    lam = np.stack([1.0 - xi[:, 0] - xi[:, 1], xi[:, 0], xi[:, 1]], axis=1)
    if degree == 1:
        S = lam
    else:
        corners = lam * (2.0 * lam - 1.0)
        S = np.concatenate([corners, 4.0 * lam[:, [0, 1, 0]] * lam[:, [1, 2, 2]]], axis=1)
    triangles: list[list[int]] = []
    for (i, j), k in where.items():
        if i + j < n:
            triangles.append([k, where[(i + 1, j)], where[(i, j + 1)]])
        if i + j < n - 1:
            triangles.append([where[(i + 1, j)], where[(i + 1, j + 1)], where[(i, j + 1)]])
    return S, np.asarray(triangles, dtype=np.int64)


def _on_facet_boundary(facet: str, resolution: int) -> np.ndarray:
    """Which points of :func:`reference_lattice`'s lattice lie on the facet's edges or corners (on an interval: its
    ends)."""
    n = int(resolution)
    if facet == "interval":
        i = np.arange(n + 1)
        return (i == 0) | (i == n)
    if facet == "quadrilateral":
        j, i = np.divmod(np.arange((n + 1) ** 2), n + 1)
        return (i == 0) | (i == n) | (j == 0) | (j == n)
    points = np.array(_triangle_points(n))
    return (points[:, 0] == 0) | (points[:, 1] == 0) | (points.sum(axis=1) == n)


def collision_proxy(
    facets: np.ndarray, facet: str, degree: int, subdivision: int, X: np.ndarray
) -> tuple[sp.csr_matrix, np.ndarray]:
    """The proxy of a surface's facets: the map :math:`W` and the linear sub-facets (module docstring).

    The vertices are ordered by their rest positions and the sub-facets by their vertices, so that the
    collision mesh is the same whatever the numbering of the nodes (which depends on the number of ranks):
    ``ipctk`` breaks ties between equally close primitives by their order.

    Args:
        facets: Each facet's nodes, indices into the surface's nodes, shape ``(f, m)``, in the order of
            :func:`reference_lattice`.
        facet: The facet's shape (:func:`reference_lattice`).
        degree: The displacement's degree, 1 or 2.
        subdivision: :math:`s \\ge 1`: a facet edge gets ``degree * s`` segments.
        X: The surface nodes' rest positions, ``(n, d)`` (:math:`W` has ``n`` columns).

    Returns:
        ``(W, faces)``: ``W`` of shape ``(v, nodes)`` (rows: proxy vertices, partitions of unity), ``faces``
        the sub-facets as proxy vertex indices, ``(t, 3)`` or ``(t, 2)``.
    """
    n = degree * int(subdivision)
    S, sub = reference_lattice(facet, degree, n)
    f, m = facets.shape
    p = S.shape[0]
    # Points on a facet's edges and corners are shared with its neighbours: found by their rows of W (the sorted
    # nonzero (node, weight) pairs, at most 3: an edge's nodes). Interior points belong to their facet alone.
    edge = _on_facet_boundary(facet, n)
    shared, inner = np.flatnonzero(edge), np.flatnonzero(~edge)
    index = np.broadcast_to(facets[:, None, :], (f, len(shared), m)).reshape(-1, m)
    weight = np.broadcast_to(S[shared][None], (f, len(shared), m)).reshape(-1, m)
    zero = np.abs(weight) < 1e-12
    index = np.where(zero, -1, index)
    weight = np.where(zero, 0.0, weight)
    order = np.argsort(index, axis=1, kind="stable")
    width = min(m, 3)  # the nonzero pairs sort last
    index = np.take_along_axis(index, order, axis=1)[:, m - width :]
    weight = np.take_along_axis(weight, order, axis=1)[:, m - width :]
    key = np.concatenate([index, np.round(weight * _EXACT).astype(np.int64)], axis=1)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    rows, cols = np.nonzero(index[first] >= 0)
    inner_weight = np.broadcast_to(S[inner][None], (f, len(inner), m)).reshape(-1, m)
    inner_rows, inner_cols = np.nonzero(np.abs(inner_weight) >= 1e-12)
    inner_index = np.broadcast_to(facets[:, None, :], (f, len(inner), m)).reshape(-1, m)
    W = sp.csr_matrix(
        (
            np.concatenate([weight[first][rows, cols], inner_weight[inner_rows, inner_cols]]),
            (np.concatenate([rows, len(first) + inner_rows]),
             np.concatenate([index[first][rows, cols], inner_index[inner_rows, inner_cols]])),
        ),
        shape=(len(first) + f * len(inner), len(X)),
    )
    vertex = np.empty((f, p), dtype=np.int64)
    vertex[:, shared] = inverse.reshape(f, len(shared))
    vertex[:, inner] = len(first) + np.arange(f * len(inner)).reshape(f, len(inner))
    faces = vertex[:, sub].reshape(-1, sub.shape[1])
    # Rank-independent order: vertices by rest position (rounded far below any mesh size), sub-facets rotated to
    # start at their smallest vertex (keeping their orientation), then sorted.
    Y = np.asarray(W @ X)
    scale = float(np.abs(Y).max()) or 1.0
    order = np.lexsort(np.round(Y / scale, 10).T[::-1])
    W = W[order]
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    faces = rank[faces]
    shift = np.argmin(faces, axis=1)
    width = faces.shape[1]
    faces = faces[np.arange(len(faces))[:, None], (shift[:, None] + np.arange(width)) % width]
    faces = faces[np.lexsort(faces.T[::-1])]
    return W.tocsr(), faces.astype(np.int32)
