r"""The collision-free step filter of point–plane contact: analytic continuous collision detection.

A node at signed distance :math:`d_0 > 0` from a plane with unit normal
:math:`n`, moved along the trial step :math:`x - \alpha y` of the Newton
solver, is at :math:`d(\alpha) = d_0 - \alpha\,(y_a\cdot n)`: linear in
:math:`\alpha`. The filter returns the largest :math:`\alpha \in (0, 1]` at
which every node keeps at least :math:`(1 - s)` of its distance,

.. math::
    \alpha = \min\Bigl(1,\ \min_{a:\ y_a\cdot n > 0} \frac{s\,d_{0,a}}{y_a\cdot n}\Bigr),

:math:`s` the safety (:data:`CCD_SAFETY`; the same rule as IPC's conservative
rescaling of a time of impact). Every trial state of the line search then
has :math:`d > 0` at every node: no accepted iterate penetrates. The check
costs one pass over the owned contact nodes and one ``allreduce``; nothing of
the (slow, for this wheel) TightInclusion CCD of ``ipctk`` is needed for a
plane. It implements :class:`~hyperfem.solver.filters.NewtonStepFilter`,
composed with the inversion filter: :math:`\alpha = \min(\alpha_\text{inv}, \alpha_\text{CCD})`.

A node at :math:`q_0 = x_a - c` from the centre of a static ball of radius
:math:`R` (:func:`sphere_step_fraction`, :class:`SphereCollisionFilter`) is at
:math:`d(\alpha) = |q_0 - \alpha y_a| - R`, convex in :math:`\alpha`. The
filter takes the first root of :math:`|q_0 - \alpha y_a| = R + (1 - s)\,d_0`,
a quadratic,

.. math::
    |y_a|^2\alpha^2 - 2 (q_0\cdot y_a)\,\alpha + |q_0|^2 - R_s^2 = 0, \qquad
    \alpha_a = \frac{|q_0|^2 - R_s^2}{q_0\cdot y_a + \sqrt{(q_0\cdot y_a)^2 - |y_a|^2(|q_0|^2 - R_s^2)}},

(the cancellation-free form; no root when the node moves away or passes
by), so again every node keeps at least :math:`(1 - s)` of its distance over
the whole filtered step, and :math:`\alpha = \min(1, \min_a \alpha_a)`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from hyperfem.solver.filters import NoAdmissibleStep

__all__ = ["CCD_SAFETY", "PlaneCollisionFilter", "SphereCollisionFilter", "plane_step_fraction", "sphere_step_fraction"]

CCD_SAFETY = 0.9
r"""The safety :math:`s`: a node keeps at least :math:`1 - s` (10 %) of its distance over a filtered step."""


def plane_step_fraction(distance: np.ndarray, approach: np.ndarray, safety: float = CCD_SAFETY) -> float:
    r"""The largest :math:`\alpha \le 1` with :math:`d_0 - \alpha v \ge (1 - s) d_0` at every node (module docstring).

    Args:
        distance: :math:`d_0 > 0` per node.
        approach: :math:`v = y\cdot n` per node: how fast the full step closes the distance.
        safety: :math:`s \in (0, 1)`.
    """
    closing = approach > 0.0
    if not np.any(closing):
        return 1.0
    return float(min(1.0, (safety * distance[closing] / approach[closing]).min()))


class PlaneCollisionFilter:
    r"""A :class:`~hyperfem.solver.filters.NewtonStepFilter` that keeps contact nodes off a plane (module docstring).

    Args:
        dofs: Owned local dofs of the contact nodes, shape ``(m, dim)``.
        distances: The signed distances of the nodes for a local array of the unknown.
        normal: The plane's unit normal.
        safety: :math:`s` (:data:`CCD_SAFETY`).

    Attributes:
        cutbacks: Always 0 (the filter never halves).
        filtered_steps: Newton steps it shortened.
        min_step_fraction: The smallest fraction it allowed since the solver reset it.
        min_distance: The smallest distance of an iterate it has seen since the
            last reset to ``inf`` (every Newton iterate but the last passes through it).
    """

    def __init__(
        self,
        dofs: np.ndarray,
        distances: Callable[[np.ndarray], np.ndarray],
        normal: np.ndarray,
        safety: float = CCD_SAFETY,
    ):
        self.dofs = dofs
        self.distances = distances
        self.normal = np.asarray(normal, dtype=float)
        self.safety = float(safety)
        self.cutbacks = 0
        self.filtered_steps = 0
        self.min_step_fraction = 1.0
        self.min_distance = float("inf")

    def step_fraction(self, x: PETSc.Vec, y: PETSc.Vec) -> float:
        """The fraction of the step (collective).

        Raises:
            NoAdmissibleStep: A node of the current iterate is on or behind the plane.
        """
        comm = x.getComm().tompi4py()
        d0 = self.distances(x.array_r)
        approach = y.array_r[self.dofs] @ self.normal if len(self.dofs) else np.zeros(0)
        lowest = comm.allreduce(float(d0.min()) if len(d0) else float("inf"), op=MPI.MIN)
        self.min_distance = min(self.min_distance, lowest)
        if not lowest > 0.0:
            raise NoAdmissibleStep(f"a contact node is on or behind the obstacle (distance {lowest:.3g})")
        fraction = comm.allreduce(plane_step_fraction(d0, approach, self.safety), op=MPI.MIN)
        if fraction < 1.0:
            self.filtered_steps += 1
            self.min_step_fraction = min(self.min_step_fraction, fraction)
        return fraction


def sphere_step_fraction(offset: np.ndarray, step: np.ndarray, radius: float, safety: float = CCD_SAFETY) -> float:
    r"""The largest :math:`\alpha \le 1` over which every node keeps :math:`|q_0 - \alpha y| - R \ge (1 - s) d_0`.

    The first root of the quadratic of the module docstring, per node.

    Args:
        offset: :math:`q_0 = x - c` per node, shape ``(m, dim)``, with :math:`|q_0| > R`.
        step: :math:`y` per node, shape ``(m, dim)`` (the trial positions are :math:`x - \alpha y`).
        radius: :math:`R`.
        safety: :math:`s \in (0, 1)`.
    """
    if not len(offset):
        return 1.0
    norm = np.linalg.norm(offset, axis=1)
    reach = radius + (1.0 - safety) * (norm - radius)  # R_s: the ball inflated by the distance each node keeps
    a = np.einsum("ij,ij->i", step, step)
    b = np.einsum("ij,ij->i", offset, step)
    c = (norm - reach) * (norm + reach)
    disc = b * b - a * c
    hit = (b > 0.0) & (disc >= 0.0) & (a > 0.0)
    if not np.any(hit):
        return 1.0
    roots = c[hit] / (b[hit] + np.sqrt(disc[hit]))
    return float(min(1.0, roots.min()))


class SphereCollisionFilter:
    r"""A :class:`~hyperfem.solver.filters.NewtonStepFilter` that keeps contact nodes outside a ball (module docstring).

    Args:
        dofs: Owned local dofs of the contact nodes, shape ``(m, dim)``.
        X: Their reference coordinates, shape ``(m, dim)``.
        center: The ball's centre now (called: it moves with the time).
        radius: :math:`R`.
        safety: :math:`s` (:data:`CCD_SAFETY`).
        projector: For a cylinder, :math:`P = I - a a^T`: offsets and steps are
            projected onto the plane normal to the axis, where the cylinder is a
            circle and the same quadratic holds (``None``: a ball).

    Attributes:
        cutbacks: Always 0 (the filter never halves).
        filtered_steps: Newton steps it shortened.
        min_step_fraction: The smallest fraction it allowed since the solver reset it.
        min_distance: The smallest distance of an iterate it has seen since the last reset to ``inf``.
    """

    def __init__(
        self,
        dofs: np.ndarray,
        X: np.ndarray,
        center: Callable[[], np.ndarray],
        radius: float,
        safety: float = CCD_SAFETY,
        projector: np.ndarray | None = None,
    ):
        self.dofs = dofs
        self.X = X
        self.center = center
        self.radius = float(radius)
        self.projector = projector
        self.safety = float(safety)
        self.cutbacks = 0
        self.filtered_steps = 0
        self.min_step_fraction = 1.0
        self.min_distance = float("inf")

    def step_fraction(self, x: PETSc.Vec, y: PETSc.Vec) -> float:
        """The fraction of the step (collective).

        Raises:
            NoAdmissibleStep: A node of the current iterate is on or inside the ball.
        """
        comm = x.getComm().tompi4py()
        offset = self.X + x.array_r[self.dofs] - self.center()
        step = y.array_r[self.dofs]
        if self.projector is not None:  # a cylinder: the motion in the plane normal to its axis
            offset, step = offset @ self.projector, step @ self.projector
        d0 = np.linalg.norm(offset, axis=1) - self.radius
        lowest = comm.allreduce(float(d0.min()) if len(d0) else float("inf"), op=MPI.MIN)
        self.min_distance = min(self.min_distance, lowest)
        if not lowest > 0.0:
            raise NoAdmissibleStep(f"a contact node is on or inside the sphere (distance {lowest:.3g})")
        fraction = comm.allreduce(sphere_step_fraction(offset, step, self.radius, self.safety), op=MPI.MIN)
        if fraction < 1.0:
            self.filtered_steps += 1
            self.min_step_fraction = min(self.min_step_fraction, fraction)
        return fraction
