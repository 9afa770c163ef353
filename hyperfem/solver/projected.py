r"""Projected Newton: the tangent with the negative modes of the material tangent clamped (seed 004).

At every quadrature point of the stored energy the material tangent

.. math::
    \mathbb{A} = \frac{\partial^2 \psi}{\partial F\,\partial F},\qquad
    \mathbb{A}_{ijkl} = \frac{\partial P_{ij}}{\partial F_{kl}},

viewed as a symmetric :math:`d^2\times d^2` matrix, is replaced by its
positive part

.. math::
    \mathbb{A}^+ = Q\,\max(\Lambda, 0)\,Q^T,\qquad \operatorname{sym}\mathbb{A} = Q\Lambda Q^T,

(or, with ``mode="abs"``, by :math:`Q\,|\Lambda|\,Q^T`, the absolute-value
filter, which flips the negative modes instead of dropping them), and the
solver's tangent by

.. math::
    K^+(u; v, \delta u) = \sum_r \int_{\Omega_r} \nabla v : \mathbb{A}^+_r : \nabla\delta u\,dX
    \; + \; \frac{\partial R_\text{follower}}{\partial u}[\delta u],

(the dead loads are linear in :math:`u` and add nothing; the follower-load
tangent, if any, is neither symmetric nor definite and is kept as it is).
Every point contributes :math:`\nabla v : \mathbb{A}^+ : \nabla v \ge 0`, so
for conservative loads :math:`K^+` is positive semi-definite whatever the
state: the Newton direction :math:`-K^{+\,-1}R` is a descent direction of
:math:`\Pi` and the energy line search always finds a step,
where the consistent tangent of a buckling, compressed or strongly rotated
state is indefinite and its Newton direction may climb. The price: every
refresh is an eigen-decomposition per quadrature point, and near a solution
at which some :math:`\mathbb{A}` is indefinite (compressed or rotated
points, common at stable equilibria too) :math:`K^+ \ne K` and Newton
converges only linearly; where every :math:`\mathbb{A}` is PSD at the
solution, :math:`K^+ = K` there and convergence stays quadratic.

Seed 004 projects in the diagonal space of the SVD :math:`F = U\Sigma V^T`;
the :math:`d^2\times d^2` matrix here differs from that one by the orthogonal
change of basis :math:`\delta F \mapsto U^T\delta F\,V`, so it has the same
eigenvalues and the same projection, and works for any energy, isotropic or not.

Measured (``benchmarks/projected_newton.py``, the cantilever of seed 003 on
``beam_h2.msh``, Neo-Hookean, full load in one step): at the solutions of the
5x bend and twist, 80-93 % of the quadrature points have an indefinite
:math:`\mathbb{A}` (Neo-Hookean under lateral compression, see
``tests/test_projected.py``), so pure projected Newton needs 2.5-4x the
iterations of plain Newton (bend 21 vs 8, twist 16 vs 6) and the refreshes
take 30-50 % of its time; on a column compressed past buckling it stalls in
linear convergence (50 iterations, cut back, fails). The hybrid of
:func:`projected_newton_solver` (``consistent_below=1e-2``: projected until
the residual has dropped 100-fold) costs one to two iterations more than plain
Newton on the bend and twist, and at 3x the buckling load converges in one
step (33 iterations) to the stable buckled state where plain Newton stalls at
an unstable one (50 iterations; 75 with one cutback of the stepper).

The material energy is the problem's own: each cell integral of
``problem.energy_internal`` (one per material region, with its measure and
quadrature rule) is differentiated twice with respect to :math:`\nabla u`,
so multi-region problems, 2D (plane strain) and any energy written in
:math:`F` work without further input.

* :func:`project_psd` — the vectorised per-point projection (a pure function);
* :class:`ProjectedTangent` — the quadrature fields of :math:`\mathbb{A}^+`,
  the form :math:`K^+` and the refresh that runs as a solver state hook;
* :func:`projected_newton_solver` — a :class:`~hyperfem.solver.NewtonSolver`
  with :math:`K^+` as its tangent.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Any

import basix.ufl
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc
from ufl.algorithms import extract_coefficients
from ufl.algorithms.analysis import extract_constants

from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import CorrectedTangentProblem, SolidProblem
from hyperfem.solver.newton import NewtonSolver

__all__ = [
    "MODES",
    "ROUNDOFF_EIGENVALUE",
    "ProjectedTangent",
    "ProjectionStatistics",
    "project_psd",
    "projected_newton_solver",
]


ROUNDOFF_EIGENVALUE = 1e-12
r"""With ``floor = 0``, eigenvalues above :math:`-10^{-12}\,|\Lambda|_\infty` count as non-negative.

The zero modes of a material tangent (the rotations of an isotropic law at
rest) come out of ``eigh`` as :math:`\pm 10^{-16}\,|\Lambda|_\infty`; such a
point is left as it is instead of being rebuilt from its eigenvectors."""


MODES = ("clamp", "abs")
"""Eigenvalue filters of :func:`project_psd`: clamp at the floor, or take absolute values first."""


def project_psd(
    matrices: np.ndarray, floor: float = 0.0, mode: str = "clamp"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""Symmetrise a stack of square matrices and filter their eigenvalues to be non-negative.

    For each matrix :math:`A`, :math:`\operatorname{sym} A = Q\Lambda Q^T` and the
    result is :math:`A^+ = Q\max(\Lambda, \phi\,|\Lambda|_\infty)Q^T` (``mode="clamp"``)
    or :math:`Q\max(|\Lambda|, \phi\,|\Lambda|_\infty)Q^T` (``mode="abs"``) with
    :math:`\phi` = ``floor``. A matrix with no eigenvalue below the bound (with
    :math:`\phi = 0`: below :data:`ROUNDOFF_EIGENVALUE` times
    :math:`-|\Lambda|_\infty`) is returned as :math:`\operatorname{sym} A`,
    without round-off from a reconstruction. Vectorised: one batched
    ``numpy.linalg.eigh`` call. Matrices with NaN/inf entries are passed
    through symmetrised (their assembly then reports the non-finite state).

    Args:
        matrices: Array of shape ``(n, m, m)``.
        floor: Relative eigenvalue floor :math:`\phi \in [0, 1)`; 0 clamps at zero.
        mode: ``"clamp"`` or ``"abs"`` (:data:`MODES`).

    Returns:
        ``(projected, smallest, clamped)``: the projected matrices ``(n, m, m)``,
        the smallest eigenvalue of each symmetrised input (NaN where non-finite)
        ``(n,)``, and whether the matrix was changed beyond symmetrisation ``(n,)``.

    Raises:
        ParameterError: Bad shape, floor or mode.
    """
    A = np.asarray(matrices, dtype=float)
    if A.ndim != 3 or A.shape[1] != A.shape[2]:
        raise ParameterError(f"project_psd: need an array of shape (n, m, m), got {A.shape}")
    _check_floor(floor, "project_psd")
    _check_mode(mode, "project_psd")
    sym = 0.5 * (A + np.swapaxes(A, 1, 2))
    n = sym.shape[0]
    smallest = np.full(n, np.nan)
    clamped = np.zeros(n, dtype=bool)
    finite = np.all(np.isfinite(sym), axis=(1, 2))
    if not np.any(finite):
        return sym, smallest, clamped
    S = sym[finite]
    lam, Q = np.linalg.eigh(S)  # ascending eigenvalues
    scale = np.max(np.abs(lam), axis=1)
    bound = floor * scale
    bad = lam[:, 0] < (bound if floor > 0 else -ROUNDOFF_EIGENVALUE * scale)
    if np.any(bad):
        lam_bad = np.abs(lam[bad]) if mode == "abs" else lam[bad]
        lam_plus = np.maximum(lam_bad, bound[bad, None])
        Qb = Q[bad]
        S[bad] = (Qb * lam_plus[:, None, :]) @ np.swapaxes(Qb, 1, 2)
        sym[finite] = S
    smallest[finite] = lam[:, 0]
    clamped[finite] = bad
    return sym, smallest, clamped


def _check_mode(mode: object, where: str) -> None:
    if mode not in MODES:
        raise ParameterError(f"{where}: mode must be one of {MODES}, got {mode!r}")


def _check_floor(floor: object, where: str) -> None:
    if not (isinstance(floor, numbers.Real) and not isinstance(floor, bool) and 0.0 <= float(floor) < 1.0):
        raise ParameterError(f"{where}: floor must be a number in [0, 1), got {floor!r}")


@dataclass(frozen=True)
class ProjectionStatistics:
    """What the last refresh of a :class:`ProjectedTangent` found (global over ranks).

    Attributes:
        points: Quadrature points (summed over the material integrals).
        projected: Points whose material tangent had an eigenvalue below the floor.
        min_eigenvalue: Smallest eigenvalue of any :math:`\\operatorname{sym}\\mathbb{A}` before
            projection (``nan`` when every point is non-finite or the projection was inactive).
        nonfinite: Points with a NaN/inf tangent (an inverted state), passed through.
        refreshes: Refreshes that recomputed the fields so far (most over the ranks;
            unchanged states are skipped).
    """

    points: int
    projected: int
    min_eigenvalue: float
    nonfinite: int
    refreshes: int

    @property
    def projected_fraction(self) -> float:
        """Share of the points that were projected."""
        return self.projected / self.points if self.points else 0.0


@dataclass
class _MaterialTerm:
    """One cell integral of the stored energy: its tangent expression and :math:`\\mathbb{A}^+` field."""

    expression: fem.Expression
    field: fem.Function
    cells: np.ndarray
    dofs: np.ndarray  # (cells, points): quadrature dofs of each cell
    inputs: list  # coefficients and constants the tangent depends on


def _material_integrals(problem: SolidProblem, where: str) -> list:
    """The cell integrals of the stored energy plus tangent correction, one per measure.

    Integrals of ``problem.energy_internal`` and of its ``tangent_correction``
    (the pseudo-energy whose second variation the problem adds to its
    tangent, e.g. the polar-rotation term of fixed-corotated energies) on the same
    measure (region, rule) are summed into one, so each region gets one
    material tangent.
    """
    correction = problem.tangent_correction if isinstance(problem, CorrectedTangentProblem) else None
    forms = [problem.energy_internal, correction]
    grouped: dict[tuple[object, ...], ufl.Integral] = {}
    for form in forms:
        for itg in () if form is None else form.integrals():
            if itg.integral_type() != "cell":
                raise ParameterError(
                    f"{where}: the stored energy has a {itg.integral_type()!r} integral (on "
                    f"{itg.subdomain_id()!r}); only cell integrals of psi(F) can be projected"
                )
            md = tuple(sorted((k, repr(v)) for k, v in itg.metadata().items()))
            key = (itg.subdomain_id(), md, id(itg.subdomain_data()))
            if key in grouped:
                grouped[key] = grouped[key].reconstruct(integrand=grouped[key].integrand() + itg.integrand())
            else:
                grouped[key] = itg
    if not grouped:
        raise ParameterError(f"{where}: the problem has no stored-energy integral")
    return list(grouped.values())


class ProjectedTangent:
    r"""The PSD-projected tangent :math:`K^+` of a displacement problem (module docstring).

    The fields :math:`\mathbb{A}^+` live on quadrature elements of the
    problem's volume rule, one per cell integral of
    ``problem.energy_internal`` (per material region), on that integral's
    cells. :meth:`refresh` (also :meth:`__call__`) re-evaluates them at the
    current state; it is meant to run as a solver state hook and does the
    eigen-decompositions only when the state (``u`` and every coefficient
    and constant the tangent depends on) changed since the last refresh.
    Refreshes are cell-local (no communication): only the owned cells, which
    are all that cell assembly reads, are updated.

    :attr:`form` is positive semi-definite (plus the follower-load tangent,
    if any, which is neither symmetric nor definite); with Dirichlet
    conditions that fix the rigid motions it is in practice positive
    definite (a null vector would need a displacement whose gradient lies in
    a clamped mode at every quadrature point), so the Newton direction is a
    descent direction of :math:`\Pi` and the energy line search and the
    inversion guard of :class:`~hyperfem.solver.NewtonSolver` work unchanged.

    Args:
        problem: A displacement problem whose stored energy depends on ``u``
            only through :math:`\nabla u` (e.g.
            :class:`~hyperfem.problem.HyperelasticProblem`, one or several regions).
        floor: Relative eigenvalue floor :math:`\phi \in [0, 1)`: eigenvalues are
            clamped at :math:`\phi` times the largest eigenvalue magnitude of the
            point (0: at zero).
        mode: Eigenvalue filter, ``"clamp"`` (seed 004: negative modes dropped)
            or ``"abs"`` (negative modes flipped); see :func:`project_psd`.

    Attributes:
        form: The UFL form of :math:`K^+` (pass as ``jacobian=`` to :class:`~hyperfem.solver.NewtonSolver`).
        fields: The :math:`\mathbb{A}^+` quadrature functions, one per material integral.
        floor: The relative eigenvalue floor.
        mode: The eigenvalue filter.
        active: Whether to project; ``False`` stores :math:`\operatorname{sym}\mathbb{A}`
            (the consistent tangent, no eigen-decomposition) at the next refresh.
        refreshes: Refreshes that recomputed the fields (on this rank).

    Raises:
        ParameterError: The stored energy has a non-cell integral, or a cell
            integrand that depends on ``u`` other than through :math:`\nabla u`
            (a mixed field, inertia of a time step), or a bad ``floor`` or ``mode``.
    """

    def __init__(self, problem: SolidProblem, *, floor: float = 0.0, mode: str = "clamp"):
        where = "ProjectedTangent"
        _check_floor(floor, where)
        _check_mode(mode, where)
        self.problem = problem
        self.floor = float(floor)
        self.mode = mode
        mesh = problem.domain.mesh
        u = problem.u
        d = problem.domain.gdim
        if u.ufl_shape != (d,):
            raise ParameterError(
                f"{where}: the unknown must be the displacement (shape ({d},)), got shape {u.ufl_shape} "
                "(a mixed problem); projected Newton needs a displacement problem"
            )
        self._d = d
        test, trial = sorted(problem.jacobian.arguments(), key=lambda a: a.number())
        grad_u = ufl.grad(u)
        G = ufl.variable(grad_u)
        probe = fem.Constant(mesh, np.zeros((d, d)))
        one = fem.Constant(mesh, 1.0)
        tdim = mesh.topology.dim
        n_owned = mesh.topology.index_map(tdim).size_local
        cell = mesh.basix_cell()
        i, j, p, q = ufl.indices(4)
        self._terms: list[_MaterialTerm] = []
        integrals = []
        for itg in _material_integrals(problem, where):
            region = itg.subdomain_id()
            integrand = itg.integrand()
            if u in extract_coefficients(ufl.replace(integrand, {grad_u: probe})):
                raise ParameterError(
                    f"{where}: the stored energy on {region!r} depends on u other than through grad(u) "
                    "(a mixed field or the inertia of a time step); projected Newton needs a displacement problem"
                )
            psi = ufl.replace(integrand, {grad_u: G})
            # ``one`` ties the expression to the mesh even when A is constant (linear elasticity).
            A = one * ufl.diff(ufl.diff(psi, G), G)
            md = itg.metadata()
            degree = md.get("quadrature_degree")
            if degree is None:
                raise ParameterError(f"{where}: the stored-energy integral on {region!r} has no quadrature_degree")
            rule = md.get("quadrature_rule", "default")
            element = basix.ufl.quadrature_element(cell, value_shape=(d, d, d, d), scheme=rule, degree=degree)
            Q = fem.functionspace(mesh, element)
            field = fem.Function(Q, name="projected_tangent")
            expression = fem.Expression(A, Q.element.interpolation_points)
            cells = self._cells(itg, n_owned, where)
            dofs = Q.dofmap.list[cells]
            inputs = list(extract_coefficients(A)) + list(extract_constants(A))
            self._terms.append(_MaterialTerm(expression, field, cells, dofs, inputs))
            integrand = ufl.grad(test)[i, j] * field[i, j, p, q] * ufl.grad(trial)[p, q]
            integrals.append(itg.reconstruct(integrand=integrand))
        form = ufl.Form(integrals)
        follower = problem.follower_residual
        if follower is not None:
            form = form + ufl.derivative(follower, u, trial)
        self.form = form
        self.fields = [t.field for t in self._terms]
        self.active = True
        self._snapshot: list[np.ndarray] | None = None
        self._snapshot_active = True
        self._local = (0, 0, 0, np.inf)
        self.refreshes = 0

    @staticmethod
    def _cells(itg: ufl.Integral, n_owned: int, where: str) -> np.ndarray:
        """Owned cells of a cell integral (``everywhere`` or tagged subdomains)."""
        region = itg.subdomain_id()
        if region == "everywhere":
            return np.arange(n_owned, dtype=np.int32)
        ids = region if isinstance(region, tuple) else (region,)
        tags = itg.subdomain_data()
        if tags is None or not all(isinstance(t, numbers.Integral) for t in ids):
            raise ParameterError(f"{where}: cannot resolve the cells of the stored-energy integral on {region!r}")
        cells = np.unique(np.concatenate([tags.find(int(t)) for t in ids]))
        return cells[cells < n_owned].astype(np.int32)

    def _state(self) -> list[np.ndarray]:
        """The current values of everything the tangents depend on (views, not copies)."""
        seen: dict[int, np.ndarray] = {}
        for term in self._terms:
            for c in term.inputs:
                if id(c) not in seen:
                    seen[id(c)] = np.asarray(c.x.array if isinstance(c, fem.Function) else c.value)
        return list(seen.values())

    def _unchanged(self, state: list[np.ndarray]) -> bool:
        old = self._snapshot
        if old is None or len(old) != len(state):
            return False
        return all(np.array_equal(a, b) for a, b in zip(old, state, strict=True))

    def refresh(self, force: bool = False) -> None:
        r"""Re-evaluate :math:`\mathbb{A}^+` at the current state (skipped when nothing changed).

        Args:
            force: Recompute even if the state is unchanged.
        """
        state = self._state()
        if not force and self.active == self._snapshot_active and self._unchanged(state):
            return
        d2 = self._d * self._d
        points = projected = nonfinite = 0
        smallest = np.inf
        for term in self._terms:
            values = term.expression.eval(term.field.function_space.mesh, term.cells)
            A = values.reshape(-1, d2, d2)
            points += A.shape[0]
            if self.active:
                Aplus, lam_min, clamped = project_psd(A, self.floor, self.mode)
                projected += int(np.count_nonzero(clamped))
                finite = np.isfinite(lam_min)
                nonfinite += int(lam_min.size - np.count_nonzero(finite))
                if np.any(finite):
                    smallest = min(smallest, float(lam_min[finite].min()))
            else:
                Aplus = 0.5 * (A + np.swapaxes(A, 1, 2))
            array = term.field.x.array.reshape(-1, d2 * d2)
            array[term.dofs.reshape(-1)] = Aplus.reshape(-1, d2 * d2)
        self._local = (points, projected, nonfinite, smallest)
        self._snapshot = [a.copy() for a in state]
        self._snapshot_active = self.active
        self.refreshes += 1

    def __call__(self) -> None:
        """State-hook form of :meth:`refresh`."""
        self.refresh()

    def statistics(self) -> ProjectionStatistics:
        """Global statistics of the last refresh (collective)."""
        comm = self.problem.domain.comm
        points, projected, nonfinite, smallest = self._local
        counts = comm.allreduce(np.array([points, projected, nonfinite], dtype=np.int64), op=MPI.SUM)
        smallest = comm.allreduce(smallest, op=MPI.MIN)
        return ProjectionStatistics(
            points=int(counts[0]),
            projected=int(counts[1]),
            min_eigenvalue=float(smallest) if np.isfinite(smallest) else float("nan"),
            nonfinite=int(counts[2]),
            refreshes=int(comm.allreduce(self.refreshes, op=MPI.MAX)),
        )


def projected_newton_solver(
    problem: SolidProblem,
    petsc_options: dict[str, Any] | None = None,
    *,
    tangent: ProjectedTangent | None = None,
    floor: float = 0.0,
    mode: str = "clamp",
    consistent_below: float | None = None,
    **kwargs: Any,
) -> NewtonSolver:
    r"""A :class:`~hyperfem.solver.NewtonSolver` whose tangent is the projected :math:`K^+`.

    The residual, the energy line search, the inversion guard, the predictor
    and the stopping tests are those of the plain solver; only the tangent
    differs, so a converged solve is a solution of the same equations (to
    the same tolerances).

    With ``consistent_below`` the solver is a hybrid: each solve starts
    projected and, from the first Newton iteration whose residual norm is
    below ``consistent_below`` times the initial one, uses the consistent
    material tangent (``tangent.active = False``, set from the SNES update
    callback at the start of the iteration), so the robust far-field
    behaviour is kept and the quadratic convergence near the solution
    regained. Near an *unstable* equilibrium the consistent direction may
    climb; the energy line search then fails and the solve is reported
    unconverged (the stepper cuts back).

    Args:
        problem: The displacement problem (see :class:`ProjectedTangent`).
        petsc_options: As for :class:`~hyperfem.solver.NewtonSolver`.
        tangent: A :class:`ProjectedTangent` of ``problem`` to use (keep a
            handle for its :meth:`~ProjectedTangent.statistics`); default: a
            new one with ``floor`` and ``mode``.
        floor: Relative eigenvalue floor of a new tangent.
        mode: Eigenvalue filter of a new tangent (``"clamp"`` or ``"abs"``).
        consistent_below: Relative residual in (0, 1) below which the
            consistent tangent takes over; ``None``: always projected.
        **kwargs: Further :class:`~hyperfem.solver.NewtonSolver` arguments
            (not ``jacobian``); ``state_hooks`` run before the refresh of
            :math:`\mathbb{A}^+`.

    Raises:
        ParameterError: ``jacobian`` given, a tangent of another problem, a
            bad ``consistent_below``, or what :class:`ProjectedTangent` and
            :class:`~hyperfem.solver.NewtonSolver` raise.
    """
    where = "projected_newton_solver"
    if "jacobian" in kwargs:
        raise ParameterError(f"{where}: the tangent is the projected one; do not pass jacobian")
    if consistent_below is not None and not (
        isinstance(consistent_below, numbers.Real)
        and not isinstance(consistent_below, bool)
        and 0.0 < float(consistent_below) < 1.0
    ):
        raise ParameterError(f"{where}: consistent_below must be a number in (0, 1) or None, got {consistent_below!r}")
    if tangent is None:
        tangent = ProjectedTangent(problem, floor=floor, mode=mode)
    elif tangent.problem is not problem:
        raise ParameterError(f"{where}: the ProjectedTangent was built for another problem")
    hooks = [*kwargs.pop("state_hooks", ()), tangent.refresh]
    solver = NewtonSolver(problem, petsc_options, jacobian=tangent.form, state_hooks=hooks, **kwargs)
    if consistent_below is not None:
        solver.snes.setUpdate(_HybridSwitch(tangent, float(consistent_below)))
    return solver


class _HybridSwitch:
    """SNES update callback: projected until the residual drops below ``ratio`` times the first one.

    Holds the tangent only (not the solver), so the SNES keeps no reference
    cycle back to the :class:`~hyperfem.solver.NewtonSolver`.
    """

    def __init__(self, tangent: ProjectedTangent, ratio: float):
        self.tangent = tangent
        self.ratio = ratio
        self.initial = np.inf

    def __call__(self, snes: PETSc.SNES, it: int) -> None:
        norm = float(snes.getFunctionNorm())  # of the current iterate, identical on every rank
        if it == 0:
            self.initial = norm
            self.tangent.active = True
        elif norm <= self.ratio * self.initial:
            self.tangent.active = False
