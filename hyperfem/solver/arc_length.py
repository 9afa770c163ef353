r"""Arc-length continuation: follow an equilibrium path through limit points, with the load factor as an unknown.

A ramp of the load factor :math:`\lambda` (:func:`~hyperfem.solver.solve_quasistatic`)
stops at a limit point: past the maximum of the pressure of an inflated
balloon there is no equilibrium at a larger pressure. Continuation makes
:math:`\lambda` an unknown and adds one equation, the *arc-length constraint*
(Riks 1979; Crisfield 1981, the spherical form with a load scaling
:math:`\psi`):

.. math::
    R(u, \lambda) = 0, \qquad
    c(\Delta u, \Delta\lambda) = \Delta u\cdot\Delta u + \psi^2 s^2\,\Delta\lambda^2 - \Delta\ell^2 = 0,

with :math:`\Delta u, \Delta\lambda` the increments since the last converged
state, :math:`\Delta u\cdot\Delta u` over the displacement entries only (the
pressure and volume of the mixed problem do not enter),
:math:`s = \lVert \mathrm d u/\mathrm d\lambda\rVert` at the start of the run (so that
:math:`\psi` is dimensionless: :math:`\psi = 1` weighs load and displacement
alike at the start, :math:`\psi = 0` is Crisfield's cylindrical form).

**The load vector.** :math:`q = \partial R/\partial\lambda` at fixed :math:`u` is
the central difference of the assembled residual in the problem's time,
exact to round-off for loads linear in :math:`\lambda` (the usual ramp).
It is taken on the solver's own residual, so dead, follower and pressure
loads and prescribed displacements that move with :math:`\lambda` all enter:
on a Dirichlet row the residual is :math:`u_D - g(\lambda)`, so
:math:`q_D = -g'(\lambda)`, and the lifting of the interior rows carries
:math:`K_{fD}\,g'`; the solve :math:`K w = q` then gives the whole path
tangent :math:`\mathrm du/\mathrm d\lambda = -w`, boundary rows included.

**Predictor.** :math:`\Delta u = \Delta\lambda\,t` with :math:`t = -K^{-1}q` and
:math:`\Delta\lambda = \pm\Delta\ell/\sqrt{t\cdot t + \psi^2 s^2}`; the sign
continues the previous increment (the sign of
:math:`t\cdot\Delta u_\text{prev} + \psi^2 s^2\Delta\lambda_\text{prev}`), which
turns back at a limit point without a determinant.

**Corrector** (Crisfield): each iteration solves :math:`K a = R` and
:math:`K w = q` with one factorisation, so :math:`\delta u = -a - \delta\lambda\,w`,
and :math:`\delta\lambda` is the root of the quadratic
:math:`c(\Delta u + \delta u, \Delta\lambda + \delta\lambda) = 0` closest in
direction to the current increment (no real root: the point of the line
closest to the constraint). The bordered system is regular at a limit
point, where :math:`K` alone is singular.

**Merit function and line search.** On the constraint the solution is a
saddle point of :math:`\Pi(u) - \lambda W(u)` in :math:`(u, \lambda)`, not a
minimum, so the energy cannot judge a step (the energy line search of
:class:`~hyperfem.solver.NewtonSolver` is not used here). The merit is the
residual norm :math:`\lVert R_f\rVert` (:math:`f`: the rows without
Dirichlet conditions): whatever root the constraint picks, the step solves
:math:`K\delta u + q\,\delta\lambda = -R`, so it descends that norm; the
step is halved until the norm does not grow. The constraint holds at the
full step (the root of the quadratic) and is restored by the next
iteration after a shortened one. (A merit that adds :math:`|c|` refused
good steps: along the step :math:`c` is quadratic, zero at both ends.)
The solver's step filters come first, so no accepted iterate inverts an
element (the exact inversion-free filter, the :math:`J` check).

**Step control.** The steps are those of the one stepper
(:func:`~hyperfem.solver.stepping.run_steps` on an :class:`ArcLengthStage`):
its step lengths are arc lengths in load-factor units of the start
(:math:`\Delta\ell = h\sqrt{t\cdot t + \psi^2 s^2}` with :math:`t` the start
tangent), so ``increment`` is the first load increment; the arc length
doubles after an easy step (at most ``target_iterations`` corrector
iterations), is cut back after a failed attempt, within the bounds. A run
stops when the load factor passes ``end`` (or falls below ``min_load``),
when ``stop`` says so, or after ``max_steps`` steps.

**Limit and bifurcation points.** A limit point lies between two steps
whose load increments have opposite signs (its load factor is located by a
parabola through the three states around it, in arc length). With
``inertia``, every converged tangent is factorised once more as
:math:`LDL^T` (MUMPS) to count its negative pivots (Sylvester's law of
inertia: the negative eigenvalues; the symmetric part of a follower
tangent): a change without a turn of the load is a bifurcation point, and a
state with more negative pivots than the start is unstable under load
control (the descending branch of a pressure maximum is). A three-field
problem's pivots include its pressure block: the count at the start is the
reference.

**Branch switching** (``switch_branch``). At the first bifurcation found,
the step's arc length is bisected :data:`BISECTIONS` times on the pivot
count, which puts the state within :math:`2^{-5}` of the step past the
bifurcation point. The critical mode :math:`\varphi` there (inverse
iteration with the factorised tangent from a start without symmetry,
orthogonal to the tangent of the step's start: at the bisected state
:math:`K^{-1}q` is itself dominated by the nearly singular mode) is the
predictor of the next step, :math:`\Delta u = \Delta\ell\,\varphi`,
:math:`\Delta\lambda = 0`, sized by the geometry: its largest nodal
displacement is :data:`SWITCH_SIZE` of the body's size (the path's own
scale can be far too small: an axially loaded column shortens by 1e-3 of
its length at the Euler load). The arc length then regrows by
:data:`CAP_GROWTH` per step; until it has, a step whose amplitude along
:math:`\varphi` (from the bifurcation point) does not grow (the switching
step: is not half its predictor's) is refused and cut back, since near the
bifurcation point the sphere of a step also meets the old branch. On the
new branch the predictor is the secant (the last increment). Measured: a
perfect clamped-free column buckles and follows the elastica to a tip
deflection of 0.3 L within 1e-4 (``tests/test_arc_length.py``). Not yet
robust: the unstable antisymmetric branch of a shallow arch (rise 0.8,
``hyperfem.cases.instability``) is left correctly but the path reverses
along it after a few steps.

A turn of the path tangent without a change of the inertia is not taken for
a limit point (at a limit point an eigenvalue crosses zero): the direction
is kept.

**Contact** (external energies, :mod:`hyperfem.contact`) enters as in a
Newton solve: its gradient in the residual (so in the merit and the load
vector), its PSD Hessian in the tangent (a sphere's or cylinder's blocks
projected at every tangent here, ``project_tangents``), its collision-free step filter
(CCD) among the step filters, so no accepted iterate interpenetrates;
friction is lagged per accepted step. The obstacles must hold still: the
load factor goes up and down, and a moving obstacle would sweep into the
body along with it (a motion or rotation is refused in one line). Measured:
a block pushed onto a plane by a prescribed displacement of its top
(``tests/test_arc_length.py``) ends where the load-controlled ramp does (3e-16).
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import Any, cast

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem

from hyperfem.errors import ConvergenceError, ParameterError
from hyperfem.solver.filters import NoAdmissibleStep
from hyperfem.solver.inertia import negative_pivots
from hyperfem.solver.newton import NewtonSolver, SolveRecord
from hyperfem.solver.state import assign_state
from hyperfem.problem.protocol import SolidProblem
from hyperfem.solver.stepping import (
    QuasiStaticStage,
    StepPolicy,
    StepRecord,
    _displacement_dofs,
    _max_nodal_distance,
    _Snapshot,
    run_steps,
)
from hyperfem.validation import check_count, check_finite_scalar, check_finite_vector, check_positive

__all__ = ["ArcLength", "ArcLengthRecord", "ArcLengthStage", "continue_arc_length"]

_CONVERGED = int(PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS)
_DIVERGED_ITS = int(PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT)
_DIVERGED_LINEAR = int(PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE)
_DIVERGED_DOMAIN = int(PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_DOMAIN)
_DIVERGED_LS = int(PETSc.SNES.ConvergedReason.DIVERGED_LINE_SEARCH)
_DIVERGED_NAN = int(PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_NANORINF)
_REASONS = {
    _CONVERGED: "CONVERGED_FNORM_ABS",
    _DIVERGED_ITS: "DIVERGED_MAX_IT",
    _DIVERGED_LINEAR: "DIVERGED_LINEAR_SOLVE",
    _DIVERGED_DOMAIN: "DIVERGED_FUNCTION_DOMAIN",
    _DIVERGED_LS: "DIVERGED_LINE_SEARCH",
    _DIVERGED_NAN: "DIVERGED_FUNCTION_NANORINF",
}
MAX_HALVINGS = 6
"""Halvings of a corrector step whose merit grew before the attempt fails (and the arc length is cut back)."""
_HASH = ((12.9898, 78.233, 37.719, 0.1), (39.346, 11.135, 83.155, 0.7), (73.156, 52.235, 9.151, 1.3))
"""Frequencies and phases of the start vector of the inverse iteration (``_start_vector``)."""

SWITCH_SIZE = 2e-3
"""The largest nodal displacement of a branch-switching predictor along the critical mode, over the body's size
(the diagonal of its bounding box): a step measured by the geometry, not by the path so far (the shortening of an
axially loaded column per unit load is orders of magnitude below the lateral deflection of its buckled branch)."""
CAP_GROWTH = 1.6
"""Growth per step of the arc length after a branch switch (slow: the new branch leaves the old one at a point)."""
BISECTIONS = 5
"""Bisections of a step's arc length that locate a bifurcation point before switching branches."""


def _norm(v: PETSc.Vec) -> float:
    """The 2-norm of ``v`` (collective)."""
    return float(v.norm())  # type: ignore[arg-type]  # petsc4py stubs: the 2-norm is a float


# -- settings -----------------------------------------------------------------------------
@dataclass(frozen=True)
class ArcLength:
    r"""Settings of arc-length continuation (module docstring).

    Attributes:
        increment: First load-factor increment (sets the first arc length), > 0.
        min_increment: Smallest arc length, in load-factor units of the first
            step (default ``increment / 1024``); below it the run fails.
        max_increment: Largest arc length, likewise (default :data:`MAX_FACTOR` ``increment``; the
            load-factor unit of the start can be far below the arc a later branch needs: give more
            for the post-buckling path of a column).
        psi: Load scaling :math:`\psi \ge 0` (1: spherical, load and
            displacement weighed alike at the start; 0: cylindrical).
        end: Stop once the load factor passes it (``None``: no such stop).
        min_load: Stop once the load factor falls below it (``None``: no such stop).
        max_displacement: Stop once a node has moved farther than this
            (length units; ``None``: no such stop).
        probe_stop: Stop once the displacement component ``component`` at the
            reference point ``point`` reaches ``value`` (from either side of
            its start): ``(point, component, value)``, or ``None``. Evaluated by a
            :class:`~hyperfem.simulation.Simulation` (case files); with
            :func:`continue_arc_length` pass a ``stop`` callable instead.
        max_steps: Accepted steps before the run stops.
        max_attempts: Attempts (accepted and cut back) before the run fails.
        target_iterations: A step of at most this many corrector iterations is easy (the arc length doubles).
        max_iterations: Corrector iterations before an attempt fails.
        rtol: Convergence: :math:`\lVert R_f\rVert \le` ``rtol`` :math:`\lVert q_f\rVert + ` ``atol``
            (:math:`q_f`: the load vector at :math:`\lambda = 1` scale, the
            reference load of Riks' method).
        atol: Absolute residual tolerance.
        cutback: Factor in (0, 1) applied to the arc length of a failed attempt.
        inertia: Count the negative pivots of every converged tangent (an
            :math:`LDL^T` factorisation per step, MUMPS); ``None``: when the
            problem has at most ``INERTIA_LIMIT`` unknowns.
        direction: +1 or -1: the sign of the first load increment.
        switch_branch: At the first bifurcation point found (it needs the
            pivots, ``inertia``), leave the path along the critical mode
            (branch switching: a perfect column buckles instead of staying straight).
    """

    increment: float = 0.1
    min_increment: float | None = None
    max_increment: float | None = None
    psi: float = 1.0
    end: float | None = 1.0
    min_load: float | None = None
    max_displacement: float | None = None
    probe_stop: tuple[Sequence[float], int, float] | None = None
    max_steps: int = 200
    max_attempts: int = 2000
    target_iterations: int = 5
    max_iterations: int = 25
    rtol: float = 1e-9
    atol: float = 1e-12
    cutback: float = 0.5
    inertia: bool | None = None
    direction: int = 1
    switch_branch: bool = False

    def __post_init__(self) -> None:
        where = "ArcLength"
        check_positive("increment", self.increment, where)
        for name in ("min_increment", "max_increment", "end", "min_load"):
            if getattr(self, name) is not None:
                check_finite_scalar(getattr(self, name), where, name)
        if self.max_displacement is not None:
            check_positive("max_displacement", self.max_displacement, where)
        if self.probe_stop is not None:
            try:
                point, component, value = self.probe_stop
            except (TypeError, ValueError):
                raise ParameterError(
                    f"{where}: probe_stop must be (point, component, value), got {self.probe_stop!r}"
                ) from None
            check_finite_vector(point, where, "probe_stop point")
            if component not in (0, 1, 2) or isinstance(component, bool):
                raise ParameterError(f"{where}: probe_stop component must be 0, 1 or 2, got {component!r}")
            check_finite_scalar(value, where, "probe_stop value")
        if not self.min_step <= self.increment <= self.max_step or self.min_step <= 0:
            raise ParameterError(
                f"{where}: need 0 < min_increment <= increment <= max_increment, got "
                f"{self.min_step}, {self.increment}, {self.max_step}"
            )
        check_finite_scalar(self.psi, where, "psi")
        if self.psi < 0:
            raise ParameterError(f"{where}: psi must be >= 0, got {self.psi!r}")
        for name in ("max_steps", "max_attempts", "target_iterations", "max_iterations"):
            check_count(name, getattr(self, name), where)
        check_positive("rtol", self.rtol, where)
        check_finite_scalar(self.atol, where, "atol")
        if self.atol < 0:
            raise ParameterError(f"{where}: atol must be >= 0, got {self.atol!r}")
        if not (isinstance(self.cutback, (int, float)) and 0 < self.cutback < 1):
            raise ParameterError(f"{where}: cutback must lie in (0, 1), got {self.cutback!r}")
        if self.switch_branch and self.inertia is False:
            raise ParameterError(f"{where}: switch_branch needs the pivot count (inertia), got inertia=False")
        if self.direction not in (1, -1):
            raise ParameterError(f"{where}: direction must be +1 or -1, got {self.direction!r}")
        if self.end is not None and self.min_load is not None and not self.min_load < self.end:
            raise ParameterError(f"{where}: need min_load < end, got {self.min_load} and {self.end}")

    @property
    def min_step(self) -> float:
        """Effective ``min_increment``."""
        return self.min_increment if self.min_increment is not None else self.increment / 2**10

    @property
    def max_step(self) -> float:
        """Effective ``max_increment``."""
        return self.max_increment if self.max_increment is not None else MAX_FACTOR * self.increment

    def policy(self, start: float = 0.0) -> StepPolicy:
        """The policy of :func:`~hyperfem.solver.stepping.run_steps` for a continuation from the load factor ``start``.

        Its increments are arc lengths in load-factor units; after an easy
        step (at most ``target_iterations`` Newton iterations) the arc length
        doubles, after a failed attempt it is cut back; the run ends when the
        load factor passes ``end`` (never, without one).
        """
        end = self.end if self.end is not None else self.direction * BIG
        if (end - start) * self.direction <= 0:
            raise ParameterError(
                f"ArcLength: end = {end:g} does not lie in the direction {self.direction:+d} from the start {start:g}"
            )
        return StepPolicy(
            end=end,
            increment=self.increment,
            min_increment=self.min_step,
            max_increment=self.max_step,
            cutback=self.cutback,
            growth=2.0,
            grow_after=1,
            easy_iterations=self.target_iterations,
            landing="clip",
            reject_inversion=False,  # the step filters refuse inverting iterates
            max_steps=self.max_attempts,
        )


LANDING_STRETCH = 4.0
"""The landing step on ``end`` may take at most this many times the arc length of its load increment at the start
(its arc is the gap over the current slope dλ/ds)."""

MAX_FACTOR = 4.0
"""The default largest arc length, in first increments (at 16 the doubling arcs overshot: the sphere's path
jumped to a negative pressure; a post-buckling path needs more, given by the user)."""

INERTIA_LIMIT = 200_000
"""Unknowns up to which ``ArcLength(inertia=None)`` counts negative pivots (one extra factorisation per step)."""


# -- records ------------------------------------------------------------------------------
@dataclass
class ArcLengthRecord(StepRecord):
    """An accepted continuation step (``time`` is the load factor reached, ``dt`` its increment).

    Attributes:
        arc_length: The arc length :math:`\\Delta\\ell` of the step.
        negative_pivots: Negative pivots of the converged tangent (``-1``: not counted).
        stable: Whether the state has no more negative pivots than the start
            (``None``: not counted).
        limit_point: A limit point lies between the previous step and this one
            (the load increment changed sign).
        limit_load: The located load factor of that limit point (``nan`` if none).
        bifurcation: The count of negative pivots changed without a turn of the load.
    """

    arc_length: float = 0.0
    negative_pivots: int = -1
    stable: bool | None = None
    limit_point: bool = False
    limit_load: float = float("nan")
    bifurcation: bool = False
    switched: bool = False

    def as_dict(self) -> dict:
        """JSON-serialisable summary (without the solve records)."""
        out = super().as_dict()
        out.update(
            arc_length=self.arc_length,
            negative_pivots=self.negative_pivots,
            stable=self.stable,
            limit_point=self.limit_point,
            limit_load=self.limit_load,
            bifurcation=self.bifurcation,
            switched=self.switched,
        )
        return out


# -- the continuation ---------------------------------------------------------------------
@dataclass
class _Path:
    """What the continuation carries from step to step."""

    arc: float
    scale2: float  # psi^2 s^2
    tangent: PETSc.Vec  # w = K^-1 q at the accepted state (the path tangent is -w)
    sign: float  # the sign of the load increment of the next predictor (the direction of travel)
    slope: float  # dλ/ds at the accepted state, in the direction of travel
    negative0: int = -1
    negative_prev: int = -1
    mode: PETSc.Vec | None = None  # the critical mode the next step follows (branch switching)
    secant: tuple[PETSc.Vec, float] | None = None  # the last increment, the predictor just after a switch
    switched: bool = False


def _check_static_obstacles(solver: NewtonSolver) -> None:
    """Contact must not move with the load factor: an obstacle or tool with a motion or a rotation is refused."""
    for energy in getattr(solver.external, "energies", ()):
        placement = getattr(energy, "obstacle", None) or getattr(energy, "tool", None)
        if placement is not None and (placement.motion is not None or placement.rotation is not None):
            where = getattr(energy, "where", type(energy).__name__)
            raise ParameterError(
                f"continue_arc_length: {where} moves (motion or rotation), which the continuation cannot follow "
                "(its load factor goes up and down); hold the obstacle still and load the body instead"
            )


class _Continuation:
    """The bordered Newton iteration on a :class:`~hyperfem.solver.NewtonSolver`'s assembly and linear solver."""

    def __init__(self, solver: NewtonSolver, settings: ArcLength) -> None:
        _check_static_obstacles(solver)
        self.solver = solver
        self.settings = settings
        self.problem = solver.problem
        self.comm = self.problem.domain.comm
        nlp = solver.nonlinear_problem
        self.snes = solver.snes
        self.ksp = self.snes.getKSP()
        A, P, _ = cast(tuple[PETSc.Mat, PETSc.Mat, Any], self.snes.getJacobian())
        self.A, self.P = A, P
        self.x = nlp.x
        self.r = nlp.b.duplicate()
        self.q = nlp.b.duplicate()
        self.work = nlp.b.duplicate()
        self.a = nlp.b.duplicate()
        self.w = nlp.b.duplicate()
        self.y = nlp.b.duplicate()
        n = self.x.getSize()
        self.inertia = settings.inertia if settings.inertia is not None else n <= INERTIA_LIMIT
        self._disp = _displacement_dofs(self.problem)
        self.q_norm = 0.0

    def close(self) -> None:
        for v in (self.r, self.q, self.work, self.a, self.w, self.y):
            v.destroy()

    # -- vectors ---------------------------------------------------------------------------
    def disp(self, v: PETSc.Vec) -> np.ndarray:
        """This rank's owned displacement entries of ``v`` (a copy)."""
        a = v.getArray(readonly=True)
        return np.array(a if self._disp is None else a[self._disp])

    def dot(self, a: np.ndarray, b: np.ndarray) -> float:
        return float(self.comm.allreduce(float(a @ b), op=MPI.SUM))

    def free_norm(self, v: PETSc.Vec) -> float:
        """Norm of ``v`` without its Dirichlet rows."""
        v.copy(self.work)
        fpetsc.set_bc(self.work, self.problem.bcs, alpha=0.0)
        return _norm(self.work)

    def load_state(self, lam: float) -> None:
        """``x`` from ``problem.u``; loads at ``lam``."""
        self.problem.u.x.petsc_vec.copy(self.x)
        self.problem.set_time(lam)

    # -- assembly --------------------------------------------------------------------------
    def residual(self, lam: float, out: PETSc.Vec) -> None:
        self.problem.set_time(lam)
        self.snes.computeFunction(self.x, out)

    def load_vector(self, lam: float) -> None:
        """``q`` = dR/dλ at ``x`` by a central difference in the load factor (exact for linear ramps)."""
        h = 1e-6 * max(1.0, abs(lam))
        self.residual(lam + h, self.q)
        self.residual(lam - h, self.work)
        self.q.axpy(-1.0, self.work)
        self.q.scale(1.0 / (2 * h))
        self.problem.set_time(lam)

    def tangent(self, lam: float) -> None:
        self.problem.set_time(lam)
        if self.solver.external:  # PSD contact blocks: the bordered solve has no descent fallback, the inertia is
            self.solver.external.project_tangents()  # counted on these tangents (hyperfem.contact.nodal)
        self.snes.computeJacobian(self.x, self.A, self.P)
        # SNES decided the KSP's reuse flag from its lag and its last solve's iteration count: a lagged
        # preconditioner would stay built on a tangent of the last Newton solve. Built on this one instead.
        self.ksp.getPC().setReusePreconditioner(False)
        self.solver._lag.rebuilt()
        self.ksp.setOperators(self.A, self.P)

    def solve(self, rhs: PETSc.Vec, out: PETSc.Vec) -> bool:
        self.ksp.solve(rhs, out)
        return int(self.ksp.getConvergedReason()) > 0 and math.isfinite(_norm(out))  # type: ignore[call-overload]

    def set_x(self, x0: np.ndarray, du: PETSc.Vec, scale: float) -> None:
        """``x = x0 + scale du`` (owned entries; ghosts updated by the next assembly)."""
        arr = self.x.getArray()
        arr[:] = x0 + scale * du.getArray(readonly=True)
        self.x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)  # type: ignore[arg-type]

    # -- one step --------------------------------------------------------------------------
    def tangent_direction(self, lam: float) -> bool:
        """``w`` = K⁻¹q at ``x`` (the path tangent is ``-w``); the tangent assembled and factorised."""
        self.load_vector(lam)
        self.tangent(lam)
        return self.solve(self.q, self.w)

    def merit(self, lam: float) -> float:
        r""":math:`\lVert R_f\rVert` at ``x`` and ``lam`` (the residual left in ``r``)."""
        self.residual(lam, self.r)
        return self.free_norm(self.r)

    def attempt(self, lam0: float, path: _Path) -> tuple[SolveRecord, float, np.ndarray]:
        """One attempt of a step of arc length ``path.arc`` from the state in ``x`` at ``lam0``.

        Returns:
            The record, the load increment and the displacement increment (owned entries).
        """
        s = self.settings
        start = _time.perf_counter()
        x0 = self.x.getArray(readonly=True).copy()
        d0 = self.disp(self.x)
        norms: list[float] = []

        def record(reason: int, iterations: int, message: str = "") -> SolveRecord:
            assign_state(self.x, self.problem.u)
            self.problem.u.x.scatter_forward()
            minJ = self.solver.min_J()
            return SolveRecord(
                converged=reason > 0 and bool(np.isfinite(minJ)),
                reason=reason,
                reason_name=_REASONS.get(reason, str(reason)),
                iterations=iterations,
                linear_iterations=0,
                residual_norms=norms,
                wall_time=_time.perf_counter() - start,
                min_J=minJ,
                message=message,
                linear_solver=self.solver.linear_solver_name,
            )

        if path.mode is not None:
            # Branch switching: along the critical mode (unit displacement norm), the load held.
            dlam = 0.0
            path.mode.copy(self.y)
            self.y.scale(-path.arc)
        elif path.secant is not None:
            # Just after a switch: along the last increment (the tangent there is dominated by the nearly
            # singular mode, and its sign can turn the path back along the new branch).
            vec, last = path.secant
            d = self.disp(vec)
            scale = path.arc / math.sqrt(self.dot(d, d) + path.scale2 * last**2)
            dlam = scale * last
            vec.copy(self.y)
            self.y.scale(-scale)
        else:
            t = self.disp(path.tangent)
            dlam = path.sign * path.arc / math.sqrt(self.dot(t, t) + path.scale2)
            # Predictor x0 - dlam w (shortened by the step filters: y = dlam w is the step x - y).
            path.tangent.copy(self.y)
            self.y.scale(dlam)
        fraction, message = self.filter(self.y)
        if message:
            return record(_DIVERGED_DOMAIN, 0, f"predictor: {message}"), 0.0, d0 * 0
        dlam *= fraction
        self.set_x(x0, self.y, -1.0)
        lam = lam0 + dlam
        for it in range(s.max_iterations + 1):
            self.residual(lam, self.r)
            norm = self.free_norm(self.r)
            norms.append(norm)
            if not math.isfinite(norm):
                return record(_DIVERGED_NAN, it, "residual NaN/inf"), 0.0, d0 * 0
            du = self.disp(self.x) - d0
            if norm <= s.rtol * self.q_norm + s.atol and it > 0:
                out = record(_CONVERGED, it)
                if out.converged:
                    out.indicators, why = self.problem.check_solution()
                    if why:
                        out.converged, out.reason, out.reason_name, out.message = (
                            False, _DIVERGED_DOMAIN, _REASONS[_DIVERGED_DOMAIN], why,
                        )
                return out, lam - lam0, du
            if it == s.max_iterations:
                break
            # Newton: K a = R, K w = q; δu = -a - δλ w; δλ from the constraint.
            if not self.tangent_direction(lam) or not self.solve(self.r, self.a):
                return record(_DIVERGED_LINEAR, it, "corrector: the tangent solve failed"), 0.0, du
            da, dw = self.disp(self.a), self.disp(self.w)
            dlam_step = self.root(du - da, -dw, lam - lam0, path)
            # y = a + δλ w, the step x - y
            self.a.copy(self.y)
            self.y.axpy(dlam_step, self.w)
            fraction, message = self.filter(self.y)
            if message:
                return record(_DIVERGED_DOMAIN, it, message), 0.0, du
            dlam_step *= fraction
            accepted, lam = self.line_search(lam, dlam_step)
            if not accepted:
                return record(_DIVERGED_LS, it + 1, "corrector: the merit did not decrease"), 0.0, du
        return record(_DIVERGED_ITS, s.max_iterations), 0.0, self.disp(self.x) - d0

    def root(self, base: np.ndarray, dirn: np.ndarray, dlam: float, path: _Path) -> float:
        """δλ with c(base + δλ dirn, dlam + δλ) = 0, the root closest in direction to (base, dlam)."""
        a1 = self.dot(dirn, dirn) + path.scale2
        a2 = 2 * (self.dot(dirn, base) + path.scale2 * dlam)
        a3 = self.dot(base, base) + path.scale2 * dlam**2 - path.arc**2
        disc = a2 * a2 - 4 * a1 * a3
        if disc < 0:
            return -a2 / (2 * a1)  # no real root: the point of the line closest to the constraint
        sq = math.sqrt(disc)
        roots = ((-a2 + sq) / (2 * a1), (-a2 - sq) / (2 * a1))
        # The new increment closest in direction to the current one (Crisfield's angle criterion).
        bb = self.dot(base, base) + path.scale2 * dlam**2
        bd = self.dot(base, dirn) + path.scale2 * dlam
        return max(roots, key=lambda r: bb + r * bd)

    def filter(self, y: PETSc.Vec) -> tuple[float, str]:
        """The solver's step filters on the step ``x - y`` (inversion, ...): the fraction kept, or why none is."""
        try:
            return self.solver.step_filters.apply(self.x, y), ""
        except NoAdmissibleStep as refusal:
            return 0.0, str(refusal)

    def line_search(self, lam: float, dlam: float) -> tuple[bool, float]:
        """Backtrack ``x - α y``, ``λ + α δλ`` until the merit does not grow; whether a step was taken."""
        xk = self.x.getArray(readonly=True).copy()
        m0 = self.free_norm(self.r)
        alpha = 1.0
        for _ in range(MAX_HALVINGS + 1):
            self.set_x(xk, self.y, -alpha)
            trial = lam + alpha * dlam
            if self.merit(trial) <= m0 * (1 + 1e-10):
                return True, trial
            alpha *= 0.5
        self.set_x(xk, self.y, 0.0)
        return False, lam

    # -- at an accepted state --------------------------------------------------------------
    def settle(self, lam: float, du: np.ndarray, dlam: float, path: _Path, trust: bool = False) -> tuple[bool, int]:
        """At a converged state: the tangent for the next predictor, the direction of travel, the pivots.

        Args:
            lam: The load factor of the state.
            du: The step's displacement increment (owned displacement entries).
            dlam: The step's load increment.
            path: The path (its tangent, direction and slope are updated).
            trust: Take the tangent's direction even where the inertia did not change
                (after a branch switch, the direction of the new branch).

        Returns:
            Whether the load turned within the step (a limit point), and the
            negative pivots of the tangent (``-1``: not counted).

        Raises:
            ConvergenceError: The tangent solve failed.
        """
        if not self.tangent_direction(lam):
            raise ConvergenceError(f"arc-length continuation: the tangent solve failed at λ = {lam:g}", lam)
        self.w.copy(path.tangent)
        t = self.disp(path.tangent)
        # The next predictor continues this step's increment: the sign of (-t, 1)·(Δu, ψ²s²Δλ).
        sign = -1.0 if -self.dot(t, du) + path.scale2 * dlam < 0 else 1.0
        negative = negative_pivots(self.A) if self.inertia else -1
        turned = sign != path.sign
        if turned and negative >= 0 and negative == path.negative_prev and path.mode is None and not trust:
            # At a limit point an eigenvalue of the tangent crosses zero; a turn of the tangent without a change
            # of the inertia is not one: near a bifurcation point K^-1 q is dominated by the nearly singular
            # mode and its sign is noise (it sent the arch back along its new branch). Keep the direction.
            sign, turned = path.sign, False
        path.sign = sign
        path.slope = sign / math.sqrt(self.dot(t, t) + path.scale2)
        return turned, negative

    def _start_vector(self, v: PETSc.Vec) -> None:
        """A start for the inverse iteration with no symmetry: a hash of the reference coordinates.

        A uniform start is symmetric, so on a symmetric body it holds almost
        nothing of an antisymmetric mode; this one depends on the position
        only, so it is the same on any number of ranks.
        """
        work = fem.Function(self.problem.u.function_space)

        def noise(x: np.ndarray) -> np.ndarray:
            rows = [np.sin(a * x[0] + b * x[1] + c * x[2] + d) * 43758.5453 for a, b, c, d in _HASH]
            return np.array([r - np.floor(r) - 0.5 for r in rows[: self.problem.domain.gdim]])

        target = work if self._disp is None else work.sub(0)
        target.interpolate(noise)
        work.x.scatter_forward()
        work.x.petsc_vec.copy(v)

    def critical_mode(self, primary: PETSc.Vec, iterations: int = 20) -> PETSc.Vec:
        r"""The eigenvector of the tangent's eigenvalue nearest zero, by inverse iteration with its factorisation.

        Called right after :meth:`settle` (the tangent at the state just past
        the bifurcation is factorised): from a start without symmetry
        (:meth:`_start_vector`) with zero Dirichlet rows, ``iterations`` solves; the component along the path
        tangent is removed, the displacement norm made 1, and the sign fixed
        so that the largest displacement entry is positive (the same on any
        number of ranks).
        """
        v = self.w.duplicate()
        self._start_vector(v)
        fpetsc.set_bc(v, self.problem.bcs, alpha=0.0)
        for _ in range(iterations):
            if not self.solve(v, self.work):
                raise ConvergenceError("arc-length continuation: the inverse iteration for the critical mode failed")
            self.work.copy(v)
            v.scale(1.0 / _norm(v))
        t, phi = self.disp(primary), self.disp(v)
        v.axpy(-self.dot(phi, t) / self.dot(t, t), primary)
        phi = self.disp(v)
        v.scale(1.0 / math.sqrt(self.dot(phi, phi)))
        local = phi[np.argmax(np.abs(phi))] if phi.size else 0.0
        biggest = self.comm.allreduce((abs(float(local)), float(local)), op=MPI.MAX)
        if biggest[1] < 0:
            v.scale(-1.0)
        return v


def _hermite_extremum(lam0: float, lam1: float, slope0: float, slope1: float) -> float:
    r"""The extremum of the cubic Hermite interpolant of :math:`\lambda` over a step.

    ``slope0``/``slope1`` are :math:`\mathrm d\lambda/\mathrm d\tau` at the ends of
    :math:`\tau \in [0, 1]` (of opposite signs at a limit point).
    """
    # λ(τ) = a τ³ + b τ² + c τ + d
    d, c = lam0, slope0
    a = 2 * (lam0 - lam1) + slope0 + slope1
    b = 3 * (lam1 - lam0) - 2 * slope0 - slope1
    roots = [r.real for r in np.roots([3 * a, 2 * b, c]) if abs(r.imag) < 1e-12 and -1e-9 <= r.real <= 1 + 1e-9]
    if not roots:
        return max(lam0, lam1, key=abs)
    values = [((a * r + b) * r + c) * r + d for r in roots]
    return float(max(values) if slope0 > 0 else min(values))


class ArcLengthStage(QuasiStaticStage):
    """Arc-length continuation as a stage of the one stepper (:func:`~hyperfem.solver.stepping.run_steps`).

    The step length the stepper asks for is the arc length in load-factor
    units of the start (:math:`\\Delta\\ell` over :math:`\\sqrt{t\\cdot t + \\psi^2 s^2}`
    at the start), so the policy's increment bounds, cut-back and growth act
    on it as on a load increment; the time reached is the load factor, which
    may go down (:attr:`last_increment` is the step's load increment). After
    each accepted step :attr:`events` holds what was found in it.

    Args:
        problem: The problem (a :class:`~hyperfem.problem.protocol.SolidProblem`); its time is the start.
        solver: The Newton solver built on it (assembly, linear solver, step filters).
        settings: The continuation settings.

    Raises:
        ParameterError: A solver with contact, or nothing that moves with the load factor.
        ConvergenceError: The tangent solve at the start failed.
    """

    kind = "arc-length"

    def __init__(self, problem: SolidProblem, solver: NewtonSolver, settings: ArcLength | None = None) -> None:
        super().__init__(problem, solver)
        self.settings = ArcLength() if settings is None else settings
        self._run = _Continuation(solver, self.settings)
        self._tangent = self._run.w.duplicate()
        self._tangent_before = self._run.w.duplicate()
        self._secant = self._run.w.duplicate()
        self._before: tuple[np.ndarray, float, float] | None = None
        self._cap: float | None = None
        self._branch: tuple[np.ndarray, np.ndarray, float] | None = None  # mode, origin, amplitude after a switch
        try:
            self._path = _start(self._run, self._time, self._tangent)
        except Exception:
            self.close()
            raise
        t = self._run.disp(self._tangent)
        self.factor = math.sqrt(self._run.dot(t, t) + self._path.scale2)
        """Arc length per unit load increment at the start (the unit of the step lengths)."""
        self._pending: tuple[float, np.ndarray, float] | None = None
        self.last_increment = 0.0
        """The load increment of the last committed step."""
        self.steps = 0
        """Steps committed (those before a restart included)."""
        self.events: dict[str, Any] = {
            "arc_length": 0.0,
            "negative_pivots": self._path.negative0,
            "stable": None if self._path.negative0 < 0 else True,
            "limit_point": False,
            "limit_load": float("nan"),
            "bifurcation": False,
            "switched": False,
        }
        """What the last committed step found (at the start: the start's pivots): ``arc_length``,
        ``negative_pivots``, ``stable``, ``limit_point``, ``limit_load``, ``bifurcation``, ``switched``."""

    def restore(self, state: _Snapshot) -> None:
        """Back to ``state`` (the unknown and the load factor)."""
        super().restore(state)
        self._pending = None

    def advance(self, t: float, dt: float) -> SolveRecord:
        """One attempt of arc length ``|dt|`` (load-factor units) from the accepted state at ``t``."""
        path = self._path
        # After a branch switch the arc length starts from the switching step's (SWITCH_SIZE) and regrows by
        # CAP_GROWTH per step (a long step from near the bifurcation point may fall back onto the old branch).
        length = abs(dt) if self._cap is None else min(abs(dt), self._cap)
        path.arc = length * self.factor
        end = self.settings.end
        if end is not None and self._cap is None and abs(self._time + dt - end) <= 1e-12 * max(1.0, abs(end)):
            # The step the policy clipped to land on `end`: its arc from the current slope dλ/ds, not the start's
            # (a path that stiffened, such as a body pressed on an obstacle, would otherwise creep toward `end`
            # by a few per cent of the gap a step); at most LANDING_STRETCH times the usual arc.
            if path.slope * dt > 0:
                path.arc = min(abs(dt) / abs(path.slope), LANDING_STRETCH * path.arc)
        self._before = (self.problem.u.x.array.copy(), path.sign, path.slope)
        path.tangent.copy(self._tangent_before)
        self._run.load_state(self._time)
        record, dlam, du = self._run.attempt(self._time, path)
        if record.converged and self._branch is not None:
            # While the arc length regrows after a switch, a step must go on along the new branch: its
            # amplitude along the critical mode (from the bifurcation point) grows, or it fell back onto the old.
            mode, origin, amplitude = self._branch
            now = abs(self._run.dot(mode, self._run.disp(self._run.x) - origin))
            if path.mode is not None:  # the switching step: half its predictor's amplitude at least
                amplitude = 0.5 * path.arc
            if not now > amplitude:
                record.converged, record.reason_name = False, "DIVERGED_FUNCTION_DOMAIN"
                record.reason = _DIVERGED_DOMAIN
                record.message = "the step fell back toward the branch it left"
            else:
                self._branch = (mode, origin, now)
        self.problem.set_time(self._time + dlam if record.converged else self._time)
        self._pending = (dlam, du, path.arc)
        return record

    def commit(self) -> None:
        """Accept the last attempt: the tangent and the direction for the next step, the pivots, the events."""
        assert self._pending is not None  # commit follows advance
        dlam, du, arc = self._pending
        path, lam0 = self._path, self._time
        lam = lam0 + dlam
        slope0 = path.slope
        turned, negative = self._run.settle(lam, du, dlam, path, trust=self._branch is not None)
        switched = path.mode is not None
        if path.mode is not None:
            path.mode.destroy()
            path.mode = None
            turned = False  # leaving the primary path is not a turn of the load
        # (the switching step leaves an unstable path: its change of the count is not a new bifurcation)
        changed = negative >= 0 and path.negative_prev >= 0 and negative != path.negative_prev
        bifurcation = changed and not turned and not switched
        self.events = {
            "arc_length": arc / self.factor,
            "negative_pivots": negative,
            "stable": None if negative < 0 else negative <= path.negative0,
            "limit_point": turned,
            "limit_load": _hermite_extremum(lam0, lam, slope0 * arc, path.slope * arc) if turned else float("nan"),
            "bifurcation": bifurcation,
            "switched": switched,
        }
        if bifurcation and self.settings.switch_branch and not path.switched:
            # Switch from a state within 2^-BISECTIONS of the step of the bifurcation point (the sphere of the
            # switching step must reach the new branch, and not much farther).
            lam, dlam, negative = self._bisect(lam0, arc, path.negative_prev, (lam, dlam, du, negative))
            self.events.update(arc_length=self.events["arc_length"], negative_pivots=negative)
            # Orthogonal to the tangent of the step's start: at the bisected state K^-1 q is polluted by the
            # nearly singular mode itself (removing it there left the arch a symmetric "mode").
            path.mode, path.switched = self._run.critical_mode(self._tangent_before), True
            amplitude = SWITCH_SIZE * self._body_size() / self._largest_nodal(path.mode)
            self._cap = amplitude / self.factor / CAP_GROWTH  # grown below: the switching step's arc is `amplitude`
            self._branch = (self._run.disp(path.mode), self._run.disp(self._run.x), 0.0)
        if self._cap is not None:
            self._cap = CAP_GROWTH * self._cap if self._cap < self.settings.max_step else None
            if self._cap is None:
                self._branch = None
        if path.switched and path.mode is None:
            # On a branch found by switching, the secant predictor (the last increment): there the tangent
            # K^-1 q can be dominated by a nearly singular mode whose sign is noise (the arch went back and forth).
            assert self._before is not None  # set by advance
            increment = self._secant.getArray()
            n = increment.size
            increment[:] = self.problem.u.x.array[:n] - self._before[0][:n]
            path.secant = (self._secant, dlam)
        path.negative_prev = negative
        self._time, self.last_increment, self._pending = lam, dlam, None
        self.steps += 1
        if self.solver.external:  # contact: the accepted state anchors the next step's pull-back and friction lag
            self.solver.external.remember()

    def _body_size(self) -> float:
        """The diagonal of the body's bounding box (reference configuration; collective)."""
        x = self.problem.domain.mesh.geometry.x
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        self.problem.domain.comm.Allreduce(x.min(axis=0, initial=np.inf), lo, op=MPI.MIN)
        self.problem.domain.comm.Allreduce(x.max(axis=0, initial=-np.inf), hi, op=MPI.MAX)
        return float(np.linalg.norm(hi - lo))

    def _largest_nodal(self, v: PETSc.Vec) -> float:
        """The largest nodal displacement of ``v`` (a vector of the unknown's layout; collective)."""
        a = v.getArray(readonly=True)
        full = np.zeros_like(self.problem.u.x.array)
        full[: a.size] = a
        return _max_nodal_distance(self.problem, self._dofs, full, np.zeros_like(full))

    def _bisect(
        self, lam0: float, arc: float, before: int, found: tuple[float, float, np.ndarray, int]
    ) -> tuple[float, float, int]:
        """The state past a bifurcation nearest the step's start, by bisecting the arc length on the pivot count.

        From the step's start (``lam0``, arc length ``arc``, ``before`` negative
        pivots) to the state ``found`` (load factor, increment, displacement
        increment, pivots) past the bifurcation: :data:`BISECTIONS` attempts.
        Leaves the nearest such state (its tangent factorised) in the problem;
        returns its load factor, increment and pivots.
        """
        assert self._before is not None  # set by advance
        u_start, sign, slope = self._before
        path, run = self._path, self._run
        best = (self.problem.u.x.array.copy(), *found)
        lo, hi = 0.0, arc
        for _ in range(BISECTIONS):
            mid = 0.5 * (lo + hi)
            self.problem.u.x.array[:] = u_start
            self._tangent_before.copy(path.tangent)
            path.sign, path.slope, path.arc = sign, slope, mid
            run.load_state(lam0)
            record, dlam, du = run.attempt(lam0, path)
            if not record.converged:
                break
            _, negative = run.settle(lam0 + dlam, du, dlam, path)
            if negative != before:
                hi, best = mid, (self.problem.u.x.array.copy(), lam0 + dlam, dlam, du, negative)
            else:
                lo = mid
        u, lam, dlam, du, negative = best
        self.problem.u.x.array[:] = u
        self._tangent_before.copy(path.tangent)
        path.sign, path.slope = sign, slope
        self.problem.set_time(lam)
        run.load_state(lam)
        run.settle(lam, du, dlam, path)  # the tangent of this state, factorised, for the critical mode
        return lam, dlam, negative

    def measure(self) -> dict[str, Any]:
        """Row entries of the last committed step (a :class:`~hyperfem.simulation.Simulation` row)."""
        return dict(self.events)

    def finished(self, record: StepRecord) -> bool:
        """Whether the run ends after ``record``: ``max_steps``, ``min_load`` or ``max_displacement`` reached.

        (``probe_stop`` is evaluated by the :class:`~hyperfem.simulation.Simulation` that runs the stage:
        point evaluation belongs to the output layer.)
        """
        s = self.settings
        if self.steps >= s.max_steps or (s.min_load is not None and self._time < s.min_load):
            return True
        if s.max_displacement is None:
            return False
        zero = np.zeros_like(self.problem.u.x.array)
        return _max_nodal_distance(self.problem, self._dofs, self.problem.u.x.array, zero) > s.max_displacement

    def checkpoint_state(self) -> dict[str, Any]:
        """What a restart needs besides the state (plain data): the arc-length unit, the direction, the pivots."""
        path = self._path
        return {
            "factor": self.factor,
            "scale2": path.scale2,
            "sign": path.sign,
            "negative0": path.negative0,
            "negative_prev": path.negative_prev,
            "switched": path.switched,
            "steps": self.steps,
        }

    def resume(self, state: dict[str, Any]) -> None:
        """Continue from a checkpoint's :meth:`checkpoint_state` (the tangent was taken at the restored state).

        A restart in the middle of the regrowth after a branch switch drops its guard.
        """
        path = self._path
        self.factor = float(state["factor"])
        path.scale2, path.sign = float(state["scale2"]), float(state["sign"])
        path.negative0, path.negative_prev = int(state["negative0"]), int(state["negative_prev"])
        path.switched, self.steps = bool(state["switched"]), int(state["steps"])
        t = self._run.disp(path.tangent)
        path.slope = path.sign / math.sqrt(self._run.dot(t, t) + path.scale2)

    def close(self) -> None:
        """Free the work vectors."""
        self._run.close()
        self._tangent.destroy()
        self._tangent_before.destroy()
        self._secant.destroy()
        if getattr(self, "_path", None) is not None and self._path.mode is not None:
            self._path.mode.destroy()
            self._path.mode = None


BIG = 1e300
"""The end of a policy whose run stops by other criteria (``ArcLength(end=None)``)."""


def continue_arc_length(
    solver: NewtonSolver,
    settings: ArcLength | None = None,
    on_step: Callable[[ArcLengthRecord], None] | None = None,
    stop: Callable[[ArcLengthRecord], bool] | None = None,
) -> list[ArcLengthRecord]:
    r"""Follow the equilibrium path of ``solver.problem`` from its current state by arc-length continuation.

    The problem's time is the load factor :math:`\lambda`: every load and
    prescribed displacement keeps its profile, and :math:`\lambda` goes where
    the path leads (up, through a maximum, down). The start should be an
    equilibrium (the unloaded state, or a converged ramp). The steps are
    taken by :func:`~hyperfem.solver.stepping.run_steps` on an
    :class:`ArcLengthStage` under :meth:`ArcLength.policy`.

    Args:
        solver: A :class:`~hyperfem.solver.NewtonSolver` on the problem (its
            assembly, linear solver and step filters are used).
        settings: The continuation settings (default :class:`ArcLength`).
        on_step: Called after every accepted step (output).
        stop: Called after every accepted step; ``True`` ends the run (e.g. a
            probe displacement reached).

    Returns:
        The accepted steps; ``problem.u`` and ``problem.time`` hold the last.

    Raises:
        ConvergenceError: The arc length fell below its minimum, or
            ``max_attempts`` were spent; ``time`` is the last load factor
            reached and ``history`` the accepted steps (the state is the last one).
        ParameterError: A contact obstacle that moves, or a problem whose loads and
            prescribed displacements do not change with the load factor.
    """
    s = ArcLength() if settings is None else settings
    if s.probe_stop is not None:
        raise ParameterError(
            "continue_arc_length: probe_stop is evaluated by a Simulation; here pass stop=, e.g. a PointProbe test"
        )
    stage = ArcLengthStage(solver.problem, solver, s)
    history: list[ArcLengthRecord] = []

    def accept(record: StepRecord) -> None:
        step = ArcLengthRecord(**{f.name: getattr(record, f.name) for f in fields(StepRecord)}, **stage.events)
        history.append(step)
        if on_step is not None:
            on_step(step)

    def done(record: StepRecord) -> bool:
        return stage.finished(record) or (stop is not None and bool(stop(history[-1])))

    try:
        run_steps(stage, s.policy(stage.time), accept, stop=done)
    except ConvergenceError as exc:
        exc.history = list(history)
        raise
    finally:
        stage.close()
    return history


def _start(run: _Continuation, lam: float, tangent: PETSc.Vec) -> _Path:
    """The reference load, the tangent and the pivots at the start state (collective)."""
    s = run.settings
    run.load_state(lam)
    run.load_vector(lam)
    run.q_norm = run.free_norm(run.q)
    if not _norm(run.q) > 0:
        raise ParameterError(
            "continue_arc_length: no load or prescribed displacement changes with the load factor "
            f"(dR/dλ = 0 at λ = {lam:g}); nothing to follow"
        )
    if not run.q_norm > 0:
        run.q_norm = 1.0  # prescribed displacements only: the residual is judged in force units as it is
    if not run.tangent_direction(lam):
        raise ConvergenceError(f"continue_arc_length: the tangent solve failed at the start (λ = {lam:g})", lam)
    run.w.copy(tangent)
    t = run.disp(tangent)
    tt = run.dot(t, t)
    scale2 = s.psi**2 * tt
    path = _Path(arc=0.0, scale2=scale2, tangent=tangent, sign=float(s.direction),
                 slope=s.direction / math.sqrt(tt + scale2))
    if run.inertia:
        path.negative0 = path.negative_prev = negative_pivots(run.A)
    return path
