r"""Line-searched Newton (PETSc SNES) on top of :class:`dolfinx.fem.petsc.NonlinearProblem`.

What this adds to the DOLFINx class:

* documented defaults (``newtonls`` + backtracking, MUMPS LU) with user
  options merged over them under a *unique* options prefix; nothing is left
  in the global options database;
* for conservative problems the total potential :math:`\Pi` is attached as
  the SNES objective, so the backtracking line search judges a step by the
  energy rather than by the residual norm;
* a round-off guard for that objective: near convergence the energy change of
  a Newton step, :math:`\tfrac12 R\cdot\delta u`, drops below the resolution
  of the assembled :math:`\Pi` (round-off and cancellation, e.g. of the inertia
  term of an incremental potential). When a trial energy is within
  ``energy_roundoff_rtol`` of the current one, the step is judged by the
  residual norm instead, so tight residual tolerances are still met;
* a line-search pre-check that refuses steps that would invert elements: for
  P1 simplices the *exact* filter of seed 004
  (:mod:`~hyperfem.solver.step_filter`) shortens the Newton step to the
  largest length at which no cell shrinks below a fraction
  :math:`\eta` of its current volume (a cubic root per cell); for other
  discretisations, and as a final check, the step is halved until no
  quadrature point has :math:`J \le J_\text{min}`. Invertible materials
  (finite energy at :math:`J \le 0`) get no guard by default;
* a convergence test that ends a solve at the floating-point floor: once
  Newton stops making progress (:math:`\|r_k\| > \tfrac12\|r_{k-1}\|`) with
  :math:`\|r_k\|` within :data:`ROUNDOFF_FACTOR` of the round-off estimate
  :math:`\varepsilon\,\|\,|K|\,|x|\,\|` (machine epsilon times the size of the
  assembled internal-force terms), the solve is *converged at round-off*
  (``SolveRecord.reason_name == "CONVERGED_ROUNDOFF"``) instead of wandering
  in noise until a lucky dip or ``snes_max_it``; a tolerance below that floor
  draws a warning;
* a boundary-increment predictor: when the prescribed boundary values moved
  since the last solve, one linear solve with the tangent at the old state
  and the increment as a lifted Dirichlet condition carries it into the
  interior (instead of moving only the boundary nodes and squeezing the
  first layer of cells);
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

import numbers
import time
import warnings
import weakref
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem
from dolfinx.la.petsc import _ghost_update

from hyperfem.errors import ConvergenceError, ParameterError, SolverError
from hyperfem.io.probes import QuadratureMinimum
from hyperfem.problem.protocol import SolidProblem
from hyperfem.solver.constraints import unconstrained_rigid_modes
from hyperfem.solver.linear import DIRECT, LinearSolver, choose_linear_solver, describe, unique_prefix
from hyperfem.solver.step_filter import DEFAULT_VOLUME_FRACTION, StepFilter, exact_filter_applies

__all__ = [
    "DEFAULT_MIN_JACOBIAN",
    "DEFAULT_PETSC_OPTIONS",
    "ROUNDOFF_FACTOR",
    "STEP_FILTERS",
    "STEP_SAFETY",
    "NewtonSolver",
    "RoundoffWarning",
    "SolveRecord",
]

ROUNDOFF_FACTOR = 100.0
r"""A stagnating residual within this factor of :math:`\varepsilon\|\,|K||x|\,\|` is at the floor.

Measured (``benchmarks/roundoff_floor.py``): once Newton has reached it, the
noise band of the assembled residual sits at 0.09–3 times the estimate on the
cantilever cases (P1/P2, dead and follower loads), so a factor 100 leaves a
margin of 30 for other BLAS/MUMPS builds and ends those solves at the first
stagnating iterate, while a residual this small is below :math:`10^{-10}` of
the loads there."""

REFERENCE_SCALE_FRACTION = 1.0 / 16.0
r"""The identity part of :math:`F` enters :meth:`NewtonSolver.roundoff_floor` as a displacement of this fraction of the largest cell.

Measured (cantilever bend and twist, beam_h2 and beam_h1, P1 and P2, load
factors 1e-6, 1e-3 and 1, MUMPS, tolerances 1e-15 and no round-off stop): the
residual stagnates at 0.6e-9 to 2e-8 at every load, while
:math:`\varepsilon\|\,|K||x|\,\|` falls with the load from about 1e-8 to 1e-15 (the
noise was up to 4e5 times the old estimate: solves at small loads wandered
to ``snes_max_it``). With the cell-size term at full size the noise band is
0.0017–0.17 of the estimate; this fraction puts it at 0.03–2.7, the band the
factor :data:`ROUNDOFF_FACTOR` was chosen for."""

MAX_INVERSION_HALVINGS = 40
"""The pre-check halves a Newton step at most this often to keep :math:`J > J_{\\min}`."""

DEFAULT_MIN_JACOBIAN = 1e-6
"""``min_jacobian="auto"`` of a problem whose material is not invertible."""

STEP_FILTERS = ("auto", "exact", "bisection")
"""Values of ``NewtonSolver(step_filter=...)``."""

STEP_SAFETY = 0.9
r"""The exact filter scales a Newton step to this times its critical :math:`\alpha^*` (when :math:`\alpha^* < 1`).

At :math:`\alpha^*` the most compressed cell is at exactly :math:`\eta` of its
volume, where a barrier energy (:math:`-\mu\ln J`) is steep; the factor keeps
the first trial of the line search strictly inside (the volume ratio stays
above :math:`\eta` for every shorter step anyway). Not needed for
:math:`J > 0`; chosen by measurement (``benchmarks/step_filter.py``, results in
``benchmarks/results/step_filter.jsonl``): of the 16 one-step solves of the
cantilever bend and twist at 20, 50, 100 and 200 times the load on
``beam_h2``/``beam_h1`` (P1), 15 converge with 0.9, 14 with 0.8, 13 with
0.95, 12 with 1.0 and 10 with 0.5 (13 with the bisection guard). At these
loads the outcome is sensitive to any change of the Newton path, so read the
counts as "0.8–0.9 is a sound range", not as an optimum."""

CONVERGED_ROUNDOFF = int(PETSc.SNES.ConvergedReason.CONVERGED_ITS)
"""SNES reason returned when the floor ends a solve (the record names it ``CONVERGED_ROUNDOFF``)."""


class RoundoffWarning(UserWarning):
    """The requested residual tolerance is below what floating point can resolve."""

SNES_DEFAULTS: dict[str, object] = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "bt",
    "snes_rtol": 1e-9,
    "snes_atol": 1e-10,
    "snes_stol": 0.0,
    "snes_max_it": 50,
}
"""SNES defaults of :class:`NewtonSolver`; the KSP/PC part comes from its :class:`LinearSolver`."""

DEFAULT_PETSC_OPTIONS: dict[str, object] = {**SNES_DEFAULTS, **DIRECT}
"""SNES defaults plus the direct solver that small problems get (for reference; see :func:`~hyperfem.solver.linear.choose_linear_solver`)."""



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
        inversion_cutbacks: Line-search steps halved to keep :math:`J > J_{\min}`.
        filtered_steps: Newton steps the exact inversion-free filter shortened.
        min_step_fraction: Smallest fraction of a Newton step the exact filter
            allowed (1 when it never shortened one).
        step_filter: The inversion guard of the solve: ``"exact"``,
            ``"bisection"`` or ``"none"``.
        roundoff_accepts: Steps the energy could not resolve, judged by the residual.
        indicators: The problem's consistency indicators (:meth:`check_solution`).
        message: Why the solve failed or was rejected (empty when it converged).
        ksp_reason: Converged reason of the last linear solve (negative: failed).
        linear_solver: KSP and PC types of the tangent solves, e.g. ``cg+gamg``.
        pc_setup_time: Seconds spent setting up the preconditioner (factorisation, AMG hierarchy).
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


def _resolve_min_jacobian(min_jacobian: float | str | None, problem: SolidProblem) -> float | None:
    """``min_jacobian`` with ``"auto"`` resolved (``None`` for an ``invertible`` problem)."""
    if isinstance(min_jacobian, str):
        if min_jacobian != "auto":
            raise ParameterError(f"NewtonSolver: min_jacobian must be a number, None or 'auto', got {min_jacobian!r}")
        return None if getattr(problem, "invertible", False) else DEFAULT_MIN_JACOBIAN
    if min_jacobian is None:
        return None
    if isinstance(min_jacobian, bool) or not isinstance(min_jacobian, numbers.Real) or not np.isfinite(min_jacobian):
        raise ParameterError(
            f"NewtonSolver: min_jacobian must be a finite number, None or 'auto', got {min_jacobian!r}"
        )
    if not 0.0 <= min_jacobian < 1.0:
        raise ParameterError(
            f"NewtonSolver: min_jacobian must be in [0, 1) (the volume ratio J below which a state counts as "
            f"inverted; the reference state has J = 1), got {min_jacobian!r}"
        )
    return float(min_jacobian)


def _reason_name(reason: int) -> str:
    if reason == CONVERGED_ROUNDOFF:
        return "CONVERGED_ROUNDOFF"
    for name in dir(PETSc.SNES.ConvergedReason):
        if not name.startswith("_") and getattr(PETSc.SNES.ConvergedReason, name) == reason:
            return name
    return str(reason)


class NewtonSolver:
    """Newton's method with line search for a :class:`~hyperfem.problem.HyperelasticProblem`.

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
            Neo-Hookean, corotated, linear — seed 004: invertible models need
            no line-search filtering), else :data:`DEFAULT_MIN_JACOBIAN`.
        step_filter: How the guard shortens a Newton step. ``"exact"``: the
            inversion-free filter of seed 004
            (:class:`~hyperfem.solver.step_filter.StepFilter`): the largest step
            at which no cell's volume drops below ``volume_fraction`` of its
            current value, from a cubic per cell, times :data:`STEP_SAFETY`;
            P1 displacement on straight simplices only. ``"bisection"``: halve
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

    Raises:
        ParameterError: Invalid PETSc options, a bad prefix, Dirichlet
            conditions that leave rigid-body motion unconstrained, an invalid
            ``min_jacobian``, ``step_filter`` or ``volume_fraction``, or
            ``step_filter="exact"`` on a problem whose unknown is not a P1
            displacement on straight simplices.
    """

    def __init__(
        self,
        problem: SolidProblem,
        petsc_options: dict | None = None,
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
        jacobian=None,
        state_hooks=(),
        form_compiler_options: dict | None = None,
        jit_options: dict | None = None,
    ):
        self.problem = problem
        comm = problem.domain.comm
        self.comm = comm
        if prefix is None:
            prefix = unique_prefix("newton")
        if not prefix.endswith("_"):
            raise ParameterError(f"NewtonSolver: options prefix must end with '_', got {prefix!r}")
        self.prefix = prefix
        if check_rigid_motion and not problem.rigid_motion_resisted:
            free = unconstrained_rigid_modes(problem)
            if free:
                raise ParameterError(
                    f"NewtonSolver: the Dirichlet conditions leave rigid-body motion unconstrained "
                    f"({', '.join(free)}); the tangent is singular — add a Clamp or PrescribedDisplacement"
                )
        defaults = dict(SNES_DEFAULTS)
        if not problem.conservative:
            # No energy to judge steps by. Measured on the twist case (P2,
            # h = 1): residual-norm 'bt' 13 iterations, 'cp' 6, 'basic' 5
            # (unsafeguarded); 'cp' is the safeguarded choice.
            defaults["snes_linesearch_type"] = "cp"
        self.linear_solver = choose_linear_solver(problem) if linear_solver is None else linear_solver
        self.options = {**defaults, **self.linear_solver.options, **(petsc_options or {})}
        try:
            self._nlp = fpetsc.NonlinearProblem(
                problem.residual,
                problem.u,
                bcs=problem.bcs,
                J=problem.jacobian if jacobian is None else jacobian,
                petsc_options_prefix=prefix,
                petsc_options=self.options,
                form_compiler_options=form_compiler_options,
                jit_options=jit_options,
            )
        except PETSc.Error as exc:
            self._clean_options()
            raise ParameterError(f"NewtonSolver: {self._describe_option_error(exc, petsc_options or {})}") from None
        snes = self._nlp.solver
        self.snes = snes
        self.state_hooks = [*getattr(problem, "state_hooks", ()), *state_hooks]
        PETSc.Log.begin()  # for the preconditioner set-up time of each solve (PCSetUp event)
        # PCSetUp: factorisations, AMG of a plain KSP; PCSetUpOnBlocks: the
        # split preconditioners of a field split (set up outside PCSetUp).
        self._pc_setup = (PETSc.Log.Event("PCSetUp"), PETSc.Log.Event("PCSetUpOnBlocks"))
        self.linear_solver_name = describe(self.options)
        if self.linear_solver.near_nullspace is not None:
            self.linear_solver.near_nullspace(self._nlp.A)
        if self.linear_solver.configure is not None:
            self.linear_solver.configure(snes.getKSP())
        self._shift: PETSc.Mat | None = None
        self._P: PETSc.Mat | None = None
        if self.linear_solver.preconditioner_shift is not None:
            # Assembled into the tangent's sparsity (every cell block of W), so
            # tangent, shift and preconditioning matrix share one pattern.
            self._shift = self._nlp.A.duplicate()
            fpetsc.assemble_matrix(
                self._shift,
                fem.form(self.linear_solver.preconditioner_shift, form_compiler_options=form_compiler_options,
                         jit_options=jit_options),
            )
            self._shift.assemble()
            self._P = self._shift.duplicate(copy=True)
        self._norms: list[float] = []
        self._callback_error: BaseException | None = None
        # Callbacks hold the solver weakly: a strong reference from the SNES
        # back to self would be a cycle through PETSc that Python never frees
        # (leaking the factorisation), or frees at different times per rank.
        me = weakref.ref(self)
        snes.setMonitor(lambda _snes, _it, norm: me()._norms.append(float(norm)))
        if self.state_hooks:
            self._wrap_assembly(me)
        if self._P is not None:
            _, _, (jacobian, _, jacobian_kw) = snes.getJacobian()

            def shifted_jacobian(snes_, x, A, P):
                jacobian(snes_, x, A, None, **jacobian_kw)
                me()._shifted(A)

            snes.setJacobian(shifted_jacobian, self._nlp.A, self._P)

        if energy_line_search is None:
            energy_line_search = problem.conservative
        if energy_line_search and not problem.conservative:
            raise ParameterError(
                "NewtonSolver: energy_line_search needs a conservative problem (follower loads have no energy)"
            )
        self.energy_line_search = energy_line_search
        self.energy_roundoff_rtol = float(energy_roundoff_rtol)
        self._energy_forms = (
            fem.form(problem.energy_internal, form_compiler_options=form_compiler_options, jit_options=jit_options),
            fem.form(problem.energy_external, form_compiler_options=form_compiler_options, jit_options=jit_options),
        )
        self._ref: tuple[float, float] | None = None
        self._full_step_change: float | None = None
        self.roundoff_accepts = 0
        if energy_line_search:
            snes.setObjective(lambda snes_, x: me()._guarded(me()._objective, snes_, x))

        self.min_jacobian = _resolve_min_jacobian(min_jacobian, problem)
        self._work = self._nlp.x.duplicate()
        self._residual_work = self._nlp.b.duplicate()
        self._reference_scale = self._make_reference_scale()
        self._min_J = QuadratureMinimum(problem.domain.mesh, problem.volume_jacobian(), problem.quadrature_points())
        self.inversion_cutbacks = 0
        self.filtered_steps = 0
        self._min_step_fraction = 1.0
        self._direction: fem.Function | None = None
        self._step_filter = self._make_step_filter(step_filter, volume_fraction)
        self.step_filter = (
            "exact" if self._step_filter is not None else "bisection" if self.min_jacobian is not None else "none"
        )
        # Every Newton direction goes through the pre-check: its Dirichlet
        # components are set exactly (see _precheck), then the inversion guard.
        snes.setLineSearchPreCheck(lambda x, y: me()._guarded(me()._precheck, x, y))

        self.predictor = bool(predictor)
        self.roundoff_factor = float(roundoff_factor)
        self._abs_jacobian: PETSc.Mat | None = None
        self._floor = float("nan")
        self._roundoff_stop = False
        self._warned_floor = False
        snes.setConvergenceTest(lambda snes_, it, norms: me()._guarded(me()._converged, snes_, it, norms))

    def _make_step_filter(self, step_filter: str, volume_fraction: float) -> StepFilter | None:
        """The exact filter where ``step_filter`` asks for it and it applies (see the class docstring)."""
        if step_filter not in STEP_FILTERS:
            raise ParameterError(
                f"NewtonSolver: step_filter must be one of {', '.join(STEP_FILTERS)}, got {step_filter!r}"
            )
        if step_filter == "bisection" or (step_filter == "auto" and self.min_jacobian is None):
            return None
        V = self.problem.u.function_space
        plain = self.problem.displacement_space() is V  # the unknown is the displacement, nothing else
        if not (plain and exact_filter_applies(V)):
            if step_filter == "exact":
                raise ParameterError(
                    "NewtonSolver: step_filter='exact' needs a displacement-only problem with P1 elements on "
                    f"straight simplices (got {V.ufl_element()}); use 'auto' or 'bisection'"
                )
            return None
        return StepFilter(V, volume_fraction)

    # -- errors ------------------------------------------------------------
    def _clean_options(self) -> None:
        """Undo what a failed ``NonlinearProblem`` construction left in PETSc's options database."""
        opts = PETSc.Options()
        try:
            opts.prefixPop()
        except PETSc.Error:
            pass
        for key in self.options:
            opts.delValue(f"-{self.prefix}{key}")

    @staticmethod
    def _describe_option_error(exc: PETSc.Error, user: dict) -> str:
        ierr = getattr(exc, "ierr", None)
        typed = {k: v for k, v in user.items() if str(k).endswith("_type")}
        if ierr == 86 and typed:  # PETSC_ERR_UNKNOWN_TYPE
            listed = ", ".join(f"{k} = {v!r}" for k, v in typed.items())
            return f"PETSc rejected an unknown type among the options {listed} (error {ierr})"
        listed = ", ".join(f"{k} = {v!r}" for k, v in user.items()) or "(defaults only)"
        return f"PETSc rejected the options {listed} (error {ierr})"

    def _guarded(self, callback, *args):
        """Run a SNES callback; keep a Python exception so :meth:`solve` can re-raise it."""
        try:
            return callback(*args)
        except Exception as exc:  # re-raised by solve(); PETSc only sees an error code
            if self._callback_error is None:
                self._callback_error = exc
            raise

    # -- callbacks -------------------------------------------------------
    def _wrap_assembly(self, me) -> None:
        """Run the state hooks before DOLFINx assembles the residual and the tangent."""
        snes = self.snes
        b, (residual, _, residual_kw) = snes.getFunction()
        _, _, (jacobian, _, jacobian_kw) = snes.getJacobian()

        def hooked_residual(snes_, x, b_):
            me()._guarded(me()._set_state, x)
            residual(snes_, x, b_, **residual_kw)

        def hooked_jacobian(snes_, x, A, P):
            me()._guarded(me()._set_state, x)
            jacobian(snes_, x, A, P, **jacobian_kw)

        snes.setFunction(hooked_residual, b)
        snes.setJacobian(hooked_jacobian, self._nlp.A, self._nlp.P_mat)

    def _shifted(self, A: PETSc.Mat) -> PETSc.Mat:
        """The preconditioning matrix: a copy of the assembled tangent ``A`` plus the constant shift."""
        P = self._P
        A.copy(P, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        P.axpy(1.0, self._shift, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        return P

    def _pc_setup_seconds(self) -> float:
        return float(sum(event.getPerfInfo()["time"] for event in self._pc_setup))

    def refresh(self) -> None:
        """Run the state hooks at the current ``problem.u``."""
        for hook in self.state_hooks:
            hook()

    def _set_state(self, x: PETSc.Vec, hooks: bool = True) -> None:
        _ghost_update(x, PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD)
        fpetsc.assign(x, self.problem.u)
        if hooks:
            self.refresh()

    def _energies(self) -> tuple[float, float]:
        a = fem.assemble_scalar(self._energy_forms[0])
        b = fem.assemble_scalar(self._energy_forms[1])
        a, b = self.comm.allreduce(np.array([a, b], dtype=float), op=MPI.SUM)
        return float(a), float(b)

    def energy(self) -> float:
        """Total potential :math:`\\Pi` at the current displacement."""
        self.refresh()
        a, b = self._energies()
        return a - b

    def _objective(self, snes: PETSc.SNES, x: PETSc.Vec) -> float:
        self._set_state(x)
        internal, external = self._energies()
        value = internal - external
        scale = abs(internal) + abs(external)
        if x.handle == snes.getSolution().handle or self._ref is None:
            self._ref = (value, scale)
            self._full_step_change = None
            return value
        ref, ref_scale = self._ref
        X = snes.getSolution()
        R = snes.getFunction()[0]
        self._work.waxpy(-1.0, X, x)
        predicted = abs(R.dot(self._work))  # first-order energy change of the trial step
        if self._full_step_change is None:  # the line search tries the full step first
            self._full_step_change = predicted
        resolution = self.energy_roundoff_rtol * max(scale, ref_scale)
        if self._full_step_change <= resolution and (abs(value - ref) <= resolution or predicted <= resolution):
            # Near convergence the energy cannot resolve the Newton step: its
            # observed or its predicted change is at the level of the
            # cancellation noise in the assembled sum (the observed change
            # alone is not enough: noise of 1e-8 of the scale was measured in a
            # dynamic step whose predicted change was 1e-12). Judge it by the
            # residual norm instead; if that decreased, report the decrease the
            # linear model predicts, -R(X)·(x - X), so the step is accepted.
            # Only when the *full* step is below the resolution: a step the line
            # search has merely shortened far from the solution is judged by
            # the energy (accepting it by a residual dip made a hard step crawl
            # for 50 iterations instead of failing fast and being cut back).
            snes.computeFunction(x, self._residual_work)
            self._set_state(x)
            if self._residual_work.norm() < R.norm():
                self.roundoff_accepts += 1
                return ref - predicted
            return ref + predicted
        return value

    def roundoff_floor(self) -> float:
        """Round-off estimate :math:`\\varepsilon\\,\\|\\,|K|\\,(|x| + h)\\,\\|` of the residual norm.

        :math:`|K|` is the entrywise absolute value of the last assembled
        tangent (with the Dirichlet rows), :math:`|x|` of the current state:
        every term summed into a residual entry is bounded by the
        corresponding entry of :math:`|K||x|` for a linear response, and a
        state is only known to :math:`\\varepsilon|x|`. The residual is
        evaluated from :math:`F = I + \\nabla u`, though: its stress terms are
        of the size the identity part gives them (:math:`\\mu F` and
        :math:`\\mu F^{-T}` cancel at :math:`F \\approx I`), which in a cell of
        size :math:`h` is that of a displacement of a fraction of :math:`h`
        (:data:`REFERENCE_SCALE_FRACTION`). Without
        :math:`h` (in every displacement dof: :attr:`_reference_scale`) the
        estimate vanished with the load: a bend at load factor 1e-4 (CG +
        GAMG, P2, beam_h1) stagnated at ``|r| = 1.1e-9``, just above its
        tolerance, for 50 iterations while the estimate said 1e-13.
        """
        A = self.snes.getJacobian()[0]
        if self._abs_jacobian is None:
            self._abs_jacobian = A.duplicate(copy=True)
        else:
            A.copy(self._abs_jacobian, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        B = self._abs_jacobian
        ai, aj, av = B.getValuesCSR()
        B.setValuesCSR(ai, aj, np.abs(av))
        B.assemble()
        x = self._work
        self.snes.getSolution().copy(x)
        x.abs()
        x.axpy(1.0, self._reference_scale)
        y = self._residual_work
        B.mult(x, y)
        return float(np.finfo(float).eps * y.norm())

    def _floor_bound(self) -> float:
        r"""Cheap upper bound :math:`\varepsilon\|K\|_F(\|x\|_2 + \|h\|_2)` of :meth:`roundoff_floor` (no copy)."""
        A = self.snes.getJacobian()[0]
        size = self.snes.getSolution().norm() + self._reference_scale_norm
        return float(np.finfo(float).eps * A.norm(PETSc.NormType.FROBENIUS) * size)

    def _make_reference_scale(self) -> PETSc.Vec:
        """The vector :math:`h` of :meth:`roundoff_floor`: the largest cell size in each displacement dof."""
        mesh = self.problem.domain.mesh
        nodes = mesh.geometry.x[mesh.geometry.dofmap]  # (cells, nodes per cell, 3)
        diagonals = np.linalg.norm(nodes.max(axis=1) - nodes.min(axis=1), axis=1)  # bounding boxes of the cells
        h = self.comm.allreduce(float(np.max(diagonals, initial=0.0)), op=MPI.MAX)
        scale = self._nlp.x.duplicate()
        owned = scale.getLocalSize()
        values = np.zeros(owned)
        field_dofs = getattr(self.problem, "field_dofs", None)
        dofs = np.arange(owned) if field_dofs is None else field_dofs()["displacement"]
        values[dofs[dofs < owned]] = REFERENCE_SCALE_FRACTION * h
        scale.array[:] = values
        self._reference_scale_norm = float(scale.norm())
        return scale

    def _converged(self, snes: PETSc.SNES, it: int, norms) -> int:
        """SNES convergence test: PETSc's default criteria, then the round-off floor."""
        xnorm, snorm, fnorm = (float(v) for v in norms)
        rtol, atol, stol, _ = snes.getTolerances()
        R = PETSc.SNES.ConvergedReason
        if it == 0:
            self._ttol = max(atol, rtol * fnorm)
            self._fnorm0 = fnorm
            self._fnorms = [fnorm]
        if not np.isfinite(fnorm):
            return int(R.DIVERGED_FUNCTION_NANORINF)
        if fnorm < atol:
            return int(R.CONVERGED_FNORM_ABS)
        if it == 0:
            return int(R.ITERATING)
        if fnorm <= self._ttol:
            return int(R.CONVERGED_FNORM_RELATIVE)
        if snorm < stol * xnorm:
            return int(R.CONVERGED_SNORM_RELATIVE)
        divtol = snes.getDivergenceTolerance()
        if divtol > 0 and fnorm > divtol * self._fnorm0:
            return int(R.DIVERGED_DTOL)
        previous = self._fnorms[-1] if self._fnorms else np.inf
        self._fnorms.append(fnorm)
        if self.roundoff_factor > 0 and fnorm > 0.5 * previous and fnorm <= self.roundoff_factor * self._floor_bound():
            self._floor = self.roundoff_floor()
            if fnorm <= self.roundoff_factor * self._floor:
                self._roundoff_stop = True
                return CONVERGED_ROUNDOFF
        return int(R.ITERATING)

    def min_J(self) -> float:
        """Smallest :math:`J` over all quadrature points at the current state."""
        return self._min_J()

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
        # state admissible; the interior part of y is untouched. The exact filter
        # scales y to STEP_SAFETY times the largest step that keeps every cell
        # above volume_fraction of its volume; then (or instead) y is halved
        # until the full step keeps every quadrature point above min_jacobian.
        fpetsc.set_bc(y, self.problem.bcs, x0=x, alpha=-1.0)
        if self._step_filter is not None:
            self._filter_step(x, y)
        if self.min_jacobian is not None:
            self._bisect_step(x, y)
        self._set_state(x, hooks=False)

    def _filter_step(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """Scale ``y`` by the exact filter's step fraction (when it is below 1)."""
        self._set_state(x, hooks=False)
        if self._direction is None:
            self._direction = fem.Function(self.problem.u.function_space)
        p = self._direction
        owned = y.getLocalSize()
        p.x.array[:owned] = y.array_r
        p.x.scatter_forward()  # ghost values of the direction, for the owned cells that touch them
        # The trial state is x - alpha * y: the direction is -y.
        alpha = self._step_filter.max_step(self.problem.u.x.array, -p.x.array)
        if alpha < 1.0:
            y.scale(STEP_SAFETY * alpha)
            self.filtered_steps += 1
            self._min_step_fraction = min(self._min_step_fraction, STEP_SAFETY * alpha)

    def _bisect_step(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """Halve ``y`` until the full step keeps every quadrature point above ``min_jacobian``."""
        for _ in range(MAX_INVERSION_HALVINGS):
            self._work.waxpy(-1.0, y, x)
            self._set_state(self._work, hooks=False)
            if self.min_J() > self.min_jacobian:
                break
            y.scale(0.5)
            self.inversion_cutbacks += 1
        else:
            # Even a step 2^-40 as long inverts: the search direction is unusable. Tell SNES
            # (DIVERGED_FUNCTION_DOMAIN, a failed solve the stepper cuts back) and say why.
            self._inversion_giveup = True
            self.snes.setFunctionDomainError()

    # -- predictor -------------------------------------------------------
    def _boundary_moved(self) -> bool:
        u = self.problem.u
        moved = u.x.array.copy()
        for bc in self.problem.bcs:
            bc.set(moved)
        local = not np.array_equal(moved, u.x.array)
        return bool(self.comm.allreduce(local, op=MPI.LOR))

    def _lift_boundary_increment(self) -> bool:
        r"""Move the state by the tangent response to the boundary increment.

        Solves :math:`K(u_n)\,\delta u = 0` in the interior with
        :math:`\delta u = g_{n+1} - u_n` on the Dirichlet dofs (a lifted
        condition), using the solver's own assembly and linear solver, and
        applies the largest fraction :math:`2^{-k}` of it that keeps
        :math:`J > J_\min`. Returns whether a step was applied.
        """
        nlp = self._nlp
        bcs = self.problem.bcs
        x = self._work
        self.problem.u.x.petsc_vec.copy(x)
        # copy() moves the owned entries only; the lifting below reads x's ghosts too.
        _ghost_update(x, PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD)
        self.refresh()
        A = nlp.A
        A.zeroEntries()
        fpetsc.assemble_matrix(A, nlp.J, bcs=bcs)
        A.assemble()
        P = None if self._P is None else self._shifted(A)
        b = self._residual_work
        with b.localForm() as loc:
            loc.set(0.0)
        fpetsc.apply_lifting(b, [nlp.J], bcs=[bcs], x0=[x], alpha=1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fpetsc.set_bc(b, bcs, x0=x, alpha=1.0)
        du = x.duplicate()
        ksp = self.snes.getKSP()
        ksp.setOperators(A, A if P is None else P)
        ksp.solve(b, du)
        ok = ksp.getConvergedReason() > 0 and bool(np.isfinite(du.norm()))
        applied = False
        if ok:
            scale = 1.0
            for _ in range(8):
                self._set_state(x, hooks=False)
                self.problem.u.x.petsc_vec.axpy(scale, du)
                self.problem.u.x.scatter_forward()
                if self.min_jacobian is None or self.min_J() > self.min_jacobian:
                    applied = True
                    break
                scale *= 0.5
            if not applied:
                self._set_state(x, hooks=False)
        du.destroy()
        return applied

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
        self._norms = []
        self._ref = None
        self._floor = float("nan")
        self._roundoff_stop = False
        self._callback_error = None
        self._inversion_giveup = False
        self._min_step_fraction = 1.0
        cutbacks0, accepts0, filtered0 = self.inversion_cutbacks, self.roundoff_accepts, self.filtered_steps
        setup0 = self._pc_setup_seconds()
        snes = self.snes
        start = time.perf_counter()
        u = self.problem.u
        predicted = False
        if self.predictor and self._boundary_moved():
            predicted = self._lift_boundary_increment()
        # Start from a state that satisfies the Dirichlet conditions, so the
        # Newton direction has no boundary components and the energy line
        # search sees only admissible states.
        for bc in self.problem.bcs:
            bc.set(u.x.array)
        u.x.scatter_forward()
        reason = int(PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_DOMAIN)
        message = ""
        solved = self.min_jacobian is None or self.min_J() > self.min_jacobian
        if solved:
            try:
                self._nlp.solve()
                reason = int(snes.getConvergedReason())
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
        else:
            message = f"start state has J <= {self.min_jacobian:g}"
        u.x.scatter_forward()
        # A solve refused at its start ran no SNES: SNES still holds the previous solve's counts.
        iterations = int(snes.getIterationNumber()) if solved else 0
        ksp_reason = int(snes.getKSP().getConvergedReason()) if solved else 0
        if self._inversion_giveup and not message:
            message = f"every step along the Newton direction inverts elements (halved {MAX_INVERSION_HALVINGS} times)"
        elif reason == int(PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE) and not message:
            message = f"linear solve failed (KSP reason {ksp_reason})"
        if self._roundoff_stop and not self._warned_floor and self._ttol < self._floor:
            self._warned_floor = True  # once per solver
            if self.comm.rank == 0:
                warnings.warn(
                    f"NewtonSolver: residual tolerance {self._ttol:.3g} is below the round-off floor "
                    f"{self._floor:.3g} of this problem; stopped at |r| = {self._norms[-1]:.3g} "
                    "(converged at round-off)",
                    RoundoffWarning,
                    stacklevel=2,
                )
        if reason == int(PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_NANORINF) and iterations == 0:
            # NaN/inf at an admissible start (J > J_min checked above): bad input, not a hard step.
            raise ParameterError(self._nan_message())
        indicators: dict[str, float] = {}
        if reason > 0:
            indicators, why = self.problem.check_solution()
            if why:
                message = why
                reason = int(PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_DOMAIN)
        wall = time.perf_counter() - start
        minJ = self.min_J()
        record = SolveRecord(
            converged=reason > 0 and bool(np.isfinite(minJ)),
            reason=reason,
            reason_name=_reason_name(reason),
            iterations=iterations,
            linear_iterations=int(snes.getLinearSolveIterations()) if solved else 0,
            residual_norms=list(self._norms),
            wall_time=wall,
            min_J=minJ,
            roundoff_floor=self._floor,
            predictor=predicted,
            inversion_cutbacks=self.inversion_cutbacks - cutbacks0,
            filtered_steps=self.filtered_steps - filtered0,
            min_step_fraction=self._min_step_fraction,
            step_filter=self.step_filter,
            roundoff_accepts=self.roundoff_accepts - accepts0,
            indicators=indicators,
            message=message,
            ksp_reason=ksp_reason,
            linear_solver=self.linear_solver_name,
            pc_setup_time=float(self.comm.allreduce(self._pc_setup_seconds() - setup0, op=MPI.MAX)),
        )
        if raise_on_failure and not record.converged:
            detail = f": {message}" if message else ""
            raise ConvergenceError(
                f"Newton solve did not converge: {record.reason_name} after {record.iterations} iterations "
                f"(t = {self.problem.time:g}){detail}",
                self.problem.time,
            )
        return record

    def _nan_message(self) -> str:
        where = f"t = {self.problem.time:g}"
        names = self.problem.nonfinite_terms()
        if names:
            return f"NewtonSolver: residual is NaN/inf at the start of the solve ({where}); non-finite term(s): {', '.join(names)}"
        return (
            f"NewtonSolver: residual is NaN/inf at the start of the solve ({where}); a load, prescribed value "
            "or the material evaluates to NaN/inf"
        )
