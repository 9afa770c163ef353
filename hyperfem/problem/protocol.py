r"""What a *problem* is: the contract between problems, solvers, time integrators and outputs.

Every problem — the displacement problem
(:class:`~hyperfem.problem.HyperelasticProblem`), the three-field problem
(:class:`~hyperfem.problem.MixedHyperelasticProblem`), and a time step of
either (:class:`~hyperfem.dynamics.IncrementalProblem`) — meets
:class:`SolidProblem`; :class:`~hyperfem.solver.NewtonSolver`, the dynamics
package and the outputs rely on nothing else, except the optional contracts
declared here too, which they test with ``isinstance`` rather than probe for:
:class:`InvertibleProblem`, :class:`StateHookedProblem` and
:class:`CorrectedTangentProblem` (members of the displacement problems),
:class:`MixedProblemProtocol` (the three-field problem) and
:class:`TimeStepProblem` / :class:`TimeStepState` (a time step wrapping the
problem of a body). :class:`EnergyProtocol` is what a problem reads of a
stored energy; a plain callable ``psi(F)`` is given neutral extras by
:func:`hyperfem.problem.energy.as_energy`.

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

from collections.abc import Callable, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np
import ufl
from dolfinx import fem

from hyperfem.mesh.domain import Domain

__all__ = [
    "CorrectedTangentProblem",
    "EnergyProtocol",
    "InvertibleProblem",
    "MixedProblemProtocol",
    "SolidProblem",
    "StateHookedProblem",
    "TimeStepProblem",
    "TimeStepState",
    "Updater",
]


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

    The optional members are declared apart, so that problems written
    before them still meet this protocol: :class:`InvertibleProblem`,
    :class:`StateHookedProblem`, :class:`CorrectedTangentProblem`,
    :class:`MixedProblemProtocol` and :class:`TimeStepProblem`.
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


@runtime_checkable
class EnergyProtocol(Protocol):
    r"""A stored energy :math:`\psi(F)` with every optional extra a problem reads.

    A plain callable ``psi(F)`` has none of them;
    :func:`hyperfem.problem.energy.as_energy` gives it the neutral ones.

    Attributes:
        invertible: Whether the energy is finite and restoring for :math:`J \le 0`
            (:mod:`hyperfem.materials.invertibility`).
        state_hooks: Callables ``hook()`` the solver runs at every new state before assembling.
        updaters: Objects with ``update(t)`` the problem moves with its loads.
        quadrature_rule_degree: Degree of the rule whose points hold the energy's
            fields (``None``: it holds none).
    """

    @property
    def invertible(self) -> bool:
        """Whether the energy is finite and restoring for :math:`J \\le 0`."""

    @property
    def state_hooks(self) -> Sequence[Callable[[], None]]:
        """Callables ``hook()`` the solver runs at every new state before assembling."""

    @property
    def updaters(self) -> Sequence[Updater]:
        """Objects with ``update(t)`` the problem moves with its loads."""

    @property
    def quadrature_rule_degree(self) -> int | None:
        """Degree of the rule whose points hold the energy's fields (``None``: none)."""

    def __call__(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """The energy density at the deformation gradient ``F``."""

    def bind(self, F: ufl.core.expr.Expr, quadrature_degree: int) -> None:
        """Attach the energy's fields to the problem's ``F`` on the volume rule of ``quadrature_degree``."""

    def tangent_correction(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr | None:
        """A pseudo-energy whose second variation is added to the tangent only (``None``: none)."""


@runtime_checkable
class InvertibleProblem(Protocol):
    r"""A problem that says whether every energy is finite and restoring for :math:`J \le 0`.

    Attributes:
        invertible: Whether the solver may drop its inversion guard.
    """

    invertible: bool


@runtime_checkable
class StateHookedProblem(Protocol):
    """A problem with callables ``hook()`` the solver runs at every new state before assembling.

    Attributes:
        state_hooks: The hooks (e.g. polar-rotation refreshes).
    """

    state_hooks: Sequence[Callable[[], None]]


@runtime_checkable
class CorrectedTangentProblem(Protocol):
    """A problem whose tangent carries a term that is not the derivative of its residual.

    Attributes:
        tangent_correction: Form whose second variation was added to the
            jacobian only (``None``: the plain derivative).
    """

    tangent_correction: ufl.Form | None


@runtime_checkable
class MixedProblemProtocol(SolidProblem, Protocol):
    """The three-field (saddle-point) problem: displacement, pressure and volume blocks.

    Attributes:
        saddle_point: ``True``: the tangent is indefinite.
    """

    saddle_point: bool

    def field_dofs(self) -> dict[str, np.ndarray]:
        """Local dofs of ``u`` in each field (``"displacement"``, ``"pressure"``, ``"volume"``)."""

    def schur_preconditioner_term(self) -> ufl.Form:
        """The pressure-mass form that preconditions the Schur complement."""

    def update_fields(self) -> tuple[fem.Function, fem.Function]:
        """The collapsed displacement and pressure at the current state."""


@runtime_checkable
class TimeStepState(Protocol):
    """A time step's wrapper around the problem of a body (implicit or explicit).

    Attributes:
        base: The problem of the body.
        v: Velocity.
    """

    base: SolidProblem
    v: fem.Function


@runtime_checkable
class TimeStepProblem(SolidProblem, Protocol):
    """One time step of a problem (what a dynamic stage drives).

    Attributes:
        base: The problem of the body.
        integrator: The time integrator.
        v: Velocity.
        a: Acceleration.
        t_n: Time of the last accepted state.
    """

    base: SolidProblem
    integrator: Any
    v: fem.Function
    a: fem.Function
    t_n: float

    def save(self) -> Any:
        """A snapshot of the accepted state (time, displacement, velocity, acceleration)."""

    def restore(self, state: Any) -> None:
        """Back to a snapshot from :meth:`save`."""

    def prepare(self, dt: float) -> None:
        """Set the step's predictors for a step of size ``dt``."""

    def commit(self, dt: float, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray) -> None:
        """Accept the step from the state ``(u_n, v_n, a_n)``."""

    def step_inputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copies of the accepted state ``(u_n, v_n, a_n)``."""
