r"""What every energy-based problem shares: loads, residual, tangent, time.

Given the stored energy form, :class:`EnergyProblem` adds the loads
(:func:`~hyperfem.problem.loads.load_terms`) and derives

.. math::
    R = \frac{\partial (\Pi_\text{int} - W_\text{dead})}{\partial w}[v] + R_\text{follower},
    \qquad K = \frac{\partial R}{\partial w}[\delta w]

with ``ufl.derivative``; :meth:`set_time` moves loads, prescribed
displacements and any *updaters* (e.g. muscle activation) to time ``t`` (the
load factor of a quasi-static ramp, or physical time). :class:`EnergyProblem`
meets :class:`~hyperfem.problem.protocol.SolidProblem`.

A subclass may pass a *tangent correction*: a form :math:`C` whose second
variation is added to the tangent only,
:math:`K \mathrel{+}= \partial^2 C/\partial w^2[v, \delta w]` (the
:math:`\partial R/\partial F` term of energies with a polar rotation held
in a quadrature field, :mod:`hyperfem.materials.fixed_corotated`). Two more
attributes tell the solver about the materials: ``invertible`` (the energy is
finite and restoring for :math:`J \le 0`, so no inversion guard is needed)
and ``state_hooks`` (callables to run at every new state before assembly).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.mesh.budget import check_problem_size
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.orientation import check_cell_volumes
from hyperfem.problem.boundary_conditions import DirichletAgreement, _CompiledDirichlet
from hyperfem.problem.loads import Load, LoadTerms, load_terms
from hyperfem.problem.protocol import Updater
from hyperfem.problem.quadrature import unify_quadrature

__all__ = ["EnergyProblem"]


class EnergyProblem:
    """Base of :class:`~hyperfem.problem.HyperelasticProblem` and the mixed problem.

    Subclasses set ``domain``, ``u``, ``F``, ``degree``, ``quadrature_degree``,
    ``energy_internal`` and ``_dirichlet``, then call :meth:`_derive_forms`.
    """

    rigid_motion_resisted = False
    """Static problems need Dirichlet conditions that fix every rigid-body motion."""

    invertible = False
    """Whether every energy is finite and restoring for :math:`J \\le 0` (the solver may drop its inversion guard)."""

    state_hooks: tuple[Callable[[], None], ...] = ()
    """Callables ``hook()`` the solver runs at every new state before assembling (e.g. polar-rotation refreshes)."""

    tangent_correction: ufl.Form | None = None
    """Form whose second variation was added to :attr:`jacobian` only (``None``: the plain derivative)."""

    # Set by the subclass before _derive_forms:
    domain: Domain
    u: fem.Function
    F: ufl.core.expr.Expr
    degree: int
    quadrature_degree: int
    energy_internal: ufl.Form
    _dirichlet: list[_CompiledDirichlet]
    # Set by _derive_forms:
    energy_external: ufl.Form
    follower_residual: ufl.Form | None
    energy: ufl.Form
    residual: ufl.Form
    jacobian: ufl.Form
    conservative: bool
    _updaters: list[Updater]
    _loads: LoadTerms

    def _check_domain(self, domain: Domain, fields: Sequence[tuple[int, int]], quadrature_degree: int) -> None:
        """Refuse cells without volume and spaces too large for the machine, before building them (collective).

        Subclasses call it before their function spaces exist. Too large: the
        estimate of :func:`~hyperfem.mesh.budget.check_problem_size` exceeds the
        available memory, unless ``HYPERFEM_ALLOW_LARGE=1`` (or
        :func:`~hyperfem.mesh.budget.allow_large_problems` in effect).

        Args:
            domain: The mesh.
            fields: ``(components, degree)`` of each field of the space.
            quadrature_degree: Degree of the volume rule.

        Raises:
            MeshError: The mesh has cells without volume (the message ``hyperfem run`` gives).
            ProblemSizeError: The space would not fit in memory.
        """
        check_cell_volumes(domain)
        check_problem_size(domain, fields, quadrature_degree, type(self).__name__)

    def _derive_forms(
        self,
        displacement: ufl.core.expr.Expr,
        test: ufl.Argument,
        test_displacement: ufl.core.expr.Expr,
        trial: ufl.Argument,
        loads: Sequence[Load],
        conservative: bool | None = None,
        updaters: Iterable[Updater] = (),
        tangent_correction: ufl.Form | None = None,
    ) -> None:
        md = {"quadrature_degree": self.quadrature_degree}
        domain = self.domain
        where = type(self).__name__
        self._updaters = list(updaters)
        self._loads = load_terms(loads, domain, displacement, test_displacement, self.F, md, where)
        zero = fem.Constant(domain.mesh, 0.0) * ufl.dot(displacement, displacement) * domain.dx(metadata=md)
        external = self._loads.external if self._loads.external is not None else zero
        # One rule per integral type across energy, loads and follower terms (FFCx 0.11).
        internal, external, self.follower_residual, tangent_correction = unify_quadrature(
            self.energy_internal, external, self._loads.follower, tangent_correction
        )
        assert internal is not None and external is not None  # unify_quadrature maps None to None only
        self.energy_internal, self.energy_external = internal, external
        self.conservative = (self.follower_residual is None) if conservative is None else conservative
        self.energy = self.energy_internal - self.energy_external
        self.residual = ufl.derivative(self.energy, self.u, test)
        if self.follower_residual is not None:
            self.residual = self.residual + self.follower_residual
        self.jacobian = ufl.derivative(self.residual, self.u, trial)
        self.tangent_correction = tangent_correction
        if tangent_correction is not None:
            self.jacobian = self.jacobian + ufl.derivative(
                ufl.derivative(tangent_correction, self.u, test), self.u, trial
            )
        self._time = 0.0
        imap = self.u.function_space.dofmap.index_map
        owned = imap.size_local * self.u.function_space.dofmap.index_map_bs
        x = domain.mesh.geometry.x
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        domain.comm.Allreduce(x.min(axis=0, initial=np.inf), lo, op=MPI.MIN)
        domain.comm.Allreduce(x.max(axis=0, initial=-np.inf), hi, op=MPI.MAX)
        self._agreement = DirichletAgreement(
            self._dirichlet, self.u.x.array.size, owned, domain.comm, length=float(np.linalg.norm(hi - lo))
        )
        if self._agreement.pairs and not self._agreement.parametric:
            # Boundary values that meet are compared at every set_time; here also at the end of a
            # unit ramp, so that a quasi-static case is refused before it runs. Not for values
            # given as value(x, t) (motions of a time integration, defined on its own interval),
            # nor where a profile cannot be evaluated at 1 (checked when set, at the run's times).
            try:
                for d in self._dirichlet:
                    d.update(1.0)
            except ParameterError:
                pass
            else:
                self._agreement.check(1.0)
        self.set_time(0.0)

    @property
    def bcs(self) -> list[fem.DirichletBC]:
        """The DOLFINx Dirichlet conditions (values follow :meth:`set_time`)."""
        return [d for c in self._dirichlet for d in c.dirichlet]

    @property
    def time(self) -> float:
        """The time (load factor of a quasi-static ramp) the loads are at."""
        return self._time

    @property
    def updaters(self) -> tuple[Updater, ...]:
        """What :meth:`set_time` moves besides loads and boundary values (the given updaters and the energies' own)."""
        return tuple(self._updaters)

    def set_time(self, t_loads: float, t_bcs: float | None = None) -> None:
        """Move loads and updaters to ``t_loads`` and prescribed displacements to ``t_bcs``.

        Args:
            t_loads: Time of the loads and updaters.
            t_bcs: Time of the Dirichlet values; default ``t_loads`` (schemes
                such as generalized-α evaluate them apart).
        """
        t_bcs = t_loads if t_bcs is None else t_bcs
        self._time = float(t_loads)
        self._loads.set(t_loads)
        for d in self._dirichlet:
            d.update(t_bcs)
        self._agreement.check(t_bcs)
        for updater in self._updaters:
            updater.update(t_loads)

    def displacement(self, state: fem.Function | None = None) -> ufl.core.expr.Expr:
        """The displacement of ``state`` (default :attr:`u`): the function itself here."""
        return self.u if state is None else state

    def displacement_space(self) -> fem.FunctionSpace:
        """The space of :attr:`u` (all of it is displacement here)."""
        return self.u.function_space

    def check_solution(self) -> tuple[dict[str, float], str | None]:
        """Consistency indicators of a converged state, and why it is not a solution (if it is not).

        Called by :class:`~hyperfem.solver.NewtonSolver` after SNES reports
        convergence; a message turns the solve into a failure (so stepping
        cuts back instead of accepting a spurious stationary point). The
        displacement formulation has nothing to check.

        Returns:
            ``(indicators, message)``: indicator name → value (recorded in the
            :class:`~hyperfem.solver.SolveRecord`), and ``None`` or a one-line
            reason.
        """
        return {}, None

    def nonfinite_terms(self) -> list[str]:
        """Names of the load terms whose residual is NaN/inf at the current state (for error messages)."""
        bad = []
        for load, form in self._loads.parts:
            compiled = fem.form(form)
            if compiled.rank == 0:
                value = self.domain.comm.allreduce(fem.assemble_scalar(compiled), op=MPI.SUM)
                ok = np.isfinite(value)
            else:
                vec = fem.assemble_vector(compiled)
                ok = self.domain.comm.allreduce(bool(np.all(np.isfinite(vec.array))), op=MPI.LAND)
            if not ok:
                # Boundary: a load names a boundary, a region, or (a user's Load) neither.
                where = getattr(load, "boundary", None) or getattr(load, "region", None)
                bad.append(f"{type(load).__name__}" + (f" on {where!r}" if where else ""))
        if not bad:
            value = self.domain.comm.allreduce(fem.assemble_scalar(fem.form(self.energy_internal)), op=MPI.SUM)
            if not np.isfinite(value):
                bad.append("the stored energy (material)")
        return bad

    def volume_jacobian(self) -> ufl.core.expr.Expr:
        """:math:`J = \\det F` as a UFL expression (for inversion checks and output)."""
        return ufl.det(self.F)

    def quadrature_points(self) -> np.ndarray:
        """Reference quadrature points of the volume rule (for :class:`dolfinx.fem.Expression`)."""
        import basix

        pts, _ = basix.make_quadrature(self.domain.mesh.basix_cell(), self.quadrature_degree)
        return pts  # type: ignore[return-value]  # basix declares ArrayLike, returns an ndarray
