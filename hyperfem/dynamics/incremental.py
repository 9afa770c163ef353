r"""One time step as a nonlinear problem for :class:`~hyperfem.solver.NewtonSolver`.

:class:`IncrementalProblem` composes any problem that meets
:class:`~hyperfem.problem.protocol.SolidProblem` — the displacement problem
or the three-field :math:`(u, p, \theta)` problem — with a
:class:`~hyperfem.dynamics.integrators.TimeIntegrator`, a
:class:`~hyperfem.dynamics.mass.MassDensity` and optional
:class:`~hyperfem.dynamics.damping.RayleighDamping` into the incremental potential

.. math::
    \Pi_\Delta(w) = \frac{A}{2}\int_\Omega \rho\,|u - \tilde u|^2\,dX
      + \frac{B}{2}(u - \hat u)^T C (u - \hat u)
      + \frac{1}{1-\alpha_f}\,\Pi(w_{\alpha}),\qquad u_\alpha = (1-\alpha_f)u + \alpha_f u_n ,

where :math:`w` is the base problem's state and :math:`u` its displacement
(:meth:`~hyperfem.problem.protocol.SolidProblem.displacement`). Only the
displacement has a rate: velocity, acceleration and the predictors
:math:`\tilde u, \hat u` are functions on the state's space whose other
blocks (pressure, volume ratio) are zero, and generalized-:math:`\alpha`
weights the displacement only — the pressure and volume fields of
:math:`w_\alpha` are those of :math:`t_{n+1}` (they are constraint fields,
not states of motion). For the displacement problem :math:`w = u`.

``energy_internal`` holds everything but the dead-load work, so
:class:`~hyperfem.solver.NewtonSolver` uses :math:`\Pi_\Delta` as its
line-search objective exactly as for a static problem (when the base problem
is conservative), its inversion pre-check acts on the base problem's
:meth:`~hyperfem.problem.protocol.SolidProblem.volume_jacobian` at
:math:`t_{n+1}`, and its boundary-increment predictor carries prescribed
boundary motion into the interior. All step-size dependent quantities are
:class:`dolfinx.fem.Constant` or :class:`dolfinx.fem.Function` values: the
forms are compiled once.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem

from hyperfem.dynamics.damping import RayleighDamping, reference_stiffness_form
from hyperfem.dynamics.integrators import TimeIntegrator
from hyperfem.dynamics.mass import MassDensity
from hyperfem.errors import ParameterError, SolverError
from hyperfem.problem.protocol import CorrectedTangentProblem, InvertibleProblem, SolidProblem, StateHookedProblem
from hyperfem.problem.quadrature import unify_cell_quadrature
from hyperfem.solver.linear import LinearSolver

__all__ = ["DisplacementBlock", "DynamicState", "IncrementalProblem"]

Expr = ufl.core.expr.Expr


class DynamicState:
    """A copy of :math:`(t, w, v, a)` to restore a rejected step."""

    def __init__(self, t: float, u: np.ndarray, v: np.ndarray, a: np.ndarray):
        self.t, self.u, self.v, self.a = float(t), u.copy(), v.copy(), a.copy()


class DisplacementBlock:
    """Where the displacement sits in the state of a :class:`~hyperfem.problem.protocol.SolidProblem`.

    The protocol puts the displacement first: the state ``u`` lives on the
    displacement space itself or on a mixed space whose first block is the
    displacement.

    Args:
        problem: The problem.

    Attributes:
        space: The displacement space, collapsed (the state's own space when
            the whole state is the displacement).
        dofs: Local indices (ghosts included) into the state's array of the
            entries of :attr:`space`, or ``None`` when the whole state is the
            displacement.
        gdim: Number of displacement components.
    """

    def __init__(self, problem: SolidProblem):
        W = problem.u.function_space
        Vd = problem.displacement_space()
        self.gdim = problem.domain.gdim
        self._shape = problem.u.ufl_shape
        if not Vd.component():  # the whole space
            self.space, self.dofs = W, None
        else:
            self.space, dofs = Vd.collapse()
            self.dofs = np.asarray(dofs[0] if isinstance(dofs, list) else dofs, dtype=np.int32)
        self._copy: fem.Function | None = None

    @property
    def whole(self) -> bool:
        """Whether the state is all displacement."""
        return self.dofs is None

    def restrict(self, array: np.ndarray) -> np.ndarray:
        """Zero, in place, the entries of a state array that are not displacement; returns it."""
        if self.dofs is not None:
            keep = array[self.dofs]
            array[:] = 0.0
            array[self.dofs] = keep
        return array

    def function(self, state: fem.Function) -> fem.Function:
        """The displacement of ``state`` as a function on :attr:`space` (``state`` itself when whole).

        The copy is one function, refreshed by every call.
        """
        if self.dofs is None:
            return state
        if self._copy is None:
            self._copy = fem.Function(self.space, name="displacement")
        self._copy.x.array[:] = state.x.array[self.dofs]
        return self._copy

    def insert(self, displacement: np.ndarray, state: fem.Function) -> None:
        """Write an array of :attr:`space` into the displacement entries of ``state`` (others untouched)."""
        if self.dofs is None:
            state.x.array[:] = displacement
        else:
            state.x.array[self.dofs] = displacement

    def embed(self, displacement: Expr) -> Expr:
        """A state-shaped UFL vector with ``displacement`` in the displacement block, zero elsewhere."""
        if self.dofs is None:
            return displacement
        rest = [0.0] * (self._shape[0] - self.gdim)
        return ufl.as_vector([displacement[i] for i in range(self.gdim)] + rest)

    def mask(self, state: Expr) -> Expr:
        """``state`` (a state-shaped UFL expression) with every block but the displacement zeroed."""
        if self.dofs is None:
            return state
        n = self._shape[0]
        return ufl.as_vector([state[i] for i in range(self.gdim)] + [0.0] * (n - self.gdim))


class IncrementalProblem:
    """The nonlinear problem of one time step; meets :class:`~hyperfem.problem.protocol.SolidProblem`.

    Args:
        base: The problem of the body (forms, loads, boundary conditions):
            any :class:`~hyperfem.problem.protocol.SolidProblem`.
        integrator: Time-stepping scheme.
        density: Mass density (and lumping); ignored by quasi-static schemes.
        damping: Rayleigh damping; ``None`` for none. For a three-field base
            the stiffness-proportional part uses the reference tangent in
            displacement directions at :math:`p = 0, \\theta = 1` (the
            isochoric stiffness: pressure and volume have no rate).
        linear_solver: Configuration of the initial-acceleration (mass) solve.

    Attributes:
        u: The state :math:`w_{n+1}` (the base problem's unknown).
        v, a: Velocity and acceleration at :math:`t_n` (functions on the
            state's space, zero outside the displacement block).
        t_n: Time of the last accepted state.
        displacement_block: Where the displacement sits in the state.
    """

    def __init__(
        self,
        base: SolidProblem,
        integrator: TimeIntegrator,
        density: MassDensity | None = None,
        damping: RayleighDamping | None = None,
        *,
        linear_solver: LinearSolver | None = None,
    ):
        if not isinstance(base, SolidProblem):
            raise ParameterError(
                f"IncrementalProblem: base must meet the SolidProblem protocol, got {type(base).__name__}"
            )
        self.base = base
        self.integrator = integrator
        self.linear_solver = LinearSolver() if linear_solver is None else linear_solver
        # Inertia makes the tangent regular without Dirichlet conditions.
        self.rigid_motion_resisted = bool(integrator.dynamic) or base.rigid_motion_resisted
        self.state_hooks = tuple(base.state_hooks) if isinstance(base, StateHookedProblem) else ()
        self.domain = base.domain
        self.degree = base.degree
        self.quadrature_degree = base.quadrature_degree
        self.u = base.u
        self.V = base.u.function_space
        self.t_n = float(base.time)
        # (t_loads, t_bcs) of the step being solved and of the last accepted one (dirichlet_time)
        self._step_times: tuple[float, float] | None = None
        self._accepted_times: tuple[float, float] | None = None
        self.damping = damping if damping is not None and damping.active else None
        if integrator.dynamic and density is None:
            raise ParameterError("IncrementalProblem: a dynamic scheme needs a MassDensity")
        self.density = density
        self.displacement_block = DisplacementBlock(base)
        mesh = self.domain.mesh
        self.v = fem.Function(self.V, name="velocity")
        self.a = fem.Function(self.V, name="acceleration")
        self._u_n = fem.Function(self.V)
        self._u_tilde = fem.Function(self.V)
        self._u_hat = fem.Function(self.V)
        self._A = fem.Constant(mesh, 0.0)
        self._B = fem.Constant(mesh, 0.0)

        alpha = self._alpha_state()
        internal = self._at_alpha(base.energy_internal, alpha)
        external = self._at_alpha(base.energy_external, alpha)
        follower = base.follower_residual
        if follower is not None:
            follower = self._at_alpha(follower, alpha, scaled=False)
        if integrator.dynamic:
            internal = self._add_inertia_and_damping(internal)
        md = self._step_rule()
        if md is not None:
            internal = unify_cell_quadrature(internal, md)
            external = unify_cell_quadrature(external, md)
            if follower is not None:
                follower = unify_cell_quadrature(follower, md)
        self._unified_md = md
        self._derive_step_forms(internal, external, follower, alpha, md)
        self._compile_diagnostics()

    def _alpha_state(self) -> tuple[Expr, float] | None:
        r"""``(w_alpha, 1/(1 - alpha_f))`` of generalized-:math:`\alpha`, or ``None`` when :math:`\alpha_f = 0`.

        Only the displacement block is weighted: :math:`u_\alpha = (1-\alpha_f)u + \alpha_f u_n`.
        """
        af = float(self.integrator.alpha_f)
        if not af:
            return None
        u, block = self.u, self.displacement_block
        if block.whole:
            u_alpha = (1.0 - af) * u + af * self._u_n
        else:
            u_alpha = u + af * block.mask(self._u_n - u)
        return u_alpha, 1.0 / (1.0 - af)

    def _at_alpha(self, form: ufl.Form, alpha: tuple[Expr, float] | None, *, scaled: bool = True) -> ufl.Form:
        r"""``form`` at :math:`w_\alpha`, times :math:`1/(1-\alpha_f)` when ``scaled``."""
        if alpha is None:
            return form
        u_alpha, scale = alpha
        replaced = ufl.replace(form, {self.u: u_alpha})
        return scale * replaced if scaled else replaced

    def _add_inertia_and_damping(self, internal: ufl.Form) -> ufl.Form:
        r"""``internal`` plus the inertia term :math:`\frac{A}{2}\int\rho|u - \tilde u|^2` and the Rayleigh terms."""
        base, block, density, degree = self.base, self.displacement_block, self.density, self.base.degree
        assert density is not None  # a dynamic scheme has one (checked by __init__)
        disp = base.displacement
        u = self.u
        du = disp(u) - disp(self._u_tilde)
        internal = internal + 0.5 * self._A * density.integral(ufl.dot(du, du), self.domain, degree)
        if self.damping is not None:
            dv = disp(u) - disp(self._u_hat)
            if self.damping.alpha:
                internal = internal + 0.5 * self.damping.alpha * self._B * density.integral(
                    ufl.dot(dv, dv), self.domain, degree
                )
            if self.damping.beta:
                dw = block.embed(dv)
                internal = internal + 0.5 * self.damping.beta * self._B * reference_stiffness_form(
                    base.energy_internal, u, dw, dw
                )
        return internal

    def _step_rule(self) -> dict | None:
        """The one cell rule of every form of the step: the mass rule (``None`` without a density).

        A consistent mass rule is raised to the base problem's volume rule; a
        lumped one (the vertex rule) is refused on cells other than simplices.
        """
        density, base = self.density, self.base
        cell = base.domain.mesh.topology.cell_type.name
        if density is not None and density.lumped and cell not in ("interval", "triangle", "tetrahedron"):
            # The lumped rule is the vertex rule, and every cell integral joins it (FFCx needs one rule per
            # kernel): on hexahedra the elastic energy would be integrated at the corners only.
            raise ParameterError(
                f"{type(self).__name__}: lumped mass on {cell} cells would "
                "integrate the elastic energy on the vertex rule; use MassDensity(rho) (consistent) here"
            )
        if density is None:
            return None
        md = density.metadata(base.degree)
        if not density.lumped:
            md = {"quadrature_degree": max(md["quadrature_degree"], base.quadrature_degree)}
        return md

    def _derive_step_forms(
        self,
        internal: ufl.Form,
        external: ufl.Form,
        follower: ufl.Form | None,
        alpha: tuple[Expr, float] | None,
        md: dict | None,
    ) -> None:
        r"""Residual and tangent of :math:`\Pi_\Delta`; the base problem's tangent correction at :math:`w_\alpha`."""
        base, u, V = self.base, self.u, self.V
        self.energy_internal = internal
        self.energy_external = external
        self.follower_residual = follower
        self.conservative = base.conservative
        self.invertible = bool(base.invertible) if isinstance(base, InvertibleProblem) else False
        self.residual = ufl.derivative(internal - external, u, ufl.TestFunction(V))
        if follower is not None:
            self.residual = self.residual + follower
        self.jacobian = ufl.derivative(self.residual, u, ufl.TrialFunction(V))
        correction = base.tangent_correction if isinstance(base, CorrectedTangentProblem) else None
        if correction is not None:
            # Tangent-only term of a material whose stress is exact with a frozen field
            # (fixed-corotated, ARAP: dR/dF); never part of the energy or the residual.
            correction = self._at_alpha(correction, alpha)
            if md is not None:
                correction = unify_cell_quadrature(correction, md)
            self.jacobian = self.jacobian + ufl.derivative(
                ufl.derivative(correction, u, ufl.TestFunction(V)), u, ufl.TrialFunction(V)
            )

    def _compile_diagnostics(self) -> None:
        """Kinetic, elastic and external energy forms at the current state (for the diagnostics)."""
        base, density = self.base, self.density
        disp = base.displacement
        self._kinetic = (
            None
            if density is None
            else fem.form(0.5 * density.integral(ufl.dot(disp(self.v), disp(self.v)), self.domain, base.degree))
        )
        self._elastic = fem.form(base.energy_internal)
        self._external = fem.form(base.energy_external)

    # -- protocol ------------------------------------------------------------
    @property
    def bcs(self) -> list[fem.DirichletBC]:
        """Dirichlet conditions of the base problem (values at :math:`t_{n+1}` during a step)."""
        return self.base.bcs

    @property
    def time(self) -> float:
        r"""The time the loads are at: :math:`t_{n+1}` (:math:`t_{n+1-\alpha_f}`) during a step, else :attr:`t_n`."""
        return self.base.time

    def set_time(self, t_loads: float, t_bcs: float | None = None) -> None:
        """Move the base problem's loads and updaters to ``t_loads``, its Dirichlet values to ``t_bcs``."""
        self.base.set_time(t_loads, t_bcs)

    def dirichlet_time(self, t: float) -> float:
        r"""The time of the Dirichlet values that goes with the load time ``t``: :math:`t_{n+1}` for the
        :math:`t_{n+1-\alpha_f}` of the step being solved or of the last accepted one, ``t`` itself otherwise.

        Prescribed motions that enter the balance unweighted, as the Dirichlet values do, read it: a rigid
        obstacle's barrier :math:`E(u_{n+1})` is not taken at :math:`w_\alpha`, so the obstacle must be where it is
        at :math:`t_{n+1}` (:mod:`hyperfem.contact`); the solver moves its external energies to
        :attr:`time` (the loads'). Without :math:`\alpha_f` the two times are the same.
        """
        t = float(t)
        for pair in (self._step_times, self._accepted_times):
            if pair is not None and pair[0] == t:
                return pair[1]
        return t

    def force_interpolation(self) -> tuple[float, np.ndarray, float] | None:
        r""":math:`(\alpha_f, w_n, t)` while a generalized-:math:`\alpha` step is being solved, else ``None``.

        Between :meth:`prepare` and :meth:`commit` (or :meth:`restore`) of a scheme with
        :math:`\alpha_f > 0`. Forces from outside UFL that enter the balance of the step read it to be
        interpolated like the internal forces (Erlicher et al. 2002): a contact's
        :math:`(1-\alpha_f)f_c(w_{n+1}) + \alpha_f f_c(w_n)` (:mod:`hyperfem.contact.interpolation`).
        ``w_n`` is the state array at the step's start (the problem's own; do not modify it); :math:`t` the
        load time :math:`w_n` was solved at (:math:`t_{n-\alpha_f}` of its step, which :meth:`dirichlet_time`
        maps to :math:`t_n`; :math:`t_n` itself for the start of a run or after a restore).
        """
        af = float(self.integrator.alpha_f)
        if not af or self._step_times is None:
            return None
        accepted = self._accepted_times
        t = accepted[0] if accepted is not None and accepted[1] == self.t_n else self.t_n
        return af, self._u_n.x.array, t

    def check_solution(self) -> tuple[dict[str, float], str | None]:
        """The base problem's consistency indicators."""
        return self.base.check_solution()

    def nonfinite_terms(self) -> list[str]:
        """The base problem's non-finite load terms."""
        return self.base.nonfinite_terms()

    def displacement(self, state: fem.Function | None = None) -> Expr:
        """The base problem's displacement of ``state``."""
        return self.base.displacement(state)

    def displacement_space(self) -> fem.FunctionSpace:
        """The base problem's displacement (sub)space."""
        return self.base.displacement_space()

    def volume_jacobian(self) -> Expr:
        """The base problem's inversion measure at :math:`t_{n+1}`."""
        return self.base.volume_jacobian()

    def quadrature_points(self) -> np.ndarray:
        """Quadrature points of the base problem."""
        return self.base.quadrature_points()

    # -- stepping ------------------------------------------------------------
    def save(self) -> DynamicState:
        """Snapshot of the accepted state."""
        return DynamicState(self.t_n, self.u.x.array, self.v.x.array, self.a.x.array)

    def restore(self, state: DynamicState) -> None:
        """Return to a snapshot (loads and boundary values included)."""
        self.t_n = state.t
        self.u.x.array[:] = state.u
        self.v.x.array[:] = state.v
        self.a.x.array[:] = state.a
        self._step_times = None  # no step is being solved (force_interpolation)
        self.base.set_time(state.t)

    def prepare(self, dt: float) -> None:
        r"""Set loads, boundary values, predictors and the initial guess for a step ``dt``.

        Loads and updaters go to :math:`t_{n+1-\alpha_f}`, Dirichlet values to
        :math:`t_{n+1}`; the initial guess is :math:`w_n + \Delta t\,v_n` (the
        secant rate when quasi-static). The solver's predictor then lifts the
        boundary increment into the interior.
        """
        t_new = self.t_n + dt
        integ = self.integrator
        self._u_n.x.array[:] = self.u.x.array
        A, u_tilde, B, u_hat = integ.coefficients(dt, self.u.x.array, self.v.x.array, self.a.x.array)
        self._A.value = A  # type: ignore[assignment]  # dolfinx: any array-like
        self._B.value = B  # type: ignore[assignment]  # dolfinx: any array-like
        self._u_tilde.x.array[:] = u_tilde
        self._u_hat.x.array[:] = u_hat
        t_loads = t_new - float(integ.alpha_f) * dt
        self.base.set_time(t_loads, t_new)
        self._step_times = (float(self.base.time), t_new)
        self.u.x.array[:] += dt * self.v.x.array

    def commit(self, dt: float, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray) -> None:
        """Accept the converged step: update :math:`v, a` and the time."""
        v, a = self.integrator.update(dt, self.u.x.array, u_n, v_n, a_n)
        self.v.x.array[:] = self.displacement_block.restrict(v)
        self.a.x.array[:] = self.displacement_block.restrict(a)
        self.t_n += dt
        self._accepted_times, self._step_times = self._step_times, None
        if self.integrator.alpha_f:
            self.base.set_time(self.t_n)

    def step_inputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copies of :math:`(w_n, v_n, a_n)` (before :meth:`prepare` changes ``u``)."""
        return self.u.x.array.copy(), self.v.x.array.copy(), self.a.x.array.copy()

    # -- initial state ---------------------------------------------------------
    def initial_acceleration(self, external: Callable[[], np.ndarray] | None = None) -> None:
        r"""Solve :math:`M a_0 = f_\text{ext}(t_0) - f_\text{int}(w_0) - C v_0` (zero on Dirichlet dofs).

        The system lives on the collapsed displacement space: the rows of the
        base residual tested with displacement directions (pressure and volume
        have no acceleration).

        Args:
            external: The gradient of energies from outside UFL at the current state, one entry per
                dof of the state on this rank (``NewtonSolver(...).external.gradient_array``): a body
                that starts within reach of an obstacle's barrier is pushed by it from the start.

        Raises:
            SolverError: If the mass solve fails.
        """
        if not self.integrator.dynamic:
            return
        assert self.density is not None and self._unified_md is not None  # a dynamic step has a density (__init__)
        base = self.base
        block = self.displacement_block
        base.set_time(self.t_n)
        Vc = block.space
        degree = base.degree
        disp = base.displacement
        test, trial = ufl.TestFunction(Vc), ufl.TrialFunction(Vc)
        m = self.density.integral(ufl.dot(trial, test), self.domain, degree)
        (base_test,) = base.residual.arguments()
        rhs = -base.residual if block.whole else -ufl.replace(base.residual, {base_test: block.embed(test)})
        if self.damping is not None:
            if self.damping.alpha:
                rhs = rhs - self.damping.alpha * self.density.integral(ufl.dot(disp(self.v), test), self.domain, degree)
            if self.damping.beta:
                rhs = rhs - self.damping.beta * reference_stiffness_form(
                    base.energy_internal, self.u, block.embed(disp(self.v)), block.embed(test)
                )
        rhs = unify_cell_quadrature(rhs, self._unified_md)
        gradient = None if external is None else external()
        if block.whole:
            M = fpetsc.assemble_matrix(fem.form(m), bcs=base.bcs)
            M.assemble()
            b = fpetsc.assemble_vector(fem.form(rhs))
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]  # int enums
            if gradient is not None:
                b.array_w[:] -= gradient[: len(b.array_r)]
            fpetsc.set_bc(b, base.bcs, alpha=0.0)
        else:
            M = fpetsc.assemble_matrix(fem.form(m))
            M.assemble()
            b = fpetsc.assemble_vector(fem.form(rhs))
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]  # int enums
            if gradient is not None:
                assert block.dofs is not None  # the displacement is a block of the state here
                b.array_w[:] -= gradient[block.dofs[: len(b.array_r)]]
            local, rows = self._constrained_rows()
            M.zeroRowsColumns(rows, diag=1.0)
            b.array_w[local] = 0.0
        x = M.createVecRight()
        try:
            reason = self.linear_solver.solve(self.domain.comm, M, b, x, kind="mass")
            if reason <= 0 or not np.isfinite(x.norm()):
                raise SolverError(
                    f"IncrementalProblem: the mass solve of the initial acceleration failed (KSP reason {reason})"
                )
            a0 = fem.Function(Vc)
            a0.x.petsc_vec.array_w[:] = x.array_r
            a0.x.scatter_forward()
        finally:
            for obj in (M, b, x):
                obj.destroy()
        self.a.x.array[:] = 0.0
        block.insert(a0.x.array, self.a)

    def _constrained_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Owned displacement dofs under a Dirichlet condition: local and global indices in the collapsed space."""
        block = self.displacement_block
        constrained = np.zeros(len(self.u.x.array), dtype=bool)
        for bc in self.base.bcs:
            constrained[bc.dof_indices()[0]] = True
        imap, bs = block.space.dofmap.index_map, block.space.dofmap.index_map_bs
        assert block.dofs is not None  # called when the displacement is a block of the state
        owned = imap.size_local * bs
        local = np.flatnonzero(constrained[block.dofs[:owned]]).astype(np.int32)
        blocks = imap.local_to_global(local // bs)
        return local, (blocks * bs + local % bs).astype(PETSc.IntType)

    # -- energies ----------------------------------------------------------------
    def _sum(self, form: fem.Form) -> float:
        return float(self.domain.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM))

    def kinetic_energy(self) -> float:
        r""":math:`\tfrac12\int\rho\,v\cdot v\,dX` (with the mass quadrature); 0 when quasi-static."""
        return 0.0 if self._kinetic is None or not self.integrator.dynamic else self._sum(self._kinetic)

    def elastic_energy(self) -> float:
        r"""Stored energy :math:`\Pi_\text{int}` of the base problem (:math:`\int\psi(F)\,dX` for displacement only)."""
        return self._sum(self._elastic)

    def external_work(self) -> float:
        r"""Work of the dead loads :math:`W = \int t\cdot u\,dA + \int b\cdot u\,dX` at the current loads."""
        return self._sum(self._external)
