r"""One linear-solver configuration for every solve in hyperfem, chosen from the problem.

Newton's tangent solves (through SNES), the boundary-increment predictor, the
initial acceleration of a dynamic run, fibre projections and the Laplace fibre
rule all get their KSP from here: the options, a unique options prefix
(:func:`unique_prefix`; nothing is left in PETSc's global options database),
and an optional near-nullspace hook.

:func:`choose_linear_solver` picks the method (any PETSc option given to the
solver overrides it):

* below :data:`DIRECT_THRESHOLD` unknowns (:data:`MIXED_DIRECT_THRESHOLD`
  for the mixed (u, p, θ) problem): sparse LU with MUMPS (:data:`DIRECT`);
* above it, for a displacement problem: AMG-preconditioned Krylov —
  :data:`SYMMETRIC_ITERATIVE` (CG + GAMG) when the tangent is symmetric
  (every load derives from Π: the Hessian of a potential, plus a mass term in
  dynamics), :data:`NONSYMMETRIC_ITERATIVE` (GMRES + GAMG) with follower loads.
  GAMG gets the rigid-body modes of the displacement space as its
  near-nullspace (6 in 3D, 3 in 2D; :func:`rigid_body_modes`), so its coarse
  spaces represent the motions the tangent barely resists. On a tangent of
  degree 2 and up CG (GMRES with follower loads) is preconditioned by the
  two-level p-multigrid of :mod:`hyperfem.solver.pmultigrid` instead
  (:data:`~hyperfem.solver.pmultigrid.P_MULTIGRID`: the P\ :sub:`k` tangent
  smoothed, that GAMG on its Galerkin P1 operator);
* above it, for the mixed problem: FGMRES with a Schur-complement
  field split (:data:`MIXED_ITERATIVE`): the displacement block by one
  V-cycle of a two-level p-multigrid (P2 smoothed, GAMG with the rigid-body
  modes on the Galerkin P1 operator; :mod:`hyperfem.solver.pmultigrid`), the
  :math:`(p, \theta)` block by LU of its Schur approximation — the tangent's
  own :math:`(p,\theta)` block with the pressure mass matrix over the shear
  modulus in place of :math:`-BK_{uu}^{-1}B^T` (see
  :meth:`~hyperfem.problem.MixedHyperelasticProblem.schur_preconditioner_term`,
  a constant matrix added to a copy of the tangent: the SNES preconditioning
  matrix costs no second assembly). The mass-matrix
  approximation is spectrally equivalent uniformly in the mesh size and
  :math:`K/\mu`; the diagonal ``selfp`` approximation is not (840 Krylov
  iterations per solve measured at 20k unknowns).

Inexact Newton with the energy line search. The Krylov solve stops at a
fixed relative tolerance (``ksp_rtol`` :math:`10^{-6}`), not an
Eisenstat–Walker forcing term. For a symmetric positive definite tangent
:math:`K` every CG iterate :math:`d_k` (from :math:`d_0 = 0`) minimises the
quadratic model :math:`	frac12 d^TKd - r^Td` over a Krylov space that
contains :math:`r`, so :math:`r^Td_k \ge 	frac12 d_k^TKd_k > 0`: an inexact
direction is still a descent direction of :math:`\Pi`, and the backtracking
line search on :math:`\Pi` and the inversion pre-check work unchanged. With
a fixed forcing term Newton converges linearly with rate about
``ksp_rtol`` once in the quadratic regime, i.e. one or two iterations more
than exact Newton at the default tolerances, without the early over-solving
or the late under-solving that made Eisenstat–Walker stall the energy line
search (50 iterations without convergence in the prototype). Only the step
predicted to be the last one is solved tighter
(:class:`~hyperfem.solver.forcing.FinalStepForcing`), so that the Krylov error
does not cost a Newton iteration of its own.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc
from dolfinx import fem

from hyperfem.problem.protocol import MixedProblemProtocol, SolidProblem, TimeStepState
from hyperfem.solver.pmultigrid import P_MULTIGRID, P_MULTIGRID_U, PMultigridLevels

__all__ = [
    "DIRECT",
    "DIRECT_THRESHOLD",
    "HIGH_ORDER_DIRECT_THRESHOLDS",
    "HIGH_ORDER_LAG",
    "MIXED_DIRECT_THRESHOLD",
    "MIXED_ITERATIVE",
    "NONSYMMETRIC_ITERATIVE",
    "SYMMETRIC_ITERATIVE",
    "AIJPreconditioner",
    "BLOCKED_TANGENT",
    "LinearSolver",
    "ShiftedPreconditioner",
    "choose_linear_solver",
    "describe",
    "direct_threshold",
    "pc_setup_seconds",
    "rigid_body_modes",
    "unique_prefix",
]

DIRECT: dict[str, object] = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
"""Sparse direct solve with MUMPS (both install routes ship it)."""

_AMG: dict[str, object] = {
    "pc_type": "gamg",
    "mg_levels_ksp_type": "chebyshev",
    "mg_levels_pc_type": "jacobi",
    "pc_gamg_reuse_interpolation": True,
    "pc_gamg_threshold": 0.02,
    "snes_lag_preconditioner": 10,
    "ksp_rtol": 1e-6,
    "ksp_atol": 1e-30,
    "ksp_max_it": 1000,
}

SYMMETRIC_ITERATIVE: dict[str, object] = {"ksp_type": "cg", **_AMG}
"""CG + smoothed-aggregation AMG (rigid-body near-nullspace) for symmetric tangents.

Two settings beyond the textbook set-up (CG, GAMG, rigid-body modes, reused
interpolation, ``ksp_rtol 1e-6``), measured on the bend (P1, full load in
one Newton solve, this 2-core machine, best of 2, interleaved; issue 20):

* ``pc_gamg_threshold 0.02`` drops weak couplings from the aggregation
  graph: 97 → 68 CG iterations at 28.6k unknowns, 100 → 55 at 92k;
* ``snes_lag_preconditioner 10``: the hierarchy is built at the first
  Newton iteration of a solve and reused (the Galerkin products are the
  dominant set-up cost), rebuilt early only where a Krylov solve takes more
  than twice the iterations of the first one with it, plus 5
  (:class:`~hyperfem.solver.lag.PreconditionerLag`). The first tangent's
  hierarchy preconditions the later ones nearly as well: on the bend at
  28.6k unknowns 11, 14, 15, 18, 16 CG iterations against 11, 13, 14, 17, 14
  rebuilt at every tangent.

With a lag of 2 (until stop 39): 3.76 → 2.67 s at 28.6k, 13.0 → 10.2 s at
92k against the textbook set-up, serially. Lag 10 against lag 2, bend and
twist, P1, 28.6k and 92k, 1 and 2 ranks (``benchmarks/scale.py --petsc
snes_lag_preconditioner=2``, three interleaved runs each,
``results/issue20_lag_s39.jsonl``): 7–20 % faster in every row (medians), the same
Newton iterations, 3–6 more CG iterations per solve, the test point to
1.5e-13; e.g. bend 28.6k on 2 ranks 0.60–0.70 against 0.72–0.77 s, 92k
serially 3.81–3.90 against 4.28–4.46 s. (Before the final-step forcing of
:mod:`~hyperfem.solver.forcing`, a lag of 5 had cost a Newton iteration at
92k.)"""

NONSYMMETRIC_ITERATIVE: dict[str, object] = {"ksp_type": "gmres", "ksp_gmres_restart": 100, **_AMG}
"""GMRES + AMG for the non-symmetric tangents of follower loads."""

MIXED_ITERATIVE: dict[str, object] = {
    "ksp_type": "fgmres",
    "ksp_gmres_restart": 200,
    "ksp_rtol": 1e-6,
    "ksp_atol": 1e-30,
    "ksp_max_it": 2000,
    "pc_type": "fieldsplit",
    "pc_fieldsplit_type": "schur",
    "pc_fieldsplit_schur_fact_type": "upper",
    "pc_fieldsplit_schur_precondition": "a11",
    **P_MULTIGRID_U,
    "fieldsplit_p_ksp_type": "preonly",
    "fieldsplit_p_pc_type": "lu",
    "fieldsplit_p_pc_factor_mat_solver_type": "mumps",
    "snes_lag_preconditioner": 3,
}
"""Schur field split for the mixed (u, p, θ) tangent (splits ``u`` and ``p``; see the module docstring).

The displacement block is preconditioned by the two-level p-multigrid of
:mod:`hyperfem.solver.pmultigrid` (:data:`~hyperfem.solver.pmultigrid.P_MULTIGRID_U`;
GAMG on the P2 block itself, :data:`~hyperfem.solver.pmultigrid.GAMG_U`, was
the choice before: 1.5× the time at 100k unknowns, 1.8× at 962k on 2 ranks).

The preconditioner is rebuilt at the first Newton iteration of every solve
and then every third (``snes_lag_preconditioner 3``). Measured with GAMG on
the P2 block (mixed bend, 31k unknowns, serial, ``PETSC_OPTIONS=-log_view``):
lag 1: 5 set-ups, 184 Krylov iterations; lag 3: 2 set-ups, 192 iterations;
GAMG set-up time down by 60 %. With the p-multigrid the set-up is cheap and
the lag matters less: at 100k unknowns on 2 ranks lag 1 took 13.6–16.3 s
(207 Krylov iterations), lag 3 11.2–14.7 s (209;
``results/issue20_pmg_rigid_s34.jsonl``).

With mesh contact (two bodies pressed together, ``SurfaceContact``) the
Krylov count rises, and it is the displacement block's preconditioner, not
the Schur approximation: on the stacked blocks of
``tests/test_contact_surfaces.py`` (h = 1.0 / 0.6, 1,000 unknowns, pushed
0.2 in 4 steps, serial) the split took about 4,850 Krylov iterations in 35 Newton
iterations, with LU on the ``u`` block about 790 (20 per Newton iteration,
contact or not). One Chebyshev step with point-block Jacobi does not smooth
what the barrier couples across the interface stiffly (two surface nodes
moving together: a small eigenvalue of :math:`D^{-1}K_{uu}` that the P1 level
cannot represent). SOR smoothing (``fieldsplit_u_mg_levels_pc_type sor``)
gave 1,719, ILU 1,516, three V-cycles 2,770, and an exact solve on the
contact surface's dofs around the V-cycle 2,104. In time: at 7.2k unknowns
70 s (default, two solves at the 2,000-iteration limit) against 35 s (SOR),
28 s (the surface solve) and 16 s (LU of the whole tangent); at 19.4k 125 s
against 145 s (SOR), 139 s (surface solve) and 166 s (LU): there the
Newton iterations (52–116 for 4 steps, most of them in the step of first
contact, where the barrier's tangent switches between exact and projected)
cost more than the Krylov ones. The defaults are kept."""

HIGH_ORDER_LAG = 5
"""``snes_lag_preconditioner`` of the iterative path for displacement degree 2 and higher (P1: 10).

The AMG set-up of a P2 tangent (its Galerkin products) costs 1.5 s at 92k
unknowns against 0.2–0.4 s of Krylov iterations per Newton iteration, and a
hierarchy built at the first iteration of a solve preconditions the later
ones nearly as well: measured (``benchmarks/scale.py --petsc
snes_lag_preconditioner=N``, 92k unknowns, quiet 2-core machine, two runs
each): bend serial 13.3–13.8 s with lag 2 vs 11.0–12.2 s with 5 (94 vs 97 CG
iterations), twist 15.8–16.1 vs 13.8–14.6 s, bend on 2 ranks 6.4–6.7 vs
5.7–6.2 s, same Newton iterations and test point. (On P1 a lag of 5 then
cost a Newton iteration, bend 92k: 4 → 5; since the final-step forcing it
does not, and P1 takes 10, :data:`SYMMETRIC_ITERATIVE`.) The early rebuild
of :class:`~hyperfem.solver.lag.PreconditionerLag` applies here too.

Measured again on the p-multigrid, whose set-up is cheap (0.1–0.6 s per
solve): lag 1 against 5, serial, beam meshes, two interleaved runs — bend P2
30.8k 1.74–1.75 vs 2.01–2.03 s and P4 35.8k 8.02–8.03 vs 9.49–10.48 s (4
Newton iterations against 5), P3 16k 1.41–1.46 vs 1.31–1.41 s, twist P2
30.8k 2.99–3.04 vs 2.58–2.76 s, twist P3 45k 7.36–7.56 vs 6.76–7.28 s; on 2
ranks the bend P2 (``benchmarks/scale.py --petsc snes_lag_preconditioner=1``)
1.02–1.03 vs 0.87–0.96 s at 28.6k and 3.24–3.57 vs 3.15 s at 92k (4 Newton
iterations either way). The lag stays 5."""

DIRECT_THRESHOLD = 10_000
"""Unknowns from which a displacement problem is solved iteratively.

Measured (``benchmarks/scale.py --variants hyperfem-iterative hyperfem-direct``,
bend, P1, this 2-core machine, serial): CG + GAMG vs MUMPS 0.42 / 0.46 s at
4.1k unknowns, 0.83 / 1.01 s at 7.6k, 1.32 / 2.33 s at 12.7k, 2.8-3.9 / 7.7 s
at 28.6k. Below 10^4 LU is as fast and more robust (indefinite tangents do
not stop it), so small problems keep it.

On 2 ranks LU is relatively slower (MUMPS's parallel set-up), but the
times are small: 0.29–0.31 / 0.17–0.18 s at 4.1k, 0.61–0.62 / 0.29 s at
7.6k, 1.25–1.38 / 0.45–0.47 s at 12.7k, 2.28–2.37 / 0.70–0.71 s at 19.6k
(MUMPS / CG + GAMG, quiet machine, ``results/issue20_thresholds_2ranks_s31.jsonl``).
The threshold does not depend on the number of ranks, so a problem takes the
same path on any number of them."""

HIGH_ORDER_DIRECT_THRESHOLDS: dict[int, int] = {3: 10_000, 4: 20_000, 5: 150_000}
r"""Unknowns from which a displacement problem of degree 3, 4, and 5 and higher is solved iteratively.

On degree 2 and up the iterative path is the two-level p-multigrid
(:mod:`hyperfem.solver.pmultigrid`): P3 and P4 need 90–180 CG iterations per
solve there, P5 270–295, each on a tangent with 450–1,500 nonzeros per row,
while the LU factorisation grows less than that. Measured with
``benchmarks/linear_degree.py`` (bend, full load in one Newton solve after
JIT, serial, quiet 2-core machine, both paths forced through the threshold,
two interleaved runs; ``results/linear_degree_thresholds_s36.jsonl``):

=====  ========  ======================  ============
degree unknowns  CG + p-multigrid        MUMPS
=====  ========  ======================  ============
P3     9.2k      0.75 / 0.75 s (96 CG)   1.27 / 1.28 s
P3     16.1k     1.45 / 1.36 s (89)      2.51 / 2.38 s
P4     20.4k     4.50 / 4.25 s (158)     5.57 / 5.49 s
P4     35.8k     8.93 / 9.48 s (174)     10.7 / 12.0 s
P4     67.3k     18.4 / 19.1 / 17.9 s    24.5 / 24.6 / 24.5 s
P5     38.2k     22.7 / 23.1 s (295)     22.4 / 20.6 s
P5     67.4k     39.0 / 41.0 s (270)     36.3 / 37.9 s
=====  ========  ======================  ============

MUMPS took 4 Newton iterations, the p-multigrid 4 (P3, P4 at 20k) or 5.
P3 is faster iteratively from below 10k, so it shares
:data:`DIRECT_THRESHOLD`; P4 from 20k (the smallest P4 size measured, already
faster); P5 stays on LU beyond the sizes
measured, and its 150k is a guess that keeps the LU's memory (about 5 GB)
inside a laptop. The follower twist (GMRES) agrees: P3 at 45k 7.1–9.4 s
against MUMPS's 17.9–19.8 s (:mod:`hyperfem.solver.pmultigrid`).
With GAMG on the P\ :sub:`k` tangent (the path before the p-multigrid,
``results/linear_degree_s32.jsonl``) the crossovers lay near 16k (P3) and
between 36k and 67k (P4), and the thresholds were 20k and 50k. On 2 ranks
(``results/linear_degree_2ranks_s32.jsonl``, GAMG) they lay lower, as for
P1. The thresholds do not depend on the number of ranks (a problem takes the
same path on any number of them; see :data:`DIRECT_THRESHOLD`). A P5 bend
on ``beam_h1`` had gone from 39 s (MUMPS, before the iterative path) to
190 s with AMG on P5; it is on MUMPS."""


def direct_threshold(degree: int) -> int:
    """Unknowns from which a displacement problem of polynomial degree ``degree`` is solved iteratively.

    :data:`DIRECT_THRESHOLD` for P1 and P2, :data:`HIGH_ORDER_DIRECT_THRESHOLDS` above (P3's is the same).
    """
    if degree < 3:
        return DIRECT_THRESHOLD
    return HIGH_ORDER_DIRECT_THRESHOLDS[min(degree, max(HIGH_ORDER_DIRECT_THRESHOLDS))]


BLOCKED_TANGENT = "baij"
"""Matrix type of the tangent on the iterative displacement path (:attr:`LinearSolver.matrix_kind`).

A blocked matrix stores one column index per 3×3 (2×2) node block and
inserts whole blocks: measured (bend, P1, 28.6k unknowns, this 2-core
machine, serial): tangent assembly 0.11 s vs 0.20–0.22 s in AIJ, a product
0.73–0.98 ms vs 1.4–1.8 ms; on 2 ranks 0.067 s vs 0.12 s and 0.37 ms vs
1.24 ms. The AIJ copy AMG needs (:class:`AIJPreconditioner`) costs
0.025–0.035 s serial, 0.015–0.02 s on 2 ranks. Not used on the direct path:
MUMPS factorises BAIJ by LU only (no :math:`LDL^T`)."""

MIXED_DIRECT_THRESHOLD = 40_000
"""Unknowns from which the mixed problem is solved with :data:`MIXED_ITERATIVE`.

Measured (``benchmarks/scale.py --formulation mixed``, nearly incompressible
bend, P2/P1/P1, this 2-core machine, serial; ``results/scale_mixed.jsonl``):
field split vs MUMPS 19.0 / 15.3 s and 0.36 / 0.59 GB at 31k unknowns,
85 / 146 s and 0.93 / 2.34 GB at 100k. The time ratio crosses 1 near 44k.

On 2 ranks the field split is faster from the smallest size measured:
2.46 / 2.69–3.23 s at 14k, 3.63–3.99 / 4.79–5.30 s at 21k, 5.83–6.29 /
7.92–8.62 s at 31k (quiet machine, ``results/issue20_thresholds_2ranks_s31.jsonl``
and ``results/issue20_mixed_sweep_s31.jsonl``). The threshold is kept for
any number of ranks: the same path everywhere, and the LU's robustness on
hard steps below it."""

_counter = itertools.count()

_PC_SETUP_EVENTS: tuple | None = None


def pc_setup_seconds(comm: MPI.Comm | None = None) -> float:
    """Seconds this process has spent setting up preconditioners (factorisations, AMG hierarchies).

    The sum of PETSc's ``PCSetUp`` (factorisations, AMG of a plain KSP) and
    ``PCSetUpOnBlocks`` (the split preconditioners of a field split, set up
    outside ``PCSetUp``) events. PETSc only times events once its default log
    handler runs: the first call starts it (``PETSc.Log.begin()``, once per
    process, nothing else is changed), so take a reading before the work to
    be timed and subtract.

    Starting the handler is collective over ``PETSC_COMM_WORLD`` (it
    duplicates that communicator), so it is started only from a call on a
    communicator that spans it: the first solve on a sub-communicator (one
    rank of several running alone on ``COMM_SELF``) must not wait for the
    other ranks. Until a call on all ranks has started it, this returns 0.

    Args:
        comm: The communicator of the calling solve (collective over it);
            ``None``: the caller vouches that every rank of
            ``PETSC_COMM_WORLD`` calls.
    """
    global _PC_SETUP_EVENTS
    if _PC_SETUP_EVENTS is None:
        if comm is not None and MPI.Comm.Compare(comm, PETSc.COMM_WORLD.tompi4py()) not in (MPI.IDENT, MPI.CONGRUENT):
            return 0.0
        PETSc.Log.begin()
        _PC_SETUP_EVENTS = (PETSc.Log.Event("PCSetUp"), PETSc.Log.Event("PCSetUpOnBlocks"))
    return float(sum(event.getPerfInfo()["time"] for event in _PC_SETUP_EVENTS))


def describe(options: Mapping[str, object]) -> str:
    """Short name of a KSP/PC configuration, e.g. ``"preonly+lu(mumps)"``, ``"cg+gamg"`` or ``"cg+pmg"``."""
    ksp, pc = options.get("ksp_type", "?"), options.get("pc_type", "?")
    if pc == "python" and str(options.get("pc_python_type", "")).endswith("pmultigrid.TwoLevel"):
        pc = "pmg"
    factor = options.get("pc_factor_mat_solver_type") if pc in ("lu", "cholesky") else None
    return f"{ksp}+{pc}" + (f"({factor})" if factor else "")


def unique_prefix(kind: str) -> str:
    """A fresh PETSc options prefix ``hyperfem_<kind>_<n>_``."""
    return f"hyperfem_{kind}_{next(_counter)}_"


@dataclass(frozen=True)
class LinearSolver:
    """A linear-solver configuration.

    Attributes:
        options: PETSc KSP/PC options (keys without prefix).
        near_nullspace: Optional ``hook(A)`` called on every operator before
            the solver is set up (e.g. to attach rigid-body modes for AMG).
        preconditioner_shift: Optional state-independent UFL bilinear form
            :math:`S`: Newton's tangent solves are then preconditioned with
            :math:`K + S` instead of :math:`K` (assembled once; each
            preconditioning matrix is a copy of the tangent plus :math:`S`).
        configure: Optional ``hook(ksp)`` run once on the KSP after its
            options are set (e.g. to define the field-split index sets).
        matrix_kind: PETSc matrix type of Newton's tangent: ``None`` (AIJ,
            DOLFINx's default) or ``"baij"`` (blocked by the displacement's
            components: assembly and products about twice as fast; see
            :data:`BLOCKED_TANGENT`). AMG then builds its hierarchy from an
            AIJ copy (:class:`AIJPreconditioner`). Honoured by
            :class:`~hyperfem.solver.NewtonSolver` for a plain displacement
            problem without a preconditioner shift or external energies; AIJ
            otherwise.
    """

    options: Mapping[str, object] = field(default_factory=lambda: dict(DIRECT))
    near_nullspace: Callable[[PETSc.Mat], None] | None = None
    preconditioner_shift: ufl.Form | None = None
    configure: Callable[[PETSc.KSP], None] | None = None
    matrix_kind: str | None = None


    def ksp(self, comm: MPI.Comm, A: PETSc.Mat | None = None, kind: str = "linear") -> PETSc.KSP:
        """A KSP configured from :attr:`options` under a unique prefix (operators set if ``A`` is given).

        The options are pushed for ``setFromOptions`` and removed again.
        """
        prefix = unique_prefix(kind)
        ksp = PETSc.KSP().create(comm)  # type: ignore[arg-type]  # petsc4py accepts an mpi4py communicator
        ksp.setOptionsPrefix(prefix)
        opts = PETSc.Options()
        for key, value in self.options.items():
            opts[f"{prefix}{key}"] = value  # type: ignore[index]  # petsc4py stubs lack Options.__setitem__
        try:
            ksp.setFromOptions()
        finally:
            for key in self.options:
                opts.delValue(f"{prefix}{key}")
        if self.configure is not None:
            self.configure(ksp)
        if A is not None:
            self.set_operators(ksp, A)
        return ksp

    def set_operators(self, ksp: PETSc.KSP, A: PETSc.Mat, P: PETSc.Mat | None = None) -> None:
        """Set the operators of ``ksp``, applying the near-nullspace hook first."""
        if self.near_nullspace is not None:
            self.near_nullspace(A)
        ksp.setOperators(A, A if P is None else P)

    def solve(self, comm: MPI.Comm, A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, kind: str = "linear") -> int:
        """One solve ``A x = b`` with a throw-away KSP; returns the KSP converged reason."""
        ksp = self.ksp(comm, A, kind)
        try:
            ksp.solve(b, x)
            return int(ksp.getConvergedReason())  # type: ignore[call-overload]  # petsc4py stubs: an int
        finally:
            ksp.destroy()


class ShiftedPreconditioner:
    r"""The preconditioning matrix :math:`K + S` of a tangent :math:`K` and a constant shift :math:`S`.

    :math:`S` (:attr:`LinearSolver.preconditioner_shift`) is assembled into
    the tangent's sparsity (every cell block), so tangent, shift and
    preconditioning matrix share one pattern; each call copies the tangent
    and adds the shift (no second assembly).

    A tangent with entries outside the form's pattern (a contact Hessian,
    :meth:`~hyperfem.solver.external.ExternalTerms.add_tangent`) makes the
    next call assemble the shift again into the grown pattern and return a
    new :attr:`matrix`: a new object, so every preconditioner given it sets
    itself up anew. The same object grown in place is not safe: PETSc's
    ``MatAXPY`` with ``DIFFERENT_NONZERO_PATTERN`` (3.25) gives the grown
    matrix the nonzero state of a fresh one, the same after each growth, so
    a field split set up before the second growth reuses its sub-matrices
    and stops ("Cannot reuse matrix. wrong number of nonzeros"). The
    previous matrix is kept until the next call (the caller may still hold
    it).

    Args:
        A: The tangent matrix (its sparsity pattern).
        shift: The compiled bilinear form of :math:`S`.

    Attributes:
        matrix: The preconditioning matrix (updated by each call).
    """

    def __init__(self, A: PETSc.Mat, shift: fem.Form) -> None:
        self._form = shift
        self._previous: PETSc.Mat | None = None
        self._pattern_size = 0
        self._shift = self._assemble_shift(A)
        self.matrix = self._shift.duplicate(copy=True)

    def _assemble_shift(self, A: PETSc.Mat) -> PETSc.Mat:
        """:math:`S` assembled into a matrix of ``A``'s pattern."""
        import dolfinx.fem.petsc as fpetsc

        S = A.duplicate()
        fpetsc.assemble_matrix(S, self._form)  # type: ignore[arg-type]  # dolfinx: singledispatch (Mat, Form)
        S.assemble()
        self._pattern_size = _nonzeros(S)  # the tangent's pattern it was assembled into
        return S

    def __call__(self, A: PETSc.Mat) -> PETSc.Mat:
        """:attr:`matrix` set to a copy of the assembled tangent ``A`` plus the shift (class docstring)."""
        same = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
        self._previous = None
        if _nonzeros(A) != self._pattern_size:  # the tangent's pattern grew
            self._shift.destroy()
            self._shift = self._assemble_shift(A)
            self._previous, self.matrix = self.matrix, A.duplicate()
        P = self.matrix
        A.copy(P, structure=same)  # type: ignore[arg-type]  # petsc4py: int enums
        P.axpy(1.0, self._shift, structure=same)  # type: ignore[arg-type]  # petsc4py: int enums
        return P


def _nonzeros(A: PETSc.Mat) -> int:
    """The number of stored entries of ``A`` over all ranks (collective)."""
    return int(A.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"])  # type: ignore[arg-type]  # an int enum


class AIJPreconditioner:
    """The AIJ copy of a blocked (BAIJ) tangent, as the preconditioning matrix of AMG.

    GAMG builds its aggregation graph from AIJ matrices only
    (``MatCreateGraph`` has no BAIJ method), so the Krylov method multiplies
    by the blocked tangent and the hierarchy is built from this copy: an AIJ
    matrix with DOLFINx's pattern of the tangent form, allocated once, into
    which each call copies the values row by row (the local rows in CSR with
    global columns: the same on any number of ranks; ``MatConvert`` reusing
    its output is not, on several ranks it leaves a column map GAMG
    rejects). The tangent's near-nullspace is attached to the copy, where
    GAMG reads it.

    Args:
        jacobian: The compiled tangent form (the pattern of the copy).

    Attributes:
        matrix: The preconditioning matrix (updated by each call).
    """

    def __init__(self, jacobian: fem.Form) -> None:
        import dolfinx.fem.petsc as fpetsc

        self.matrix = fpetsc.create_matrix(jacobian)

    def __call__(self, A: PETSc.Mat) -> PETSc.Mat:
        """:attr:`matrix` set to the values of the assembled tangent ``A``."""
        P = self.matrix
        P.setValuesCSR(*A.getValuesCSR())  # type: ignore[arg-type]  # petsc4py takes the arrays it returns
        P.assemble()
        nullspace = A.getNearNullSpace()
        if nullspace:  # a null object is false
            P.setNearNullSpace(nullspace)
        return P


def _global_size(V: fem.FunctionSpace) -> int:
    imap = V.dofmap.index_map
    return int(imap.size_global * V.dofmap.index_map_bs)


def rigid_body_modes(V: fem.FunctionSpace, A: PETSc.Mat) -> list[PETSc.Vec]:
    """Orthonormal rigid-body modes of the blocked displacement space ``V`` as vectors of ``A``'s layout.

    Translations :math:`e_i` and rotations :math:`e_i \\times X` evaluated at the
    dof coordinates (6 in 3D, 3 in 2D), orthonormalised (modified Gram–Schmidt,
    collective).
    """
    from hyperfem.solver.constraints import rigid_modes

    bs = V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local
    x = V.tabulate_dof_coordinates()[:n_owned].T
    vectors: list[PETSc.Vec] = []
    for mode in rigid_modes(bs):
        vec = A.createVecRight()
        vec.array_w[:] = np.asarray(mode(x)).T.reshape(-1)
        for other in vectors:
            vec.axpy(-vec.dot(other), other)
        vec.scale(1.0 / vec.norm())  # type: ignore[operator]  # petsc4py: the 2-norm is a float
        vectors.append(vec)
    return vectors


def _near_nullspace_hook(V: fem.FunctionSpace) -> Callable[[PETSc.Mat], None]:
    def attach(A: PETSc.Mat) -> None:
        A.setNearNullSpace(PETSc.NullSpace().create(vectors=rigid_body_modes(V, A), comm=A.comm))

    return attach


def _owned_global(W: fem.FunctionSpace, local: np.ndarray) -> np.ndarray:
    """Global indices of the owned entries of the local dof indices ``local`` of the (unblocked) space ``W``."""
    imap = W.dofmap.index_map
    bs = W.dofmap.index_map_bs
    n_owned = imap.size_local * bs
    return local[local < n_owned] + imap.local_range[0] * bs


def _fieldsplit_configure(problem: SolidProblem, base: MixedProblemProtocol) -> Callable[[PETSc.KSP], None]:
    """Index sets of the ``u`` and ``p`` (pressure and volume) splits, rigid-body modes on ``u``, the P1 level.

    The ``u`` index set has the block size of the displacement (its owned
    dofs come in node triples on every rank), so the ``u`` block is a
    blocked matrix: its smoother inverts node blocks and GAMG (on it, or on
    the P1 level of :class:`~hyperfem.solver.pmultigrid.PMultigridLevels`,
    registered for the ``u`` block's options prefix) aggregates nodes, not scalar
    dofs. Measured with GAMG on the ``u`` block
    (``benchmarks/scale.py --formulation mixed --variants hyperfem-iterative``,
    quiet 2-core machine, 100k unknowns): 45.7 → 29.3 s serial, 21.1 →
    16.4 s on 2 ranks; the field split's set-up 15.4 → 3.2 s, 208 → 247
    Krylov iterations; at 31k 11.1 → 8.7 s.

    ``base`` is the three-field problem: ``problem`` itself, or the body of a time step ``problem``.
    """
    from hyperfem.solver.constraints import rigid_modes

    W = problem.u.function_space
    fields = base.field_dofs()
    comm = W.mesh.comm
    u_local = fields["displacement"]
    order = np.argsort(u_local)
    owned = u_local[order] < W.dofmap.index_map.size_local * W.dofmap.index_map_bs
    u_rows = order[owned]  # positions in the collapsed displacement space, sorted by W index
    u_global = _owned_global(W, u_local[u_rows])
    p_global = np.sort(_owned_global(W, np.concatenate([fields["pressure"], fields["volume"]])))
    gdim = W.mesh.geometry.dim
    V = base.displacement_space().collapse()[0]
    X = V.tabulate_dof_coordinates()[u_rows // gdim].T
    component = u_rows % gdim
    # The owned displacement dofs in node triples (x, y, z at consecutive indices) on every rank: then the
    # u block is a blocked matrix (the block size of its index set) and GAMG aggregates nodes, not scalar dofs.
    triples = len(u_global) % gdim == 0 and bool(
        np.all(component == np.arange(len(component)) % gdim)
        and np.all(np.diff(u_global.reshape(-1, gdim), axis=1) == 1)
    )
    nodal = bool(comm.allreduce(triples, op=MPI.LAND))
    multigrid = PMultigridLevels(V, u_rows, nodal)

    def configure(ksp: PETSc.KSP) -> None:
        pc = ksp.getPC()
        if pc.getType() != PETSc.PC.Type.FIELDSPLIT:
            return  # options overrode the split (e.g. pc_type lu)
        is_u = PETSc.IS().createGeneral(u_global.astype(PETSc.IntType), comm=comm)  # type: ignore[arg-type]  # arrays
        is_p = PETSc.IS().createGeneral(p_global.astype(PETSc.IntType), comm=comm)  # type: ignore[arg-type]  # arrays
        vectors: list[PETSc.Vec] = []
        for mode in rigid_modes(gdim):
            vec = PETSc.Vec().createMPI((len(u_global), PETSc.DETERMINE), comm=comm)
            vec.array_w[:] = np.asarray(mode(X))[component, np.arange(len(component))]
            for other in vectors:
                vec.axpy(-vec.dot(other), other)
            vec.scale(1.0 / vec.norm())  # type: ignore[operator]  # petsc4py: the 2-norm is a float
            vectors.append(vec)
        if nodal:
            is_u.setBlockSize(gdim)
        is_u.compose("nearnullspace", PETSc.NullSpace().create(vectors=vectors, comm=comm))
        pc.setFieldSplitIS(("u", is_u), ("p", is_p))
        multigrid.register(f"{ksp.getOptionsPrefix() or ''}fieldsplit_u_")

    return configure


def choose_linear_solver(
    problem: SolidProblem, threshold: int | None = None, mixed_threshold: int = MIXED_DIRECT_THRESHOLD
) -> LinearSolver:
    """The linear solver for ``problem`` (see the module docstring for the rule).

    Args:
        problem: A :class:`~hyperfem.problem.protocol.SolidProblem`.
        threshold: Unknowns from which a displacement problem is solved iteratively
            (the default rises with the degree from P4: :data:`HIGH_ORDER_DIRECT_THRESHOLDS`).
        mixed_threshold: Unknowns from which the mixed problem is solved iteratively.
    """
    W = problem.u.function_space
    V = problem.displacement_space()
    base = problem.base if isinstance(problem, TimeStepState) else problem
    if V is not W:
        if _global_size(W) < mixed_threshold or not isinstance(base, MixedProblemProtocol):
            return LinearSolver()
        return LinearSolver(
            dict(MIXED_ITERATIVE),
            preconditioner_shift=base.schur_preconditioner_term(),
            configure=_fieldsplit_configure(problem, base),
        )
    degree = V.ufl_element().embedded_superdegree
    if threshold is None:  # by degree: P4 and up keep LU longer (their tangents are dense)
        threshold = direct_threshold(degree)
    if _global_size(W) < threshold:
        return LinearSolver()
    options = dict(SYMMETRIC_ITERATIVE if problem.conservative else NONSYMMETRIC_ITERATIVE)
    configure = None
    if degree >= 2:
        options["snes_lag_preconditioner"] = HIGH_ORDER_LAG
        # The p-multigrid, under CG or (follower loads) GMRES.
        options = {k: v for k, v in options.items() if not k.startswith(("pc_", "mg_"))} | P_MULTIGRID
        configure = _p_multigrid_configure(V)
    return LinearSolver(
        options, near_nullspace=_near_nullspace_hook(V), configure=configure, matrix_kind=BLOCKED_TANGENT
    )


def _p_multigrid_configure(V: fem.FunctionSpace) -> Callable[[PETSc.KSP], None]:
    """Register the P1 level of the displacement space ``V`` for the two-level p-multigrid of a KSP."""
    levels = PMultigridLevels(V)

    def configure(ksp: PETSc.KSP) -> None:
        levels.register(ksp.getOptionsPrefix() or "")

    return configure
