r"""Explicit time integration: central differences with a lumped (or consistent) mass.

Seed 003 (eqs. 2.10–2.11, 3.97) steps the semi-discrete balance of momentum
:math:`M\ddot u + C\dot u + f_\text{int}(u) = f_\text{ext}(t)` with the
elastic force taken at the *old* positions. :class:`ExplicitDynamics` writes
it in the kick–drift–kick (velocity Verlet) form of the central difference
method, one residual assembly per step and no tangent:

.. math::
    v_{n+1/2} &= v_n + \tfrac{\Delta t}{2}\,a_n,\qquad
    u_{n+1} = u_n + \Delta t\,v_{n+1/2},\\
    g_{n+1} &= M^{-1}\bigl(f_\text{ext}(t_{n+1}) - f_\text{int}(u_{n+1})\bigr),\\
    v_{n+1} &= \frac{v_{n+1/2} + \tfrac{\Delta t}{2}\,g_{n+1}}{1 + \tfrac{\Delta t}{2}\alpha},\qquad
    a_{n+1} = g_{n+1} - \alpha\,v_{n+1},

with :math:`C = \alpha M` (seed 003's viscous body force
:math:`c\rho\dot u`, :func:`~hyperfem.dynamics.damping.viscous_damping`),
which the velocity update treats exactly, so the scheme stays second order.
The positions are those of seed 003's symplectic Euler
:math:`v^{t+\Delta t} = v^t + \Delta t\,M^{-1}(f - C v - k(x^t))`,
:math:`x^{t+\Delta t} = x^t + \Delta t\,v^{t+\Delta t}` (its :math:`v` is
:math:`v_{n+1/2}` here); with the lumped P1 mass this *is* the finite volume
method of seed 003 §3.4 (eq. 3.97: :math:`m_i = V^i\rho_0`, the median-dual
control-volume mass, equals the row-sum lumped mass of linear tetrahedra, and
the FVM node force equals the FEM :math:`f_\text{int}`).

* :math:`f_\text{int} - f_\text{ext}` is the base problem's residual form,
  assembled with :func:`dolfinx.fem.petsc.assemble_vector` at
  :math:`u_{n+1}` (follower loads included);
* with ``MassDensity(rho, lumped=True)`` :math:`M` is the lumped diagonal
  (:func:`~hyperfem.dynamics.mass.lumped_mass`): no linear solve. Otherwise
  the consistent mass is solved for (CG + Jacobi by default: the diagonal of
  :math:`M` as preconditioner, as in seed 003 §5.5) — seed 003's SI-FEM with
  the elastic forces explicit;
* Dirichlet dofs take their prescribed values at :math:`t_{n+1}`
  (:meth:`~hyperfem.problem.protocol.SolidProblem.set_time`, so moving
  boundaries move), their velocity is the difference quotient of the
  prescribed motion and their acceleration zero. With the consistent mass the
  coupling :math:`M_{FA}\,a_A` of the prescribed accelerations into the free
  rows is neglected (exact for clamps and for boundaries moving at constant
  velocity);
* the base problem's updaters (e.g. the step rotation of corotational
  elasticity) run from ``set_time`` after the drift, i.e. at :math:`u_{n+1}`
  with the Dirichlet dofs still at their :math:`t_n` values; its
  ``state_hooks`` run at the full :math:`u_{n+1}` before the force assembly;
* every step is checked against the stable step estimate
  (:func:`~hyperfem.dynamics.stability.stable_time_step`) from the Lamé
  parameters and the density given here; a larger step raises
  :class:`~hyperfem.errors.ParameterError`.

**Contact** (:mod:`hyperfem.contact`) is not available here: the IPC barrier
stiffens without bound as a gap closes, so no fixed explicit step stays
stable, and intersection-free steps need the implicit step's collision
filter and line search. Contact runs with the implicit integrators
(:func:`~hyperfem.dynamics.integrate`), the semi-implicit scheme
(:mod:`~hyperfem.dynamics.semi_implicit`, where impacts are inelastic) and
the real-time stepper (analytic obstacles).

:func:`integrate_explicit` runs the scheme as a
:class:`~hyperfem.simulation.Simulation` with :class:`ExplicitStage`, i.e. with
the same stepping loop (:func:`~hyperfem.solver.stepping.run_steps`), policies,
step records, outputs (probes, CSV, JSON, VTX, checkpoints) and
:class:`~hyperfem.dynamics.Diagnostics` as the implicit integrators: a step
whose state is not finite, or that inverts an element, is rejected and
retried with half the step. Directly::

    Simulation(dynamics, None, stepping, outputs, stage=ExplicitStage).run()
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem

from hyperfem.dynamics.damping import RayleighDamping
from hyperfem.dynamics.incremental import DisplacementBlock, DynamicState
from hyperfem.dynamics.mass import MassDensity, lumped_mass
from hyperfem.dynamics.stability import DEFAULT_SAFETY, StableStep, stable_time_step
from hyperfem.errors import ParameterError, SolverError
from hyperfem.problem.inversion import QuadratureMinimum
from hyperfem.materials.parameters import LameParameters
from hyperfem.problem.protocol import SolidProblem, StateHookedProblem
from hyperfem.solver.linear import LinearSolver, describe
from hyperfem.solver.newton import SolveRecord
from hyperfem.simulation.outputs import OnStep
from hyperfem.simulation.runner import Simulation
from hyperfem.solver.stepping import StepRecord, TimeStepping

__all__ = ["MASS_SOLVER", "ExplicitDynamics", "ExplicitStage", "integrate_explicit"]

MASS_SOLVER: dict[str, object] = {"ksp_type": "cg", "pc_type": "jacobi", "ksp_rtol": 1e-12, "ksp_atol": 1e-50}
"""Consistent-mass solve: CG preconditioned by the diagonal of M (seed 003 §5.5)."""

_EXPLICIT = 1
_NONFINITE = int(PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_NANORINF)


def _checked_block(
    base: SolidProblem,
    density: MassDensity,
    damping: RayleighDamping | None,
    lame: LameParameters | None,
    check_step: bool,
) -> DisplacementBlock:
    """The displacement block of ``base``, after refusing what :class:`ExplicitDynamics` cannot step."""
    where = "ExplicitDynamics"
    if not isinstance(base, SolidProblem):
        raise ParameterError(f"{where}: base must meet the SolidProblem protocol, got {type(base).__name__}")
    if not isinstance(density, MassDensity):
        raise ParameterError(f"{where}: density must be a MassDensity, got {type(density).__name__}")
    block = DisplacementBlock(base)
    if not block.whole:
        raise ParameterError(
            f"{where}: explicit stepping needs a displacement-only state; {type(base).__name__} has "
            "constraint fields without inertia (use IncrementalProblem)"
        )
    if damping is not None and damping.beta:
        raise ParameterError(
            f"{where}: stiffness-proportional damping (beta = {damping.beta:g}) is not supported explicitly; "
            "use mass-proportional damping (alpha)"
        )
    if check_step and lame is None:
        raise ParameterError(
            f"{where}: pass lame= (Lame parameters of the stiffest material) for the stable step, "
            "or check_step=False"
        )
    return block


class ExplicitDynamics:
    r"""Central-difference time stepping of a displacement problem (see the module docstring).

    Args:
        base: The problem of the body (a displacement-only
            :class:`~hyperfem.problem.protocol.SolidProblem`, e.g.
            :class:`~hyperfem.problem.HyperelasticProblem`).
        density: Mass density; ``lumped=True`` for the diagonal mass (P1 only).
        damping: Mass-proportional damping :math:`C = \alpha M`; ``None`` for none.
        lame: Lamé parameters of the stiffest material, for the stable step.
        safety: Factor on :math:`h_\min/c` (see :class:`~hyperfem.dynamics.stability.StableStep`).
        check_step: Refuse steps above ``safety * dt_crit``; ``False`` runs
            unchecked (to study instability).
        linear_solver: Configuration of the consistent-mass solve (default :data:`MASS_SOLVER`).

    Attributes:
        u: The displacement :math:`u_n` (the base problem's unknown).
        v, a: Velocity and acceleration at :math:`t_n`.
        t_n: Time of the current state.
        stable_step: The :class:`~hyperfem.dynamics.stability.StableStep`
            estimate (``None`` without ``lame``).
        mass: The lumped mass per dof (``None`` with the consistent mass).

    Raises:
        ParameterError: A mixed (non-displacement) state, stiffness-proportional
            damping, no ``lame`` while ``check_step``, or a lumped mass of degree > 1.
    """

    name = "central-difference"

    def __init__(
        self,
        base: SolidProblem,
        density: MassDensity,
        damping: RayleighDamping | None = None,
        *,
        lame: LameParameters | None = None,
        safety: float = DEFAULT_SAFETY,
        check_step: bool = True,
        linear_solver: LinearSolver | None = None,
    ):
        block = _checked_block(base, density, damping, lame, check_step)
        self.base = base
        self.domain = base.domain
        self.degree = base.degree
        self.quadrature_degree = base.quadrature_degree
        self.displacement_block = block
        self.u = base.u
        V = self.V = base.u.function_space
        self.density = density
        self.damping = damping if damping is not None and damping.active else None
        self._alpha = 0.0 if self.damping is None else float(self.damping.alpha)
        self.v = fem.Function(V, name="velocity")
        self.a = fem.Function(V, name="acceleration")
        self.t_n = float(base.time)
        self.check_step = bool(check_step)
        rho_min = min(density.value.values()) if isinstance(density.value, Mapping) else float(density.value)
        self.stable_step: StableStep | None = (
            None if lame is None else stable_time_step(self.domain, lame, rho_min, safety, lumped=density.lumped)
        )
        self._ready = False
        self.comm = self.domain.comm

        # Dirichlet dofs (local, ghosts included) and the owned range.
        constrained = np.zeros(len(self.u.x.array), dtype=bool)
        for bc in base.bcs:
            constrained[bc.dof_indices()[0]] = True
        self._constrained = constrained
        self._owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs

        self._residual = fem.form(base.residual)
        self._b = fpetsc.create_vector(V)
        self._g = fem.Function(V)  # M^{-1}(f_ext - f_int), zero on Dirichlet dofs
        self.lumped = bool(density.lumped)
        self.mass: fem.Function | None = None
        self._ksp: PETSc.KSP | None = None
        if self.lumped:
            self._setup_lumped_mass()
        else:
            self._setup_consistent_mass(linear_solver)
        disp = base.displacement
        self._kinetic = fem.form(0.5 * density.integral(ufl.dot(disp(self.v), disp(self.v)), self.domain, self.degree))
        self._elastic = fem.form(base.energy_internal)
        self._external = fem.form(base.energy_external)
        self._min_J = QuadratureMinimum(self.domain.mesh, base.volume_jacobian(), base.quadrature_points())
        self.state_hooks = list(base.state_hooks) if isinstance(base, StateHookedProblem) else []

    def _setup_lumped_mass(self) -> None:
        """The lumped (diagonal) mass and its inverse on the owned dofs (zero on Dirichlet dofs)."""
        constrained = self._constrained
        self.mass = lumped_mass(self.density, self.domain, self.V)
        m = self.mass.x.array
        if np.any(m[~constrained] <= 0):
            raise ParameterError("ExplicitDynamics: the lumped mass has a non-positive entry at a free dof")
        self._inverse_mass = np.where(constrained, 0.0, 1.0 / np.where(m > 0, m, 1.0))[: self._owned]
        self.linear_solver_name = "none (lumped mass)"

    def _setup_consistent_mass(self, linear_solver: LinearSolver | None) -> None:
        """The consistent mass matrix, assembled once, and the KSP that solves with it."""
        V = self.V
        solver = LinearSolver(dict(MASS_SOLVER)) if linear_solver is None else linear_solver
        test, trial = ufl.TestFunction(V), ufl.TrialFunction(V)
        self._mass_form = fem.form(self.density.integral(ufl.dot(trial, test), self.domain, self.degree))
        self._M = fpetsc.assemble_matrix(self._mass_form, bcs=self.base.bcs)
        self._M.assemble()
        self._ksp = solver.ksp(self.comm, self._M, kind="mass")
        self._x = self._M.createVecRight()
        self.linear_solver_name = describe(solver.options)

    # -- protocol (what Diagnostics and outputs use) ----------------------------
    @property
    def bcs(self) -> list[fem.DirichletBC]:
        """Dirichlet conditions of the base problem."""
        return self.base.bcs

    @property
    def time(self) -> float:
        """Time of the current state."""
        return self.t_n

    def displacement(self, state: fem.Function | None = None) -> ufl.core.expr.Expr:
        """The base problem's displacement of ``state``."""
        return self.base.displacement(state)

    def displacement_space(self) -> fem.FunctionSpace:
        """The displacement space."""
        return self.base.displacement_space()

    def volume_jacobian(self) -> ufl.core.expr.Expr:
        """The base problem's inversion measure."""
        return self.base.volume_jacobian()

    def quadrature_points(self) -> np.ndarray:
        """Quadrature points of the base problem."""
        return self.base.quadrature_points()

    def min_J(self) -> float:
        """Smallest :math:`J` over all quadrature points at the current state (collective)."""
        return self._min_J()

    # -- state -------------------------------------------------------------------
    def save(self) -> DynamicState:
        """Snapshot :math:`(t, u, v, a)`."""
        self._ensure_acceleration()
        return DynamicState(self.t_n, self.u.x.array, self.v.x.array, self.a.x.array)

    def restore(self, state: DynamicState) -> None:
        """Return to a snapshot (loads and boundary values included)."""
        self.t_n = state.t
        self.u.x.array[:] = state.u
        self.v.x.array[:] = state.v
        self.a.x.array[:] = state.a
        self.base.set_time(state.t)
        self._ready = True

    # -- the scheme ----------------------------------------------------------------
    def _force_over_mass(self) -> int:
        r"""Fill ``_g`` with :math:`M^{-1}(f_\text{ext} - f_\text{int}(u))` (zero on Dirichlet dofs); KSP iterations."""
        for hook in self.state_hooks:
            hook()
        b = self._b
        with b.localForm() as loc:
            loc.set(0.0)
        fpetsc.assemble_vector(b, self._residual)  # type: ignore[arg-type]  # dolfinx: singledispatch (Vec, Form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]  # int enums
        g = self._g.x
        if self.lumped:
            g.array[: self._owned] = -b.array_r * self._inverse_mass
            its = 0
        else:
            b.scale(-1.0)
            fpetsc.set_bc(b, self.base.bcs, alpha=0.0)
            assert self._ksp is not None  # a consistent mass has its solver
            self._ksp.solve(b, self._x)
            reason = self._ksp.getConvergedReason()
            its = int(self._ksp.getIterationNumber())
            if reason == PETSc.KSP.ConvergedReason.DIVERGED_NANORINF:
                g.array[:] = np.nan  # a non-finite force: the step reports a non-finite state
                return its
            if reason <= 0:  # type: ignore[operator]  # petsc4py stubs: the reason is an int
                raise SolverError(f"ExplicitDynamics: the mass solve failed at t = {self.t_n:g} (KSP reason {reason})")
            g.array[: self._owned] = self._x.array_r
        g.scatter_forward()
        return its

    def initial_acceleration(self) -> None:
        r"""Set :math:`a_0 = M^{-1}(f_\text{ext}(t_0) - f_\text{int}(u_0)) - \alpha v_0` (zero on Dirichlet dofs)."""
        self.base.set_time(self.t_n)
        self._force_over_mass()
        a = self._g.x.array - self._alpha * self.v.x.array
        a[self._constrained] = 0.0
        self.a.x.array[:] = a
        self._ready = True

    def _ensure_acceleration(self) -> None:
        if not self._ready:
            self.initial_acceleration()

    def step(self, dt: float) -> SolveRecord:
        """Advance the state by ``dt`` (one residual assembly).

        Returns:
            A :class:`~hyperfem.solver.SolveRecord`: ``converged`` when the
            new state is finite, zero Newton iterations, the mass-solve Krylov
            iterations, :math:`\\min J`.

        Raises:
            ParameterError: If ``dt`` is not positive or exceeds the stable step.
        """
        if not dt > 0:
            raise ParameterError(f"ExplicitDynamics: time steps must be > 0, got dt = {dt:g} at t = {self.t_n:g}")
        if self.check_step and self.stable_step is not None:
            self.stable_step.check(dt, f"ExplicitDynamics (t = {self.t_n:g})")
        start = _time.perf_counter()
        self._ensure_acceleration()
        fixed = self._constrained
        u, v, a = self.u.x.array, self.v.x.array, self.a.x.array
        prescribed_old = u[fixed].copy()
        v_half = v + 0.5 * dt * a
        u += dt * v_half
        t_new = self.t_n + dt
        self.base.set_time(t_new)
        for bc in self.base.bcs:
            bc.set(u)
        self.u.x.scatter_forward()
        v_half[fixed] = (u[fixed] - prescribed_old) / dt
        its = self._force_over_mass()
        g = self._g.x.array
        v_new = (v_half + 0.5 * dt * g) / (1.0 + 0.5 * dt * self._alpha)
        a_new = g - self._alpha * v_new
        v_new[fixed] = v_half[fixed]
        a_new[fixed] = 0.0
        v[:] = v_new
        a[:] = a_new
        self.t_n = t_new
        owned = self._owned
        finite = bool(np.all(np.isfinite(u[:owned])) and np.all(np.isfinite(v[:owned])))
        finite = bool(self.comm.allreduce(finite, op=MPI.LAND))
        min_J = self._min_J() if finite else float("nan")
        return SolveRecord(
            converged=finite and bool(np.isfinite(min_J)),
            reason=_EXPLICIT if finite else _NONFINITE,
            reason_name="EXPLICIT" if finite else "DIVERGED_FUNCTION_NANORINF",
            iterations=0,
            linear_iterations=its,
            wall_time=_time.perf_counter() - start,
            min_J=min_J,
            message="" if finite else f"non-finite state after the explicit step dt = {dt:g}",
            linear_solver=self.linear_solver_name,
        )

    # -- energies ---------------------------------------------------------------------
    def _sum(self, form: fem.Form) -> float:
        return float(self.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM))

    def kinetic_energy(self) -> float:
        r""":math:`\tfrac12 v^T M v` (with the mass quadrature: :math:`\tfrac12\sum_a m_a v_a^2` when lumped)."""
        return self._sum(self._kinetic)

    def elastic_energy(self) -> float:
        r"""Stored energy :math:`\Pi_\text{int}` of the base problem."""
        return self._sum(self._elastic)

    def external_work(self) -> float:
        r"""Work of the dead loads at the current loads."""
        return self._sum(self._external)

    # -- the sharp stability limit ------------------------------------------------------
    def spectral_time_step(self, max_iterations: int = 2000, rtol: float = 1e-7) -> float:
        r"""The linearised stability limit :math:`2/\omega_\max` at the current state.

        Power iteration on :math:`M^{-1}K` over the free dofs (:math:`K` the
        tangent ``base.jacobian`` at the current :math:`u`), with the
        Rayleigh quotient :math:`x^TKx / x^TMx` as the eigenvalue estimate.
        The estimate of :math:`\omega_\max` converges from below, so the
        returned step is an upper estimate of the true limit.

        Args:
            max_iterations: Iteration limit.
            rtol: Stop when the Rayleigh quotient changes by less than this (relative).
        """
        comm = self.comm
        bcs = self.base.bcs
        K = fpetsc.assemble_matrix(fem.form(self.base.jacobian), bcs=bcs, diag=0.0)
        K.assemble()
        x = K.createVecRight()
        y = x.duplicate()
        owned = self._owned
        free = ~self._constrained[:owned]
        coords = self.V.tabulate_dof_coordinates()[: owned // self.V.dofmap.index_map_bs]
        bs = self.V.dofmap.index_map_bs
        phase = np.repeat(coords @ np.array([3.7, 2.3, 1.1]), bs) + np.tile(np.arange(bs), len(coords))
        x.array_w[:] = np.where(free, np.cos(phase) + 1.5, 0.0)
        mx = x.duplicate()

        def apply_mass(src: PETSc.Vec, dst: PETSc.Vec) -> None:
            if self.lumped:
                assert self.mass is not None  # the lumped mass
                dst.array_w[:] = src.array_r * self.mass.x.array[:owned]
            else:
                self._M.mult(src, dst)

        def solve_mass(src: PETSc.Vec, dst: PETSc.Vec) -> None:
            if self.lumped:
                dst.array_w[:] = src.array_r * self._inverse_mass
            else:
                src.array_w[~free] = 0.0
                assert self._ksp is not None  # a consistent mass has its solver
                self._ksp.solve(src, dst)
            dst.array_w[~free] = 0.0

        lam_old = 0.0
        lam = 0.0
        try:
            for _ in range(max_iterations):
                x.scale(1.0 / x.norm())
                K.mult(x, y)
                apply_mass(x, mx)
                lam = y.dot(x) / mx.dot(x)
                if lam_old > 0 and abs(lam - lam_old) <= rtol * lam:
                    break
                lam_old = lam
                solve_mass(y, x)
        finally:
            for obj in (K, x, y, mx):
                obj.destroy()
        lam = comm.bcast(lam, root=0)
        if not lam > 0:
            raise SolverError("ExplicitDynamics.spectral_time_step: the tangent has no positive eigenvalue")
        return float(2.0 / np.sqrt(lam))


class ExplicitStage:
    """The :class:`~hyperfem.solver.stepping.Stage` of an :class:`ExplicitDynamics`.

    What :func:`~hyperfem.solver.stepping.run_steps` steps: save, one explicit step, commit or restore.
    Built by :class:`~hyperfem.simulation.Simulation` as ``ExplicitStage(dynamics, None)``.

    Args:
        dynamics: The explicit scheme; its state is the start (its initial
            acceleration is computed here unless it has one).
        solver: ``None``: the scheme takes no Newton solver.

    Raises:
        ParameterError: A solver is given.
    """

    kind = "dynamic"

    def __init__(self, dynamics: ExplicitDynamics, solver: None = None):
        if solver is not None:
            raise ParameterError(
                f"ExplicitStage: the explicit scheme takes no Newton solver, got {type(solver).__name__} "
                "(Simulation(dynamics, None, stepping, outputs, stage=ExplicitStage))"
            )
        self.dynamics = dynamics
        dynamics._ensure_acceleration()
        self._time = dynamics.t_n

    @property
    def time(self) -> float:
        """Time of the accepted state."""
        return self._time

    def save(self) -> DynamicState:
        """Snapshot of the accepted state."""
        return self.dynamics.save()

    def restore(self, state: DynamicState) -> None:
        """Back to ``state``."""
        self.dynamics.restore(state)
        self._time = state.t

    def advance(self, t: float, dt: float) -> SolveRecord:
        """One explicit step from the accepted state."""
        return self.dynamics.step(dt)

    def commit(self) -> None:
        """The stepped state becomes the accepted one."""
        self._time = self.dynamics.t_n

    def distance(self, state: DynamicState) -> float:
        """Largest nodal displacement difference from ``state``."""
        d = self.dynamics
        owned = d._owned
        diff = (d.u.x.array[:owned] - state.u[:owned]).reshape(-1, d.domain.gdim)
        local = float(np.sqrt((diff**2).sum(axis=1)).max()) if diff.size else 0.0
        return d.comm.allreduce(local, op=MPI.MAX)


def integrate_explicit(
    dynamics: ExplicitDynamics,
    stepping: TimeStepping,
    on_step: Callable[[StepRecord], None] | None = None,
    outputs: Sequence = (),
) -> list[StepRecord]:
    """Advance ``dynamics`` to ``stepping.t_end`` with the stepping loop and outputs of the implicit schemes.

    ``Simulation(dynamics, None, stepping, [*outputs, OnStep(on_step)], stage=ExplicitStage).run()``.

    Args:
        dynamics: The explicit scheme; its state is the start.
        stepping: Step control (fixed steps; with ``adaptive`` the largest
            step ``dt_max`` must respect the stable step too).
        on_step: Called after every accepted step (after ``outputs``).
        outputs: Observers of every accepted step (:mod:`hyperfem.simulation.outputs`).

    Returns:
        The accepted steps.

    Raises:
        ParameterError: If the largest step of ``stepping`` exceeds the stable step.
        ConvergenceError: When non-finite or inverted states cut the step below ``dt_min``.
    """
    if dynamics.check_step and dynamics.stable_step is not None:
        dynamics.stable_step.check(stepping.max_step, "integrate_explicit")
    observers = [*outputs, *([OnStep(on_step)] if on_step is not None else [])]
    sim = Simulation(dynamics, None, stepping, observers, stage=ExplicitStage, name="integrate_explicit")
    sim.run()
    return sim.steps
