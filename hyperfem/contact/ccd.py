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
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from hyperfem.solver.filters import NoAdmissibleStep

__all__ = ["CCD_SAFETY", "PlaneCollisionFilter", "plane_step_fraction"]

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
