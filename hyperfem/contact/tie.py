r"""Gluing (tied contact, seed 003 §6.2): two boundary groups with non-matching meshes held together.

:class:`TieContact` names two boundary groups that face each other (coincide,
or lie within ``tolerance``), ``slave`` and ``master``. At binding, each node
:math:`a` of either group is projected onto the closest triangle of the
other group in the reference configuration: barycentric weights
:math:`\xi_{a,i}` of its vertices :math:`i`. The tie is the penalty energy

.. math::
    T(u) = \frac{k}{2}\sum_a \Bigl|u_a - \sum_i \xi_{a,i}\,u_i\Bigr|^2
         = \frac{k}{2}\,|B U|^2,

which keeps every node at its reference place on the other surface (a gap in
the reference configuration is kept, not closed). It is quadratic:
gradient :math:`k B^T B U`, Hessian :math:`k B^T B`, constant and positive
semi-definite, coupling nodes of the two bodies (added through
``coupled_hessian`` like the contact barrier's).

**Two passes** (both groups' nodes tied, Taylor & Papadopoulos 1991): with
one pass (slave nodes only) the surfaces may part between the slave nodes,
which lowers the energy of a patch test below the homogeneous state:
measured on two cubes of non-matching meshes pulled 20 % apart, one pass
gives the uniaxial stress 0.22 % off with a wavy interface, two passes the
closed form to 6e-9.

**P2, Q1 and Q2 groups** are tied through the collision proxy of
:mod:`~hyperfem.contact.proxy`, as for contact by default: its points
:math:`y = Wx`, each tied to the other group's proxy triangles, give the rows
:math:`B_y W`. On the nodes alone (a P2 facet four linear triangles, a Q1
face two) the patch test below missed the uniaxial stress by 0.43 % (P2
tetrahedra), 0.074 % (Q1) and 3.7 % (Q2): a node tied to the other group's
linear sub-triangles cannot follow its curved (or bilinear) face, and the
consistent loads of a uniform traction are not carried. Through the proxy
(a facet edge in 4 segments for degree 2, 2 for Q1) the tied points pin the
faces to each other and the test passes to 2e-10–6e-10
(``tests/test_contact_tie.py``).

**2D** (triangles and quadrilaterals, degree 1 and 2): the groups are edges,
each node is tied to the closest point of the other group's segments
(:func:`closest_on_segments`; a P2 edge is two segments on its three nodes).
The patch test (``tests/test_contact_2d.py``: two non-matching squares 5e-4
apart, glued and pulled 20 %) gives the closed-form plane-strain stress to
4e-9 on P1 and Q1. On P2 edges through the proxy it does to 2e-10 and 3e-10 (on the
nodes alone 2.3e-4 and 2.5e-4 off: the tie's forces acted through the linear
sub-segments, which cannot reproduce the consistent loads (1, 4, 1)/6 of a
uniform traction on non-matching P2 edges).

The penalty :math:`k` = :data:`TIE_FACTOR` times the mean tangent diagonal at
the tied nodes by default: the tie then yields by about :math:`10^{-8}` of
the displacement the elements alone would take, so a conforming interface
tied this way reproduces the merged mesh to about :math:`10^{-8}`. That is
meant for direct solvers (MUMPS, the default below :math:`10^5` unknowns);
with an iterative solver choose a smaller ``stiffness`` (the tie's error
grows as :math:`1/k`).

**Generalized-**:math:`\alpha`: the tie is an elastic term, and its force is
taken as the internal forces are, between the ends of the step,
:math:`(1-\alpha_f)f_T(u_{n+1}) + \alpha_f f_T(u_n)` (:class:`~hyperfem.contact.ForceInterpolation`),
which for the linear :math:`f_T = kB^TBU` is exactly :math:`f_T(u_{n+1-\alpha_f})`.
Taken at :math:`u_{n+1}` alone it balanced the internal forces of
:math:`u_{n+1-\alpha_f}`: measured on the conforming split bar of
``tests/test_contact_tie.py`` (light, :math:`\rho = 10^{-4}`, pulled over
:math:`t \in [0, 1]`, :math:`\rho_\infty = 0.8`, ``benchmarks/contact_tie_alpha.py``),
the final tie force was 2.2 % below the quasi-static one at :math:`\Delta t = 0.05`
and 4.4 % at 0.1 (:math:`\alpha_f` times a step's pull behind); interpolated,
-0.04 % and +0.14 %. With a soft tie (:math:`k = 0.1`) the cut's opening
itself was 1.4 % (2.8 %) short of the quasi-static one, interpolated +0.01 %
(+0.13 %). The displacements of a stiff tie hardly change (the tie force is
then a multiplier: the interface nodes' balance holds either way), only the
force it reports. A checkpoint holds the frozen force, as for contact.

MPI: both groups are gathered to every rank (:mod:`~hyperfem.contact.surface`)
and :math:`B` built there once; each rank keeps the rows of the nodes it owns.

Example::

    glue = hf.contact.TieContact("upper_bottom", "lower_top").bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[glue])
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from hyperfem.contact.defaults import mean_tangent_diagonal
from hyperfem.contact.interpolation import ForceInterpolation
from hyperfem.contact.surface import ContactSurface, contact_surface
from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import SolidProblem
from hyperfem.validation import check_name, check_positive

__all__ = ["TIE_FACTOR", "TieBarrier", "TieContact", "closest_on_segments", "closest_on_triangles"]

TIE_FACTOR = 1e8
r"""The tie's penalty by default: this factor times the mean tangent diagonal at the tied nodes."""


def _closest_in_chunks(
    points: np.ndarray, facets: np.ndarray, candidates: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closest facet of each point, all points against all facets in chunks of about 10^6 pairs.

    ``candidates(p)`` gives, for points ``p`` of shape ``(c, 1, d)``, the weights ``(c, f, k)`` of the closest
    point on each facet and its distance ``(c, f)``.
    """
    index = np.zeros(len(points), dtype=np.int64)
    weights = np.zeros((len(points), facets.shape[1]))
    distance = np.full(len(points), np.inf)
    chunk = max(1, 1_000_000 // max(1, len(facets)))
    for start in range(0, len(points), chunk):
        w, d = candidates(points[start : start + chunk][:, None, :])
        k = d.argmin(axis=1)
        rows = np.arange(len(k))
        index[start : start + chunk] = k
        weights[start : start + chunk] = w[rows, k]
        distance[start : start + chunk] = d[rows, k]
    return index, weights, distance


def closest_on_triangles(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closest triangle of each point and the barycentric weights of the closest point on it.

    Exact point–triangle distances (the projection onto the plane where it falls
    inside, else the closest point of the three edges), all points against
    all triangles in chunks.

    Args:
        points: Shape ``(m, 3)``.
        triangles: Corner positions, shape ``(f, 3, 3)``.

    Returns:
        The triangle index ``(m,)``, the weights ``(m, 3)`` and the distance ``(m,)``.
    """
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]

    def candidates(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        options = [_plane_weights(p, a, b, c)]
        for i, j in ((0, 1), (1, 2), (0, 2)):
            corners = (a, b, c)
            s = _segment_parameter(p, corners[i], corners[j])
            w = np.zeros(s.shape + (3,))
            w[..., i], w[..., j] = 1.0 - s, s
            options.append(w)
        best_w = np.zeros(options[0].shape)
        best_d = np.full(options[0].shape[:-1], np.inf)
        for w in options:
            q = w[..., 0:1] * a + w[..., 1:2] * b + w[..., 2:3] * c
            d = np.linalg.norm(p - q, axis=-1)
            better = d < best_d  # NaN (a projection outside its triangle) is never better
            best_w = np.where(better[..., None], w, best_w)
            best_d = np.where(better, d, best_d)
        return best_w, best_d

    return _closest_in_chunks(points, triangles, candidates)


def closest_on_segments(points: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closest segment of each point and the weights of the closest point on it (2D ties).

    Args:
        points: Shape ``(m, 2)``.
        segments: End positions, shape ``(f, 2, 2)``.

    Returns:
        The segment index ``(m,)``, the weights ``(m, 2)`` and the distance ``(m,)``.
    """
    a, b = segments[:, 0], segments[:, 1]

    def candidates(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = _segment_parameter(p, a, b)
        d = np.linalg.norm(p - (a + t[..., None] * (b - a)), axis=-1)
        return np.stack([1.0 - t, t], axis=-1), d

    return _closest_in_chunks(points, segments, candidates)


def _plane_weights(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric weights of the projection of ``p`` on each triangle's plane; NaN where it falls outside."""
    e1, e2, d = b - a, c - a, p - a
    d11, d12, d22 = (e1 * e1).sum(-1), (e1 * e2).sum(-1), (e2 * e2).sum(-1)
    r1, r2 = (d * e1).sum(-1), (d * e2).sum(-1)
    det = d11 * d22 - d12 * d12
    det = np.where(det > 0.0, det, np.nan)
    v = (d22 * r1 - d12 * r2) / det
    w = (d11 * r2 - d12 * r1) / det
    u = 1.0 - v - w
    out = np.stack([u, v, w], axis=-1)
    inside = (u >= 0.0) & (v >= 0.0) & (w >= 0.0)
    return np.where(inside[..., None], out, np.nan)


def _segment_parameter(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The parameter in [0, 1] of the closest point of segment ``a b`` to ``p``."""
    e = b - a
    length = np.maximum((e * e).sum(-1), 1e-300)
    return np.clip(((p - a) * e).sum(-1) / length, 0.0, 1.0)


@dataclass(frozen=True)
class TieContact:
    r"""Glue two boundary groups together with a two-pass penalty tie (module docstring).

    Attributes:
        slave: One group (its force is the ``<name>_force`` output).
        master: The other group.
        stiffness: The penalty :math:`k > 0` (``None``: :data:`TIE_FACTOR` times the mean tangent diagonal).
        tolerance: The largest reference distance of a node of one group from the other group's triangles
            (``None``: 1 % of the mean edge of their triangles; a node farther away: the groups do not face).
        name: Prefix of the output columns (``tie_force``: the force on the slave group).

    Raises:
        ParameterError: A bad entry (one line).
    """

    slave: str
    master: str
    stiffness: float | None = None
    tolerance: float | None = None
    name: str = "tie"

    def __post_init__(self) -> None:
        where = f"TieContact {self.slave!r} to {self.master!r}"
        check_name(self.slave, "slave", "TieContact")
        check_name(self.master, "master", "TieContact")
        if self.slave == self.master:
            raise ParameterError(f"{where}: slave and master must be different groups")
        for key in ("stiffness", "tolerance"):
            value = getattr(self, key)
            if value is not None:
                check_positive(key, value, where)
        check_name(self.name, "name", where)

    @property
    def where(self) -> str:
        """The tie, for messages."""
        return f"TieContact {self.slave!r} to {self.master!r}"

    def bind(self, problem: SolidProblem) -> TieBarrier:
        """The tie on ``problem`` (collective).

        Raises:
            UnknownGroupError: A group does not exist (the message lists them).
            ParameterError: A node farther than ``tolerance`` from the other group's triangles (the groups do
                not face each other; the message gives the node and its distance).
        """
        return TieBarrier(self, problem)


class TieBarrier:
    r"""The tie energy :math:`T(u)` of a :class:`TieContact` on a problem: an ``ExternalEnergy`` (module docstring).

    Attributes:
        surface: Both groups, gathered (group 0: slave, 1: master).
        stiffness: :math:`k`.
        gaps: The reference distance of every tied node from the other group's triangles.
        step_filter: ``None`` (a tie needs none).
    """

    step_filter = None

    def __init__(self, contact: TieContact, problem: SolidProblem):
        self.contact = contact
        self.problem = problem
        self.comm = problem.domain.comm
        self.where = contact.where
        surface = contact_surface(problem, [contact.slave, contact.master], contact.where)
        self.surface: ContactSurface = surface
        X = surface.X
        sizes = np.linalg.norm(X[surface.faces][:, 1] - X[surface.faces][:, 0], axis=1)
        tolerance = contact.tolerance if contact.tolerance is not None else 0.01 * float(sizes.mean())
        self.dim = X.shape[1]
        # Two passes: the slave nodes on the master facets, and the master nodes on the slave facets.
        passes = [self._tie_rows(surface, 0, 1, tolerance), self._tie_rows(surface, 1, 0, tolerance)]
        self.gaps = np.concatenate([gaps for _, gaps in passes])
        B = sp.vstack([rows for rows, _ in passes]).tocsr()
        d = self.dim
        self._B = sp.kron(B, sp.identity(d), format="csr")
        self._global = surface.global_dofs.ravel()
        self._fixed = surface.constrained.ravel()
        own = np.zeros(d * surface.size, dtype=bool)
        own[(d * surface.rows[:, None] + np.arange(d)).ravel()] = True
        self._own = own
        if contact.stiffness is not None:
            self.stiffness = float(contact.stiffness)
        else:
            self.stiffness = TIE_FACTOR * mean_tangent_diagonal(problem, surface.dofs, np.full(d, 1.0 / d))
        H = (self.stiffness * (self._B.T @ self._B)).tocoo()
        keep = own[H.row] & ~self._fixed[H.row] & ~self._fixed[H.col] & (H.data != 0.0)
        self._hessian = (self._global[H.row[keep]], self._global[H.col[keep]], np.asarray(H.data[keep], dtype=float))
        self._interpolation = ForceInterpolation(problem, lambda u, t: self._own_gradient(u), self.comm)

    def _tie_rows(
        self, surface: ContactSurface, nodes: int, faces: int, tolerance: float
    ) -> tuple[sp.csr_matrix, np.ndarray]:
        """Rows of :math:`B` tying the nodes of group ``nodes`` to the facets of group ``faces``, and their gaps.

        The facets are triangles in 3D, segments in 2D.

        Raises:
            ParameterError: A node farther than ``tolerance`` from the facets (the groups do not face).
        """
        # The collision proxy's points and facets where the surface has one (y = W x; the tie rows B_y W).
        W = surface.proxy_map
        X = surface.to_collision(surface.X)
        group = surface.group if W is None else surface.group[W.indices[W.indptr[:-1]]]
        all_facets = surface.collision_faces
        tied = np.flatnonzero(group == nodes)
        facets = all_facets[np.all(group[all_facets] == faces, axis=1)]
        name = (self.contact.slave, self.contact.master)
        if not len(facets):
            kind = "triangles" if self.dim == 3 else "segments"
            raise ParameterError(f"{self.where}: the group {name[faces]!r} has no {kind} of its own")
        closest = closest_on_triangles if self.dim == 3 else closest_on_segments
        index, weights, distance = closest(X[tied], X[facets])
        if len(distance) and distance.max() > tolerance:
            k = int(distance.argmax())
            raise ParameterError(
                f"{self.where}: the point of {name[nodes]!r} at {tuple(float(f'{v:.6g}') for v in X[tied[k]])} is "
                f"{distance[k]:.3g} from {name[faces]!r} (tolerance {tolerance:.3g}): the groups do not face each other"
            )
        m = len(tied)
        rows = np.repeat(np.arange(m), 1 + facets.shape[1])
        cols = np.column_stack([tied, facets[index]]).ravel()
        vals = np.column_stack([np.ones(m), -weights]).ravel()
        B = sp.csr_matrix((vals, (rows, cols)), shape=(m, len(X)))
        return (B if W is None else (B @ W).tocsr()), distance

    # -- the ExternalEnergy contract ----------------------------------------
    def update(self, t: float) -> None:
        r"""Nothing moves with the time; at the start of a generalized-:math:`\alpha` step the tie force of the
        step's start state is taken (:mod:`~hyperfem.contact.interpolation`; collective)."""
        self._interpolation.begin()

    def _residuals(self, u: np.ndarray) -> np.ndarray:
        return self._B @ self.surface.displacements(u).ravel()

    def energy(self, u: np.ndarray) -> float:
        r"""Rank 0's :math:`\tfrac k2|BU|^2` (the whole tie; 0 on the other ranks).

        Interpolated during a generalized-:math:`\alpha` step (module docstring).
        """
        r = self._residuals(u)
        own = 0.5 * self.stiffness * float(r @ r) if self.comm.rank == 0 else 0.0
        return self._interpolation.energy(own, u)

    def _gradient_full(self, u: np.ndarray) -> np.ndarray:
        return self.stiffness * (self._B.T @ self._residuals(u))

    def _own_gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g = self._gradient_full(u).reshape(-1, self.dim)
        return self.surface.dofs, g[self.surface.rows]

    def gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`k B^T B U` at this rank's owned nodes: ``(dofs, values)``.

        Interpolated during a generalized-:math:`\alpha` step (module docstring).
        """
        return self._interpolation.gradient(*self._own_gradient(u))

    def hessian(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """No node blocks (the Hessian couples nodes: :meth:`coupled_hessian`)."""
        return self.surface.dofs[:0], np.zeros((0, self.dim, self.dim))

    def coupled_hessian(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r""":math:`k B^T B` in this rank's owned rows, Dirichlet rows and columns left out.

        Constant; times :math:`1-\alpha_f` in a generalized-:math:`\alpha` step.
        """
        weight = self._interpolation.weight
        rows, cols, values = self._hessian
        return rows, cols, values if weight == 1.0 else weight * values

    def state_functions(self) -> dict[str, Any]:
        r"""What a checkpoint holds: under generalized-:math:`\alpha` the frozen tie force of the accepted state."""
        return self._interpolation.state_functions()

    def restart(self, t: float) -> None:
        """The checkpoint's functions were read back: the state at the accepted time ``t``."""
        self._interpolation.restart(t)

    def admissible(self, u: np.ndarray) -> str:
        """Always admissible."""
        return ""

    # -- outputs ------------------------------------------------------------
    def force(self, u: np.ndarray | PETSc.Vec | None = None) -> np.ndarray:
        r"""The force the master side exerts on the slave group, :math:`-\sum_{a} \partial T/\partial u_a` (collective).

        Every rank must call it: the tie gathers the surface from all ranks, and
        a call from one rank alone waits for the others forever. The result is
        the same on every rank."""
        state = self.problem.u.x.array if u is None else (u.array_r if isinstance(u, PETSc.Vec) else u)
        g = self._gradient_full(state).reshape(-1, self.dim)
        return -g[self.surface.group == 0].sum(axis=0)

    def max_gap(self, u: np.ndarray | PETSc.Vec | None = None) -> float:
        """The largest distance of a slave node from its tied place on the master surface (collective)."""
        state = self.problem.u.x.array if u is None else (u.array_r if isinstance(u, PETSc.Vec) else u)
        r = self._residuals(state).reshape(-1, self.dim)
        return float(np.linalg.norm(r, axis=1).max()) if len(r) else 0.0

    def summary(self) -> dict[str, object]:
        """The summary's ``contact`` entry: type, groups, last force on the slave group, largest gap (collective)."""
        entry = {
            "type": "TieContact",
            "boundaries": [self.contact.slave, self.contact.master],
            "force": [float(v) for v in self.force()],
            "max_gap": self.max_gap(),
        }
        return {"contact": {self.contact.name: entry}}

    def record(self, step: object = None) -> dict[str, object]:
        """The output columns: ``<name>_force`` (on the slave group), ``<name>_max_gap`` (collective)."""
        name = self.contact.name
        return {f"{name}_force": [float(v) for v in self.force()], f"{name}_max_gap": self.max_gap()}
