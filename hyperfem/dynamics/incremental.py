r"""One time step as a nonlinear problem for :class:`~hyperfem.solver.NewtonSolver`.

:class:`IncrementalProblem` composes a
:class:`~hyperfem.problem.HyperelasticProblem` (its public forms
``energy_internal``, ``energy_external``, ``follower_residual``, its
Dirichlet conditions and :meth:`set_load_factor`) with a
:class:`~hyperfem.dynamics.integrators.TimeIntegrator`, a
:class:`~hyperfem.dynamics.mass.MassDensity` and optional
:class:`~hyperfem.dynamics.damping.RayleighDamping` into the incremental potential

.. math::
    \Pi_\Delta(u) = \frac{A}{2}\int_\Omega \rho\,|u - \tilde u|^2\,dX
      + \frac{B}{2}(u - \hat u)^T C (u - \hat u)
      + \frac{1}{1-\alpha_f}\,\Pi(u_{\alpha}),\qquad u_\alpha = (1-\alpha_f)u + \alpha_f u_n .

``energy_internal`` holds everything but the dead-load work, so
:class:`~hyperfem.solver.NewtonSolver` uses :math:`\Pi_\Delta` as its
line-search objective exactly as for a static problem, and its inversion
pre-check acts on :math:`J = \det F(u_{n+1})`. All step-size dependent
quantities are :class:`dolfinx.fem.Constant` or :class:`dolfinx.fem.Function`
values: the forms are compiled once.
"""

from __future__ import annotations

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem

from hyperfem.dynamics.damping import RayleighDamping, reference_stiffness_form
from hyperfem.dynamics.integrators import TimeIntegrator
from hyperfem.dynamics.mass import MassDensity
from hyperfem.problem.quadrature import unify_cell_quadrature

__all__ = ["DynamicState", "IncrementalProblem", "unify_cell_quadrature"]


class DynamicState:
    """A copy of :math:`(t, u, v, a)` to restore a rejected step."""

    def __init__(self, t: float, u: np.ndarray, v: np.ndarray, a: np.ndarray):
        self.t, self.u, self.v, self.a = float(t), u.copy(), v.copy(), a.copy()


class IncrementalProblem:
    """The nonlinear problem of one time step (satisfies the NewtonSolver protocol).

    Args:
        base: The hyperelastic problem (forms, loads, boundary conditions).
        integrator: Time-stepping scheme.
        density: Mass density (and lumping); ignored by quasi-static schemes.
        damping: Rayleigh damping; ``None`` for none.
        boundary_predictor: When prescribed boundary values change over a
            step, start Newton from one linearised step that carries the
            boundary increment into the interior (instead of moving only the
            boundary nodes, which can invert the adjacent cells).

    Attributes:
        u: Displacement :math:`u_{n+1}` (the base problem's unknown).
        v, a: Velocity and acceleration at the current time.
        time: Current time :math:`t_n` (of the last accepted state).
    """

    def __init__(
        self,
        base,
        integrator: TimeIntegrator,
        density: MassDensity | None = None,
        damping: RayleighDamping | None = None,
        boundary_predictor: bool = True,
    ):
        self.base = base
        self.boundary_predictor = boundary_predictor
        # Inertia makes the tangent regular without Dirichlet conditions.
        self.rigid_motion_resisted = bool(integrator.dynamic)
        self._predictor = None
        self.integrator = integrator
        self.domain = base.domain
        self.V = base.V
        self.u = base.u
        self.time = float(base.load_factor)
        self.damping = damping if damping is not None and damping.active else None
        if integrator.dynamic and density is None:
            raise ValueError("IncrementalProblem: a dynamic scheme needs a MassDensity")
        self.density = density
        mesh = self.domain.mesh
        V = self.V
        u = self.u
        self.v = fem.Function(V, name="velocity")
        self.a = fem.Function(V, name="acceleration")
        self._u_n = fem.Function(V)
        self._u_tilde = fem.Function(V)
        self._u_hat = fem.Function(V)
        self._A = fem.Constant(mesh, 0.0)
        self._B = fem.Constant(mesh, 0.0)
        test = ufl.TestFunction(V)
        self._test = test
        degree = base.degree

        af = float(integrator.alpha_f)
        if af:
            u_alpha = (1.0 - af) * u + af * self._u_n
            scale = 1.0 / (1.0 - af)
            internal = scale * ufl.replace(base.energy_internal, {u: u_alpha})
            external = scale * ufl.replace(base.energy_external, {u: u_alpha})
            follower = None if base.follower_residual is None else ufl.replace(base.follower_residual, {u: u_alpha})
        else:
            internal, external, follower = base.energy_internal, base.energy_external, base.follower_residual

        if integrator.dynamic:
            du = u - self._u_tilde
            internal = internal + 0.5 * self._A * density.integral(ufl.dot(du, du), self.domain, degree)
            if self.damping is not None:
                dv = u - self._u_hat
                if self.damping.alpha:
                    internal = internal + 0.5 * self.damping.alpha * self._B * density.integral(
                        ufl.dot(dv, dv), self.domain, degree
                    )
                if self.damping.beta:
                    internal = internal + 0.5 * self.damping.beta * self._B * reference_stiffness_form(
                        base.energy_internal, u, dv, dv
                    )
        if density is not None:
            md = density.metadata(degree)
            if not density.lumped:
                md = {"quadrature_degree": max(md["quadrature_degree"], base.quadrature_degree)}
            internal = unify_cell_quadrature(internal, md)
            external = unify_cell_quadrature(external, md)
            if follower is not None:
                follower = unify_cell_quadrature(follower, md)
        self._unified_md = md if density is not None else None
        self.energy_internal = internal
        self.energy_external = external
        self.follower_residual = follower
        self.conservative = base.conservative
        self.residual = ufl.derivative(internal - external, u, test)
        if follower is not None:
            self.residual = self.residual + follower
        self.jacobian = ufl.derivative(self.residual, u, ufl.TrialFunction(V))

        # Diagnostics forms at the current state.
        self._kinetic = (
            None if density is None else fem.form(0.5 * density.integral(ufl.dot(self.v, self.v), self.domain, degree))
        )
        self._elastic = fem.form(base.energy_internal)
        self._external = fem.form(base.energy_external)

    # -- protocol ------------------------------------------------------------
    @property
    def bcs(self):
        """Dirichlet conditions of the base problem (values at :math:`t_{n+1}`)."""
        return self.base.bcs

    @property
    def load_factor(self) -> float:
        """The time the loads are evaluated at (for messages)."""
        return self.base.load_factor

    def check_solution(self):
        """The base problem's consistency indicators."""
        return self.base.check_solution()

    def nonfinite_terms(self) -> list[str]:
        """The base problem's non-finite load terms."""
        return self.base.nonfinite_terms()

    def displacement(self, state=None):
        """The base problem's displacement of ``state``."""
        return self.base.displacement(state)

    def displacement_space(self):
        """The base problem's displacement (sub)space."""
        return self.base.displacement_space()

    def volume_jacobian(self):
        """:math:`J = \\det F(u_{n+1})`."""
        return self.base.volume_jacobian()

    def quadrature_points(self):
        """Quadrature points of the base problem."""
        return self.base.quadrature_points()

    # -- stepping ------------------------------------------------------------
    def save(self) -> DynamicState:
        """Snapshot of the accepted state."""
        return DynamicState(self.time, self.u.x.array, self.v.x.array, self.a.x.array)

    def restore(self, state: DynamicState) -> None:
        """Return to a snapshot (loads and boundary values included)."""
        self.time = state.t
        self.u.x.array[:] = state.u
        self.v.x.array[:] = state.v
        self.a.x.array[:] = state.a
        self.base.set_load_factor(state.t)

    def prepare(self, dt: float) -> None:
        """Set loads, boundary values, predictors and the initial guess for a step ``dt``."""
        t_new = self.time + dt
        integ = self.integrator
        self._u_n.x.array[:] = self.u.x.array
        A, u_tilde, B, u_hat = integ.coefficients(dt, self.u.x.array, self.v.x.array, self.a.x.array)
        self._A.value = A
        self._B.value = B
        self._u_tilde.x.array[:] = u_tilde
        self._u_hat.x.array[:] = u_hat
        af = float(integ.alpha_f)
        old = [bc.g.x.array.copy() for bc in self.base.bcs]
        self.base.set_load_factor(t_new)
        if af:
            # Loads at t_{n+1-alpha_f}, boundary values at t_{n+1}.
            values = [bc.g.x.array.copy() for bc in self.base.bcs]
            self.base.set_load_factor(t_new - af * dt)
            for bc, g in zip(self.base.bcs, values, strict=True):
                bc.g.x.array[:] = g
        # Predictor u_n + dt v_n as the Newton initial guess (secant rate when quasi-static).
        self.u.x.array[:] += dt * self.v.x.array
        if self.boundary_predictor:
            moved = any(not np.array_equal(g, bc.g.x.array) for g, bc in zip(old, self.base.bcs, strict=True))
            if self.domain.comm.allreduce(moved, op=MPI.LOR):
                self._lift_boundary_increment()

    def _lift_boundary_increment(self) -> None:
        """One linearised step from the predictor with the new boundary values."""
        if self._predictor is None:
            R, K = fem.form(self.residual), fem.form(self.jacobian)
            A = fpetsc.create_matrix(K)
            b = fpetsc.create_vector(self.V)
            ksp = PETSc.KSP().create(self.domain.comm)
            ksp.setOperators(A)
            ksp.setType("preonly")
            ksp.getPC().setType("lu")
            ksp.getPC().setFactorSolverType("mumps")
            self._predictor = (R, K, A, b, ksp, A.createVecRight())
        R, K, A, b, ksp, du = self._predictor
        bcs = self.base.bcs
        x = self.u.x.petsc_vec
        A.zeroEntries()
        fpetsc.assemble_matrix(A, K, bcs=bcs)
        A.assemble()
        with b.localForm() as loc:
            loc.set(0.0)
        fpetsc.assemble_vector(b, R)
        b.scale(-1.0)
        fpetsc.apply_lifting(b, [K], bcs=[bcs], x0=[x], alpha=1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fpetsc.set_bc(b, bcs, x0=x, alpha=1.0)
        ksp.solve(b, du)
        if ksp.getConvergedReason() > 0 and np.isfinite(du.norm()):
            x.axpy(1.0, du)
            self.u.x.scatter_forward()

    def commit(self, dt: float, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray) -> None:
        """Accept the converged step: update :math:`v, a` and the time."""
        v, a = self.integrator.update(dt, self.u.x.array, u_n, v_n, a_n)
        self.v.x.array[:] = v
        self.a.x.array[:] = a
        self.time += dt
        if self.integrator.alpha_f:
            self.base.set_load_factor(self.time)

    def step_inputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copies of :math:`(u_n, v_n, a_n)` (before :meth:`prepare` changes ``u``)."""
        return self.u.x.array.copy(), self.v.x.array.copy(), self.a.x.array.copy()

    # -- initial state ---------------------------------------------------------
    def initial_acceleration(self) -> None:
        r"""Solve :math:`M a_0 = f_\text{ext}(t_0) - f_\text{int}(u_0) - C v_0` (zero on Dirichlet dofs)."""
        if not self.integrator.dynamic:
            return
        base = self.base
        base.set_load_factor(self.time)
        V = self.V
        degree = base.degree
        test, trial = self._test, ufl.TrialFunction(V)
        m = self.density.integral(ufl.dot(trial, test), self.domain, degree)
        rhs = -base.residual
        if self.damping is not None:
            if self.damping.alpha:
                rhs = rhs - self.damping.alpha * self.density.integral(ufl.dot(self.v, test), self.domain, degree)
            if self.damping.beta:
                rhs = rhs - self.damping.beta * reference_stiffness_form(base.energy_internal, self.u, self.v, test)
        rhs = unify_cell_quadrature(rhs, self._unified_md)
        M = fpetsc.assemble_matrix(fem.form(m), bcs=base.bcs)
        M.assemble()
        b = fpetsc.assemble_vector(fem.form(rhs))
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fpetsc.set_bc(b, base.bcs, alpha=0.0)
        ksp = PETSc.KSP().create(self.domain.comm)
        ksp.setOperators(M)
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
        ksp.getPC().setFactorSolverType("mumps")
        x = M.createVecRight()
        ksp.solve(b, x)
        self.a.x.petsc_vec.array_w[:] = x.array_r
        self.a.x.scatter_forward()
        for obj in (ksp, M, b, x):
            obj.destroy()

    # -- energies ----------------------------------------------------------------
    def _sum(self, form) -> float:
        return float(self.domain.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM))

    def kinetic_energy(self) -> float:
        r""":math:`\tfrac12\int\rho\,v\cdot v\,dX` (with the mass quadrature); 0 when quasi-static."""
        return 0.0 if self._kinetic is None or not self.integrator.dynamic else self._sum(self._kinetic)

    def elastic_energy(self) -> float:
        r"""Stored energy :math:`\int\psi(F)\,dX`."""
        return self._sum(self._elastic)

    def external_work(self) -> float:
        r"""Work of the dead loads :math:`W = \int t\cdot u\,dA + \int b\cdot u\,dX` at the current loads."""
        return self._sum(self._external)
