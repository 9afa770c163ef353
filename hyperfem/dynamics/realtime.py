r"""Real-time stepping: implicit time steps on a fixed mesh with a fixed, small Newton budget.

Seed 000 asks of an interactive simulation that a step take less than the
frame time, :math:`1/30` s. :class:`RealtimeStepper` takes repeated implicit
steps (backward Euler, seed 000 eq. 2.15, or Newmark) of an
:class:`~hyperfem.dynamics.IncrementalProblem` with everything that does not
change from step to step done once.

The step minimises the same incremental potential as
:class:`~hyperfem.solver.stepping.DynamicStage`,

.. math::
    \Pi_\Delta(u) = \frac{A}{2}\|u - \tilde u\|_M^2 + \frac{B}{2}\|u - \hat u\|_C^2 + \Pi(u),
    \qquad C = \alpha M + \beta K_0 ,

split into its parts. The inertia and damping part is quadratic with constant
matrices: :math:`M = \partial^2_u \tfrac12\int\rho\,u\cdot u\,dX` and
:math:`K_0` (the reference elastic tangent) are assembled once, and with
:math:`Q = (A + \alpha B)M + \beta B K_0` the residual and tangent are

.. math::
    r(u) = \frac{\partial\Pi}{\partial u} + Q u - g, \qquad
    g = M(A\tilde u + \alpha B\hat u) + \beta B K_0\hat u, \qquad
    J(u) = \frac{\partial^2\Pi}{\partial u^2} + Q ,

where only :math:`\partial\Pi/\partial u` and :math:`\partial^2\Pi/\partial u^2`
(``ufl.derivative`` of the base problem's energy, compiled once, at the base
problem's quadrature: one point per P1 cell instead of the mass rule's four)
are assembled per iteration and :math:`g` once per step. The tangent is
assembled into a DOLFINx CSR matrix (whose insertion is several times faster
than PETSc's ``MatSetValues``) that starts each time as a copy of :math:`Q`,
and handed to one PETSc matrix through a COO map set up once
(``MatSetValuesCOO``): the sparsity, the KSP and its preconditioner (the
symbolic LU factorisation, the AMG interpolation with
``pc_gamg_reuse_interpolation``) are built once and reused.

Per step: the loads and boundary values move to :math:`t_{n+1}`, the state
is warm-started at :math:`u_n + \Delta t\,v_n` with the new boundary values,
and at most ``newton_budget`` Newton iterations

.. math::
    J(u_k)\,\delta u = r(u_k), \qquad u_{k+1} = u_k - \delta u

are taken (no line search; a step stops early at
:math:`\|r\| \le \max(\text{atol}, \text{rtol}\,\|r_0\|)`). The residual left is
never hidden: every step returns a :class:`RealtimeStep` with the iterations,
:math:`\|r\|/\|r_0\|` and the wall time split into assembly, solve and the rest.

*Modified Newton* (``RealtimeConfig.tangent_every > 1`` or ``None``) keeps a
tangent, and its factorisation or preconditioner, across iterations and steps
until the residual contraction :math:`\|r_{k+1}\|/\|r_k\|` exceeds
``refresh_ratio``, the tangent is ``tangent_every`` iterations old, or a step
ended on its budget above the tolerance: the mass term at
:math:`\Delta t = 1/30` s makes the step matrix change slowly for soft bodies.

What is measured (``benchmarks/realtime.py``, the bend case, budget 2,
``rtol`` :math:`10^{-4}`, on a shared 2-core machine, so indicative): the
tangent assembly dominates a Newton iteration (P1 Neo-Hookean, 1.7 ms per
1000 cells for kernel and insertion against 0.15–0.2 ms for the residual,
serial), so the presets differ mostly in how often they assemble and
factorise it. Modified Newton with CG + ICC(0) (``cg-icc-modified``, the
default) keeps about one tangent per six steps and sustained 30–57 steps/s on
10,206 tetrahedra serially (94 on 2 ranks) depending on the load of the
machine; Newton with a fresh tangent per iteration reached 30 steps/s up to
about 4,000–6,000 tetrahedra. At ``rtol`` :math:`10^{-4}` every preset ends 33
steps within :math:`3\cdot 10^{-6}` (relative) of the most converged one at
the test point.

The default budget is 6 (issue 20: every step converged). With budget 2,
14 of 60 timed steps of ``cg-icc-modified`` on 10,206 tetrahedra ended above
``rtol`` (at 60 steps/s); with budget 3, 6 (72 steps/s, a noisy machine); with
budget 4 or 6 none, every relative residual at most :math:`9.9\cdot 10^{-5}`,
3.3 Newton iterations per step on average, 40–45 steps/s serially with the
machine's load average at 2.5 (``benchmarks/realtime.py --sizes 10000
--config cg-icc-modified --ranks 1 --budget 6 --repeat 2``). ``demos/realtime.py``
needs 5 (budget 4: 5 of 89 steps above ``rtol``, the largest 1.35e-4). A step stops as soon as it
meets the tolerance, so the larger budget costs only the steps that need it.

**Contact** (``contacts=[...]``: rigid analytic obstacles bound to the problem,
:class:`~hyperfem.contact.PlaneContact`, :class:`~hyperfem.contact.SphereContact`,
:class:`~hyperfem.contact.CylinderContact`, friction included): the barrier's
gradient is added to every residual and its node blocks to every tangent (they
lie in the fixed pattern: a node's own block), the obstacles move to
:math:`t_{n+1}` before the warm start, and no iterate ever penetrates: a warm
start the barrier refuses is pulled back toward :math:`u_n` (with the nodes the
obstacle's move overran carried along with it, as the Newton solver's predictor
does) as far as the collision filters allow, and every Newton update is cut to
the fraction they allow (``contact_cutbacks``); a step ends with
``min_distance`` > 0 whatever its residual. Mesh contact (``ToolContact``,
``SurfaceContact``, ``TieContact``) couples nodes outside the fixed pattern and
is refused. Measured (``benchmarks/contact_realtime.py``: a ball of radius 0.15
indenting a soft 1 x 1 x 0.25 slab by 0.1 while dragging 0.3 over 2 s,
:math:`\Delta t = 1/30`, budget 6, serial, a machine with load average 3.4):
47 steps/s on 1,452 tetrahedra and 11 on 6,144 (``cg-icc-modified``), every step
intersection-free. What limits it is Newton, not the barrier's terms: they
cost 0.2–0.3 ms per iteration against 7.7 ms for the elastic tangent at 6,144
tetrahedra, but a step in contact takes about 6 Newton iterations with a fresh
tangent each (the log barrier's first update overshoots and the residual
grows before it converges; without a line search the stepper cannot stop
that), where a step without contact takes one tangent per six steps; 43 of 55
steps ended on the budget above ``rtol`` (largest :math:`\|r\|/\|r_0\|` 0.21).
30 steps/s on a few thousand tetrahedra would need about 2 iterations per
step in contact. A wider barrier helps (``--dhat 3e-3``, about twice the tool's
advance per frame, against the mesh default 0.9–1.3e-3): 60 and 12.7 steps/s,
15 and 21 of 55 steps above ``rtol`` (largest 0.038), one tangent per step
fewer. With every step converged (budget 20, the mesh's :math:`\hat d`, a
quiet machine; ``results/contact_realtime_converged_s37.jsonl``): 53 steps/s on
1,200 tetrahedra, 23–26 on 3,042 and 10–13 on 6,144, with 7.8–8.2 Newton
iterations and 4.3–5 tangents a step. A wider barrier converges in fewer
iterations, 6–6.7 a step (``--dhat``; ``results/contact_realtime_dhat_s37.jsonl``):
d-hat 2 mm, 83 steps/s on 1,200 tetrahedra, 42 on 3,042, 13 on 8,664 (1 of
55 steps above ``rtol``); 3 mm, 87, 42, and on 8,664 only 4 (25 above). There
the ball pushes hard enough to invert cells: see "Inversion".

**Inversion.** The stepper has no line search, and checking every update for
inverted cells would cost a real-time step about 1 ms per 6,000 tetrahedra
and iteration (the exact filter). So the check is lazy: where an update gives
a non-finite residual (a cell inverted: :math:`\log J` of the energy) on P1
simplices, the update is taken again from its start as far as the exact
inversion filter allows (:class:`~hyperfem.solver.filters.ExactInversionFilter`,
``inversion_cutbacks``), and a start (warm start or contact start) that
inverts a cell is pulled back toward the accepted state (with the new
boundary values and the carried nodes) the same way, as far as the collision
filters also allow from there; the tangent is then assembled afresh. The
guard's time counts as assembly. Without it the tool on tissue above raised
on 1,200, 3,042 and 8,664 tetrahedra with d-hat 2–3 mm (residual NaN); with it
every step of those runs finishes with :math:`J > 0`
(``tests/test_realtime.py``). Not caught: an energy finite for
:math:`J \le 0`, and an accepted state whose new boundary values or carried
nodes invert a cell themselves; those still raise as before.

**Not a** :class:`~hyperfem.simulation.Simulation`. Every other time stepper
(implicit, semi-implicit, explicit) runs as a ``Simulation`` with its outputs;
this one does not, by design. A ``Simulation`` owns the time: its
:class:`~hyperfem.solver.stepping.StepPolicy` chooses the steps, cuts a failed
one back and retries it, and its outputs write files after every step (a CSV
line, the JSON summary rewritten, a VTX frame: milliseconds each, against a
33 ms frame). A real-time step is driven by the caller's frame clock instead
(one :meth:`RealtimeStepper.step` per frame, ``step(t)`` to catch up after a
dropped frame), must end within the frame on a fixed Newton budget, and is
never retried: it is accepted with the residual it leaves, which its
:class:`RealtimeStep` reports. The state is the
:class:`~hyperfem.dynamics.IncrementalProblem`'s, so between frames anything
can read it (:class:`~hyperfem.dynamics.Diagnostics`, probes), and files are
written after the frames (``demos/realtime.py`` writes its summary with
:func:`~hyperfem.io.write_json`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem, la

from hyperfem.dynamics.damping import reference_stiffness_form
from hyperfem.dynamics.incremental import IncrementalProblem
from hyperfem.dynamics.integrators import BackwardEuler
from hyperfem.errors import ConvergenceError, ParameterError
from hyperfem.solver.external import ExternalEnergy, ExternalTerms
from hyperfem.solver.filters import ExactInversionFilter
from hyperfem.solver.linear import LinearSolver, rigid_body_modes
from hyperfem.solver.step_filter import StepFilter, exact_filter_applies
from hyperfem.validation import check_positive, is_finite_number

__all__ = ["CONFIGS", "RealtimeConfig", "RealtimeStep", "RealtimeStepper", "RealtimeSummary"]


@dataclass(frozen=True)
class RealtimeConfig:
    """How the linear systems of a real-time step are solved.

    Attributes:
        options: PETSc KSP/PC options (keys without prefix). For a
            non-conservative problem (follower loads: non-symmetric tangent)
            ``cg`` becomes ``gmres`` and ``icc`` becomes ``ilu``.
        tangent_every: Newton iterations (counted across steps) a tangent is
            kept before it is reassembled: ``1`` is Newton's method, more is
            modified Newton, ``None`` keeps it until the contraction test asks
            for a new one.
        refresh_ratio: Modified Newton: reassemble the tangent at the next
            iteration once :math:`\\|r_{k+1}\\|/\\|r_k\\|` exceeds this. A
            step that ends on the budget above the tolerance also has the
            tangent reassembled for the next step.
        near_nullspace: Attach the rigid-body modes to the matrix (for AMG).
    """

    options: Mapping[str, object]
    tangent_every: int | None = 1
    refresh_ratio: float = 0.25
    near_nullspace: bool = False

    def __post_init__(self) -> None:
        if self.tangent_every is not None and not (
            isinstance(self.tangent_every, int) and not isinstance(self.tangent_every, bool) and self.tangent_every >= 1
        ):
            raise ParameterError(
                f"RealtimeConfig: tangent_every must be an integer >= 1 or None, got {self.tangent_every!r}"
            )
        if not (is_finite_number(self.refresh_ratio) and 0 < self.refresh_ratio <= 1):
            raise ParameterError(f"RealtimeConfig: refresh_ratio must lie in (0, 1], got {self.refresh_ratio!r}")

    @property
    def modified(self) -> bool:
        """Whether tangents are kept over several iterations (modified Newton)."""
        return self.tangent_every != 1


_ITERATIVE = {"ksp_rtol": 1e-4, "ksp_atol": 0.0, "ksp_max_it": 500}
_ICC = {"ksp_type": "cg", "pc_type": "bjacobi", "sub_pc_type": "icc", **_ITERATIVE}
_MUMPS = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}

CONFIGS: dict[str, RealtimeConfig] = {
    "cg-jacobi": RealtimeConfig({"ksp_type": "cg", "pc_type": "jacobi", **_ITERATIVE}),
    "cg-icc": RealtimeConfig(_ICC),
    "cg-gamg": RealtimeConfig(
        {
            "ksp_type": "cg",
            "pc_type": "gamg",
            "pc_gamg_reuse_interpolation": True,
            "mg_levels_ksp_type": "chebyshev",
            "mg_levels_pc_type": "jacobi",
            **_ITERATIVE,
        },
        near_nullspace=True,
    ),
    "mumps": RealtimeConfig(_MUMPS),
    "cg-icc-modified": RealtimeConfig(_ICC, tangent_every=None),
    "mumps-modified": RealtimeConfig(_MUMPS, tangent_every=None),
}
"""Presets (``RealtimeStepper(..., config="cg-icc")``): Newton with CG + Jacobi,
CG + block-Jacobi ICC(0), CG + GAMG (interpolation reused), MUMPS LU (symbolic
factorisation reused), and modified Newton with a kept tangent and its ICC or
LU factors (``cg-icc-modified``: the default, the fastest (or tied) from 4,000
tetrahedra up; ``benchmarks/results/realtime.jsonl``). CG stops at a relative tolerance
of :math:`10^{-4}` (inexact Newton). With follower loads ``cg`` becomes
``gmres`` and ``icc`` ``ilu``."""


@dataclass
class RealtimeStep:
    """Record of one real-time step.

    Attributes:
        step: Index of the step (1, 2, ...).
        time: Time reached, :math:`t_{n+1}`.
        iterations: Newton iterations taken (linear solves).
        tangents: Tangent assemblies in this step (fewer than ``iterations``
            with modified Newton).
        linear_iterations: Krylov iterations of the step (1 per solve for a direct solve).
        linear_failures: Linear solves that did not converge (e.g. ``ksp_max_it``
            reached); their Newton updates were still applied.
        initial_residual: :math:`\\|r_0\\|` at the warm start (pulled back where it inverted a cell).
        residual_norm: :math:`\\|r\\|` left at the end of the step.
        relative_residual: :math:`\\|r\\|/\\|r_0\\|` (0 when :math:`r_0 = 0`).
        converged: Whether the tolerance was met within the budget.
        wall_time: Seconds for the whole step (this rank).
        assembly_time: Seconds spent assembling residuals and tangents.
        solve_time: Seconds in the linear solves (factorisation or
            preconditioner set-up included).
        min_J: Smallest quadrature-point :math:`J` at the end (``nan`` unless
            the stepper monitors it).
        min_distance: With contacts: the smallest distance of a contact node from its obstacle at the end
            (``nan`` without); always > 0.
        contact_cutbacks: With contacts: Newton updates (and the start guess) the collision filters shortened.
        inversion_cutbacks: Newton updates (and the start) that inverted a cell and were taken again shortened
            by the exact inversion filter (P1 simplices; "Inversion" in the module docstring).
    """

    step: int
    time: float
    iterations: int
    tangents: int
    linear_iterations: int
    linear_failures: int
    initial_residual: float
    residual_norm: float
    relative_residual: float
    converged: bool
    wall_time: float
    assembly_time: float
    solve_time: float
    min_J: float = float("nan")
    min_distance: float = float("nan")
    contact_cutbacks: int = 0
    inversion_cutbacks: int = 0

    @property
    def other_time(self) -> float:
        """Seconds outside assembly and solves (loads, boundary values, vector updates, norms)."""
        return max(self.wall_time - self.assembly_time - self.solve_time, 0.0)

    def as_dict(self) -> dict:
        """JSON-serialisable form (with :attr:`other_time`)."""
        return {**self.__dict__, "other_time": self.other_time}


@dataclass
class RealtimeSummary:
    """Statistics of the steps taken so far (times: the slowest rank).

    Attributes:
        steps: Steps taken.
        wall_time: Seconds spent in :meth:`RealtimeStepper.step` in all.
        steps_per_second: ``steps / wall_time``.
        frame_time: The step :math:`\\Delta t` (real time means a step in less).
        realtime_fraction: Fraction of steps whose wall time was at most :attr:`frame_time`.
        max_step_time: Slowest step (s).
        mean_iterations: Newton iterations per step.
        tangents: Tangent assemblies in all.
        linear_iterations: Krylov iterations per step.
        linear_failures: Linear solves that did not converge, in all.
        unconverged: Steps that ended on the budget above the tolerance.
        relative_residual_mean, relative_residual_median, relative_residual_max:
            Statistics of :math:`\\|r\\|/\\|r_0\\|` at the end of the steps.
        residual_max: Largest :math:`\\|r\\|` left.
        assembly_time, solve_time, other_time: Mean seconds per step of each part.
    """

    steps: int
    wall_time: float
    steps_per_second: float
    frame_time: float
    realtime_fraction: float
    max_step_time: float
    mean_iterations: float
    tangents: int
    linear_iterations: float
    linear_failures: int
    unconverged: int
    relative_residual_mean: float
    relative_residual_median: float
    relative_residual_max: float
    residual_max: float
    assembly_time: float
    solve_time: float
    other_time: float

    def as_dict(self) -> dict:
        """JSON-serialisable form."""
        return dict(self.__dict__)


class _StepMatrices:
    r"""The step tangent in a DOLFINx CSR matrix mapped once onto a PETSc matrix, and the constant matrices.

    DOLFINx assembles the tangent into :attr:`csr` (expanded blocks); the
    owned rows go to the PETSc matrix :attr:`A` through a COO map set up once
    (``MatSetPreallocationCOO``), so each assembly ends in one
    ``MatSetValuesCOO``. Constant bilinear forms (mass, reference stiffness)
    are assembled into the same pattern once; their combination
    :math:`Q = \sum_i c_i M_i` (with Dirichlet rows and columns zeroed) is
    the start of every tangent assembly.

    Args:
        tangent: The compiled tangent form (its sparsity is the pattern).
        constants: Name → compiled constant bilinear form.
        bcs: Dirichlet conditions: their rows and columns of the tangent are
            the identity.
    """

    def __init__(self, tangent: fem.Form, constants: Mapping[str, fem.Form], bcs: list[fem.DirichletBC]):
        self.tangent, self.bcs = tangent, bcs
        V = tangent.function_spaces[0]
        comm = V.mesh.comm
        self.csr = csr = fem.create_matrix(tangent, block_mode=la.BlockMode.expanded)
        rmap, cmap = csr.index_map(0), csr.index_map(1)
        n_rows, indptr = rmap.size_local, csr.indptr
        self.nnz = int(indptr[n_rows])
        row_global = rmap.local_to_global(np.arange(len(indptr) - 1, dtype=np.int32))
        col_global = cmap.local_to_global(csr.indices.astype(np.int32))
        rows = np.repeat(row_global[:n_rows], np.diff(indptr[: n_rows + 1])).astype(PETSc.IntType)
        cols = col_global[: self.nnz].astype(PETSc.IntType)
        sizes = ((n_rows, rmap.size_global), (cmap.size_local, cmap.size_global))

        def coo_matrix() -> PETSc.Mat:
            mat = PETSc.Mat().create(comm)
            mat.setSizes(sizes)
            mat.setType(PETSc.Mat.Type.AIJ)
            # PETSc may overwrite the index arrays; petsc4py takes arrays where its stubs say Sequence
            mat.setPreallocationCOO(rows.copy(), cols.copy())  # type: ignore[arg-type]
            return mat

        self.A = coo_matrix()
        self.constant_data: dict[str, np.ndarray] = {}
        self.constant: dict[str, PETSc.Mat] = {}
        for name, form in constants.items():
            csr.data[:] = 0.0
            fem.assemble_matrix(csr, form)  # type: ignore[arg-type]  # dolfinx: singledispatch (MatrixCSR, Form)
            csr.scatter_reverse()
            data = csr.data.copy()
            data[self.nnz :] = 0.0  # ghost rows were added to their owners
            self.constant_data[name] = data
            self.constant[name] = coo_matrix()
            self.constant[name].setValuesCOO(data[: self.nnz], PETSc.InsertMode.INSERT_VALUES)  # type: ignore[arg-type]
        # Entries in Dirichlet rows or columns (the CSR column map has its own
        # ghosts: dofs are matched by global index), and the diagonal of the owned Dirichlet rows.
        bc_local = np.unique(np.concatenate([bc.dof_indices()[0] for bc in bcs] or [np.zeros(0, np.int32)]))
        bs = V.dofmap.index_map_bs
        bc_global = V.dofmap.index_map.local_to_global((bc_local // bs).astype(np.int32)) * bs + bc_local % bs
        entry_row = np.repeat(row_global, np.diff(indptr))
        self._constrained = np.flatnonzero(np.isin(entry_row, bc_global) | np.isin(col_global, bc_global))
        self.bc_rows = bc_local[bc_local < n_rows].astype(np.int32)
        diagonal = [np.flatnonzero(col_global[indptr[i] : indptr[i + 1]] == row_global[i])[0] for i in self.bc_rows]
        self._bc_diagonal = (indptr[self.bc_rows] + np.array(diagonal, dtype=np.int64)).astype(np.int64)
        self._Q = np.zeros_like(csr.data)

    def set_constant_part(self, coefficients: Mapping[str, float]) -> None:
        r""":math:`Q = \sum_i c_i M_i` for ``coefficients`` name → :math:`c_i` (Dirichlet entries zero)."""
        self._Q[:] = 0.0
        for name, c in coefficients.items():
            if c:
                self._Q += c * self.constant_data[name]
        self._Q[self._constrained] = 0.0

    def assemble(self) -> None:
        """:math:`A = Q + K(u)` at the current state of the tangent's coefficients."""
        csr = self.csr
        np.copyto(csr.data, self._Q)
        fem.assemble_matrix(csr, self.tangent, bcs=self.bcs)  # type: ignore[arg-type, misc]  # dolfinx: singledispatch
        csr.scatter_reverse()
        csr.data[self._bc_diagonal] = 1.0
        self.A.setValuesCOO(csr.data[: self.nnz], PETSc.InsertMode.INSERT_VALUES)  # type: ignore[arg-type]  # petsc4py


@dataclass
class _Tally:
    """Counters and timers of one :meth:`RealtimeStepper.step`."""

    iterations: int = 0
    tangents: int = 0
    linear: int = 0
    failures: int = 0
    assembly: float = 0.0
    solve: float = 0.0
    cutbacks: int = 0
    inversions: int = 0


def _check_contacts(problem: IncrementalProblem, contacts: Sequence[ExternalEnergy]) -> ExternalTerms | None:
    """The contacts' terms (``None`` without any); a one-line error for mesh contact."""
    if not contacts:
        return None
    for contact in contacts:
        if hasattr(contact, "coupled_hessian"):
            raise ParameterError(
                f"RealtimeStepper: {getattr(contact, 'where', type(contact).__name__)}: mesh contact couples nodes "
                "outside the tangent's fixed sparsity pattern; use a rigid analytic obstacle (PlaneContact, "
                "SphereContact, CylinderContact) in real time"
            )
        if not hasattr(contact, "min_distance"):
            raise ParameterError(
                f"RealtimeStepper: contacts must be bound rigid obstacles (e.g. SphereContact(...).bind(problem)), "
                f"got {type(contact).__name__}"
            )
    return ExternalTerms(problem, contacts)


def _check_arguments(problem: object, dt: float, newton_budget: int, rtol: float, atol: float) -> None:
    """Refuse a problem or a step setting :class:`RealtimeStepper` cannot run with."""
    where = "RealtimeStepper"
    if not isinstance(problem, IncrementalProblem):
        raise ParameterError(f"{where}: problem must be an IncrementalProblem, got {type(problem).__name__}")
    integ = problem.integrator
    if not integ.dynamic or float(integ.alpha_f) != 0.0:
        raise ParameterError(
            f"{where}: needs a dynamic scheme without alpha_f (backward Euler, Newmark), got {integ.name}"
        )
    if not problem.displacement_block.whole:
        raise ParameterError(f"{where}: needs a displacement base problem (mixed problems are not supported)")
    check_positive("dt", dt, where)
    if not (isinstance(newton_budget, int) and not isinstance(newton_budget, bool) and newton_budget >= 1):
        raise ParameterError(f"{where}: newton_budget must be an integer >= 1, got {newton_budget!r}")
    for name, value in (("rtol", rtol), ("atol", atol)):
        if not (is_finite_number(value) and value >= 0):
            raise ParameterError(f"{where}: {name} must be a finite number >= 0, got {value!r}")


def _resolve_config(config: str | RealtimeConfig) -> tuple[str, RealtimeConfig]:
    """The configuration's name (``"custom"`` for an object) and the :class:`RealtimeConfig`."""
    where = "RealtimeStepper"
    if isinstance(config, str):
        if config not in CONFIGS:
            raise ParameterError(f"{where}: unknown config {config!r} (choose from {', '.join(CONFIGS)})")
        return config, CONFIGS[config]
    if isinstance(config, RealtimeConfig):
        return "custom", config
    raise ParameterError(f"{where}: config must be a name or a RealtimeConfig, got {type(config).__name__}")


class RealtimeStepper:
    """Fixed-budget implicit steps of an :class:`~hyperfem.dynamics.IncrementalProblem` (see the module docstring).

    The stepper takes over the time stepping of ``problem``: each
    :meth:`step` advances its state (``u``, ``v``, ``a``, ``t_n``), so the
    problem's diagnostics (energies) and any output read it as after a
    :class:`~hyperfem.solver.stepping.DynamicStage` step. For Newmark, call
    ``problem.initial_acceleration()`` first (backward Euler does not use it).

    Args:
        problem: The incremental problem of a displacement
            (:class:`~hyperfem.problem.HyperelasticProblem`) base problem,
            with a dynamic scheme without :math:`\\alpha_f` (backward Euler, Newmark).
        dt: The time step (s), e.g. :math:`1/30`.
        newton_budget: Most Newton iterations per step (1: semi-implicit). The default 6 lets every
            step of the bend at 10^4 tetrahedra and of ``demos/realtime.py`` reach ``rtol`` (module docstring).
        config: A key of :data:`CONFIGS` or a :class:`RealtimeConfig`.
        petsc_options: KSP/PC options merged over the configuration's.
        rtol: Stop a step early at :math:`\\|r\\| \\le \\text{rtol}\\,\\|r_0\\|`.
        atol: ... or at :math:`\\|r\\| \\le \\text{atol}`.
        monitor_jacobian: Record the smallest quadrature-point :math:`J` per
            step (costs an expression evaluation over the mesh).
        raise_on_nonfinite: Raise :class:`~hyperfem.errors.ConvergenceError`
            (after restoring the previous state) when the residual is NaN/inf.
        form_compiler_options, jit_options: Passed to :func:`dolfinx.fem.form`
            (e.g. ``{"cffi_extra_compile_args": ["-O3", "-march=native"]}``).
        contacts: Rigid obstacles bound to ``problem`` (``PlaneContact``, ``SphereContact``,
            ``CylinderContact``: per-node barriers whose Hessian blocks lie in the tangent's fixed pattern;
            see "Contact" in the module docstring). Mesh contact (``ToolContact``, ``SurfaceContact``) is refused.

    Attributes:
        history: The :class:`RealtimeStep` records.
        forms: The compiled forms (residual, tangent, mass, ...), built once.

    Raises:
        ParameterError: For a quasi-static or :math:`\\alpha_f \\ne 0` scheme, a
            mixed base problem, a bad ``dt``/budget/tolerance, an unknown configuration, or a
            contact whose Hessian couples nodes (mesh contact).
    """

    def __init__(
        self,
        problem: IncrementalProblem,
        dt: float,
        newton_budget: int = 6,
        *,
        config: str | RealtimeConfig = "cg-icc-modified",
        petsc_options: Mapping[str, object] | None = None,
        rtol: float = 1e-4,
        atol: float = 1e-10,
        monitor_jacobian: bool = False,
        raise_on_nonfinite: bool = True,
        form_compiler_options: dict | None = None,
        jit_options: dict | None = None,
        contacts: Sequence[ExternalEnergy] = (),
    ):
        _check_arguments(problem, dt, newton_budget, rtol, atol)
        self._contact = _check_contacts(problem, contacts)
        self.config_name, config = _resolve_config(config)
        self.config = config
        self.problem = problem
        self.dt = float(dt)
        self.newton_budget = int(newton_budget)
        self.rtol, self.atol = float(rtol), float(atol)
        self.raise_on_nonfinite = bool(raise_on_nonfinite)
        self.history: list[RealtimeStep] = []
        self.comm = problem.domain.comm
        self._bcs = problem.bcs
        self._compile_forms(form_compiler_options, jit_options)
        self._allocate()
        self._setup_linear_solver(config, petsc_options)

        # -- step coefficients (fixed dt) -----------------------------------------------
        self._set_dt(self.dt)
        V = problem.u.function_space
        self._inversion = ExactInversionFilter(problem.u, StepFilter(V)) if exact_filter_applies(V) else None
        self._min_J = None
        if monitor_jacobian:
            from hyperfem.problem.inversion import QuadratureMinimum

            self._min_J = QuadratureMinimum(problem.domain.mesh, problem.volume_jacobian(), problem.quadrature_points())

    def _compile_forms(self, form_compiler_options: dict | None, jit_options: dict | None) -> None:
        """Compile the residual, tangent, mass (and reference stiffness) forms, once."""
        problem = self.problem
        base, u = problem.base, problem.u
        v, du = ufl.TestFunction(problem.V), ufl.TrialFunction(problem.V)
        disp = base.displacement
        assert problem.density is not None  # a dynamic scheme (checked by the constructor)
        kinetic = 0.5 * problem.density.integral(ufl.dot(disp(u), disp(u)), problem.domain, problem.degree)
        mass = ufl.derivative(ufl.derivative(kinetic, u, v), u, du)
        damping = problem.damping
        self._alpha = 0.0 if damping is None else float(damping.alpha)
        self._beta = 0.0 if damping is None else float(damping.beta)

        def compile_(form: ufl.Form) -> fem.Form:
            return fem.form(form, form_compiler_options=form_compiler_options, jit_options=jit_options)

        self.forms: dict[str, fem.Form] = {
            "residual": compile_(base.residual),
            "tangent": compile_(base.jacobian),
            "mass": compile_(mass),
        }
        if self._beta:
            self.forms["reference_stiffness"] = compile_(reference_stiffness_form(base.energy_internal, u, du, v))

    def _allocate(self) -> None:
        """The tangent's pattern and the constant matrices (assembled once), and the work vectors."""
        V = self.problem.V
        constants = {"mass": self.forms["mass"]}
        if self._beta:
            constants["reference_stiffness"] = self.forms["reference_stiffness"]
        self._matrices = _StepMatrices(self.forms["tangent"], constants, self._bcs)
        self.A = self._matrices.A  # the step tangent J
        self._M = self._matrices.constant["mass"]
        self._K0 = self._matrices.constant.get("reference_stiffness")
        self._b = fpetsc.create_vector(fem.extract_function_spaces(self.forms["residual"]))
        self._du = self.A.createVecRight()
        self._z = self.A.createVecRight()
        self._u_n = fem.Function(V)
        self._u_hat = fem.Function(V)
        self._v_n = fem.Function(V)
        self._w = fem.Function(V)
        self._scratch = fem.Function(V)

    def _setup_linear_solver(self, config: RealtimeConfig, petsc_options: Mapping[str, object] | None) -> None:
        """The KSP of the configuration (GMRES/ILU for a non-conservative problem), user options over it."""
        options = dict(config.options)
        if not self.problem.conservative:
            swap = {"cg": "gmres", "icc": "ilu"}
            options = {k: swap.get(v, v) if isinstance(v, str) else v for k, v in options.items()}
        options.update(petsc_options or {})
        self.petsc_options = options
        if config.near_nullspace:
            modes = rigid_body_modes(self.problem.V, self.A)
            self.A.setNearNullSpace(PETSc.NullSpace().create(vectors=modes, comm=self.A.comm))
        self.ksp = LinearSolver(options).ksp(self.comm, kind="realtime")
        self.ksp.setOperators(self.A, self.A)
        self._tangent_age: int | None = None  # iterations since the last assembly; None: none yet
        self._stale = False

    def _set_dt(self, dt: float) -> None:
        """Coefficients of the quadratic part for a step ``dt`` (the constant part ``Q`` of the tangent)."""
        problem = self.problem
        arr = problem.u.x.array
        A, _, B, _ = problem.integrator.coefficients(dt, arr, problem.v.x.array, problem.a.x.array)
        self._coef = (float(A), float(B))
        self._cM = float(A) + self._alpha * float(B)  # Q = cM M + cK K0
        self._cK = self._beta * float(B)
        self._matrices.set_constant_part({"mass": self._cM, "reference_stiffness": self._cK})
        self._step_dt = dt
        self._backward_euler = isinstance(problem.integrator, BackwardEuler)
        self._stale = True  # Q changed: the kept tangent is out of date

    # -- assembly --------------------------------------------------------------------
    def _assemble_tangent(self) -> None:
        self._matrices.assemble()
        if self._contact is not None:
            # Projected (PSD) blocks: the stepper has no descent check or line search to fall back on where a
            # curved obstacle's exact block would make the tangent indefinite (hyperfem.contact.nodal).
            self._contact.project_tangents()
            self._contact.add_tangent(self.A)  # node blocks: inside the fixed pattern

    def _assemble_residual(self) -> float:
        """:math:`r(u) = \\partial\\Pi/\\partial u + Q u - g` (zero on Dirichlet rows); returns its norm."""
        b = self._b
        with b.localForm() as local:
            local.set(0.0)
        fpetsc.assemble_vector(b, self.forms["residual"])  # type: ignore[arg-type]  # dolfinx: singledispatch
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]  # int enums
        u = self.problem.u.x.petsc_vec
        z = self._z
        # Q u - g = M (cM u - w) + cK K0 (u - u_hat)
        z.waxpy(-1.0 / self._cM, self._w.x.petsc_vec, u)  # z = u - w / cM
        z.scale(self._cM)
        self._M.multAdd(z, b, b)
        if self._K0 is not None:
            z.waxpy(-1.0, self._u_hat.x.petsc_vec, u)
            z.scale(self._cK)
            self._K0.multAdd(z, b, b)
        if self._contact is not None:
            self._contact.add_residual(b)  # the barriers' (and friction's) gradient, Dirichlet rows excepted
        b.array_w[self._matrices.bc_rows] = 0.0
        return float(b.norm())  # type: ignore[arg-type]  # petsc4py: the 2-norm is a float

    # -- stepping --------------------------------------------------------------------
    def _prepare(self, dt: float) -> None:
        r"""Keep :math:`(u_n, v_n)`, form :math:`w = A\tilde u + \alpha B\hat u`, warm-start :math:`u`.

        Backward Euler works in place (:math:`\tilde u = u_n + \Delta t\,v_n`,
        :math:`\hat u = u_n`); other schemes go through their
        :meth:`~hyperfem.dynamics.TimeIntegrator.coefficients`.
        """
        problem = self.problem
        u, v = problem.u.x.array, problem.v.x.array
        un, vn, w, scratch = self._u_n.x.array, self._v_n.x.array, self._w.x.array, self._scratch.x.array
        np.copyto(un, u)
        np.copyto(vn, v)
        A, B = self._coef
        if self._backward_euler:
            np.multiply(un, self._cM, out=w)
            np.multiply(vn, A * dt, out=scratch)
            w += scratch
            if self._K0 is not None:
                np.copyto(self._u_hat.x.array, un)
        else:
            _, u_tilde, _, u_hat = problem.integrator.coefficients(dt, un, vn, problem.a.x.array)
            np.multiply(u_tilde, A, out=w)
            w += (self._alpha * B) * u_hat
            np.copyto(self._u_hat.x.array, u_hat)
        t_new = problem.t_n + dt
        problem.base.set_time(t_new, t_new)
        # Warm start: the previous state moved on by its velocity, with the new boundary values.
        np.multiply(vn, dt, out=scratch)
        u += scratch
        for bc in self._bcs:
            bc.set(u)

    def _commit(self, dt: float) -> None:
        problem = self.problem
        u = problem.u.x.array
        un, vn = self._u_n.x.array, self._v_n.x.array
        if self._backward_euler:
            v, a = problem.v.x.array, problem.a.x.array
            np.subtract(u, un, out=v)
            v *= 1.0 / dt
            np.subtract(v, vn, out=a)
            a *= 1.0 / dt
        else:
            v, a = problem.integrator.update(dt, u, un, vn, problem.a.x.array)
            problem.v.x.array[:] = v
            problem.a.x.array[:] = a
        problem.t_n += dt

    def _restore(self) -> None:
        problem = self.problem
        np.copyto(problem.u.x.array, self._u_n.x.array)
        np.copyto(problem.v.x.array, self._v_n.x.array)
        problem.base.set_time(problem.t_n)

    def step(self, t: float | None = None) -> RealtimeStep:
        """Advance the state to ``t`` (default :math:`t_n + \\Delta t`) within the Newton budget.

        A ``t`` other than :math:`t_n + \\Delta t` takes a step of that length
        (the constant part of the tangent is rescaled and the kept tangent
        refreshed), e.g. to catch up after a dropped frame.

        Returns:
            The step's :class:`RealtimeStep` (also appended to :attr:`history`).

        Raises:
            ParameterError: If ``t`` is not after :math:`t_n`.
            ConvergenceError: If the residual is NaN/inf (with
                ``raise_on_nonfinite``); the previous state is restored.
        """
        start = time.perf_counter()
        problem = self.problem
        dt = self.dt if t is None else float(t) - problem.t_n
        if not (math.isfinite(dt) and dt > 0):
            raise ParameterError(
                f"RealtimeStepper.step: t must be a finite time after t_n = {problem.t_n:g}, got {t!r}"
            )
        if abs(dt - self._step_dt) > 1e-12 * max(dt, self._step_dt):
            self._set_dt(dt)
        t_from = problem.t_n
        self._prepare(dt)
        tally = _Tally()
        if self._contact is not None:
            self._contact_start(t_from, tally)
        t0 = time.perf_counter()
        r0 = self._assemble_residual()
        if not math.isfinite(r0) and self._inversion is not None:
            r0 = self._uninvert_start(t_from, tally)
        tally.assembly += time.perf_counter() - t0
        tol = max(self.atol, self.rtol * r0)
        r = self._newton(tally, r0, tol)
        if not math.isfinite(r) and self.raise_on_nonfinite:
            self._restore()
            self._stale = True
            raise ConvergenceError(
                f"RealtimeStepper: residual is NaN/inf in the step to t = {problem.t_n + dt:g} "
                f"(after {tally.iterations} Newton iterations); state restored to t = {problem.t_n:g}",
                problem.t_n,
                self.history,
            )
        converged = bool(r <= tol)
        if self.config.modified and not converged:
            self._stale = True  # the kept tangent no longer reaches the tolerance within the budget
        self._commit(dt)
        min_distance = float("nan")
        if self._contact is not None:
            self._contact.remember()  # the friction's lag at the accepted state
            min_distance = min(float(e.min_distance()) for e in self._contact.energies)  # type: ignore[attr-defined]
        min_J = self._min_J() if self._min_J is not None else float("nan")
        record = RealtimeStep(
            step=len(self.history) + 1,
            time=problem.t_n,
            iterations=tally.iterations,
            tangents=tally.tangents,
            linear_iterations=tally.linear,
            linear_failures=tally.failures,
            initial_residual=r0,
            residual_norm=r,
            relative_residual=r / r0 if r0 > 0 else 0.0,
            converged=converged,
            wall_time=time.perf_counter() - start,
            assembly_time=tally.assembly,
            solve_time=tally.solve,
            min_J=min_J,
            min_distance=min_distance,
            contact_cutbacks=tally.cutbacks,
            inversion_cutbacks=tally.inversions,
        )
        self.history.append(record)
        return record

    def _contact_start(self, t_from: float, tally: _Tally) -> None:
        """Move the obstacles to the new time and make the warm start intersection-free (Contact, module docstring).

        Collective. Raises :class:`~hyperfem.errors.ConvergenceError` (state restored) when even the previous
        state with the overrun nodes carried is refused.
        """
        contact, problem = self._contact, self.problem
        assert contact is not None
        contact.update(problem.time)
        if not contact.refusal():
            return
        u = problem.u
        guess = u.x.array.copy()
        anchor = self._anchor(t_from)
        u.x.array[:] = anchor
        u.x.scatter_forward()
        why = contact.refusal()
        if why:
            self._restore()
            raise ConvergenceError(
                f"RealtimeStepper: no intersection-free start for the step to t = {problem.t_n + self._step_dt:g}: "
                f"{why}",
                problem.t_n,
                self.history,
            )
        step = self._z
        step.array_w[:] = anchor[: len(step.array_r)] - guess[: len(step.array_r)]
        fraction = self._contact_fraction(u.x.petsc_vec, step, tally)
        u.x.array[:] = anchor + fraction * (guess - anchor)
        u.x.scatter_forward()

    def _anchor(self, t_from: float) -> np.ndarray:
        """The accepted state with the new boundary values and the nodes the obstacles' move overran carried along:
        the fallback start of a step."""
        anchor = self._u_n.x.array.copy()
        for energy in () if self._contact is None else self._contact.energies:
            carried = getattr(energy, "carried", None)
            if carried is not None:
                dofs, increments = carried(self._u_n.x.array, t_from)
                anchor[np.asarray(dofs).ravel()] += np.asarray(increments).ravel()
        for bc in self._bcs:
            bc.set(anchor)
        return anchor

    def _uninvert_start(self, t_from: float, tally: _Tally) -> float:
        """The start of the step inverted a cell (a non-finite residual): move it back toward :meth:`_anchor` as far as
        the exact inversion filter and the collision filters allow, both measured from the anchor (collective; the
        anchor refused by a contact raises as in :meth:`_contact_start`). Returns the new residual norm."""
        assert self._inversion is not None
        u = self.problem.u
        guess = u.x.array.copy()
        anchor = self._anchor(t_from)
        u.x.array[:] = anchor
        u.x.scatter_forward()
        why = "" if self._contact is None else self._contact.refusal()
        if why:
            self._restore()
            raise ConvergenceError(
                f"RealtimeStepper: no start for the step to t = {self.problem.t_n + self._step_dt:g} that inverts "
                f"no cell: {why}",
                self.problem.t_n,
                self.history,
            )
        step = self._z
        n = len(step.array_r)
        step.array_w[:] = anchor[:n] - guess[:n]
        fraction = self._inversion.step_fraction(u.x.petsc_vec, step)
        if self._contact is not None:  # a segment from the anchor can enter a convex obstacle the guess is out of
            fraction = min(fraction, self._contact_fraction(u.x.petsc_vec, step, tally))
        u.x.array[:] = anchor + fraction * (guess - anchor)
        u.x.scatter_forward()
        tally.inversions += int(fraction < 1.0)
        self._stale = True
        return self._assemble_residual()

    def _contact_fraction(self, x: PETSc.Vec, y: PETSc.Vec, tally: _Tally) -> float:
        r"""The largest fraction :math:`\alpha \le 1` of the update :math:`x \to x - \alpha y` that the collision
        filters allow (every contact node keeps part of its distance; collective)."""
        assert self._contact is not None
        fraction = min((f.step_fraction(x, y) for f in self._contact.step_filters), default=1.0)
        tally.cutbacks += int(fraction < 1.0)
        return fraction

    def _newton(self, tally: _Tally, r: float, tol: float) -> float:
        """Newton iterations from residual norm ``r`` until ``tol`` or the budget; the last residual norm."""
        u = self.problem.u
        cfg = self.config
        while tally.iterations < self.newton_budget and math.isfinite(r) and r > tol:
            self._refresh_tangent(tally)
            t0 = time.perf_counter()
            self.ksp.solve(self._b, self._du)
            tally.solve += time.perf_counter() - t0
            tally.linear += max(int(self.ksp.getIterationNumber()), 1)
            tally.failures += int(self.ksp.getConvergedReason() < 0)  # type: ignore[operator]  # petsc4py: an int
            step = 1.0 if self._contact is None else self._contact_fraction(u.x.petsc_vec, self._du, tally)
            u.x.petsc_vec.axpy(-step, self._du)
            u.x.scatter_forward()
            tally.iterations += 1
            assert self._tangent_age is not None  # _refresh_tangent assembled one
            self._tangent_age += 1
            t0 = time.perf_counter()
            r_new = self._assemble_residual()
            if not math.isfinite(r_new) and self._inversion is not None:
                r_new = self._uninvert(step, tally)
            tally.assembly += time.perf_counter() - t0
            if cfg.modified and r_new > cfg.refresh_ratio * r:
                self._stale = True
            r = r_new
        return r

    def _uninvert(self, step: float, tally: _Tally) -> float:
        """The update ``u -= step du`` gave a non-finite residual: take it again as far as the exact inversion filter
        allows (collective; "Inversion" in the module docstring). Returns the new residual norm."""
        assert self._inversion is not None
        x = self.problem.u.x.petsc_vec
        x.axpy(step, self._du)  # back to the state before the update
        self.problem.u.x.scatter_forward()
        fraction = min(step, self._inversion.step_fraction(x, self._du))
        x.axpy(-fraction, self._du)
        self.problem.u.x.scatter_forward()
        if fraction < step:
            tally.inversions += 1
            self._stale = True  # a tangent whose update inverts a cell: assemble a fresh one
        return self._assemble_residual()

    def _refresh_tangent(self, tally: _Tally) -> None:
        """Assemble the tangent if there is none yet, it is stale, or it is ``tangent_every`` iterations old."""
        age, every = self._tangent_age, self.config.tangent_every
        if age is None or self._stale or (every is not None and age >= every):
            t0 = time.perf_counter()
            self._assemble_tangent()
            tally.assembly += time.perf_counter() - t0
            self._tangent_age, self._stale = 0, False
            tally.tangents += 1

    def run(self, steps: int) -> list[RealtimeStep]:
        """Take ``steps`` steps of :math:`\\Delta t`; returns their records."""
        if not (isinstance(steps, int) and not isinstance(steps, bool) and steps >= 0):
            raise ParameterError(f"RealtimeStepper.run: steps must be an integer >= 0, got {steps!r}")
        return [self.step() for _ in range(steps)]

    def summary(self, skip: int = 0) -> RealtimeSummary:
        """Statistics of the steps taken (wall times: the slowest rank; collective).

        Args:
            skip: Leave out the first ``skip`` steps (e.g. the first, which
                sets up the preconditioner or factorisation).
        """
        steps = self.history[skip:]
        n = len(steps)
        times = np.array([[s.wall_time, s.assembly_time, s.solve_time, s.other_time] for s in steps]).reshape(n, 4)
        slowest = np.empty_like(times)
        self.comm.Allreduce(times, slowest, op=MPI.MAX)
        walls, parts = slowest[:, 0], slowest[:, 1:]
        total = float(walls.sum())
        rel = np.array([s.relative_residual for s in steps])
        mean = (lambda x: float(np.mean(x))) if n else (lambda x: float("nan"))
        return RealtimeSummary(
            steps=n,
            wall_time=total,
            steps_per_second=n / total if total > 0 else float("nan"),
            frame_time=self.dt,
            realtime_fraction=mean(walls <= self.dt),
            max_step_time=float(walls.max()) if n else float("nan"),
            mean_iterations=mean([s.iterations for s in steps]),
            tangents=int(sum(s.tangents for s in steps)),
            linear_iterations=mean([s.linear_iterations for s in steps]),
            linear_failures=int(sum(s.linear_failures for s in steps)),
            unconverged=int(sum(not s.converged for s in steps)),
            relative_residual_mean=mean(rel),
            relative_residual_median=float(np.median(rel)) if n else float("nan"),
            relative_residual_max=float(rel.max()) if n else float("nan"),
            residual_max=float(max(s.residual_norm for s in steps)) if n else float("nan"),
            assembly_time=mean(parts[:, 0]),
            solve_time=mean(parts[:, 1]),
            other_time=mean(parts[:, 2]),
        )
