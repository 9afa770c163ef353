r"""What the barriers of contact nodes against a rigid obstacle share: energy, checks and outputs.

A rigid obstacle (a plane, a sphere) gives every contact node :math:`a` a
signed distance :math:`d_a(u)`, positive on the body's side; the barrier term
is :math:`\kappa B(u) = \kappa\sum_a b(d_a(u))` (:mod:`~hyperfem.contact.barrier`).
:class:`NodalBarrier` holds what does not depend on the obstacle's shape: the
energy, the admissibility check (a node on or through the obstacle), the
start check at binding, and the outputs (the force the obstacle exerts,
:math:`-\sum_a \kappa b'(d_a)\nabla d_a`, the active nodes, the smallest
distance). A subclass gives :meth:`~NodalBarrier.distances`,
:meth:`~NodalBarrier.normals`, ``_barrier_gradient``, ``_barrier_hessian`` and
:meth:`~NodalBarrier.update`, and a ``step_filter``.

**Friction** (Coulomb, smoothed and lagged as in IPC, Li et al. 2020 §5; the
contact's ``friction`` :math:`\mu > 0`): the dissipative potential

.. math::
    D(u) = \mu \sum_a \lambda_a\, f_0\bigl(\lVert P_a (x_a - x_a^n)\rVert\bigr), \qquad
    f_0(y) = \begin{cases} -\dfrac{y^3}{3\epsilon^2} + \dfrac{y^2}{\epsilon} + \dfrac{\epsilon}{3} & y < \epsilon \\
    y & y \ge \epsilon \end{cases}

is added to the energy, gradient and Hessian. Lagged (fixed within a step,
taken at the step's start state :math:`x^n`, :meth:`NodalBarrier.lag`): the
normal force magnitudes :math:`\lambda_a = \kappa|b'(d_a(x^n))|`, the
tangent projectors :math:`P_a = I - n_a n_a^T` (:math:`\lVert T_a^T v\rVert =
\lVert P_a v\rVert` for an orthonormal tangent basis :math:`T_a`) and
:math:`x^n` itself, so :math:`D` is a conservative potential within the
step. The slip is relative to the obstacle's surface: the point
:math:`x_a^n` is carried with the obstacle's rigid motion (translation and
rotation, :mod:`~hyperfem.contact.obstacles`) from the lag's time to now,
:math:`x_a^n \to \Phi(x_a^n)`, and the slip is :math:`P_a(x_a - \Phi(x_a^n))`
(a rough ball turned about its centre drags the nodes it holds; a plane or a
ball pushed along its normal slips nothing). :math:`\Phi` is fixed within a
solve, so the derivatives below are unchanged. :math:`\epsilon` (``friction_epsilon``, a slip length: quasi-static
IPC's :math:`\epsilon_v\,\Delta t`) is the slip below which the node sticks
elastically. With :math:`w = P_a(x_a - \Phi(x_a^n))`, :math:`y = \lVert w\rVert` and
:math:`g(y) = f_0'(y)/y` (:math:`2/\epsilon - y/\epsilon^2`, or :math:`1/y`),
the gradient is :math:`\mu\lambda_a g\,w` and the Hessian
:math:`\mu\lambda_a(g P_a + g'(y)/y\; w w^T)`, whose eigenvalues in the tangent
plane are :math:`\mu\lambda_a g > 0` and :math:`\mu\lambda_a f_0''(y) =
\mu\lambda_a\max(2/\epsilon - 2y/\epsilon^2, 0) \ge 0`: it is positive
semi-definite as it stands (the closed form of IPC's projection), no
clipping is needed. Written with numpy rather than ipctk's
``TangentialCollisions`` (which needs ipctk collision sets of mesh
primitives; for an analytic obstacle the per-node formulas are a few lines,
run on each rank's owned nodes, with no gathering). The lag is refreshed by
:meth:`~hyperfem.solver.external.ExternalTerms.remember`, i.e. after every
converged solve (an accepted step), at construction and at a restart; a
solve that failed and is cut back leaves it at the last accepted state.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from hyperfem.contact.barrier import barrier, barrier_derivatives
from hyperfem.contact.interpolation import ForceInterpolation
from hyperfem.contact.nodes import BoundaryNodes
from hyperfem.contact.obstacles import obstacle_time
from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import SolidProblem

__all__ = ["SETTLED_MOVE", "NodalBarrier"]

SETTLED_MOVE = 0.1
r"""A curved obstacle's tangent is exact once no node moved by this fraction of :math:`\hat d` since the last one.

Measured (the surgery demo's slab, the probe as an analytic ball, 8 steps; Newton iterations in all): dragged
frictionless / with :math:`\mu = 0.3`, ``--n 10``: 149 / 139 always projected, 78 / 85 at 0.1, 73 / 78 at 1;
``--n 14``: 146 / 140, 81 / 91, 77 / 86. The Hertz indentation of ``tests/test_contact.py`` (:math:`n = 16`,
:math:`\hat d = 10^{-4}`, two steps): 41 iterates projected and at 0.1, 47 at 1 (exact tangents taken while the
iterates still travel, every other one then projected again). The mesh barrier settles at :math:`\hat d`
(:mod:`~hyperfem.contact.mesh_barrier`).
"""


class NodalBarrier:
    r"""The shape-independent part of the barrier of a boundary's nodes against a rigid obstacle (module docstring).

    Attributes:
        contact: The contact it was bound from (``boundary``, ``name``).
        problem: The problem.
        nodes: The owned contact nodes.
        dhat: :math:`\hat d`.
        stiffness: :math:`\kappa`.
        time: The time (load factor) the obstacle is at.
    """

    contact: Any
    where: str
    problem: SolidProblem
    comm: MPI.Comm
    nodes: BoundaryNodes
    dhat: float
    stiffness: float
    time: float
    curved = False
    """Whether the exact Hessian can be indefinite (a sphere's, a cylinder's: :meth:`hessian`)."""
    exact_tangent = False
    """Whether the last tangent took the exact Hessian (:meth:`hessian`)."""
    _tangent_at: np.ndarray | None = None
    _project_next = False
    behind = "on or behind the obstacle"
    """How a refused node is placed, for the messages."""
    side_hint = ""
    """What the start check's message adds (which side is the body's)."""

    def distances(self, u: np.ndarray) -> np.ndarray:
        """Signed distances :math:`d_a` of the owned nodes for the unknown's local array ``u``."""
        raise NotImplementedError

    def normals(self, u: np.ndarray) -> np.ndarray:
        r"""The unit normals :math:`\nabla d_a` of the owned nodes, shape ``(n, dim)``."""
        raise NotImplementedError

    def _barrier_gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`\kappa b'(d_a)\nabla d_a` at the active nodes: ``(dofs, values)`` of shape ``(m, dim)``."""
        raise NotImplementedError

    def _barrier_hessian(self, u: np.ndarray, project: bool = True) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    mu: float = 0.0
    r"""The Coulomb coefficient :math:`\mu` (0: frictionless)."""
    friction_epsilon: float = 0.0
    r"""The smoothing slip :math:`\epsilon` of :math:`f_0`."""
    _lagged: tuple[np.ndarray, np.ndarray, np.ndarray, float] | None = None
    _pending: tuple[np.ndarray, np.ndarray, np.ndarray, float] | None = None

    def _init_friction(self, contact: Any) -> None:
        r"""Set :math:`\mu` and :math:`\epsilon` from the contact (after ``dhat``)."""
        self.mu = float(getattr(contact, "friction", 0.0))
        eps = getattr(contact, "friction_epsilon", None)
        self.friction_epsilon = float(eps) if eps is not None else 0.1 * self.dhat
        self._lagged = self._pending = None

    def _refresh_lag(self) -> None:
        """Make the lag taken by :meth:`lag` the one in use (``update(t)``, at the start of a solve, calls it)."""
        if self._pending is not None:
            self._lagged, self._pending = self._pending, None

    def lag(self, u: np.ndarray) -> None:
        r"""Take the friction's lagged :math:`\lambda_a`, :math:`P_a`, :math:`x_a^n` at the state ``u`` (module doc).

        They come into use at the next ``update(t)`` (the start of the next
        solve): until then the energy, gradient and :meth:`friction_force`
        stay those of the step just solved (its outputs and reactions).
        """
        if self.mu <= 0.0:
            return
        d = self.distances(u)
        lam = np.zeros(len(d))
        rows = np.flatnonzero((d < self.dhat) & (d > 0.0))
        lam[rows] = self.stiffness * np.abs(barrier_derivatives(d[rows], self.dhat)[0])
        n = self.normals(u)
        P = np.eye(n.shape[1])[None, :, :] - np.einsum("mi,mj->mij", n, n)
        self._pending = (lam, P, self.nodes.positions(u).copy(), self.time)

    def _slips(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        r"""Rows with :math:`\lambda_a > 0`, their :math:`\mu\lambda_a`, tangential slips :math:`w` and :math:`|w|`.

        The slip is relative to the obstacle: :math:`x_a^n` is carried with the obstacle's rigid motion from the
        lag's time to now (module docstring).
        """
        assert self._lagged is not None
        lam, P, x0, t0 = self._lagged
        rows = np.flatnonzero(lam > 0.0)
        obstacle = getattr(self, "obstacle", None)
        start = x0[rows] if obstacle is None or t0 == self.time else obstacle.transfer(x0[rows], t0, self.time)
        w = np.einsum("mij,mj->mi", P[rows], self.nodes.positions(u)[rows] - start)
        return rows, self.mu * lam[rows], w, np.linalg.norm(w, axis=1)

    def friction_energy(self, u: np.ndarray) -> float:
        r"""This rank's :math:`D(u) = \mu\sum_a\lambda_a f_0(|w_a|)` (0 when frictionless or not lagged yet)."""
        if self.mu <= 0.0 or self._lagged is None:
            return 0.0
        _, ml, _, y = self._slips(u)
        e = self.friction_epsilon
        f0 = np.where(y < e, -(y**3) / (3 * e * e) + y * y / e + e / 3, y)
        return float((ml * f0).sum())

    def friction_gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`\mu\lambda_a g(|w_a|)\,w_a` at the lagged contact nodes: ``(dofs, values)``."""
        if self.mu <= 0.0 or self._lagged is None:
            return self.nodes.dofs[:0], np.zeros((0, self.nodes.X.shape[1]))
        rows, ml, w, y = self._slips(u)
        e = self.friction_epsilon
        g = np.where(y < e, 2.0 / e - y / (e * e), 1.0 / np.maximum(y, e))
        return self.nodes.dofs[rows], (ml * g)[:, None] * w

    def friction_hessian(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`\mu\lambda_a(g P_a + g'(y)/y\,w w^T)` (PSD as it stands, module docstring): ``(dofs, blocks)``."""
        dim = self.nodes.X.shape[1]
        if self.mu <= 0.0 or self._lagged is None:
            return self.nodes.dofs[:0], np.zeros((0, dim, dim))
        rows, ml, w, y = self._slips(u)
        e = self.friction_epsilon
        small = y < e
        ys = np.maximum(y, e)
        g = np.where(small, 2.0 / e - y / (e * e), 1.0 / ys)
        # g'(y)/y: -1/(e^2 y) below e (times w w^T with |w| = y: bounded), -1/y^3 above
        dg = np.where(small, -1.0 / (e * e * np.maximum(y, 1e-300)), -1.0 / ys**3)
        P = self._lagged[1][rows]
        blocks = ml[:, None, None] * (g[:, None, None] * P + dg[:, None, None] * np.einsum("mi,mj->mij", w, w))
        return self.nodes.dofs[rows], blocks

    _force_interpolation: ForceInterpolation | None = None

    def _interpolation(self) -> ForceInterpolation:
        r"""The generalized-:math:`\alpha` weights of this contact (:mod:`~hyperfem.contact.interpolation`)."""
        if self._force_interpolation is None:
            self._force_interpolation = ForceInterpolation(self.problem, self._gradient_at)
        return self._force_interpolation

    def state_functions(self) -> dict[str, Any]:
        r"""What a checkpoint holds: under generalized-:math:`\alpha` the frozen contact force of the accepted state
        (:meth:`~hyperfem.contact.ForceInterpolation.state_functions`), else nothing."""
        return self._interpolation().state_functions()

    def restart(self, t: float) -> None:
        """The checkpoint's functions were read back: the state at the accepted time ``t``."""
        self._interpolation().restart(t)

    def _place(self, time: float) -> None:
        """Put the obstacle where it is at the obstacle time ``time`` (sets :attr:`time`; the lag is left alone)."""
        raise NotImplementedError

    def update(self, t: float) -> None:
        """Move the obstacle to time (load factor) ``t`` (:func:`~hyperfem.contact.obstacles.obstacle_time`).

        At the start of a generalized-:math:`\alpha` step the contact force of the step's start state is taken
        first, with the obstacle and the friction's lag of that state (:mod:`~hyperfem.contact.interpolation`).
        """
        self._interpolation().begin()
        self._place(obstacle_time(self.problem, t))
        self._refresh_lag()
        self._tangent_at, self._project_next = None, False  # the obstacle moved: projected until settled anew

    def _own_gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The barrier's gradient and the friction's (if any), not interpolated."""
        dofs, values = self._barrier_gradient(u)
        if self.mu <= 0.0:
            return dofs, values
        fdofs, fvalues = self.friction_gradient(u)
        return np.concatenate([dofs, fdofs]), np.concatenate([values, fvalues])

    def _gradient_at(self, u: np.ndarray, time: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_own_gradient` with the obstacle placed at ``time``; placed back after."""
        now = self.time
        self._place(time)
        try:
            return self._own_gradient(u)
        finally:
            self._place(now)

    def gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r"""The barrier's :math:`\kappa b'(d_a)\nabla d_a` at the active nodes, and the friction's (if any).

        Interpolated during a generalized-:math:`\alpha` step (:mod:`~hyperfem.contact.interpolation`).
        """
        return self._interpolation().gradient(*self._own_gradient(u))

    def project_tangent(self) -> None:
        """Project the Hessian at the next tangent, and until the nodes settle again (:meth:`hessian`)."""
        self._project_next = True

    def _settled(self, u: np.ndarray) -> bool:
        r"""Whether no contact node moved by :data:`SETTLED_MOVE` :math:`\hat d` or more since the last tangent
        (collective)."""
        x = self.nodes.positions(u)
        moved = np.inf if self._tangent_at is None else float(np.abs(x - self._tangent_at).max(initial=0.0))
        self._tangent_at = x
        return bool(self.comm.allreduce(moved, op=MPI.MAX) < SETTLED_MOVE * self.dhat)

    def hessian(self, u: np.ndarray, project: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
        r"""The barrier's Hessian blocks, and the friction's (if any).

        Times :math:`1 - \alpha_f` during a generalized-:math:`\alpha` step.

        Args:
            u: The unknown's local array.
            project: ``True``: each block projected onto the PSD cone; ``False``: the exact Hessian;
                ``None`` (the tangent; collective): for a :attr:`curved` obstacle as the mesh barrier does
                (:mod:`~hyperfem.contact.mesh_barrier`), projected while the nodes still move (one moved by
                :data:`SETTLED_MOVE` :math:`\hat d` or more since the last tangent) and exact once they
                settle, which gives Newton its quadratic rate back (always projected, the ball dragged across
                the surgery demo's slab converged at a linear rate of 0.41 in every step); where the exact
                direction does not descend the solver asks for a projected one (:meth:`project_tangent`).
        """
        if project is None:
            settled = self._settled(u) if self.curved else False
            self.exact_tangent = settled and not self._project_next
            if self._project_next:  # this one tangent projected; exact again once the nodes settle anew
                self._project_next, self._tangent_at = False, None
            project = not self.exact_tangent
        dofs, blocks = self._barrier_hessian(u, project)
        if self.mu > 0.0:
            fdofs, fblocks = self.friction_hessian(u)
            dofs, blocks = np.concatenate([dofs, fdofs]), np.concatenate([blocks, fblocks])
        weight = self._interpolation().weight
        return dofs, blocks if weight == 1.0 else weight * blocks

    def energy(self, u: np.ndarray) -> float:
        r"""This rank's :math:`\kappa\sum_a b(d_a)` (``inf`` on or through the obstacle), plus :math:`D`.

        Interpolated during a generalized-:math:`\alpha` step (:mod:`~hyperfem.contact.interpolation`).
        """
        value = self.stiffness * float(barrier(self.distances(u), self.dhat).sum())
        value = value + self.friction_energy(u) if self.mu > 0.0 else value
        return self._interpolation().energy(value, u)

    def _active(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rows of the nodes with :math:`d < \\hat d` and their :math:`b'`, :math:`b''`."""
        d = self.distances(u)
        rows = np.flatnonzero(d < self.dhat)
        first, second = barrier_derivatives(d[rows], self.dhat)
        return rows, first, second

    def carried(self, u: np.ndarray, t_from: float) -> tuple[np.ndarray, np.ndarray]:
        r"""The nodes the obstacle's move from ``t_from`` to now would overrun, and their increments.

        Returns ``(dofs, increments)``.

        A node is overrun where, left in place while the obstacle moves (by
        :math:`\Delta p`, or rigidly with a rotation:
        :meth:`~hyperfem.contact.obstacles.RigidPlacement.transfer`), it would
        keep less than :math:`1 - s` of its distance (the collision filter's
        rule); moved rigidly with the obstacle it keeps its distance exactly. The solver's predictor
        prescribes these increments (:meth:`~hyperfem.solver.external.ExternalTerms.carry`).
        """
        obstacle = getattr(self, "obstacle", None)
        dim = self.nodes.X.shape[1]
        empty = self.nodes.dofs[:0], np.zeros((0, dim))
        if obstacle is None or not len(self.nodes.dofs):
            return empty
        x = self.nodes.positions(u)
        t_from = obstacle_time(self.problem, t_from)  # where the obstacle was at the anchor
        shift = obstacle.increments(x, t_from, self.time)  # a translation, or a rigid motion with a rotation
        if not np.any(shift):
            return empty
        moved = np.array(u, copy=True)
        moved[self.nodes.dofs] += shift
        rows = np.flatnonzero(self.distances(u) < (1.0 - self.contact.safety) * self.distances(moved))
        return self.nodes.dofs[rows], shift[rows]

    def overrun_after_lift(self, u: np.ndarray, anchor: np.ndarray, t_from: float) -> tuple[np.ndarray, np.ndarray]:
        r"""The nodes of a lifted state ``u`` that keep less than :math:`1 - s` of the distance they would keep
        carried rigidly with the obstacle from ``anchor`` (:meth:`carried`), and that carry's increments:
        ``(dofs, increments)``.

        Carried rigidly a node keeps its distance at the anchor, so the solver's next lift with these nodes carried
        too (:meth:`~hyperfem.solver.external.ExternalTerms.carry_more`) keeps them out of the obstacle.
        """
        obstacle = getattr(self, "obstacle", None)
        if obstacle is None or not len(self.nodes.dofs):
            return self.nodes.dofs[:0], np.zeros((0, self.nodes.X.shape[1]))
        shift = obstacle.increments(self.nodes.positions(anchor), obstacle_time(self.problem, t_from), self.time)
        if not np.any(shift):  # a static obstacle carries nothing (its nodes are not pinned at the anchor)
            return self.nodes.dofs[:0], np.zeros((0, self.nodes.X.shape[1]))
        rigid = np.array(anchor, copy=True)
        rigid[self.nodes.dofs] += shift
        rows = np.flatnonzero(self.distances(u) < (1.0 - self.contact.safety) * self.distances(rigid))
        return self.nodes.dofs[rows], shift[rows]

    def admissible(self, u: np.ndarray) -> str:
        """``""``, or which owned node is on or through the obstacle and its distance."""
        d = self.distances(u)
        if not len(d) or d.min() > 0.0:
            return ""
        k = int(np.argmin(d))
        return (
            f"{self.where}: the node at {tuple(float(f'{v:.6g}') for v in self.nodes.X[k])} is {self.behind} "
            f"at t = {self.time:g} (distance {d[k]:.3g})"
        )

    # -- outputs ------------------------------------------------------------
    def _state(self, u: np.ndarray | PETSc.Vec | None) -> np.ndarray:
        if u is None:
            return self.problem.u.x.array
        return u.array_r if isinstance(u, PETSc.Vec) else u

    def force(self, u: np.ndarray | PETSc.Vec | None = None) -> np.ndarray:
        r"""The force the obstacle exerts on the body, :math:`-\sum_a \kappa b'(d_a)\nabla d_a` (collective).

        Args:
            u: The unknown's local array or a SNES vector (default: the current state).
        """
        _, values = self._barrier_gradient(self._state(u))
        local = values.sum(axis=0) if len(values) else np.zeros(self.nodes.X.shape[1])
        return -self.comm.allreduce(local, op=MPI.SUM)

    def friction_force(self, u: np.ndarray | PETSc.Vec | None = None) -> np.ndarray:
        r"""The friction force the obstacle exerts on the body, :math:`-\sum_a \mu\lambda_a g\,w_a` (collective)."""
        _, values = self.friction_gradient(self._state(u))
        local = values.sum(axis=0) if len(values) else np.zeros(self.nodes.X.shape[1])
        return -self.comm.allreduce(local, op=MPI.SUM)

    def moment(self, u: np.ndarray | PETSc.Vec | None = None) -> np.ndarray:
        r"""The moment about the origin of the obstacle's forces on the nodes (friction included): sum of x_a x f_a.

        Collective; zero-padded to 3 components in 2D (the moment about z in the last).
        """
        state = self._state(u)
        x = self.nodes.positions(state)
        rows, first, _ = self._active(state)
        parts = [(x[rows], -self.stiffness * first[:, None] * self.normals(state)[rows])]
        if self.mu > 0.0 and self._lagged is not None:
            friction_rows, ml, w, y = self._slips(state)
            e = self.friction_epsilon
            g = np.where(y < e, 2.0 / e - y / (e * e), 1.0 / np.maximum(y, e))
            parts.append((x[friction_rows], -(ml * g)[:, None] * w))
        local = np.zeros(3)
        for points, forces in parts:
            if len(points):
                pad = lambda a: np.pad(a, ((0, 0), (0, 3 - a.shape[1])))  # noqa: E731
                local += np.cross(pad(points), pad(forces)).sum(axis=0)
        return self.comm.allreduce(local, op=MPI.SUM)

    def summary(self) -> dict[str, object]:
        """The summary's ``contact`` entry of this contact: type, boundary, last force, moment, active nodes, gap."""
        entry: dict[str, object] = {
            "type": type(self.contact).__name__,
            "boundaries": [self.contact.boundary],
            "force": [float(v) for v in self.force()],
            "moment": [float(v) for v in self.moment()],
            "active": self.active_count(),
            "min_distance": self.min_distance(),
        }
        if self.mu > 0.0:
            entry["friction_force"] = [float(v) for v in self.friction_force()]
        return {"contact": {self.contact.name: entry}}

    def active_count(self, u: np.ndarray | PETSc.Vec | None = None) -> int:
        r"""Nodes with :math:`d_a < \hat d`, over all ranks (collective)."""
        return int(self.comm.allreduce(int((self.distances(self._state(u)) < self.dhat).sum()), op=MPI.SUM))

    def min_distance(self, u: np.ndarray | PETSc.Vec | None = None) -> float:
        """The smallest signed distance of a contact node, over all ranks (collective)."""
        d = self.distances(self._state(u))
        return float(self.comm.allreduce(float(d.min()) if len(d) else float("inf"), op=MPI.MIN))

    def record(self, step: object = None) -> dict[str, object]:
        """The output columns at the current state: ``<name>_force``, ``<name>_moment`` (about the origin, friction
        included: :meth:`moment`), ``<name>_active``, ``<name>_min_distance``.

        With friction also ``<name>_friction_force`` (:meth:`friction_force`; ``<name>_force`` is the normal part).
        """
        name = self.contact.name
        out: dict[str, object] = {
            f"{name}_force": [float(v) for v in self.force()],
            f"{name}_moment": [float(v) for v in self.moment()],
            f"{name}_active": self.active_count(),
            f"{name}_min_distance": self.min_distance(),
        }
        if self.mu > 0.0:
            out[f"{name}_friction_force"] = [float(v) for v in self.friction_force()]
        return out

    def _check_start(self, obstacle: str) -> None:
        """A one-line :class:`ParameterError` (every rank) if a node starts on or through the obstacle."""
        u = self.problem.u.x.array
        d = self.distances(u)
        local = (float(d.min()), self.nodes.X[int(np.argmin(d))].tolist()) if len(d) else (float("inf"), [])
        distance, X = min(self.comm.allgather(local), key=lambda item: item[0])
        if not distance > 0.0:
            where = tuple(float(f"{v:.6g}") for v in X)
            raise ParameterError(
                f"{self.where}: the body starts on the wrong side of the {obstacle}: the node at {where} has "
                f"distance {distance:.6g} (need > 0{self.side_hint})"
            )
