r"""Default barrier width :math:`\hat d` and stiffness :math:`\kappa` of a contact, from the mesh and the material.

* :math:`\hat d` = :data:`DHAT_FRACTION` times the mean facet diameter
  :math:`h` of the contact boundary. A node at rest on an obstacle sits at a
  distance in :math:`(0, \hat d)`: 1 % of :math:`h` keeps that geometric error
  well below the discretisation error of the surface.
* :math:`\kappa` = :data:`STIFFNESS_FACTOR` times the mean normal stiffness of
  the body at the contact nodes, :math:`\bar k_n = \langle n^T K_{aa} n\rangle`
  (the diagonal of the elastic tangent at the state where the contact is
  bound, :math:`\approx (\lambda + 2\mu)\,h` up to a factor of order one for a
  linear-elastic body: the material modulus times the mesh size, for any
  energy). With :math:`b'' \ge 3.6` on :math:`(0, \hat d/2)` the barrier is then
  at least as stiff as the elements it pushes, and a node carries the force
  :math:`\kappa|b'(d)| \approx \kappa\hat d^2/d` at :math:`d \ll \hat d`.

This :math:`\kappa` is fixed for a run. IPC's adaptive stiffness (raise
:math:`\kappa` when a distance keeps shrinking, ``ipctk.update_barrier_stiffness``)
is a later slice of issue 19.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
import dolfinx.fem.petsc as fpetsc
from dolfinx import fem

from hyperfem.contact.nodes import BoundaryNodes, facet_size
from hyperfem.problem.protocol import SolidProblem

__all__ = ["DHAT_FRACTION", "STIFFNESS_FACTOR", "default_dhat", "default_stiffness", "mean_tangent_diagonal"]

DHAT_FRACTION = 1e-2
r""":math:`\hat d` by default: this fraction of the mean facet diameter of the contact boundary."""

STIFFNESS_FACTOR = 1.0
r""":math:`\kappa` by default: this factor times the mean normal tangent diagonal at the contact nodes."""


def default_dhat(problem: SolidProblem, boundary: str) -> float:
    r""":data:`DHAT_FRACTION` times the mean facet diameter of ``boundary`` (collective)."""
    return DHAT_FRACTION * facet_size(problem.domain, boundary)


def mean_tangent_diagonal(problem: SolidProblem, dofs: np.ndarray, weights: np.ndarray) -> float:
    r"""The mean over the rows of ``dofs`` of :math:`\sum_i w_i K_{d_i d_i}` at the current state (collective).

    Assembles the problem's tangent once (without boundary conditions).

    Args:
        problem: The problem.
        dofs: Owned local dofs, shape ``(m, k)``.
        weights: :math:`w`, shape ``(k,)`` (a normal squared, or :math:`1/k` for the mean of the components).
    """
    A = fpetsc.assemble_matrix(fem.form(problem.jacobian))
    A.assemble()
    diagonal = A.getDiagonal()
    try:
        values = diagonal.array_r[dofs] if len(dofs) else np.zeros((0, len(weights)))
        local = np.array([float((values * weights).sum()), float(len(values))])
    finally:
        diagonal.destroy()
        A.destroy()
    total, count = problem.domain.comm.allreduce(local, op=MPI.SUM)
    return float(total / count)


def default_stiffness(problem: SolidProblem, nodes: BoundaryNodes, normal: np.ndarray) -> float:
    r""":data:`STIFFNESS_FACTOR` times :math:`\bar k_n` (module docstring) at the current state (collective).

    Assembles the problem's tangent once (without boundary conditions).
    """
    return STIFFNESS_FACTOR * mean_tangent_diagonal(problem, nodes.dofs, np.asarray(normal, dtype=float) ** 2)
