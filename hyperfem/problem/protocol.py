r"""What a *problem* is: the contract between problems, solvers, time integrators and outputs.

Every problem — the displacement problem
(:class:`~hyperfem.problem.HyperelasticProblem`), the three-field problem
(:class:`~hyperfem.problem.MixedHyperelasticProblem`), and a time step of
either (:class:`~hyperfem.dynamics.IncrementalProblem`) — meets
:class:`SolidProblem`; :class:`~hyperfem.solver.NewtonSolver`, the dynamics
package and the outputs rely on nothing else.

The unknown ``u`` is a :class:`dolfinx.fem.Function` on a space that is the
displacement space or has it as its first block;
:meth:`SolidProblem.displacement` gives the displacement of any function on
that space as a UFL expression, :meth:`SolidProblem.displacement_space` the
(sub)space, so code written for the displacement problem works for the mixed
one.

Time: ``t`` is the pseudo-time of a quasi-static ramp (the load factor, 0 → 1)
or the physical time of a dynamic run. :meth:`SolidProblem.set_time` moves loads
and updaters to ``t_loads`` and Dirichlet values to ``t_bcs`` (the same unless
a scheme evaluates them apart, as generalized-α does).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
import ufl
from dolfinx import fem

from hyperfem.mesh.domain import Domain

__all__ = ["SolidProblem", "Updater"]


@runtime_checkable
class Updater(Protocol):
    """Anything with ``update(t)`` that a problem calls from :meth:`SolidProblem.set_time` (e.g. an activation)."""

    def update(self, t: float) -> None:
        """Move to time ``t``."""


@runtime_checkable
class SolidProblem(Protocol):
    """The problem contract (see the module docstring).

    Attributes:
        domain: Mesh with named groups.
        u: The unknown (displacement, or mixed state with the displacement first).
        degree: Lagrange degree of the displacement.
        quadrature_degree: Degree of the volume rule.
        energy_internal: UFL form of everything but the dead-load work.
        energy_external: UFL form of the dead-load work (:math:`\\Pi` = internal − external).
        follower_residual: Residual of non-conservative loads, or ``None``.
        residual: UFL residual form (derivative of :math:`\\Pi` plus follower terms).
        jacobian: UFL tangent form (derivative of the residual).
        conservative: Whether :math:`\\Pi` is a valid line-search merit function.
        rigid_motion_resisted: Whether the tangent is regular without Dirichlet
            conditions (inertia); static problems need conditions that fix
            every rigid-body motion.
        invertible: *Optional* (read it with ``getattr(problem, "invertible", False)``):
            whether every energy is finite and restoring for :math:`J \\le 0`
            (:mod:`hyperfem.materials.invertibility`), so the solver may drop
            its inversion guard. Not a required member, so that problems
            written before it still meet the protocol.
    """

    domain: Domain
    u: fem.Function
    degree: int
    quadrature_degree: int
    energy_internal: ufl.Form
    energy_external: ufl.Form
    follower_residual: ufl.Form | None
    residual: ufl.Form
    jacobian: ufl.Form
    conservative: bool
    rigid_motion_resisted: bool

    @property
    def bcs(self) -> list[fem.DirichletBC]:
        """DOLFINx Dirichlet conditions on ``u`` (values follow :meth:`set_time`)."""

    @property
    def time(self) -> float:
        """The time the loads are at."""

    def set_time(self, t_loads: float, t_bcs: float | None = None) -> None:
        """Move loads and updaters to ``t_loads``, Dirichlet values to ``t_bcs`` (default: the same)."""

    def displacement(self, state: fem.Function | None = None) -> ufl.core.expr.Expr:
        """The displacement of ``state`` (default ``u``), a function on ``u``'s space, as UFL."""

    def displacement_space(self) -> fem.FunctionSpace:
        """The (sub)space of ``u.function_space`` that holds the displacement."""

    def volume_jacobian(self) -> ufl.core.expr.Expr:
        """The volume ratio guarded against inversion (``det F``; ``min(J, θ)`` for the mixed problem)."""

    def quadrature_points(self) -> np.ndarray:
        """Reference points of the volume rule (for :class:`dolfinx.fem.Expression`)."""

    def check_solution(self) -> tuple[dict[str, float], str | None]:
        """Consistency indicators of a converged state and, if it is not a solution, why."""

    def nonfinite_terms(self) -> list[str]:
        """Names of load terms whose residual is NaN/inf at the current state."""
