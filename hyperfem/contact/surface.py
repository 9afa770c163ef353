r"""The collision surface of mesh–mesh contact: the boundary triangles of named groups, gathered on every rank.

Self-contact, two bodies and rigid triangulated tools need distances between
surface *primitives* (point–triangle, edge–edge), not only between nodes and
an analytic obstacle, and a primitive pair may join nodes that different
ranks own. The IPC Toolkit (``ipctk``) has no MPI, so this first version
gathers the boundary surface to every rank (:func:`contact_surface`, once, at
binding) and the surface displacement at every evaluation
(:meth:`ContactSurface.positions`, one ``allgather`` of the owned surface
nodes): every rank then evaluates the whole barrier redundantly and keeps the
rows of the nodes it owns. Cost per evaluation: :math:`O(n_s)` communication
and :math:`O(n_s \log n_s)` broad phase on every rank, :math:`n_s` the surface
nodes: fine to :math:`10^4`–:math:`10^5` surface nodes, not beyond. The
scalable alternative is a halo exchange: each rank keeps its own surface plus
the part of the others' within its bounding box inflated by the largest
displacement of a step and :math:`\hat d`, rebuilt when a node leaves it.

The surface of a P1 displacement is its boundary triangles; a P2 boundary
triangle is split into four linear sub-triangles on its six nodes (vertices
and edge midpoints), so every displacement node of the boundary is a vertex
of these triangles (:attr:`ContactSurface.faces`). On hexahedra a Q1
face is split into two triangles and a Q2 face into eight on its nine nodes
(corners, edge midpoints, centre).

In 2D (plane strain, triangles or quadrilaterals) the boundary is made of
edges: the collision mesh is segments (``ipctk``'s 2D collision mesh: no
faces, edge–vertex pairs), a degree-1 edge one segment, a degree-2 edge two
segments through its midpoint node. Other cells are refused in one line.

Those triangles and segments on the nodes are :attr:`ContactSurface.faces`.
The barrier acts on them for P1 tetrahedra and degree-1 edges; for degree 2
and hexahedra, by default, on the finer collision proxy of
:mod:`~hyperfem.contact.proxy` (``subdivision``), whose vertices follow the
facets' shape functions: on the nodes alone a uniform pressure is not carried
(a uniform pressure's consistent loads differ between a quadratic facet's
nodes, none at a P2 triangle's corners; a Q1 face's two triangles are not
the bilinear face).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import basix
import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from dolfinx import fem

from hyperfem.contact.proxy import collision_proxy, default_subdivision
from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import SolidProblem

__all__ = ["ContactSurface", "contact_surface", "global_dofs"]


@dataclass(frozen=True)
class ContactSurface:
    """A boundary surface of the displacement, gathered on every rank (module docstring).

    Attributes:
        boundaries: The boundary groups it is made of.
        X: Reference positions of the surface nodes, shape ``(n, d)`` (``d`` the mesh's dimension, 2 or 3), the
            same on every rank.
        faces: The linear triangles ``(f, 3)`` (in 2D segments ``(f, 2)``) on the nodes, indices into :attr:`X`:
            the collision mesh's facets where there is no proxy (:attr:`collision_faces`).
        group: Index into :attr:`boundaries` of each node's (first) group, shape ``(n,)``.
        global_dofs: The global (PETSc) dofs of each node's components, shape ``(n, d)``.
        constrained: Whether each component is a Dirichlet dof, shape ``(n, d)``.
        rows: This rank's owned nodes: indices into :attr:`X`.
        dofs: Their local dofs in the unknown's array, shape ``(len(rows), d)``.
        comm: The communicator.
        proxy_map: The collision proxy's map :math:`W` from the nodes to its vertices, shape ``(v, n)``
            (:mod:`~hyperfem.contact.proxy`); ``None``: the collision mesh's vertices are the nodes.
        proxy_faces: The proxy's facets, indices into its vertices (``None`` without a proxy).
    """

    boundaries: tuple[str, ...]
    X: np.ndarray
    faces: np.ndarray
    group: np.ndarray
    global_dofs: np.ndarray
    constrained: np.ndarray
    rows: np.ndarray
    dofs: np.ndarray
    comm: MPI.Comm
    proxy_map: sp.csr_matrix | None = None
    proxy_faces: np.ndarray | None = None

    @property
    def size(self) -> int:
        """The number of surface nodes."""
        return len(self.X)

    @property
    def dim(self) -> int:
        """The number of components of a node, 2 or 3."""
        return int(self.X.shape[1])

    def displacements(self, u: np.ndarray) -> np.ndarray:
        """The displacement of every surface node, shape ``(n, d)``, from the unknown's local array (collective)."""
        parts = self.comm.allgather((self.rows, u[self.dofs]))
        out = np.empty_like(self.X)
        for rows, values in parts:
            out[rows] = values
        return out

    def positions(self, u: np.ndarray) -> np.ndarray:
        """Current positions :math:`X + u` of every surface node, shape ``(n, d)`` (collective)."""
        return self.X + self.displacements(u)

    @property
    def collision_faces(self) -> np.ndarray:
        """The collision mesh's facets: the proxy's, or :attr:`faces`."""
        return self.faces if self.proxy_faces is None else self.proxy_faces

    @property
    def collision_size(self) -> int:
        """The number of collision-mesh vertices: the proxy's, or the nodes."""
        return self.size if self.proxy_map is None else int(self.proxy_map.shape[0])

    def to_collision(self, values: np.ndarray) -> np.ndarray:
        """Node values ``(n, d)`` (positions, displacements) at the collision mesh's vertices, ``(v, d)``."""
        return values if self.proxy_map is None else np.asarray(self.proxy_map @ values)

    def collision_nodes(self, vertices: Sequence[int] | np.ndarray) -> np.ndarray:
        """The nodes whose shape functions make up the given collision-mesh vertices (themselves without a proxy)."""
        index = np.asarray(vertices, dtype=np.int64).reshape(-1)
        if self.proxy_map is None:
            return np.unique(index)
        return np.unique(self.proxy_map[index].indices).astype(np.int64)

    def owned_vertices(self) -> np.ndarray:
        """The collision-mesh vertices made up of (at least one of) this rank's owned nodes."""
        if self.proxy_map is None:
            return np.asarray(self.rows, dtype=np.int64)
        return np.unique(self.proxy_map[:, self.rows].nonzero()[0]).astype(np.int64)


def global_dofs(problem: SolidProblem) -> np.ndarray:
    """The global (PETSc) index of every local entry of the unknown's array (owned, then ghosts)."""
    W = problem.u.function_space
    index_map, bs = W.dofmap.index_map, W.dofmap.index_map_bs
    blocks = index_map.local_to_global(np.arange(index_map.size_local + index_map.num_ghosts, dtype=np.int32))
    return (blocks[:, None] * bs + np.arange(bs)).ravel().astype(np.int64)


def _facet_node_grid(topology: list, cell_type: str, local: int, node: Callable[[int, int], int]) -> list[list[int]]:
    """The nodes of a degree-2 facet, ``node(dim, entity)`` the node of a cell-local entity.

    A triangle: ``[[v0, v1, v2], [m01, m12, m02]]``; a quadrilateral (vertices a, b, c, d in basix order):
    ``[[a, b], [c, d], [m_ab, m_ac, centre, m_bd, m_cd]]``.
    """
    vertices = list(topology[2][local])
    edges = [set(e) for e in topology[1]]

    def mid(a: int, b: int) -> int:
        return node(1, edges.index({a, b}))

    if cell_type == "tetrahedron":
        a, b, c = vertices
        return [[node(0, a), node(0, b), node(0, c)], [mid(a, b), mid(b, c), mid(a, c)]]
    a, b, c, d = vertices  # basix: (0, 0), (1, 0), (0, 1), (1, 1) of the face
    corners = [[node(0, a), node(0, b)], [node(0, c), node(0, d)]]
    return corners + [[mid(a, b), mid(a, c), node(2, local), mid(b, d), mid(c, d)]]


def _triangles(cell_type: str, vertices: list[int], grid: list[list[int]] | None) -> list[list[int]]:
    """Linear triangles on a facet's nodes, every node a vertex: the vertices (degree 1) or the grid (degree 2)."""
    if grid is None:
        if cell_type == "tetrahedron":
            return [vertices]
        a, b, c, d = vertices  # basix: (0, 0), (1, 0), (0, 1), (1, 1) of the face
        return [[a, b, d], [a, d, c]]
    if cell_type == "tetrahedron":
        (v0, v1, v2), (m01, m12, m02) = grid
        return [[v0, m01, m02], [v1, m12, m01], [v2, m02, m12], [m01, m12, m02]]
    (a, b), (c, d), (ab, ac, centre, bd, cd) = grid
    rows = [[a, ab, b], [ac, centre, bd], [c, cd, d]]  # the 3 x 3 nodes of a Q2 face, two triangles per quarter
    out = []
    for i in range(2):
        for j in range(2):
            p, q, r, t = rows[i][j], rows[i][j + 1], rows[i + 1][j], rows[i + 1][j + 1]
            out += [[p, q, t], [p, t, r]]
    return out


def _segments(vertices: list[int], middle: int | None) -> list[list[int]]:
    """The segments of a 2D boundary edge: the edge (degree 1), or its two halves through the midpoint node."""
    a, b = vertices
    return [[a, b]] if middle is None else [[a, middle], [middle, b]]


def _facet_triangles(
    problem: SolidProblem, boundary: str, parents: list[np.ndarray], spaces: list
) -> tuple[np.ndarray, np.ndarray]:
    """The linear triangles (3D) or segments (2D) of this rank's owned facets of ``boundary``, and the facets' nodes.

    Tetrahedra: a P1 facet is one triangle, a P2 facet four on its six nodes. Hexahedra: a Q1 face is two
    triangles, a Q2 face eight on its nine nodes. Triangles and quadrilaterals: a degree-1 edge is one segment, a
    degree-2 edge two. Every displacement node of the facet is a vertex.

    Returns:
        ``(triangles, nodes)``: local dofs of the x component, ``(t, 3)`` or ``(t, 2)``, and each facet's nodes
        ``(f, m)`` in the order of :func:`~hyperfem.contact.proxy.reference_lattice`.
    """
    domain = problem.domain
    mesh = domain.mesh
    tdim = domain.tdim
    fdim = tdim - 1
    facets = domain.facets(boundary)
    facets = facets[facets < mesh.topology.index_map(fdim).size_local]
    mesh.topology.create_connectivity(fdim, tdim)
    mesh.topology.create_connectivity(tdim, fdim)
    f2c = mesh.topology.connectivity(fdim, tdim)
    c2f = mesh.topology.connectivity(tdim, fdim)
    V = spaces[0]
    layout = V.dofmap.dof_layout
    degree = V.element.basix_element.degree
    cell_type = mesh.topology.cell_name()
    topology = basix.topology(basix.CellType[cell_type])
    out, lists = [], []
    for facet in facets:
        cell = int(f2c.links(facet)[0])
        local = int(np.flatnonzero(c2f.links(cell) == facet)[0])
        cell_dofs = V.dofmap.cell_dofs(cell)

        def node(dim: int, entity: int, cell_dofs: np.ndarray = cell_dofs) -> int:
            return int(parents[0][cell_dofs[layout.entity_dofs(dim, entity)[0]]])

        vertices = [node(0, v) for v in topology[fdim][local]]
        if tdim == 2:
            middle = node(1, local) if degree == 2 else None
            out += _segments(vertices, middle)
            lists.append(vertices + ([] if middle is None else [middle]))
            continue
        grid = _facet_node_grid(topology, cell_type, local, node) if degree == 2 else None
        out += _triangles(cell_type, vertices, grid)
        lists.append(vertices if grid is None else [v for row in grid for v in row])
    width = (degree + 1) ** fdim if tdim == 2 or cell_type == "hexahedron" else (3 if degree == 1 else 6)
    return np.asarray(out, dtype=np.int64).reshape(-1, tdim), np.asarray(lists, dtype=np.int64).reshape(-1, width)


def contact_surface(
    problem: SolidProblem, boundaries: Sequence[str], where: str, subdivision: int | None = None
) -> ContactSurface:
    """The collision surface of ``boundaries`` on every rank (collective; module docstring).

    Args:
        problem: The problem (its displacement space: degree 1 or 2 on tetrahedra or hexahedra, or in 2D on
            triangles or quadrilaterals).
        boundaries: Boundary group names.
        where: The contact, for messages.
        subdivision: 1: the collision mesh is the facets' linear triangles on the nodes; :math:`s > 1`: the finer
            proxy of :mod:`~hyperfem.contact.proxy` (a facet edge cut into ``degree * s`` segments); ``None``:
            :func:`~hyperfem.contact.proxy.default_subdivision` (2 for degree 2 and hexahedra, else 1).

    Raises:
        UnknownGroupError: A group does not exist (the message lists those that do).
        ParameterError: Not a 3D mesh of tetrahedra or hexahedra or a 2D mesh of triangles or quadrilaterals, a
            degree other than 1 or 2, or no facets.
    """
    domain = problem.domain
    comm = domain.comm
    for name in boundaries:
        domain.facet_tag(name)  # UnknownGroupError listing the groups, on every rank
    cell = domain.mesh.topology.cell_name()
    supported = {2: ("triangle", "quadrilateral"), 3: ("tetrahedron", "hexahedron")}
    gdim = domain.gdim
    if cell not in supported.get(gdim, ()) or domain.tdim != gdim:
        raise ParameterError(
            f"{where}: mesh contact needs a 3D mesh of tetrahedra or hexahedra or a 2D mesh of triangles or "
            f"quadrilaterals, got {gdim}D {cell} cells"
        )
    V = problem.displacement_space()
    subs = [V.sub(i).collapse() for i in range(gdim)]
    spaces = [s[0] for s in subs]
    parents = [np.asarray(s[1], dtype=np.int64).reshape(-1) for s in subs]  # 0.11: a list of one array
    degree = spaces[0].element.basix_element.degree
    if degree not in (1, 2):
        raise ParameterError(f"{where}: mesh contact supports displacement degree 1 or 2, got {degree}")
    # The local dofs of the other components of a node: the collapsed spaces share one layout.
    to_component = [np.full(problem.u.x.array.size, -1, dtype=np.int64) for _ in range(gdim)]
    for i in range(gdim):
        to_component[i][parents[0]] = parents[i]
    gdofs = global_dofs(problem)
    W = problem.u.function_space
    owned = W.dofmap.index_map.size_local * W.dofmap.index_map_bs
    constrained = np.zeros(problem.u.x.array.size, dtype=bool)
    for bc in problem.bcs:
        constrained[bc.dof_indices()[0]] = True

    triangles, lists, nodes = [], [], {}
    for k, name in enumerate(boundaries):
        tri, facet_nodes = _facet_triangles(problem, name, parents, spaces)
        triangles.append(gdofs[tri])
        lists.append(gdofs[facet_nodes])
        # The owned nodes of the group's facets (every facet's nodes, on the rank that owns each).
        fdim = domain.tdim - 1
        x_dofs = fem.locate_dofs_topological((V.sub(0), spaces[0]), fdim, domain.facets(name))[0]
        for d in np.asarray(x_dofs, dtype=np.int64):
            if d < owned and int(gdofs[d]) not in nodes:
                nodes[int(gdofs[d])] = (k, d)
    coordinates = spaces[0].tabulate_dof_coordinates()
    inverse = np.full(problem.u.x.array.size, -1, dtype=np.int64)
    inverse[parents[0]] = np.arange(len(parents[0]))
    mine = []
    for key, (k, d) in nodes.items():
        comps = [int(to_component[i][d]) for i in range(gdim)]
        mine.append((key, k, comps, [int(gdofs[c]) for c in comps], [bool(constrained[c]) for c in comps],
                     coordinates[inverse[d], :gdim].tolist()))
    gathered = comm.allgather(mine)
    faces_all = np.concatenate(comm.allgather(np.concatenate(triangles) if triangles else np.zeros((0, gdim))))
    every = sorted((item for part in gathered for item in part), key=lambda item: item[0])
    keys = np.array([item[0] for item in every], dtype=np.int64)
    if not len(keys) or not len(faces_all):
        raise ParameterError(f"{where}: the boundary groups {list(boundaries)} have no facets")
    X = np.array([item[5] for item in every], dtype=float).reshape(-1, gdim)
    group = np.array([item[1] for item in every], dtype=np.int32)
    gd = np.array([item[3] for item in every], dtype=np.int64).reshape(-1, gdim)
    fixed = np.array([item[4] for item in every], dtype=bool).reshape(-1, gdim)
    faces = np.searchsorted(keys, faces_all.astype(np.int64)).astype(np.int32)
    _, first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)  # a facet in two groups: once
    faces = faces[np.sort(first)]
    rank_keys = np.array([item[0] for item in mine], dtype=np.int64)
    rows = np.searchsorted(keys, rank_keys).astype(np.int64)
    dofs = np.array([item[2] for item in mine], dtype=np.int64).reshape(-1, gdim)
    proxy_map, proxy_faces = None, None
    shape = "interval" if gdim == 2 else ("triangle" if cell == "tetrahedron" else "quadrilateral")
    if subdivision is None:
        subdivision = default_subdivision(shape, degree)
    if subdivision > 1:
        facet_nodes = np.concatenate(comm.allgather(np.concatenate(lists)))
        facet_nodes = np.searchsorted(keys, facet_nodes)
        _, first = np.unique(np.sort(facet_nodes, axis=1), axis=0, return_index=True)  # a facet in two groups: once
        proxy_map, proxy_faces = collision_proxy(facet_nodes[np.sort(first)], shape, degree, subdivision, X)
    return ContactSurface(tuple(boundaries), X, faces, group, gd, fixed, rows, dofs, comm, proxy_map, proxy_faces)
