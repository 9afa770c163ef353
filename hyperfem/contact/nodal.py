r"""What the barriers of contact nodes against a rigid obstacle share: energy, checks and outputs.

A rigid obstacle (a plane, a sphere) gives every contact node :math:`a` a
signed distance :math:`d_a(u)`, positive on the body's side; the barrier term
is :math:`\kappa B(u) = \kappa\sum_a b(d_a(u))` (:mod:`~hyperfem.contact.barrier`).
:class:`NodalBarrier` holds what does not depend on the obstacle's shape: the
energy, the admissibility check (a node on or through the obstacle), the
start check at binding, and the outputs (the force the obstacle exerts,
:math:`-\sum_a \kappa b'(d_a)\nabla d_a`, the active nodes, the smallest
distance). A subclass gives :meth:`~NodalBarrier.distances`,
:meth:`~NodalBarrier.gradient`, :meth:`~NodalBarrier.hessian` and
:meth:`~NodalBarrier.update`, and a ``step_filter``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from hyperfem.contact.barrier import barrier, barrier_derivatives
from hyperfem.contact.nodes import BoundaryNodes
from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import SolidProblem

__all__ = ["NodalBarrier"]


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
    behind = "on or behind the obstacle"
    """How a refused node is placed, for the messages."""
    side_hint = ""
    """What the start check's message adds (which side is the body's)."""

    def distances(self, u: np.ndarray) -> np.ndarray:
        """Signed distances :math:`d_a` of the owned nodes for the unknown's local array ``u``."""
        raise NotImplementedError

    def gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`\kappa b'(d_a)\nabla d_a` at the active nodes: ``(dofs, values)`` of shape ``(m, dim)``."""
        raise NotImplementedError

    def energy(self, u: np.ndarray) -> float:
        r"""This rank's :math:`\kappa\sum_a b(d_a)` (``inf`` if a node is on or through the obstacle)."""
        return self.stiffness * float(barrier(self.distances(u), self.dhat).sum())

    def _active(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rows of the nodes with :math:`d < \\hat d` and their :math:`b'`, :math:`b''`."""
        d = self.distances(u)
        rows = np.flatnonzero(d < self.dhat)
        first, second = barrier_derivatives(d[rows], self.dhat)
        return rows, first, second

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
        _, values = self.gradient(self._state(u))
        local = values.sum(axis=0) if len(values) else np.zeros(self.nodes.X.shape[1])
        return -self.comm.allreduce(local, op=MPI.SUM)

    def active_count(self, u: np.ndarray | PETSc.Vec | None = None) -> int:
        r"""Nodes with :math:`d_a < \hat d`, over all ranks (collective)."""
        return int(self.comm.allreduce(int((self.distances(self._state(u)) < self.dhat).sum()), op=MPI.SUM))

    def min_distance(self, u: np.ndarray | PETSc.Vec | None = None) -> float:
        """The smallest signed distance of a contact node, over all ranks (collective)."""
        d = self.distances(self._state(u))
        return float(self.comm.allreduce(float(d.min()) if len(d) else float("inf"), op=MPI.MIN))

    def record(self, step: object = None) -> dict[str, object]:
        """The output columns at the current state: ``<name>_force``, ``<name>_active``, ``<name>_min_distance``."""
        name = self.contact.name
        return {
            f"{name}_force": [float(v) for v in self.force()],
            f"{name}_active": self.active_count(),
            f"{name}_min_distance": self.min_distance(),
        }

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
