r"""Line-searched Newton (PETSc SNES) on top of :class:`dolfinx.fem.petsc.NonlinearProblem`.

What this adds to the DOLFINx class (each concern in its own module; this
one wires them to the SNES and runs the solve):

* documented defaults (``newtonls`` + backtracking, MUMPS LU) with user
  options merged over them under a *unique* options prefix; nothing is left
  in the global options database (:mod:`~hyperfem.solver.options`);
* for conservative problems the total potential :math:`\Pi` is attached as
  the SNES objective, so the backtracking line search judges a step by the
  energy rather than by the residual norm; near convergence, where the
  assembled :math:`\Pi` cannot resolve a step, the step is judged by the
  residual norm instead (:mod:`~hyperfem.solver.objective`);
* a line-search pre-check: the Dirichlet components of the Newton step are
  set exactly, then step filters (:mod:`~hyperfem.solver.filters`) shorten
  it. The default filters refuse steps that would invert elements: for P1
  simplices the *exact* filter of seed 004
  (:mod:`~hyperfem.solver.step_filter`) shortens the Newton step to the
  largest length at which no cell shrinks below a fraction :math:`\eta` of
  its current volume (a cubic root per cell); for other discretisations,
  and as a final check, the step is halved until no quadrature point has
  :math:`J \le J_\text{min}`. Invertible materials (finite energy at
  :math:`J \le 0`) get no guard by default. Further filters (e.g. a
  collision detection) are added with :meth:`NewtonSolver.add_step_filter`;
* a convergence test that ends a solve at the floating-point floor
  (``SolveRecord.reason_name == "CONVERGED_ROUNDOFF"``), with a warning when
  the tolerance asked for less (:mod:`~hyperfem.solver.roundoff`);
* external energies (:mod:`~hyperfem.solver.external`, e.g. a contact
  barrier, :mod:`hyperfem.contact`): added to the objective, the residual and
  the tangent (Dirichlet rows kept exact), with their step filters and a
  start check (a state they refuse is not solved from);
* a boundary-increment predictor: when the prescribed boundary values moved
  since the last solve, one linear solve with the tangent at the old state
  carries the increment into the interior (:mod:`~hyperfem.solver.predictor`);
* the problem's :meth:`check_solution` after convergence (a spurious
  stationary point of a mixed problem is reported as a failure);
* clear errors: invalid PETSc options, a NaN residual at an admissible start
  (a load or material that evaluates to NaN), Dirichlet conditions that leave
  rigid-body motion free, exceptions raised inside SNES callbacks;
* a :class:`SolveRecord` per solve (reason, iterations, residual history).

The solver works with any problem that meets
:class:`~hyperfem.problem.protocol.SolidProblem` (the displacement and the
three-field problem, and a time step of either). Its tangent solves use one
:class:`~hyperfem.solver.linear.LinearSolver` configuration.
"""

from __future__ import annotations

import time
import weakref
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, TypeVar, cast

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem

from hyperfem.errors import ConvergenceError, ParameterError, SolverError
from hyperfem.problem.inversion import QuadratureMinimum
from hyperfem.problem.protocol import SolidProblem, StateHookedProblem
from hyperfem.solver.constraints import unconstrained_rigid_modes
from hyperfem.solver.external import ExternalEnergy, ExternalTerms
from hyperfem.solver.filters import (
    DEFAULT_MIN_JACOBIAN,
    STEP_FILTERS,
    STEP_SAFETY,
    ComposedFilters,
    JacobianBisectionFilter,
    NewtonStepFilter,
    NoAdmissibleStep,
    inversion_filters,
    resolve_min_jacobian,
)
from hyperfem.solver.forcing import FinalStepForcing
from hyperfem.solver.garbage import release_garbage, state_communicators
from hyperfem.solver.lag import PreconditionerLag
from hyperfem.solver.linear import (
    AIJPreconditioner,
    LinearSolver,
    ShiftedPreconditioner,
    choose_linear_solver,
    describe,
    pc_setup_seconds,
)
from hyperfem.solver.objective import EnergyObjective
from hyperfem.solver.options import (
    DEFAULT_PETSC_OPTIONS,
    clean_options,
    describe_option_error,
    merge_options,
    solver_prefix,
)
from hyperfem.solver.predictor import BoundaryPredictor
from hyperfem.solver.roundoff import CONVERGED_ROUNDOFF, ROUNDOFF_FACTOR, RoundoffStop, RoundoffWarning
from hyperfem.solver.state import assign_state
from hyperfem.solver.step_filter import DEFAULT_VOLUME_FRACTION

__all__ = [
    "DEFAULT_MIN_JACOBIAN",
    "DEFAULT_PETSC_OPTIONS",
    "CARRY_ROUNDS",
    "DIRECT_FALLBACK_LIMIT",
    "ROUNDOFF_FACTOR",
    "STEP_FILTERS",
    "STEP_SAFETY",
    "NewtonSolver",
    "RoundoffWarning",
    "SolveRecord",
]

CARRY_ROUNDS = 3
"""Lifts the predictor may add after the first when it pushed a node clear of an obstacle into it.

Each carries those nodes too (:meth:`~hyperfem.solver.external.ExternalTerms.carry_more`) and costs one
tangent solve; measured on the surgery demo's slab with the probe as an analytic ball dragged across it
(``--n 14``, frictionless, 8 steps): without them the drag's starts were refused and cut back to 1/128 of
the path (842 Newton iterations)."""

_DOMAIN = int(PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_DOMAIN)
_LINEAR = int(PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE)
_INDEFINITE_MATRIX = int(PETSc.KSP.ConvergedReason.DIVERGED_INDEFINITE_MAT)

DIRECT_FALLBACK_LIMIT = 400_000
"""Unknowns up to which a Newton direction whose Krylov solve failed is solved again with MUMPS.

A tangent that is indefinite (an exact contact Hessian, a strongly
compressed element) stops CG (``KSP_DIVERGED_INDEFINITE_MAT``/``_PC``); one
LU solve of that tangent is cheaper than the cut-backs the failure would
cost. Above this size the factorisation's memory (several GB for P1 at
4·10^5 unknowns) is not risked: the solve fails as before."""

_T = TypeVar("_T")
_SolverRef = Callable[[], "NewtonSolver"]
"""How the SNES callbacks reach their solver: a weak reference, called while the solver exists."""
_Callback = tuple[Callable[..., None], tuple[Any, ...], dict[str, Any]]
"""A SNES callback as petsc4py gives it back: function, arguments, keyword arguments."""


@dataclass
class SolveRecord:
    r"""Outcome of one nonlinear solve.

    Attributes:
        converged: Whether SNES reported convergence.
        reason: SNES converged reason (positive: converged, negative: diverged).
        reason_name: Name of the reason, e.g. ``CONVERGED_FNORM_RELATIVE``.
        iterations: Newton iterations.
        linear_iterations: Total Krylov iterations.
        residual_norms: Residual 2-norm at each Newton iterate (first: initial).
        wall_time: Seconds spent in the solve.
        min_J: Smallest quadrature-point volume ratio at the end of the solve.
        roundoff_floor: Round-off estimate of the residual norm at the end
            (``nan`` when the floor was never needed).
        predictor: Whether the boundary-increment predictor ran.
        inversion_cutbacks: Trial steps the step filters halved (the bisection
            check that keeps :math:`J > J_{\min}`), summed over the filters.
        filtered_steps: Newton steps the step filters shortened (the exact
            inversion-free filter, and any added filter), summed over the filters.
        min_step_fraction: Smallest fraction of a Newton step a shortening
            filter allowed (1 when none shortened one).
        step_filter: The inversion guard of the solve: ``"exact"``,
            ``"bisection"`` or ``"none"``.
        roundoff_accepts: Steps the energy could not resolve, judged by the residual.
        indicators: The problem's consistency indicators (:meth:`check_solution`).
        message: Why the solve failed or was rejected (empty when it converged), e.g.
            why a step filter found no admissible step.
        ksp_reason: Converged reason of the last linear solve (negative: failed).
        linear_solver: KSP and PC types of the tangent solves, e.g. ``cg+gamg``.
        pc_setup_time: Seconds spent setting up the preconditioner (factorisation, AMG hierarchy); 0 before
            PETSc's log could be started (:func:`~hyperfem.solver.linear.pc_setup_seconds`).
    """

    converged: bool
    reason: int
    reason_name: str
    iterations: int
    linear_iterations: int
    residual_norms: list[float] = field(default_factory=list)
    wall_time: float = 0.0
    min_J: float = float("nan")
    roundoff_floor: float = float("nan")
    predictor: bool = False
    inversion_cutbacks: int = 0
    filtered_steps: int = 0
    min_step_fraction: float = 1.0
    step_filter: str = ""
    roundoff_accepts: int = 0
    indicators: dict = field(default_factory=dict)
    message: str = ""
    ksp_reason: int = 0
    linear_solver: str = ""
    pc_setup_time: float = 0.0

    def as_dict(self) -> dict:
        """JSON-serialisable form."""
        return dict(self.__dict__)


def _reason_name(reason: int) -> str:
    if reason == CONVERGED_ROUNDOFF:
        return "CONVERGED_ROUNDOFF"
    for name in dir(PETSc.SNES.ConvergedReason):
        if not name.startswith("_") and getattr(PETSc.SNES.ConvergedReason, name) == reason:
            return name
    return str(reason)


def _check_rigid_motion(problem: SolidProblem) -> None:
    """Refuse Dirichlet conditions that leave a rigid-body motion free (the tangent is singular)."""
    free = unconstrained_rigid_modes(problem)
    if free:
        raise ParameterError(
            f"NewtonSolver: the Dirichlet conditions leave rigid-body motion unconstrained "
            f"({', '.join(free)}); the tangent is singular — add a Clamp or PrescribedDisplacement"
        )


class NewtonSolver:
    """Newton's method with line search for a :class:`~hyperfem.problem.protocol.SolidProblem`.

    Args:
        problem: The problem (provides residual, Jacobian, energy, BCs).
        petsc_options: PETSc options for the SNES and its KSP/PC, merged over
            :data:`DEFAULT_PETSC_OPTIONS` (keys without the prefix).
        prefix: Options prefix (must end with ``_``); unique by default.
        energy_line_search: Use :math:`\\Pi` as the SNES objective. ``None``:
            when the problem is conservative.
        energy_roundoff_rtol: Relative energy change (w.r.t. the stored plus
            external energy magnitudes) below which a trial step is judged by
            the residual norm instead of the energy.
        min_jacobian: Smallest admissible :math:`J` at quadrature points; the
            line-search step is halved until it holds. ``None`` disables the
            guard. ``"auto"``: ``None`` when the problem says its material is
            ``invertible`` (finite energy for :math:`J \\le 0`: robust and stable
            Neo-Hookean, fixed-corotated, ARAP, linear and corotational linear —
            seed 004: invertible models need no line-search filtering), else
            :data:`DEFAULT_MIN_JACOBIAN`.
        step_filter: How the guard shortens a Newton step. ``"exact"``: the
            inversion-free filter of seed 004
            (:class:`~hyperfem.solver.filters.ExactInversionFilter`): the largest step
            at which no cell's volume drops below ``volume_fraction`` of its
            current value, from a cubic per cell, times :data:`STEP_SAFETY`;
            P1 displacement on straight simplices only. ``"bisection"``
            (:class:`~hyperfem.solver.filters.JacobianBisectionFilter`): halve
            the step until :math:`J > J_{\\min}` at every quadrature point.
            ``"auto"``: exact where it applies, bisection elsewhere. With a
            ``min_jacobian`` the bisection check also runs after the exact
            filter (a safety net; it does not halve a filtered step unless
            the current state is within ``1/volume_fraction`` of
            :math:`J_{\\min}`). ``"exact"`` with ``min_jacobian=None`` filters
            without the :math:`J_{\\min}` check; ``"auto"``/``"bisection"``
            with ``None`` install no guard.
        volume_fraction: :math:`\\eta` of the exact filter.
        predictor: Carry a change of the prescribed boundary values into the
            interior with one tangent solve before Newton starts.
        roundoff_factor: See :data:`ROUNDOFF_FACTOR`; ``0`` disables the
            round-off stop (plain SNES tolerances).
        check_rigid_motion: Refuse Dirichlet conditions that leave a
            rigid-body motion free (the tangent is singular). Problems with
            ``rigid_motion_resisted`` (inertia) are not checked.
        jacobian: A UFL form to use as the tangent instead of
            ``problem.jacobian`` (e.g. a PSD-projected tangent); the
            residual is unchanged.
        state_hooks: Callables ``hook()`` run whenever the solver has moved
            ``problem.u`` to a new state and before it assembles a residual,
            tangent or energy there (e.g. to refresh quadrature fields such
            as polar rotations or projected tangent moduli). The problem's
            own ``state_hooks`` attribute, if any, runs first.
        linear_solver: The linear-solver configuration of the tangent solves
            (default: :func:`~hyperfem.solver.linear.choose_linear_solver`:
            MUMPS LU for small and mixed problems, AMG-preconditioned CG/GMRES
            above the threshold); its options sit between the SNES defaults
            and ``petsc_options``, its near-nullspace hook is applied to the
            tangent matrix.
        form_compiler_options: FFCx options of the compiled forms.
        jit_options: JIT options of the compiled forms.
        step_filters: Further step filters
            (:class:`~hyperfem.solver.filters.NewtonStepFilter`), added in
            order with :meth:`add_step_filter`.
        external_energies: Energies of the unknown's nodal values added to
            :math:`\\Pi` (:class:`~hyperfem.solver.external.ExternalEnergy`, e.g.
            ``hf.contact.PlaneContact(...).bind(problem)``): in the objective,
            the residual and the tangent; their step filters are added after
            ``step_filters``; :meth:`solve` moves them to the problem's time.
            A motion that only an obstacle holds (a block resting on a plane
            under a dead load) needs ``check_rigid_motion=False``.

    Attributes:
        step_filter: The inversion guard: ``"exact"``, ``"bisection"`` or ``"none"``.
        step_filters: All step filters of the pre-check, in the order they run
            (:class:`~hyperfem.solver.filters.ComposedFilters`).

    Raises:
        ParameterError: Invalid PETSc options, a bad prefix, Dirichlet
            conditions that leave rigid-body motion unconstrained, an invalid
            ``min_jacobian``, ``step_filter`` or ``volume_fraction``,
            ``step_filter="exact"`` on a problem whose unknown is not a P1
            displacement on straight simplices, an entry of
            ``step_filters`` that is not a step filter, or one of
            ``external_energies`` that is not an external energy.
    """

    def __init__(
        self,
        problem: SolidProblem,
        petsc_options: dict[str, Any] | None = None,
        *,
        prefix: str | None = None,
        energy_line_search: bool | None = None,
        energy_roundoff_rtol: float = 1e-9,
        min_jacobian: float | str | None = "auto",
        step_filter: str = "auto",
        volume_fraction: float = DEFAULT_VOLUME_FRACTION,
        predictor: bool = True,
        roundoff_factor: float = ROUNDOFF_FACTOR,
        check_rigid_motion: bool = True,
        linear_solver: LinearSolver | None = None,
        jacobian: ufl.Form | None = None,
        state_hooks: Iterable[Callable[[], None]] = (),
        form_compiler_options: dict[str, Any] | None = None,
        jit_options: dict[str, Any] | None = None,
        step_filters: Iterable[NewtonStepFilter] = (),
        external_energies: Iterable[ExternalEnergy] = (),
    ) -> None:
        self.problem = problem
        self.comm = problem.domain.comm
        self._garbage_comms = state_communicators(problem.u)
        self._in_snes = False  # inside the SNES solve (not a tangent assembled outside it)
        self.prefix = solver_prefix(prefix)
        if check_rigid_motion and not problem.rigid_motion_resisted:
            _check_rigid_motion(problem)
        self.external = ExternalTerms(problem, external_energies)
        self.linear_solver = choose_linear_solver(problem) if linear_solver is None else linear_solver
        self.options = merge_options(problem.conservative, self.linear_solver.options, petsc_options)
        compiler = {"form_compiler_options": form_compiler_options, "jit_options": jit_options}
        self._nlp = self._nonlinear_problem(problem.jacobian if jacobian is None else jacobian, petsc_options, compiler)
        self.snes = self._nlp.solver
        own_hooks = problem.state_hooks if isinstance(problem, StateHookedProblem) else ()
        self.state_hooks = [*own_hooks, *state_hooks]
        self.linear_solver_name = describe(self.options)
        self._preconditioner = self._attach_linear_solver(compiler)
        self._norms: list[float] = []
        self._callback_error: BaseException | None = None
        self._refusal = ""
        self._linear_failure = 0
        self.direct_fallbacks = 0
        """Newton directions solved by the MUMPS fallback after a failed Krylov solve (see ``_recover_direction``)."""
        self._lag = PreconditionerLag(self.snes, int(str(self.options.get("snes_lag_preconditioner", 1))))
        self.preconditioner_rebuilds = 0
        """Lagged preconditioners rebuilt on the current tangent after a failed solve (``_recover_direction``)."""
        # Callbacks hold the solver weakly: a strong reference from the SNES
        # back to self would be a cycle through PETSc that Python never frees
        # (leaking the factorisation), or frees at different times per rank.
        # The SNES calls back only while its solver exists, so the reference is typed as always alive.
        me = cast(_SolverRef, weakref.ref(self))
        self._wire_assembly(me)
        self._objective = self._energy_objective(me, energy_line_search, energy_roundoff_rtol, compiler)
        if self._objective is not None:
            self._reuse_judged_residual(me)
        self.min_jacobian = resolve_min_jacobian(min_jacobian, problem)
        self._roundoff = RoundoffStop(self.snes, problem, self._nlp.x, self._nlp.b, roundoff_factor)
        self._forcing = FinalStepForcing(self.snes)
        self._min_J = QuadratureMinimum(problem.domain.mesh, problem.volume_jacobian(), problem.quadrature_points())
        self._install_step_filters(step_filter, volume_fraction, [*step_filters, *self.external.step_filters])
        # Every Newton direction goes through the pre-check: its Dirichlet
        # components are set exactly (see _precheck), then the step filters.
        self.snes.setLineSearchPreCheck(lambda x, y: me()._guarded(me()._precheck, x, y))
        # A failed linear solve goes on to the pre-check, which recovers a direction or ends the solve.
        self.snes.setMaxLinearSolveFailures(1_000_000)
        self.predictor = bool(predictor)
        self._boundary_predictor = BoundaryPredictor(problem, self._nlp, lag=self._lag)

        def test(snes_: PETSc.SNES, it: int, norms: tuple[float, float, float]) -> int:
            return me()._guarded(me()._converged, snes_, it, norms)

        self.snes.setConvergenceTest(test)  # type: ignore[arg-type]  # petsc4py stubs: the reason is an int

    # -- construction ------------------------------------------------------
    def _nonlinear_problem(
        self, jacobian: ufl.Form, petsc_options: dict[str, Any] | None, compiler: dict[str, Any]
    ) -> fpetsc.NonlinearProblem:
        """The DOLFINx problem under :attr:`prefix` with :attr:`options`; rejected options as a ParameterError."""
        problem = self.problem
        try:
            return fpetsc.NonlinearProblem(
                problem.residual,
                problem.u,
                bcs=problem.bcs,
                J=jacobian,
                kind=self._matrix_kind(),
                petsc_options_prefix=self.prefix,
                petsc_options=self.options,
                **compiler,
            )
        except PETSc.Error as exc:
            clean_options(self.prefix, self.options)
            raise ParameterError(f"NewtonSolver: {describe_option_error(exc, petsc_options or {})}") from None

    def _matrix_kind(self) -> str | None:
        """The tangent's matrix type: the linear solver's :attr:`~LinearSolver.matrix_kind` where it applies.

        A blocked tangent needs a blocked displacement space (not the mixed
        one), and neither a preconditioner shift (added to an AIJ copy) nor
        external energies (their Hessians add entries outside DOLFINx's
        sparsity pattern, one scalar at a time).
        """
        linear = self.linear_solver
        plain = self.problem.displacement_space() is self.problem.u.function_space
        if linear.matrix_kind is None or not plain or linear.preconditioner_shift is not None or self.external:
            return None
        return linear.matrix_kind

    def _attach_linear_solver(
        self, compiler: dict[str, Any]
    ) -> ShiftedPreconditioner | AIJPreconditioner | None:
        """Apply the linear solver's hooks; the preconditioning matrix that differs from the tangent, if any.

        That is the tangent plus a shift (:class:`ShiftedPreconditioner`), or
        the AIJ copy of a blocked tangent (:class:`AIJPreconditioner`), else ``None``.
        """
        linear = self.linear_solver
        A = self._nlp.A
        if linear.near_nullspace is not None:
            linear.near_nullspace(A)
        if linear.configure is not None:
            linear.configure(self.snes.getKSP())
        if linear.preconditioner_shift is not None:
            return ShiftedPreconditioner(A, fem.form(linear.preconditioner_shift, **compiler))
        if A.getType() in (PETSc.Mat.Type.SEQBAIJ, PETSc.Mat.Type.MPIBAIJ):
            return AIJPreconditioner(cast(fem.Form, self._nlp.J))  # one form: the blocked path has one field
        return None

    def _wire_assembly(self, me: _SolverRef) -> None:
        """The monitor, the state hooks before each assembly, and the separate preconditioning matrix."""
        self.snes.setMonitor(lambda _snes, _it, norm: me()._norms.append(float(norm)))
        if self.state_hooks or self.external:
            self._hook_assembly(me)
        if self._preconditioner is not None:
            self._shift_jacobian(me)

    def _hook_assembly(self, me: _SolverRef) -> None:
        """Run the state hooks before DOLFINx assembles the residual and the tangent; add the external energies."""
        snes = self.snes
        b, (residual, _, residual_kw) = cast(tuple[PETSc.Vec, _Callback], snes.getFunction())  # petsc4py stubs
        _, _, (jacobian, _, jacobian_kw) = cast(tuple[PETSc.Mat, PETSc.Mat, _Callback], snes.getJacobian())

        def hooked_residual(snes_: PETSc.SNES, x: PETSc.Vec, b_: PETSc.Vec) -> None:
            me()._guarded(me()._set_state, x)
            residual(snes_, x, b_, **residual_kw)
            if me().external:
                me()._guarded(me().external.add_residual, b_)

        def hooked_jacobian(snes_: PETSc.SNES, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
            me()._guarded(me()._set_state, x)
            jacobian(snes_, x, A, P, **jacobian_kw)
            if me().external:
                me()._guarded(me().external.add_tangent, A)

        snes.setFunction(hooked_residual, b)
        snes.setJacobian(hooked_jacobian, self._nlp.A, self._nlp.P_mat)

    def _shift_jacobian(self, me: _SolverRef) -> None:
        """Assemble the tangent, then update the preconditioning matrix from it (plus the shift, or its AIJ copy)."""
        snes = self.snes
        _, _, (jacobian, _, jacobian_kw) = cast(tuple[PETSc.Mat, PETSc.Mat, _Callback], snes.getJacobian())
        preconditioner = self._preconditioner  # holds no reference to the solver
        assert preconditioner is not None  # _wire_assembly calls this only when there is one
        # The AIJ copy of a blocked tangent is read only when the preconditioner is set up: inside the SNES
        # solve, only at the iterations SNES sets it up (the blocked path has no external energies, whose
        # recovery assembles and sets up out of turn); a tangent assembled outside it (continuation) always
        # updates it, and a shifted one always.
        copy_always = not isinstance(preconditioner, AIJPreconditioner)

        replaced: list[PETSc.Mat] = []

        def shifted_jacobian(snes_: PETSc.SNES, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
            jacobian(snes_, x, A, None, **jacobian_kw)
            replaced.clear()
            if copy_always or not me()._in_snes or not me()._lag.reused:
                preconditioner(A)
            if preconditioner.matrix.handle != P.handle:
                if me()._in_snes:
                    # A lagged preconditioner would stay on the old pattern (PCSetUp returns at once when the
                    # KSP reuses it): SNES rebuilds it at this tangent; the next convergence test restores the lag.
                    me()._lag.rebuild_now()
                # A new preconditioning matrix (the tangent's pattern grew, ShiftedPreconditioner): SNES
                # hands it to its KSP after this call, which then sets the preconditioner up anew. The old
                # one is kept alive until the next call (SNESComputeJacobian still holds it).
                replaced.append(P)
                snes_.setJacobian(shifted_jacobian, A, preconditioner.matrix)

        snes.setJacobian(shifted_jacobian, self._nlp.A, preconditioner.matrix)

    def _reuse_judged_residual(self, me: _SolverRef) -> None:
        """The residual of a step the energy line search judged by its residual is not assembled twice."""
        snes = self.snes
        b, (residual, _, residual_kw) = cast(tuple[PETSc.Vec, _Callback], snes.getFunction())  # petsc4py stubs

        def residual_once(snes_: PETSc.SNES, x: PETSc.Vec, b_: PETSc.Vec) -> None:
            objective = me()._objective
            if objective is None or not objective.judged_residual(x, b_):
                residual(snes_, x, b_, **residual_kw)

        snes.setFunction(residual_once, b)

    def _energy_objective(
        self, me: _SolverRef, energy_line_search: bool | None, rtol: float, compiler: dict[str, Any]
    ) -> EnergyObjective | None:
        """Compile :math:`\\Pi`; attach it as the SNES objective when the line search judges by energy."""
        problem = self.problem
        if energy_line_search is None:
            energy_line_search = problem.conservative
        if energy_line_search and not problem.conservative:
            raise ParameterError(
                "NewtonSolver: energy_line_search needs a conservative problem (follower loads have no energy)"
            )
        self.energy_line_search = energy_line_search
        self.energy_roundoff_rtol = float(rtol)
        self._energy_forms = (
            fem.form(problem.energy_internal, **compiler),
            fem.form(problem.energy_external, **compiler),
        )
        if not energy_line_search:
            return None
        objective = EnergyObjective(
            rtol, lambda x: me()._set_state(x), lambda: me()._energies(), self._nlp.x, self._nlp.b
        )
        # The objective holds no reference to the solver (its callbacks go through me).

        def energy(snes_: PETSc.SNES, x: PETSc.Vec) -> float:
            return me()._guarded(objective, snes_, x)

        self.snes.setObjective(energy)  # type: ignore[arg-type]  # petsc4py stubs: the objective returns a float
        return objective

    def _install_step_filters(
        self, step_filter: str, volume_fraction: float, extra: Iterable[NewtonStepFilter]
    ) -> None:
        """The inversion guard (exact filter, bisection check) plus the added filters."""
        exact, bisection = inversion_filters(
            self.problem, step_filter, self.min_jacobian, volume_fraction, self._min_J, self._nlp.x
        )
        self.step_filters = ComposedFilters(f for f in (exact, bisection) if f is not None)
        self.step_filter = "exact" if exact is not None else "bisection" if bisection is not None else "none"
        for added in extra:
            self.add_step_filter(added)

    def add_step_filter(self, step_filter: NewtonStepFilter) -> None:
        r"""Add a step filter to the pre-check (e.g. a continuous collision detection for contact).

        It runs after the exact inversion filter and the filters added before
        it, and before the bisection check on :math:`J` (which checks only
        the end point of the step, so it stays last). Each filter sees the
        step already shortened by those before it; see
        :mod:`~hyperfem.solver.filters`.

        Raises:
            ParameterError: ``step_filter`` does not meet
                :class:`~hyperfem.solver.filters.NewtonStepFilter`.
        """
        filters = self.step_filters.filters
        last_is_bisection = bool(filters) and isinstance(filters[-1], JacobianBisectionFilter)
        self.step_filters.insert(len(filters) - last_is_bisection, step_filter)

    # -- callbacks -------------------------------------------------------
    def _guarded(self, callback: Callable[..., _T], *args: Any) -> _T:
        """Run a SNES callback; keep a Python exception so :meth:`solve` can re-raise it."""
        try:
            return callback(*args)
        except Exception as exc:  # re-raised by solve(); PETSc only sees an error code
            if self._callback_error is None:
                self._callback_error = exc
            raise

    def _set_state(self, x: PETSc.Vec, hooks: bool = True) -> None:
        assign_state(x, self.problem.u)
        if hooks:
            self.refresh()

    def _energies(self) -> tuple[float, float]:
        a = fem.assemble_scalar(self._energy_forms[0])
        b = fem.assemble_scalar(self._energy_forms[1])
        a, b = self.comm.allreduce(np.array([a, b], dtype=float), op=MPI.SUM)
        if self.external:
            a += self.external.energy()
        return float(a), float(b)

    def _precheck(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        # SNES line searches try x - lambda*y with lambda <= 1. First the
        # Dirichlet components: the tangent's Dirichlet rows are identity rows
        # decoupled from the rest, so an exact solve gives y = x - g there, but
        # a Krylov solve preconditioned by AMG (whose aggregates mix Dirichlet
        # and interior dofs) leaves an error of the order of ksp_rtol in them.
        # The energy line search then accepts steps that move the clamped nodes
        # (they lower Pi below its constrained minimum) and Newton stalls at a
        # residual that is all boundary rows: a bend at load 0.001 ended with
        # DIVERGED_LINE_SEARCH at |r| = 0.07 with CG + GAMG, converged with LU.
        # Setting y = x - g on those rows costs nothing and makes every trial
        # state admissible; the interior part of y is untouched. Then the step
        # filters scale y in turn (default: the exact filter to STEP_SAFETY
        # times the largest step that keeps every cell above volume_fraction
        # of its volume, then halving until the full step keeps every
        # quadrature point above min_jacobian).
        if not self._recover_direction(x, y):
            y.zeroEntries()  # no usable direction: the solve ends as a failed linear solve (_failure)
            self._set_state(x, hooks=False)
            return
        fpetsc.set_bc(y, self.problem.bcs, x0=x, alpha=-1.0)
        try:
            self.step_filters.apply(x, y)
        except NoAdmissibleStep as refusal:
            # The search direction is unusable: the convergence test ends the
            # solve (DIVERGED_FUNCTION_DOMAIN, a failed solve the stepper cuts back).
            self._refusal = str(refusal)
        self._set_state(x, hooks=False)

    def _recover_direction(self, x: PETSc.Vec, y: PETSc.Vec) -> bool:
        r"""Make ``y`` a usable Newton direction after a failed linear solve or a non-descending exact tangent.

        SNES tries :math:`x - \lambda y`: a descent direction has :math:`r\cdot y > 0`.

        1. An exact (possibly indefinite) contact Hessian whose direction does
           not descend, or whose tangent stopped the Krylov solve (CG on an
           indefinite operator or preconditioner): the energies project their
           Hessians (until the iterates settle again, :mod:`hyperfem.contact.mesh_barrier`),
           the tangent is assembled again at ``x`` and ``y`` solved anew.
        2. A Krylov solve that failed with a lagged preconditioner
           (``snes_lag_preconditioner``, built on an older tangent): the
           preconditioner is rebuilt on this tangent and ``y`` solved anew.
           In the surgery demo's drag (``--n 16``, 15k unknowns, CG + GAMG
           lagged by 2, serial) 36 of 42 MUMPS fallbacks were CG stopping
           with ``KSP_DIVERGED_INDEFINITE_PC`` on a hierarchy built before
           the contact pairs changed; rebuilt, each solved (0.14 s against
           0.35 s per fallback), the same 16 steps and forces.
        3. A linear solve that still failed: ``y`` solved once with MUMPS on the
           same tangent, if the problem has at most :data:`DIRECT_FALLBACK_LIMIT`
           unknowns (a Krylov solve that hit an indefinite tangent or its
           iteration limit is not the end of the load step).

        Returns:
            False when no direction could be found (the solve ends as a failed
            linear solve, which the stepper cuts back).
        """
        ksp = self.snes.getKSP()
        failed = int(ksp.getConvergedReason()) < 0  # type: ignore[call-overload]  # petsc4py stubs: an int
        exact = bool(self.external) and self.external.exact_tangents()
        if not failed and not exact:
            return True
        r = self.snes.getFunction()[0]  # type: ignore[index, unused-ignore]  # petsc4py stubs: (Vec, callback)
        if exact and (failed or r.dot(y) <= 0.0):
            self.external.project_tangents()
            J, P, _ = self.snes.getJacobian()
            self.snes.computeJacobian(x, J, P)
            J, P, _ = self.snes.getJacobian()  # a grown pattern gives a new preconditioning matrix
            ksp.setOperators(J, P)
            ksp.solve(r, y)
            failed = int(ksp.getConvergedReason()) < 0  # type: ignore[call-overload]  # an int
        if failed and self._lag.reused and int(ksp.getConvergedReason()) != _INDEFINITE_MATRIX:  # type: ignore[call-overload]
            # A lagged preconditioner (``snes_lag_preconditioner``) built on an
            # older tangent, e.g. before the contact pairs changed: the AMG's
            # Chebyshev bounds no longer fit, CG stops with an indefinite
            # preconditioner. Rebuild it on this tangent and solve again (SNES
            # sets the reuse flag anew at its next tangent). An indefinite
            # tangent itself is not the preconditioner's fault.
            J, P, _ = self.snes.getJacobian()
            if isinstance(self._preconditioner, AIJPreconditioner):  # its copy is refreshed only when SNES sets up
                self._preconditioner(J)
            ksp.getPC().setReusePreconditioner(False)
            self._lag.rebuilt()
            ksp.setOperators(J, P)
            ksp.solve(r, y)
            failed = int(ksp.getConvergedReason()) < 0  # type: ignore[call-overload]  # an int
            self.preconditioner_rebuilds += 1
        if not failed:
            return True
        self._linear_failure = int(ksp.getConvergedReason())  # type: ignore[call-overload]  # an int
        if self._nlp.x.getSize() > DIRECT_FALLBACK_LIMIT:
            return False
        J, _, _ = self.snes.getJacobian()
        reason = LinearSolver().solve(self.comm, J, r, y, kind="fallback")
        self.direct_fallbacks += 1
        if reason < 0:
            return False
        self._linear_failure = 0
        return True

    def _converged(self, snes: PETSc.SNES, it: int, norms: tuple[float, float, float]) -> int:
        """SNES convergence test: a refused step ends the solve, else the round-off stop's test."""
        if self._refusal:
            return _DOMAIN
        if self._linear_failure:
            return _LINEAR
        if it == 0 and self._objective is not None:
            self._objective.reset()  # a solve started through the public SNES too
        reason = self._roundoff(snes, it, norms)
        self._lag(it, reason)  # before the forcing sets the next solve's tolerance (the lag reads the last one's)
        self._forcing(snes, it, float(norms[2]), reason)
        return reason

    @property
    def nonlinear_problem(self) -> fpetsc.NonlinearProblem:
        """The DOLFINx problem whose SNES this solver drives (its ``x``, ``b`` and matrices; e.g. for continuation)."""
        return self._nlp

    # -- state -------------------------------------------------------------
    def refresh(self) -> None:
        """Run the state hooks at the current ``problem.u``."""
        for hook in self.state_hooks:
            hook()

    def energy(self) -> float:
        """Total potential :math:`\\Pi` at the current displacement."""
        self.refresh()
        a, b = self._energies()
        return a - b

    def min_J(self) -> float:
        """Smallest :math:`J` over all quadrature points at the current state."""
        return self._min_J()

    def roundoff_floor(self) -> float:
        """Round-off estimate of the residual norm (:meth:`~hyperfem.solver.roundoff.RoundoffStop.floor`)."""
        return self._roundoff.floor()

    def _start_refusal(self) -> str:
        """Why the current state cannot be solved from, ``""`` if it can (collective).

        :math:`J \\le J_\\text{min}` somewhere, or an external energy refuses it
        (a contact node on or behind its obstacle).
        """
        if self.min_jacobian is not None and not self.min_J() > self.min_jacobian:
            return f"start state has J <= {self.min_jacobian:g}"
        return self.external.refusal() if self.external else ""

    def _admissible(self) -> bool:
        """Whether the current state can be solved from (:meth:`_start_refusal`; always, without guards)."""
        return not self._start_refusal()

    @property
    def roundoff_factor(self) -> float:
        """The factor of the round-off stop (:data:`ROUNDOFF_FACTOR`; 0: off)."""
        return self._roundoff.factor

    @roundoff_factor.setter
    def roundoff_factor(self, value: float) -> None:
        self._roundoff.factor = float(value)

    @property
    def inversion_cutbacks(self) -> int:
        """Line-search steps halved by the step filters so far (the bisection on :math:`J`)."""
        return self.step_filters.cutbacks

    @property
    def filtered_steps(self) -> int:
        """Newton steps shortened by the step filters so far (the exact filter)."""
        return self.step_filters.filtered_steps

    @property
    def roundoff_accepts(self) -> int:
        """Steps the energy could not resolve, accepted by the residual so far."""
        return 0 if self._objective is None else self._objective.roundoff_accepts

    # -- solve -------------------------------------------------------------
    def solve(self, raise_on_failure: bool = False) -> SolveRecord:
        """Solve for the current loads, starting from the current displacement.

        Args:
            raise_on_failure: Raise :class:`ConvergenceError` instead of
                returning a record with ``converged=False``.

        Returns:
            The :class:`SolveRecord`.

        Raises:
            ParameterError: The residual is NaN/inf at the (admissible)
                starting state: a load, prescribed value or material
                evaluates to NaN.
            Exception: Whatever a SNES callback (objective, pre-check,
                convergence test) raised.
        """
        release_garbage(self._garbage_comms)  # every rank is here: what earlier solves dropped goes now
        counts = self._start_solve()
        start = time.perf_counter()
        # An external energy (contact) is never assembled at a refused state: a refused start guess is pulled
        # back toward the last converged state first, and the predictor runs only from an admissible one.
        if self.external:
            self.external.pull_back()
        carried = None
        if self.external and self.predictor and (self.external.refusal() or self.external.sweep_refusal()):
            # An obstacle moved into the body (or, a thin tool, through the part of it that may touch): carry the
            # nodes it overran in the predictor's tangent solve.
            carried = self.external.carry()
        admissible = carried is not None or not (self.external and self.external.refusal())
        moved = carried is not None or self._boundary_predictor.moved()
        if carried is not None and self.external and self.external.carries_more():
            predicted = self._carry(carried)
        else:
            predicted = admissible and self.predictor and moved and self._predict(carried)
        self._apply_dirichlet()
        refusal = self._start_refusal()
        if not refusal and self.external:  # a start that passes through a surface since the last converged state
            refusal = self.external.sweep_refusal()
        if refusal and carried is None and self.external and self.predictor:
            # A prescribed surface pushed into a body it touches: carry the touched nodes with it, predict again.
            guess = self.problem.u.x.array.copy()
            pushed = self.external.carry_by_supports()
            if pushed is not None:
                predicted = self._predict(pushed) or predicted
                self._apply_dirichlet()
                refusal = self._start_refusal() or self.external.sweep_refusal()
            else:
                self.problem.u.x.array[:] = guess
        if refusal and self.external and self.external.pull_back():
            # The prediction passes through a surface (a body driven onto another from beyond the barrier's
            # reach): keep its collision-free part, the Dirichlet values in full (Newton closes the rest).
            self._apply_dirichlet()
            refusal = self._start_refusal() or self.external.sweep_refusal()
        solved = not refusal
        reason, message = (self._run_snes(), "") if solved else (_DOMAIN, refusal)
        self._forcing.restore()
        self.problem.u.x.scatter_forward()
        # A solve refused at its start ran no SNES: SNES still holds the previous solve's counts.
        iterations = int(self.snes.getIterationNumber()) if solved else 0
        ksp_reason = int(self.snes.getKSP().getConvergedReason()) if solved else 0  # type: ignore[call-overload]  # an int
        reason, message = self._failure(reason, message, ksp_reason)
        self._roundoff.warn_below_floor(self.comm, self._norms, stacklevel=2)
        if reason == int(PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_NANORINF) and iterations == 0:
            # NaN/inf at an admissible start (J > J_min checked above): bad input, not a hard step.
            raise ParameterError(self._nan_message())
        reason, message, indicators = self._check_solution(reason, message)
        wall = time.perf_counter() - start
        record = self._record(counts, reason, message, indicators, solved, iterations, ksp_reason, predicted, wall)
        if record.converged and self.external:
            self.external.remember()
        if raise_on_failure and not record.converged:
            detail = f": {message}" if message else ""
            raise ConvergenceError(
                f"Newton solve did not converge: {record.reason_name} after {record.iterations} iterations "
                f"(t = {self.problem.time:g}){detail}",
                self.problem.time,
            )
        return record

    def _start_solve(self) -> tuple[int, int, int, float]:
        """Reset the per-solve state; the counters and PC set-up time before the solve."""
        self._norms = []
        self._callback_error = None
        self._refusal = ""
        self._linear_failure = 0
        self._roundoff.reset()
        self._forcing.restore()
        if self._objective is not None:
            self._objective.reset()
        self.step_filters.min_step_fraction = 1.0
        self.external.update(self.problem.time)
        return self.inversion_cutbacks, self.roundoff_accepts, self.filtered_steps, pc_setup_seconds(self.comm)

    def _carry(self, carried: tuple[np.ndarray, np.ndarray]) -> bool:
        """The predictor's lift with the carried nodes, and with those it pushes into an obstacle (collective).

        The lift is applied whole; where it pushes a node that was clear of the obstacle into it, that node is
        carried too and the lift solved again (:data:`CARRY_ROUNDS`, ``ExternalTerms.carry_more``). A lift refused
        for another reason, or with no node to add, is shortened to the largest admissible ``2^-k`` without a new
        solve. Whether it moved the state (else the state is the anchor).
        """
        assert self.external is not None
        predictor = self._boundary_predictor
        for _ in range(CARRY_ROUNDS):
            if self._predict(carried, halve=False):
                return True
            if not predictor.refused:  # the lift's linear solve failed: the state is the anchor
                return False
            more = self.external.carry_more(carried) if self.external.refusal() else None
            if more is None:
                return predictor.halve_refused(self._admissible)
            carried = more  # carry_more put the state back at the anchor
        return self._predict(carried)  # the rounds ran out: the last set's lift, halved as far as needed

    def _predict(self, carried: tuple[np.ndarray, np.ndarray] | None = None, halve: bool = True) -> bool:
        """Run the boundary-increment predictor (with the nodes an obstacle carries); whether it moved the state
        (``halve=False``: whether the whole lift is admissible, :meth:`BoundaryPredictor.lift`)."""
        tangent_terms = self.external.add_tangent if self.external else None
        if carried is not None:
            external = self.external

            def tangent_terms(A: PETSc.Mat) -> None:
                # The tangent at the anchor, where the obstacles still were at the anchor's time.
                external.update(external.anchor_time)
                try:
                    external.add_tangent(A)
                finally:
                    external.update(self.problem.time)

        return self._boundary_predictor.lift(
            self.snes.getKSP(),
            refresh=self.refresh,
            preconditioner=self._preconditioner,
            admissible=self._admissible,
            tangent_terms=tangent_terms,
            carried=carried,
            halve=halve,
        )

    def _apply_dirichlet(self) -> None:
        # Start from a state that satisfies the Dirichlet conditions, so the
        # Newton direction has no boundary components and the energy line
        # search sees only admissible states.
        u = self.problem.u
        for bc in self.problem.bcs:
            bc.set(u.x.array)
        u.x.scatter_forward()

    def _run_snes(self) -> int:
        """The SNES solve; its converged reason. PETSc errors become a Python error that says what failed."""
        self._in_snes = True
        try:
            self._nlp.solve()
            return int(self.snes.getConvergedReason())  # type: ignore[call-overload]  # petsc4py stubs: an int
        except PETSc.Error as exc:
            if self._callback_error is not None:
                raise self._callback_error from None
            if isinstance(exc.__cause__, KeyboardInterrupt):
                # Ctrl-C inside an assembly callback: PETSc saw error 101 (a Python error); it is the interrupt.
                raise KeyboardInterrupt(f"interrupted in the solve at t = {self.problem.time:g}") from None
            raise SolverError(
                f"NewtonSolver: PETSc error {getattr(exc, 'ierr', '?')} in the solve at t = {self.problem.time:g} "
                f"(options prefix {self.prefix}); not a hard step but a failure of PETSc itself"
            ) from exc
        finally:
            self._in_snes = False
            self._lag.restore()  # also after a solve ended in a callback (the convergence test did not run)
            if self._objective is not None:  # its caches belong to this solve (the public SNES may solve again)
                self._objective.reset()

    def _failure(self, reason: int, message: str, ksp_reason: int) -> tuple[int, str]:
        """The reason and message of a refused step or a failed linear solve."""
        if self._refusal and not message:
            return _DOMAIN, self._refusal
        if self._linear_failure and not message:  # no direction recovered (the line search saw a zero step)
            return _LINEAR, f"linear solve failed (KSP reason {self._linear_failure})"
        if reason == _LINEAR and not message:
            return reason, f"linear solve failed (KSP reason {ksp_reason})"
        return reason, message

    def _check_solution(self, reason: int, message: str) -> tuple[int, str, dict[str, float]]:
        """The problem's consistency check of a converged state (a veto turns it into a failure)."""
        indicators: dict[str, float] = {}
        if reason > 0:
            indicators, why = self.problem.check_solution()
            if why:
                return _DOMAIN, why, indicators
        return reason, message, indicators

    def _record(
        self,
        counts: tuple[int, int, int, float],
        reason: int,
        message: str,
        indicators: dict[str, float],
        solved: bool,
        iterations: int,
        ksp_reason: int,
        predicted: bool,
        wall: float,
    ) -> SolveRecord:
        """The :class:`SolveRecord` of the solve that just ended (collective: min J, PC set-up time)."""
        cutbacks0, accepts0, filtered0, setup0 = counts
        minJ = self.min_J()
        return SolveRecord(
            converged=reason > 0 and bool(np.isfinite(minJ)),
            reason=reason,
            reason_name=_reason_name(reason),
            iterations=iterations,
            linear_iterations=int(self.snes.getLinearSolveIterations()) if solved else 0,
            residual_norms=list(self._norms),
            wall_time=wall,
            min_J=minJ,
            roundoff_floor=self._roundoff.floor_value,
            predictor=predicted,
            inversion_cutbacks=self.inversion_cutbacks - cutbacks0,
            filtered_steps=self.filtered_steps - filtered0,
            min_step_fraction=self.step_filters.min_step_fraction,
            step_filter=self.step_filter,
            roundoff_accepts=self.roundoff_accepts - accepts0,
            indicators=indicators,
            message=message,
            ksp_reason=ksp_reason,
            linear_solver=self.linear_solver_name,
            pc_setup_time=float(self.comm.allreduce(pc_setup_seconds(self.comm) - setup0, op=MPI.MAX)),
        )

    def _nan_message(self) -> str:
        where = f"t = {self.problem.time:g}"
        names = self.problem.nonfinite_terms()
        if names:
            return (
                f"NewtonSolver: residual is NaN/inf at the start of the solve ({where}); "
                f"non-finite term(s): {', '.join(names)}"
            )
        return (
            f"NewtonSolver: residual is NaN/inf at the start of the solve ({where}); a load, prescribed value "
            "or the material evaluates to NaN/inf"
        )
