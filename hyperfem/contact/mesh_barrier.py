r"""The IPC barrier between surface primitives (self-contact, two bodies, a rigid triangulated tool), from ``ipctk``.

For a collision mesh of surface triangles (:mod:`~hyperfem.contact.surface`,
plus the triangles of a rigid tool, if any), the barrier term is

.. math::
    \kappa B(x) = \kappa \sum_{k \in C(x)} b\bigl(d_k^2(x), \hat d^2\bigr),

summed over the primitive pairs :math:`k` (point–triangle, edge–edge and
their degenerate point–edge, point–point cases, edge–edge pairs mollified
where the edges are nearly parallel) closer than :math:`\hat d`, with the
IPC log barrier :math:`b` taken on *squared* distances as ``ipctk`` does
(``BarrierPotential``; the nodal barriers of the plane and sphere take
:math:`b(d, \hat d)`). Energy, gradient and the Hessian, projected onto the
positive semi-definite cone per pair (``PSDProjectionMethod.CLAMP``), all come
from ``ipctk``. The pair set :math:`C(x)` is rebuilt at every state the
solver evaluates, line-search trial states included, from the candidates of
a broad phase (``HashGrid``) with boxes inflated by :math:`\hat d`.

**2D** (plane strain): the collision mesh is the boundary segments
(:mod:`~hyperfem.contact.surface`), a tool a polyline, and the pairs are
edge–vertex (with their vertex–vertex cases); the rest is the same.

**Tangent.** A pair couples the nodes of different elements (of different
bodies), outside the finite-element sparsity pattern: the entries are added
to the tangent with PETSc allowed to allocate new nonzeros
(``MAT_NEW_NONZERO_ALLOCATION_ERR`` off;
:meth:`~hyperfem.solver.external.ExternalTerms.add_tangent`). The pattern
grows to the union of the pairs ever active and keeps its (zeroed) entries
when a pair separates; PETSc sees the changed nonzero state and redoes the
symbolic set-up of the preconditioner or factorisation. A matrix of its own
added with ``MatAXPY`` would re-merge the patterns at every iteration; a
pattern preallocated for every possible pair would be dense over the surface.

**Projection and Newton's rate.** The projected Hessian is not the
derivative of the gradient: with it Newton converges linearly (a rate of
0.74 per iteration seen on a sphere indenting a slab). The tangent is
therefore projected while the iterates still move (a vertex moved by more
than :math:`\hat d` since the last tangent) and exact once they settle, which
restores the quadratic rate at the end of a solve. An exact tangent can be
indefinite; where its Newton direction is not a descent direction of
:math:`\Pi`, the solver recomputes the direction with the projected tangent
(:meth:`MeshBarrier.project_tangent`, called from the line search's
pre-check, ``NewtonSolver._recover_direction``, which also does so when the
tangent stops CG), and the tangent stays projected
until the iterates settle again. Projecting for the rest of the solve
instead stalled the sphere indenting a finer slab (10 x 10 x 5 boxes:
``DIVERGED_MAX_IT``, the residual growing while :math:`\Pi` fell); with the
rule above it reaches half the slab's thickness at 10 x 10 x 5 and
14 x 14 x 7 boxes, and at :math:`\hat d` from 1e-3 to 5e-3.

**Friction** (``friction`` :math:`\mu > 0`): smoothed Coulomb friction, lagged
per step as in IPC, from ``ipctk``: at every accepted state (:meth:`MeshBarrier.lag`)
the active pairs become ``TangentialCollisions`` with their normal force
magnitudes and tangent bases, fixed during the next step; the dissipative
potential :math:`D` of ``FrictionPotential`` (its :math:`\epsilon_v` our slip
length ``friction_epsilon``) is evaluated on the vertices' displacement since
the lag, the tool's motion included (the relative slip), and added to the
energy, gradient and (projected) Hessian. Checked: a block on a rough plate
pushed by half :math:`\mu N` holds it to 1e-8, dragged it slides at
:math:`\mu N` to 0.03 %.

**Collision proxy.** Where the surface has one (degree 2 and hexahedra by default,
:mod:`~hyperfem.contact.proxy`), the collision mesh's vertices are
:math:`y = W x` of the surface nodes: the pairs, the barrier, the friction and
the collision filters act on :math:`y`, and the gradient and Hessian come back
to the nodes as :math:`W^T g` and :math:`W^T H W` (per component; the tool's
vertices are their own).

**Step filter** (:class:`MeshCollisionFilter`): ``ipctk``'s continuous
collision detection of the linear trajectory from the iterate to the full
Newton step, with ``AdditiveCCD`` (TightInclusion, the default, is
pathologically slow in the 1.6 wheel), whose conservative rescaling is our
safety :math:`s`: every pair keeps at least :math:`(1 - s)` of its distance,
as for the plane.

**Default stiffness.** With :math:`b` on squared distances a pair at
:math:`d \ll \hat d` carries the force :math:`2\kappa\hat d^4/d`, the nodal
barrier :math:`\kappa_n\hat d^2/d`: the default :math:`\kappa = \bar k/(2\hat d^2)`
(:math:`\bar k` the mean tangent diagonal at the surface nodes,
:mod:`~hyperfem.contact.defaults`) gives the force law of the nodal default;
with a collision proxy it is divided by the proxy's vertices per node, which
keeps the pressure at a given gap.

MPI: the surface is gathered to every rank and the barrier evaluated
redundantly (:mod:`~hyperfem.contact.surface` says how that scales and what
a halo exchange would do); each rank keeps the gradient rows and Hessian rows
of the nodes it owns, rank 0 reports the energy. The result is the same on
any number of ranks.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from hyperfem.contact.barrier import require_ipctk
from hyperfem.contact.interpolation import ForceInterpolation
from hyperfem.contact.obstacles import obstacle_time
from hyperfem.contact.settings import check_dhat_fits
from hyperfem.contact.surface import ContactSurface
from hyperfem.errors import ParameterError
from hyperfem.loading.motion import RigidRotation
from hyperfem.problem.protocol import SolidProblem
from hyperfem.solver.filters import NoAdmissibleStep

__all__ = ["MeshBarrier", "MeshCollisionFilter", "RigidSurface", "ray_hits"]


class RigidSurface:
    r"""A rigid triangulated surface (a tool) with a prescribed translation and rotation.

    Its vertices at time :math:`t` are :math:`R(\theta(t))(X - c_r) + c_r + s(t)`, the rotation (if any)
    about the pivot :math:`c_r` of the reference placement, then the translation :math:`s(t)`
    (:mod:`~hyperfem.contact.obstacles`).

    Args:
        points: Vertex positions where the translation is 0, shape ``(k, 3)`` (3D) or ``(k, 2)`` (2D).
        faces: Triangles, shape ``(f, 3)`` (3D), or segments, shape ``(f, 2)`` (2D), indices into ``points``.
        motion: The translation :math:`m` (``None``: it stays), or a path: a
            callable giving the translation at ``t`` (then ``profile`` is not used).
        profile: :math:`f(t)` of the translation.
        rotation: A :class:`~hyperfem.loading.RigidRotation` (``None``: it does not turn).
    """

    def __init__(
        self,
        points: np.ndarray,
        faces: np.ndarray,
        motion: np.ndarray | Callable[[float], Any] | None,
        profile: Callable[[float], float],
        rotation: RigidRotation | None = None,
    ):
        points = np.asarray(points, dtype=float)
        self.dim = int(points.shape[1]) if points.ndim == 2 else 3
        self.points = points.reshape(-1, self.dim)
        self.faces = np.asarray(faces, dtype=np.int32).reshape(-1, self.dim)
        self.motion = motion if motion is None or callable(motion) else np.asarray(motion, dtype=float)
        self.profile = profile
        self.rotation = rotation

    def offset(self, t: float) -> np.ndarray:
        """The translation :math:`s(t)` (:math:`f(t)\\,m`, or the path's) at time (load factor) ``t``."""
        if self.motion is None:
            return np.zeros(self.dim)
        if callable(self.motion):
            return np.asarray(self.motion(t), dtype=float).reshape(self.dim)
        return float(self.profile(t)) * self.motion

    def vertices(self, t: float) -> np.ndarray:
        """The vertex positions at time ``t``."""
        points = self.points if self.rotation is None else self.rotation.rotate(self.points, t)
        return points + self.offset(t)

    def transfer(self, x: np.ndarray, t_from: float, t: float) -> np.ndarray:
        """Points ``(m, d)`` moved rigidly with the tool from its placement at ``t_from`` to the one at ``t``."""
        x = np.asarray(x, dtype=float)
        if self.rotation is None:
            return x + (self.offset(t) - self.offset(t_from))
        c = np.asarray(self.rotation.center, dtype=float)
        Q = self.rotation.matrix(t) @ self.rotation.matrix(t_from).T
        return (x - self.offset(t_from) - c) @ Q.T + c + self.offset(t)

    def increments(self, x: np.ndarray, t_from: float, t: float) -> np.ndarray:
        """:meth:`transfer` minus the points (the translation itself, exactly, without a rotation)."""
        x = np.asarray(x, dtype=float)
        if self.rotation is None:
            return np.broadcast_to(self.offset(t) - self.offset(t_from), x.shape).copy()
        return self.transfer(x, t_from, t) - x


SWEEP_RESCALING = 0.999
"""The sweep check's CCD rescaling: a move is refused where two primitives come within 0.1 % of their distance."""


def _f(a: np.ndarray) -> np.ndarray:
    """An F-ordered float64 copy (what the ``ipctk`` bindings take without converting)."""
    return np.asfortranarray(a, dtype=float)


def ray_hits(origins: np.ndarray, direction: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distance along ``direction`` (a unit vector) from each origin to the first triangle it hits, and its index.

    ``inf`` and -1 where the ray hits none.

    Möller–Trumbore, vectorised over origins × triangles in chunks; in 2D the first segment (:func:`_ray_hits_2d`).

    Args:
        origins: Shape ``(m, 3)`` (2D: ``(m, 2)``).
        direction: Shape ``(3,)``, or one unit vector per origin, ``(m, 3)`` (2D: 2 components).
        triangles: Corner positions, shape ``(f, 3, 3)`` (2D: segments, ``(f, 2, 2)``).
    """
    out = np.full(len(origins), np.inf)
    index = np.full(len(origins), -1, dtype=np.int64)
    if not len(origins) or not len(triangles):
        return out, index
    if triangles.shape[-1] == 2:
        return _ray_hits_2d(origins, direction, triangles)
    a = triangles[:, 0]
    e1 = triangles[:, 1] - a
    e2 = triangles[:, 2] - a
    directions = np.broadcast_to(np.asarray(direction, dtype=float), origins.shape)
    chunk = max(1, 2_000_000 // max(1, len(triangles)))
    for start in range(0, len(origins), chunk):
        o = origins[start : start + chunk]
        d = directions[start : start + chunk]
        p = np.cross(d[:, None, :], e2[None, :, :])  # (m, f, 3)
        det = np.einsum("fi,mfi->mf", e1, p)
        ok = np.abs(det) > 1e-300
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o[:, None, :] - a[None, :, :]  # (m, f, 3)
        b1 = np.einsum("mfi,mfi->mf", s, p) * inv
        q = np.cross(s, e1[None, :, :])
        b2 = np.einsum("mfi,mi->mf", q, d) * inv
        t = np.einsum("mfi,fi->mf", q, e2) * inv
        inside = ok & (b1 >= 0.0) & (b2 >= 0.0) & (b1 + b2 <= 1.0) & (t >= 0.0)
        t = np.where(inside, t, np.inf)
        first = t.argmin(axis=1)
        out[start : start + chunk] = t[np.arange(len(o)), first]
        index[start : start + chunk] = np.where(np.isfinite(out[start : start + chunk]), first, -1)
    return out, index


def _ray_hits_2d(origins: np.ndarray, direction: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`ray_hits` in the plane: the first segment ``(f, 2, 2)`` each ray from ``origins`` ``(m, 2)`` hits."""
    out = np.full(len(origins), np.inf)
    index = np.full(len(origins), -1, dtype=np.int64)
    a = segments[:, 0]
    e = segments[:, 1] - a
    directions = np.broadcast_to(np.asarray(direction, dtype=float), origins.shape)
    chunk = max(1, 2_000_000 // max(1, len(segments)))
    for start in range(0, len(origins), chunk):
        o = origins[start : start + chunk]
        d = directions[start : start + chunk]
        # o + t d = a + b e: t = (s x e) / (d x e), b = (s x d) / (d x e), s = a - o, x the scalar cross product.
        det = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (m, f)
        ok = np.abs(det) > 1e-300
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = a[None, :, :] - o[:, None, :]  # (m, f, 2)
        t = (s[..., 0] * e[None, :, 1] - s[..., 1] * e[None, :, 0]) * inv
        b = (s[..., 0] * d[:, None, 1] - s[..., 1] * d[:, None, 0]) * inv
        inside = ok & (b >= 0.0) & (b <= 1.0) & (t >= 0.0)
        t = np.where(inside, t, np.inf)
        first = t.argmin(axis=1)
        out[start : start + chunk] = t[np.arange(len(o)), first]
        index[start : start + chunk] = np.where(np.isfinite(out[start : start + chunk]), first, -1)
    return out, index


class MeshBarrier:
    r"""The barrier term :math:`\kappa B` of a collision surface and an optional rigid tool (module docstring).

    An :class:`~hyperfem.solver.external.ExternalEnergy` whose tangent entries
    couple nodes (:meth:`coupled_hessian`).

    Args:
        contact: The contact it was bound from (``name`` for the outputs).
        problem: The problem.
        surface: The gathered collision surface.
        where: The contact, for messages.
        dhat: :math:`\hat d`.
        stiffness: :math:`\kappa` (``ipctk``'s, on squared distances).
        safety: The collision filter's :math:`s`.
        tool: A rigid surface (``None``: none).

    Attributes:
        step_filter: The :class:`MeshCollisionFilter`.
        time: The time the tool is at.
    """

    def __init__(
        self,
        contact: Any,
        problem: SolidProblem,
        surface: ContactSurface,
        *,
        where: str,
        dhat: float,
        stiffness: float,
        safety: float,
        tool: RigidSurface | None = None,
        friction: float = 0.0,
        friction_epsilon: float | None = None,
    ):
        self.ipctk = ipctk = require_ipctk(where)
        self.contact = contact
        self.problem = problem
        self.surface = surface
        self.comm = problem.domain.comm
        if self.comm.size > 1:
            # Every rank evaluates the whole barrier: ipctk's threads would oversubscribe the cores the ranks use
            # (the surgery demo on 2 ranks of 2 cores: 23 s with them, 8 s on 1 rank), and one thread per rank
            # gives every rank the same sums.
            ipctk.set_num_threads(1)
        self.where = where
        self.dhat = float(dhat)
        check_dhat_fits(problem, self.dhat, where)
        self.stiffness = float(stiffness)
        self.tool = tool
        n = surface.collision_size
        faces = surface.collision_faces
        rest = surface.to_collision(surface.X)
        if tool is not None:
            faces = np.vstack([faces, tool.faces + n])
            rest = np.vstack([rest, tool.vertices(problem.time)])
        self.dim = surface.dim
        if self.dim == 2:  # segments: the edges themselves, no faces (ipctk's 2D collision mesh: edge-vertex pairs)
            self.mesh = ipctk.CollisionMesh(_f(rest), np.asfortranarray(faces, dtype=np.int32))
        else:
            self.mesh = ipctk.CollisionMesh(_f(rest), np.asfortranarray(ipctk.edges(faces)), np.asfortranarray(faces))
        if tool is not None:
            self.mesh.can_collide = ipctk.make_static_obstacle_filter(n)  # no tool–tool pairs
        self.potential = ipctk.BarrierPotential(self.dhat, self.stiffness)
        self._ccd = ipctk.AdditiveCCD(conservative_rescaling=float(safety))
        # The sweep check of a start state looks for primitives that meet on the way, not for ones that come close.
        self._sweep_ccd = ipctk.AdditiveCCD(conservative_rescaling=SWEEP_RESCALING)
        # The global dof of every collision-mesh dof (-1: a tool's) and whether it is a Dirichlet dof.
        tool_dofs = 0 if tool is None else self.dim * len(tool.points)
        self._global = np.concatenate([surface.global_dofs.ravel(), np.full(tool_dofs, -1, dtype=np.int64)])
        self._fixed = np.concatenate([surface.constrained.ravel(), np.ones(tool_dofs, dtype=bool)])
        # The collision dofs' map to the nodes' (the proxy's W per component; the tool's vertices are their own).
        self._expand: sp.csr_matrix | None = None
        if surface.proxy_map is not None:
            blocks = [surface.proxy_map] + ([] if tool is None else [sp.identity(len(tool.points), format="csr")])
            self._expand = sp.kron(sp.block_diag(blocks, format="csr"), sp.identity(self.dim), format="csr")
        own = (self.dim * surface.rows[:, None] + np.arange(self.dim)).ravel()
        self._own = np.zeros(len(self._global), dtype=bool)
        self._own[own] = True
        self._cache: tuple[np.ndarray, Any] | None = None
        self._tangent_at: np.ndarray | None = None
        self._project = False
        self.exact_tangent = False
        self.time = float(problem.time)
        self._tool_now = None if tool is None else tool.vertices(self.time)
        self.step_filter = MeshCollisionFilter(self, float(safety))
        self.mu = float(friction)
        self.friction_epsilon = float(friction_epsilon) if friction_epsilon is not None else 0.1 * self.dhat
        self._friction = ipctk.FrictionPotential(self.friction_epsilon) if self.mu > 0.0 else None
        self._lagged: tuple[np.ndarray, Any] | None = None
        self._pending: tuple[np.ndarray, Any] | None = None
        self._interpolation = ForceInterpolation(problem, self._gradient_at, self.comm)
        self._check_start()

    # -- states -------------------------------------------------------------
    def _place(self, time: float) -> None:
        """Put the tool (if any) where it is at the obstacle time ``time``."""
        self.time = float(time)
        if self.tool is not None:
            self._tool_now = self.tool.vertices(self.time)

    def update(self, t: float) -> None:
        """Move the tool (if any) to time (load factor) ``t`` (:func:`~hyperfem.contact.obstacles.obstacle_time`).

        At the start of a generalized-:math:`\alpha` step the contact force of the step's start state is taken
        first, with the tool and the friction's lag of that state (:mod:`~hyperfem.contact.interpolation`).
        """
        self._interpolation.begin()
        self._place(obstacle_time(self.problem, t))
        self._cache = None
        self._tangent_at = None
        self._project = False
        if self._pending is not None:
            self._lagged, self._pending = self._pending, None

    def state_functions(self) -> dict[str, Any]:
        r"""What a checkpoint holds: under generalized-:math:`\alpha` the frozen contact force of the accepted state
        (:meth:`~hyperfem.contact.ForceInterpolation.state_functions`), else nothing (collective)."""
        return self._interpolation.state_functions()

    def restart(self, t: float) -> None:
        """The checkpoint's functions were read back: the state at the accepted time ``t``."""
        self._interpolation.restart(t)

    def project_tangent(self) -> None:
        """Project the Hessian at the next tangent, and until the iterates settle again (module docstring)."""
        self._project = True

    def vertices(self, u: np.ndarray) -> np.ndarray:
        """The collision mesh's vertices for the unknown's local array ``u`` (collective)."""
        body = self.surface.to_collision(self.surface.positions(u))
        return body if self._tool_now is None else np.vstack([body, self._tool_now])

    def _to_nodes(self, g: np.ndarray) -> np.ndarray:
        """A gradient over the collision mesh's dofs as one over the nodes' (and the tool's), flat."""
        return g if self._expand is None else np.asarray(self._expand.T @ g)

    def _pair_nodes(self, pair: Any) -> np.ndarray:
        """The surface nodes of a pair's collision vertices (the tool's left out)."""
        body = self.surface.collision_size
        ids = [int(v) for v in pair.vertex_ids(self.mesh.edges, self.mesh.faces) if 0 <= v < body]
        return self.surface.collision_nodes(ids)

    def _collisions(self, V: np.ndarray) -> Any:
        """The pairs closer than :math:`\\hat d` at the vertices ``V`` (cached for the last ``V``)."""
        if self._cache is not None and np.array_equal(self._cache[0], V):
            return self._cache[1]
        ipctk = self.ipctk
        candidates = ipctk.Candidates()
        candidates.build(self.mesh, _f(V), self.dhat, ipctk.HashGrid())
        collisions = ipctk.NormalCollisions()
        collisions.build(candidates, self.mesh, _f(V), self.dhat)
        self._cache = (V.copy(), collisions)
        return collisions

    def _min_distance(self, V: np.ndarray) -> float:
        """The smallest distance of a pair closer than :math:`\\hat d`; ``inf`` where there is none."""
        collisions = self._collisions(V)
        if not len(collisions):
            return float("inf")
        return float(np.sqrt(collisions.compute_minimum_distance(self.mesh, _f(V))))

    # -- friction -------------------------------------------------------------
    def lag(self, u: np.ndarray) -> None:
        r"""Take the friction's lag at the state ``u``: the vertices, the pairs, their normal forces and bases.

        ``ipctk``'s ``TangentialCollisions`` of the pairs active at ``u`` (their
        normal force magnitudes :math:`\lambda_k` and tangent bases, fixed
        within the next step, as in IPC). It comes into use at the next
        :meth:`update` (the start of the next solve); called after every
        converged solve (:meth:`~hyperfem.solver.external.ExternalTerms.remember`).
        """
        if self._friction is None:
            return
        V = self.vertices(u)
        tangential = self.ipctk.TangentialCollisions()
        collisions = self._collisions(V)
        if len(collisions):
            tangential.build(self.mesh, _f(V), collisions, self.potential, self.mu)
        self._pending = (V.copy(), tangential)

    def _slip(self, u: np.ndarray) -> tuple[Any, np.ndarray] | None:
        """The lagged tangential pairs and the vertices' displacement since the lag (the tool's included)."""
        if self._friction is None or self._lagged is None or not len(self._lagged[1]):
            return None
        return self._lagged[1], _f(self.vertices(u) - self._lagged[0])

    def friction_energy(self, u: np.ndarray) -> float:
        r"""The smoothed Coulomb dissipation potential :math:`D` of the lagged pairs (``ipctk.FrictionPotential``)."""
        slip = self._slip(u)
        return 0.0 if slip is None else float(self._friction(slip[0], self.mesh, slip[1]))  # type: ignore[misc, unused-ignore]

    def _friction_gradient(self, u: np.ndarray) -> np.ndarray:
        slip = self._slip(u)
        if slip is None:
            return np.zeros(self.dim * (self.surface.size + (0 if self.tool is None else len(self.tool.points))))
        return self._to_nodes(np.asarray(self._friction.gradient(slip[0], self.mesh, slip[1])).ravel())  # type: ignore[union-attr, unused-ignore]

    def friction_force(self, u: np.ndarray | PETSc.Vec | None = None, group: int | None = None) -> np.ndarray:
        r"""The friction force on the body's surface nodes (of one group), :math:`-\sum_a \partial D/\partial x_a`.

        Args:
            u: The unknown's local array or a SNES vector (default: the current state).
            group: Index into the surface's boundaries (``None``: every node; of a pair contact that sums the
                forces on both bodies, which cancel, as for :meth:`force`).
        """
        g = self._friction_gradient(self._state(u)).reshape(-1, self.dim)[: self.surface.size]
        if group is not None:
            g = g[self.surface.group == group]
        return -g.sum(axis=0)

    # -- the ExternalEnergy contract ----------------------------------------
    def energy(self, u: np.ndarray) -> float:
        r"""Rank 0's :math:`\kappa B` (the whole barrier; 0 on the other ranks), ``inf`` where a pair touches."""
        V = self.vertices(u)
        collisions = self._collisions(V)
        if len(collisions) and not self._min_distance(V) > 0.0:
            return float("inf")
        value = float(self.potential(collisions, self.mesh, _f(V))) if len(collisions) else 0.0
        value += self.friction_energy(u)
        # Interpolated during a generalized-alpha step (hyperfem.contact.interpolation): the frozen force's linear
        # term is each rank's owned rows, the barrier rank 0's.
        return self._interpolation.energy(value if self.comm.rank == 0 else 0.0, u)

    def _gradient_full(self, u: np.ndarray) -> np.ndarray:
        V = self.vertices(u)
        collisions = self._collisions(V)
        if not len(collisions):
            return np.zeros(self._global.size)
        return self._to_nodes(np.asarray(self.potential.gradient(collisions, self.mesh, _f(V))).ravel())

    def _own_gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The barrier's and the friction's gradient at this rank's owned surface nodes, not interpolated."""
        g = self._gradient_full(u)
        if self._friction is not None:
            g = g + self._friction_gradient(u)
        return self.surface.dofs, g.reshape(-1, self.dim)[self.surface.rows]

    def _gradient_at(self, u: np.ndarray, time: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_own_gradient` with the tool placed at ``time``; placed back after (collective)."""
        now = self.time
        self._place(time)
        try:
            return self._own_gradient(u)
        finally:
            self._place(now)

    def gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`\partial\kappa B/\partial u` at this rank's owned surface nodes: ``(dofs, values)``, ``(m, d)``.

        Interpolated during a generalized-:math:`\alpha` step (:mod:`~hyperfem.contact.interpolation`).
        """
        return self._interpolation.gradient(*self._own_gradient(u))

    def hessian(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """No node blocks: the Hessian couples nodes and comes from :meth:`coupled_hessian`."""
        return self.surface.dofs[:0], np.zeros((0, self.dim, self.dim))

    def coupled_hessian(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The PSD-projected Hessian's entries in this rank's owned rows: global ``(rows, cols, values)``.

        Rows and columns of Dirichlet dofs and of the tool are left out (the
        tangent keeps its identity rows and zero columns there).
        """
        V = self.vertices(u)
        collisions = self._collisions(V)
        if not len(collisions) and self._slip(u) is None:
            empty = np.zeros(0, dtype=np.int64)
            return empty, empty, np.zeros(0)
        # Projected while the iterates move by more than d-hat, exact once they settle (module docstring).
        settled = self._tangent_at is not None and float(np.abs(V - self._tangent_at).max()) < self.dhat
        self._tangent_at = V.copy()
        self.exact_tangent = settled and not self._project
        if self._project:  # this one tangent projected; exact again once the iterates settle anew
            self._project = False
            self._tangent_at = None
        method = self.ipctk.PSDProjectionMethod
        H = self.potential.hessian(collisions, self.mesh, _f(V), method.NONE if self.exact_tangent else method.CLAMP)
        slip = self._slip(u)
        if slip is not None:  # the friction's Hessian, projected (ipctk's is indefinite where the slip is large)
            H = H + self._friction.hessian(slip[0], self.mesh, slip[1], method.CLAMP)  # type: ignore[union-attr, unused-ignore]
        if self._expand is not None:  # W^T H W per component
            H = self._expand.T @ (H @ self._expand)
        H = H.tocoo()
        keep = self._own[H.row] & ~self._fixed[H.row] & ~self._fixed[H.col] & (H.data != 0.0)
        values = np.asarray(H.data[keep], dtype=float) * self._interpolation.weight  # 1 - alpha_f in a g-alpha step
        return self._global[H.row[keep]], self._global[H.col[keep]], values

    def carried(self, u: np.ndarray, t_from: float) -> tuple[np.ndarray, np.ndarray]:
        r"""This rank's surface nodes the tool's move from ``t_from`` to now would overrun: ``(dofs, increments)``.

        Relative to the tool, a node moves by :math:`-\Delta` (the tool's
        translation; with a rotation, each node's own rigid increment
        :math:`\Delta_a`, taken as a straight line): it is overrun where that ray
        hits a tool triangle (at ``t_from``) within :math:`|\Delta|/s`, i.e.
        where it would keep less than :math:`1 - s` of its distance along the
        way (Möller–Trumbore, all owned nodes against all tool triangles).
        Moved rigidly with the tool it keeps its position relative to the tool
        exactly.
        """
        empty = (self.surface.dofs[:0], np.zeros((0, self.dim)))
        if self.tool is None:
            return empty
        t_from = obstacle_time(self.problem, t_from)  # where the tool was at the anchor
        body = self.surface.positions(u)  # collective: every rank calls carried(), also one without surface nodes
        if not len(self.surface.rows):
            return empty
        tool = self.tool.vertices(t_from)
        shift = self.tool.increments(body, t_from, self.time)  # each node moved with the tool
        tool_shift = self.tool.increments(tool, t_from, self.time)
        length = np.linalg.norm(shift, axis=1)
        tool_length = np.linalg.norm(tool_shift, axis=1)
        if not np.any(length > 0.0) and not np.any(tool_length > 0.0):
            return empty
        safety = float(self.step_filter.safety)

        def unit(v: np.ndarray, n: np.ndarray) -> np.ndarray:
            return np.divide(v, n[:, None], out=np.zeros_like(v), where=n[:, None] > 0.0)

        # On the collision mesh (the proxy's vertices and triangles, if any; a rigid increment is affine, so the
        # vertices move as their nodes' rigid increments interpolated): a vertex whose ray hits the tool, and the
        # vertices of a collision triangle a tool vertex would cross, carry their nodes with the tool.
        surface = self.surface
        y = surface.to_collision(body)
        mine_y = surface.owned_vertices()
        shift_y = self.tool.increments(y[mine_y], t_from, self.time)
        length_y = np.linalg.norm(shift_y, axis=1)
        hit = ray_hits(y[mine_y], -unit(shift_y, length_y), tool[self.tool.faces])[0]
        hit_vertices = mine_y[(hit < length_y / safety) & (length_y > 0.0)]
        faces = surface.collision_faces
        distance, face = ray_hits(tool, unit(tool_shift, tool_length), y[faces])
        crossing = (distance < tool_length / safety) & (tool_length > 0.0)
        overrun = np.zeros(surface.size, dtype=bool)
        overrun[surface.collision_nodes(np.concatenate([hit_vertices, faces[face[crossing]].ravel()]))] = True
        mine = np.flatnonzero(overrun[surface.rows])
        return surface.dofs[mine], shift[surface.rows[mine]]

    def carried_by_supports(self, u: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r"""This rank's free surface nodes pushed by prescribed ones: ``(dofs, increments)``.

        A node with free components that is in an active pair (closer than
        :math:`\hat d`) with nodes whose components are prescribed (a
        Dirichlet-driven surface, e.g. a beam's end pushed into another body)
        gets the mean increment :math:`g - u` of those components: it moves
        with the surface that pushes it, instead of being overrun by it.

        Args:
            u: The unknown's local array at the anchor.
            target: The same with the prescribed values of the new time set.
        """
        V = self.vertices(u)
        collisions = self._collisions(V)
        n = self.surface.size
        increment = (self.surface.displacements(target) - self.surface.displacements(u)) * self.surface.constrained
        moving = np.abs(increment).max(axis=1) > 0.0
        if not len(collisions) or not np.any(moving):
            return self.surface.dofs[:0], np.zeros((0, self.dim))
        total = np.zeros((n, self.dim))
        count = np.zeros(n)
        for k in range(len(collisions)):
            ids = self._pair_nodes(collisions[k])
            pushers = [v for v in ids if moving[v]]
            if not pushers:
                continue
            push = increment[pushers].mean(axis=0)
            for v in ids:
                if not moving[v]:
                    total[v] += push
                    count[v] += 1
        carried = count > 0
        mine = carried[self.surface.rows]
        rows = self.surface.rows[mine]
        return self.surface.dofs[mine], total[rows] / count[rows, None]

    def sweep_fraction(self, u_from: np.ndarray, t_from: float, u: np.ndarray) -> float:
        """The collision-free fraction of the joint move of body (``u_from`` to ``u``) and tool (``t_from`` to now).

        ``ipctk``'s continuous collision detection of both linear trajectories:
        1 where no two primitives meet on the way (come within 0.1 % of their
        distance, :data:`SWEEP_RESCALING`), else the fraction before they do.
        """
        V0 = self.surface.to_collision(self.surface.positions(u_from))
        V1 = self.surface.to_collision(self.surface.positions(u))
        if self.tool is not None:
            V0 = np.vstack([V0, self.tool.vertices(obstacle_time(self.problem, t_from))])
            V1 = np.vstack([V1, self.tool.vertices(self.time)])
        fraction = float(self.ipctk.compute_collision_free_stepsize(self.mesh, _f(V0), _f(V1), 0.0,
                                                                    self.ipctk.HashGrid(), self._sweep_ccd))
        return 1.0 if fraction >= SWEEP_RESCALING else fraction

    def admissible(self, u: np.ndarray) -> str:
        """``""``, or that the surfaces touch or intersect at the state ``u`` (the same answer on every rank)."""
        V = self.vertices(u)
        distance = self._min_distance(V)
        if not distance > 0.0:
            return f"{self.where}: two surface primitives touch at t = {self.time:g} (distance {distance:.3g})"
        if self.ipctk.has_intersections(self.mesh, _f(V), self.ipctk.HashGrid()):
            return f"{self.where}: the surfaces intersect at t = {self.time:g}"
        return ""

    def _check_start(self) -> None:
        """A one-line :class:`ParameterError` (every rank) where the surfaces start touching or intersecting."""
        V = self.vertices(self.problem.u.x.array)
        collisions = self._collisions(V)
        distance = self._min_distance(V)
        if not distance > 0.0:
            k = self._closest_vertex(V, collisions)
            raise ParameterError(
                f"{self.where}: the surfaces start in contact: the surface point at "
                f"{tuple(float(f'{v:.6g}') for v in V[k])} is at distance {distance:.3g} from another primitive"
            )
        if self.ipctk.has_intersections(self.mesh, _f(V), self.ipctk.HashGrid()):
            raise ParameterError(
                f"{self.where}: the surfaces intersect at the start (a body starts inside the other){self._crossing(V)}"
            )

    def _crossing(self, V: np.ndarray) -> str:
        """Where the surfaces cross at the vertices ``V``: ``": the edge from A to B crosses the triangle at C"`` for
        the first crossing edge (by index; 2D: segment), or ``""`` where none is found."""
        ipctk, mesh = self.ipctk, self.mesh
        grid = ipctk.HashGrid()
        grid.build(_f(V), mesh.edges, mesh.faces, 0.0)

        def at(points: np.ndarray) -> tuple[float, ...]:
            return tuple(float(f"{v:.6g}") for v in points)

        if self.dim == 3:
            pairs = sorted((c.edge_id, c.face_id) for c in grid.detect_edge_face_candidates())
            for e, f in pairs:
                edge, face = mesh.edges[e], mesh.faces[f]
                if set(edge) & set(face):
                    continue
                if ipctk.is_edge_intersecting_triangle(*(V[i][:, None] for i in (*edge, *face))):
                    return (f": the edge from {at(V[edge[0]])} to {at(V[edge[1]])} crosses the triangle at "
                            f"{at(V[face].mean(axis=0))}")
            return ""
        pairs = sorted((min(c.edge0_id, c.edge1_id), max(c.edge0_id, c.edge1_id))
                       for c in grid.detect_edge_edge_candidates())
        for a, b in pairs:
            first, second = mesh.edges[a], mesh.edges[b]
            if set(first) & set(second):
                continue
            if ipctk.segment_segment_intersect(*(V[i][:, None] for i in (*first, *second))):
                return (f": the segment from {at(V[first[0]])} to {at(V[first[1]])} crosses the one from "
                        f"{at(V[second[0]])} to {at(V[second[1]])}")
        return ""

    def _closest_vertex(self, V: np.ndarray, collisions: Any) -> int:
        """A vertex of the closest pair."""
        best, vertex = float("inf"), 0
        for i in range(len(collisions)):
            c = collisions[i]
            ids = [int(v) for v in c.vertex_ids(self.mesh.edges, self.mesh.faces) if v >= 0]
            d = float(c.compute_distance(np.ascontiguousarray(V[ids].ravel())))
            if d < best:
                best, vertex = d, ids[0]
        return vertex

    # -- outputs ------------------------------------------------------------
    def _state(self, u: np.ndarray | PETSc.Vec | None) -> np.ndarray:
        if u is None:
            return self.problem.u.x.array
        return u.array_r if isinstance(u, PETSc.Vec) else u

    def force(self, u: np.ndarray | PETSc.Vec | None = None, group: int | None = None) -> np.ndarray:
        r"""The contact force on the body's surface nodes (of one group), :math:`-\sum_a \partial\kappa B/\partial x_a`.

        Args:
            u: The unknown's local array or a SNES vector (default: the current state).
            group: Index into the surface's boundaries (``None``: every node).
        """
        g = self._gradient_full(self._state(u)).reshape(-1, self.dim)[: self.surface.size]
        if group is not None:
            g = g[self.surface.group == group]
        return -g.sum(axis=0)

    def moment(self, u: np.ndarray | PETSc.Vec | None = None, group: int | None = None) -> np.ndarray:
        r"""The moment about the origin of the contact forces (friction included) on the surface nodes (of one group).

        :math:`\sum_a x_a \times f_a`, the same on every rank (collective); zero-padded to 3 components in 2D
        (the moment about z in the last).

        Args:
            u: The unknown's local array or a SNES vector (default: the current state).
            group: Index into the surface's boundaries (``None``: every node; of a pair contact the moments on
                both bodies, which cancel, as for :meth:`force`).
        """
        state = self._state(u)
        g = self._gradient_full(state)
        if self._friction is not None:
            g = g + self._friction_gradient(state)
        x = self.surface.positions(state)
        f = -g.reshape(-1, self.dim)[: self.surface.size]
        if group is not None:
            mine = self.surface.group == group
            x, f = x[mine], f[mine]
        if self.dim == 2:
            return np.array([0.0, 0.0, float((x[:, 0] * f[:, 1] - x[:, 1] * f[:, 0]).sum())])
        return np.cross(x, f).sum(axis=0)

    def summary(self) -> dict[str, object]:
        """The summary's ``contact`` entry: type, boundaries, last force (the output's), moment, pairs, gap."""
        group = None if self.tool is not None else 0
        entry: dict[str, object] = {
            "type": type(self.contact).__name__,
            "boundaries": list(self.surface.boundaries),
            "force": [float(v) for v in self.force(group=group)],
            "moment": [float(v) for v in self.moment(group=group)],
            "active": self.active_count(),
            "min_distance": self.min_distance(),
        }
        if self.mu > 0.0:
            entry["friction_force"] = [float(v) for v in self.friction_force(group=group)]
        return {"contact": {self.contact.name: entry}}

    def active_count(self, u: np.ndarray | PETSc.Vec | None = None) -> int:
        r"""The number of primitive pairs closer than :math:`\hat d`."""
        return len(self._collisions(self.vertices(self._state(u))))

    def min_distance(self, u: np.ndarray | PETSc.Vec | None = None) -> float:
        r"""The smallest distance of a pair closer than :math:`\hat d` (``inf`` where none is)."""
        return self._min_distance(self.vertices(self._state(u)))

    def pair_gaps(self, u: np.ndarray | PETSc.Vec | None = None) -> tuple[np.ndarray, np.ndarray]:
        r"""Per owned surface node, the smallest distance of the pairs closer than :math:`\hat d` it belongs to.

        :math:`\hat d` where it is in none (out of the barrier's reach: a gap belongs to a pair of primitives, the
        node's is the closest of its pairs). Through a collision proxy a node belongs to the pairs of every proxy
        vertex its shape function takes part in. Returns ``(dofs, gaps)``, shapes ``(m, d)`` and ``(m,)``.
        """
        V = self.vertices(self._state(u))
        collisions = self._collisions(V)
        gaps = np.full(self.surface.size, self.dhat)
        for k in range(len(collisions)):
            c = collisions[k]
            ids = [int(v) for v in c.vertex_ids(self.mesh.edges, self.mesh.faces) if v >= 0]
            d = float(np.sqrt(c.compute_distance(np.ascontiguousarray(V[ids].ravel()))))  # ipctk: squared
            nodes = self._pair_nodes(c)
            gaps[nodes] = np.minimum(gaps[nodes], d)
        return self.surface.dofs, gaps[self.surface.rows]

    def intersecting(self, u: np.ndarray | PETSc.Vec | None = None) -> bool:
        """Whether any two triangles or edges of the collision mesh intersect (``ipctk.has_intersections``)."""
        return bool(self.ipctk.has_intersections(self.mesh, _f(self.vertices(self._state(u))), self.ipctk.HashGrid()))

    def record(self, step: object = None) -> dict[str, object]:
        """The output columns: ``<name>_force`` (on the first boundary, or on the body from a tool), ``_moment`` (of
        the same forces about the origin, friction included: :meth:`moment`), ``_active``, ``_min_distance``; with
        friction ``_friction_force`` (on the same nodes)."""
        name = self.contact.name
        group = None if self.tool is not None else 0
        out: dict[str, object] = {
            f"{name}_force": [float(v) for v in self.force(group=group)],
            f"{name}_moment": [float(v) for v in self.moment(group=group)],
            f"{name}_active": self.active_count(),
            f"{name}_min_distance": self.min_distance(),
        }
        if self.mu > 0.0:  # on the same nodes as the force (a pair's on the first boundary: both bodies' cancel)
            out[f"{name}_friction_force"] = [float(v) for v in self.friction_force(group=group)]
        return out


class MeshCollisionFilter:
    r"""A :class:`~hyperfem.solver.filters.NewtonStepFilter`: ``ipctk``'s CCD of the Newton step (module docstring).

    Attributes:
        cutbacks: Always 0 (the filter never halves).
        filtered_steps: Newton steps it shortened.
        min_step_fraction: The smallest fraction it allowed since the solver reset it.
        min_distance: The smallest pair distance of an iterate it has seen since the last reset to ``inf``.
    """

    def __init__(self, barrier: MeshBarrier, safety: float):
        self.barrier = barrier
        self.safety = safety
        self.cutbacks = 0
        self.filtered_steps = 0
        self.min_step_fraction = 1.0
        self.min_distance = float("inf")

    def step_fraction(self, x: PETSc.Vec, y: PETSc.Vec) -> float:
        """The largest fraction of the step ``x -> x - y`` over which no pair loses more than ``s`` of its distance.

        Raises:
            NoAdmissibleStep: Two primitives of the iterate touch.
        """
        b = self.barrier
        comm: MPI.Comm = b.comm
        V0 = b.vertices(x.array_r)
        step = b.surface.to_collision(b.surface.displacements(y.array_r))
        if b._tool_now is not None:
            step = np.vstack([step, np.zeros_like(b._tool_now)])
        lowest = b._min_distance(V0)
        self.min_distance = min(self.min_distance, lowest)
        if not lowest > 0.0:
            raise NoAdmissibleStep(f"two contact primitives touch (distance {lowest:.3g})")
        fraction = float(
            b.ipctk.compute_collision_free_stepsize(b.mesh, _f(V0), _f(V0 - step), 0.0, b.ipctk.HashGrid(), b._ccd)
        )
        fraction = float(comm.allreduce(min(1.0, fraction), op=MPI.MIN))
        if fraction < 1.0:
            self.filtered_steps += 1
            self.min_step_fraction = min(self.min_step_fraction, fraction)
        return fraction
