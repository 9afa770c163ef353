r"""Two-level p-multigrid for the displacement block of the mixed field split.

The displacement block :math:`K_{uu}` of the mixed (u, p, θ) tangent lives in
a P2 (or higher) space. Smoothed-aggregation AMG on it directly aggregates a
graph with 81 or more nonzeros per row and smooths every level it builds on
that stencil. Here the block is preconditioned by one V-cycle of a two-level
method instead:

* the **fine level** is the P\ :sub:`k` block itself, smoothed by one
  Chebyshev step with point-block Jacobi (3×3 node blocks);
* the **coarse level** is the P1 displacement space on the same mesh, reached
  through the interpolation :math:`\Pi` from P1 to P\ :sub:`k`
  (:func:`dolfinx.fem.petsc.interpolation_matrix`, its rows put into the
  split's ordering of the displacement dofs), with the Galerkin operator
  :math:`\Pi^T K_{uu} \Pi` (``MatPtAP``): what the P1 elements would
  assemble for a linear tangent, without a second form;
* the coarse operator gets one GAMG V-cycle, with the rigid-body modes of
  the P1 node coordinates as its near-nullspace.

The cycle is a PETSc ``python`` preconditioner, :class:`TwoLevel`, which
PETSc creates from the options (``pc_python_type``) when it creates the
field split's sub-solvers, inside the first Krylov solve. It finds its
levels (:class:`PMultigridLevels`, registered under its options prefix by
the solver's ``configure`` hook) by that prefix. Its set-up runs where
PETSc sets up a preconditioner, so ``snes_lag_preconditioner`` and a
rebuild after a failed solve apply to it as to any other. (A first version
handed an interpolation to PETSc's ``PCMG`` from the KSP's pre-solve hook:
the coarse solver was still PCMG's default LU there, so the coordinates
never reached GAMG, and it depended on when PETSc calls that hook.)

Measured (the mixed bend of ``benchmarks/scale.py --formulation mixed
--variants hyperfem-iterative hyperfem-gamg-u``, P2/P1/P1, full load in one
Newton solve, quiet 2-core machine, interleaved; the same 5 Newton
iterations and the same test point, to 1e-15 at 962k;
``results/issue20_pmg_rigid_s34.jsonl``, memory the peak resident set of
all ranks):

=================  ===============================  ===============================
case               GAMG on the P2 block             p-multigrid
=================  ===============================  ===============================
100k, serial       30.7 s (247 Krylov), 0.85 GB     18.1–20.8 s (207), 0.80 GB
100k, 2 ranks      16.4–16.8 s (247), 1.22 GB       10.7–11.5 s (209), 1.04 GB
962k, 2 ranks      250 s (285), 10.5 GB             137 s (210), 8.3 GB
=================  ===============================  ===============================

At 962k the block's set-up takes 13.8 s instead of 30.5 s and the Krylov
solve 71 s instead of 159 s. The rigid-body rotations on the coarse level
matter: the first version, whose coarse GAMG had the translations only
(``results/issue20_pmg_s34.jsonl``), took 192 s and 336 Krylov iterations
at 962k. With two Chebyshev steps on the fine level the Krylov count drops
but each costs more (31–33 s against 29–31 s serially at 100k, first
version); SOR smoothing 64 s.

The displacement problem of degree 2 and up takes the same two levels on its
whole tangent (:data:`P_MULTIGRID`, CG). Against GAMG on the P\ :sub:`k`
tangent (``benchmarks/linear_degree.py --variants iterative gamg direct``,
bend, serial, quiet machine, ``results/linear_degree_pmg_s35.jsonl``;
MUMPS in brackets): P2 30.8k 2.60 / 3.01 s, 86.8k 6.79 / 8.15 s; P3 16k
1.84 / 3.15 s (2.75 s); P4 35.8k 13.9 / 13.1 s (13.0 s; 5 Newton iterations
against 4); P5 67k 47.8 / 58.7 s (41.0 s). Follower loads take it under
GMRES: the twist (``--load twist``, serial, p-multigrid / GAMG / MUMPS, two
interleaved runs, ``results/linear_degree_twist_pmg_s36.jsonl``): P2 30.8k
3.01–3.76 / 4.16–4.32 / 8.3–8.5 s (85 / 125 GMRES iterations), 86.8k
7.58–8.86 / 11.3–13.6 / 48–52 s (79 / 116), P3 45k 7.12–9.37 / 11.1–12.3 /
17.9–19.8 s (133 / 197), the same 6 Newton iterations; on 2 ranks against the
hand-tuned GMRES + GAMG (``benchmarks/scale.py --case twist --degree 2``,
``results/issue20_twist_p2_pmg_s36.jsonl``) 1.50–2.30 / 3.18–4.38 s at 28.6k
and 5.17–5.97 / 13.5–14.7 s at 92k, the test point equal to 3e-14.
"""

from __future__ import annotations

import weakref

import numpy as np
from petsc4py import PETSc
from dolfinx import fem

from hyperfem.errors import ParameterError

__all__ = ["GAMG_U", "P_MULTIGRID", "P_MULTIGRID_U", "PMultigridLevels", "TwoLevel", "p_multigrid_options"]


def p_multigrid_options(prefix: str = "") -> dict[str, object]:
    """The options of the two-level p-multigrid (module docstring) of the preconditioner under ``prefix``."""
    own: dict[str, object] = {
        "pc_type": "python",
        "pc_python_type": f"{__name__}.TwoLevel",
        "mg_levels_ksp_type": "chebyshev",
        "mg_levels_ksp_max_it": 1,
        "mg_levels_ksp_chebyshev_esteig": "0,0.1,0,1.1",
        "mg_levels_ksp_norm_type": "none",
        "mg_levels_pc_type": "pbjacobi",
        "mg_coarse_ksp_type": "preonly",
        "mg_coarse_pc_type": "gamg",
        "mg_coarse_pc_gamg_threshold": 0.02,
        "mg_coarse_pc_gamg_reuse_interpolation": True,
        "mg_coarse_mg_levels_ksp_type": "chebyshev",
        "mg_coarse_mg_levels_pc_type": "jacobi",
    }
    return {prefix + key: value for key, value in own.items()}


P_MULTIGRID_U: dict[str, object] = {"fieldsplit_u_ksp_type": "preonly", **p_multigrid_options("fieldsplit_u_")}
"""The field split's displacement-block options of the two-level p-multigrid (module docstring)."""

P_MULTIGRID: dict[str, object] = p_multigrid_options()
"""The two-level p-multigrid as the preconditioner of the whole tangent (the displacement problem of degree ≥ 2).

Measured against CG + GAMG on the P2 tangent (``benchmarks/linear_degree.py
--variants iterative gamg``, bend, full load in one Newton solve, serial,
quiet machine, ``results/linear_degree_pmg_s35.jsonl``): 2.60 s against
3.01 s at 30.8k unknowns, 6.79 against 8.15 s at 86.8k, although Newton
took 5 iterations against 4. Stopping CG on the true residual
(``ksp_norm_type unpreconditioned``) gave 4 Newton iterations and 1.78 s
against 2.48–2.55 s, 6.3–6.4 against 8.5–9.9 s, but on 2 ranks the P2 bend
at a load increment of 1e-4 (``tests/test_linear_paths.py``) then stalled at
|r|/|r0| = 1.5e-3 and was cut back three times; CG's own (preconditioned)
norm converges there in one step, as LU does."""

GAMG_U: dict[str, object] = {
    "fieldsplit_u_ksp_type": "preonly",
    "fieldsplit_u_pc_type": "gamg",
    "fieldsplit_u_pc_gamg_threshold": 0.02,
    "fieldsplit_u_mg_levels_ksp_type": "chebyshev",
    "fieldsplit_u_mg_levels_pc_type": "jacobi",
    "fieldsplit_u_pc_gamg_reuse_interpolation": True,
}
"""The displacement block by GAMG on the P2 (P\\ :sub:`k`) block itself: the field split before the p-multigrid.

Kept for comparison (``benchmarks/scale.py --formulation mixed --variants
hyperfem-iterative hyperfem-gamg-u``) and for users who want it back
(``petsc_options=GAMG_U``: the rigid-body modes come with the split's index set)."""

_REGISTRY: weakref.WeakValueDictionary[str, PMultigridLevels] = weakref.WeakValueDictionary()
"""The levels of each preconditioner, by its options prefix (alive as long as the solver that registered them)."""


class PMultigridLevels:
    """The P1 level of a P\\ :sub:`k` displacement block: the interpolation and the P1 node coordinates.

    Args:
        space: The displacement space (P\\ :sub:`k`, blocked; collapsed from a mixed space).
        rows: Positions, in ``space``'s local (unrolled) dof array, of the
            owned dofs of the preconditioned block, in that block's order
            (``None``: the space itself, in its own order).
        nodal: Whether those dofs come in node triples (pairs in 2D) on every
            rank, so the interpolation's rows are node blocks.

    Built at the first set-up that needs them.
    """

    def __init__(self, space: fem.FunctionSpace, rows: np.ndarray | None = None, nodal: bool = True) -> None:
        self._space = space
        if rows is None:
            rows = np.arange(space.dofmap.index_map.size_local * space.dofmap.index_map_bs)
        self._rows = rows
        self._nodal = nodal
        self._levels: tuple[PETSc.Mat, np.ndarray] | None = None

    def register(self, prefix: str) -> None:
        """Make these the levels of the :class:`TwoLevel` preconditioner under the options prefix ``prefix``."""
        _REGISTRY[prefix] = self

    def coarse_level(self) -> tuple[PETSc.Mat, np.ndarray]:
        """The interpolation from P1 (rows in the block's order) and the P1 node coordinates owned here."""
        import dolfinx.fem.petsc as fpetsc

        if self._levels is None:
            fine = self._space
            mesh = fine.mesh
            gdim = mesh.geometry.dim
            coarse = fem.functionspace(mesh, ("Lagrange", 1, (gdim,)))
            full = fpetsc.interpolation_matrix(coarse, fine)
            full.assemble()
            comm = mesh.comm
            fine_map, coarse_map = fine.dofmap.index_map, coarse.dofmap.index_map
            rows = fine_map.local_range[0] * gdim + self._rows
            cols = np.arange(coarse_map.local_range[0] * gdim, coarse_map.local_range[1] * gdim)
            P = full.createSubMatrix(
                PETSc.IS().createGeneral(rows.astype(PETSc.IntType), comm=comm),
                PETSc.IS().createGeneral(cols.astype(PETSc.IntType), comm=comm),  # type: ignore[arg-type]
            )
            full.destroy()
            P.setBlockSizes(gdim if self._nodal else 1, gdim)
            X = coarse.tabulate_dof_coordinates()[: coarse_map.size_local, :gdim]
            self._levels = (P, np.ascontiguousarray(X))
        return self._levels


class TwoLevel:
    """A petsc4py ``python`` preconditioner context: one V(1, 1)-cycle of the two-level p-multigrid.

    PETSc creates it (``pc_python_type``); its levels are the
    :class:`PMultigridLevels` registered under its options prefix. Its
    smoother (``<prefix>mg_levels_``) and coarse solver (``<prefix>mg_coarse_``)
    are KSPs configured from the options.
    """

    def __init__(self) -> None:
        self._P: PETSc.Mat | None = None
        self._coarse_matrix: PETSc.Mat | None = None
        self._smoother: PETSc.KSP | None = None
        self._coarse: PETSc.KSP | None = None
        self._work: tuple[PETSc.Vec, PETSc.Vec, PETSc.Vec] | None = None
        self._modes: PETSc.NullSpace | None = None
        self._nonzeros = -1.0

    def setUp(self, pc: PETSc.PC) -> None:
        """Galerkin P1 operator of the current block; smoother and coarse solver set up on it.

        The product is redone from scratch (symbolically) when the block's
        nonzero count changed (contact pairs add entries), else only numerically.
        """
        A, B = pc.getOperators()
        nonzeros = B.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"]  # type: ignore[arg-type]  # an int enum
        if self._P is None:
            prefix = pc.getOptionsPrefix() or ""
            levels = _REGISTRY.get(prefix)
            if levels is None:
                raise ParameterError(
                    f"p-multigrid: no levels registered for the options prefix {prefix!r} "
                    "(pc_python_type TwoLevel needs PMultigridLevels(...).register(prefix) first)"
                )
            self._P, X = levels.coarse_level()
            coordinates = self._P.createVecRight()
            coordinates.array_w[:] = X.reshape(-1)
            # The rigid-body modes from the P1 node coordinates, on every coarse operator (GAMG reads them there).
            self._modes = PETSc.NullSpace().createRigidBody(coordinates)
            coordinates.destroy()
            self._coarse = _ksp(pc.getComm(), prefix + "mg_coarse_")
            self._smoother = _ksp(pc.getComm(), prefix + "mg_levels_")
            self._work = (A.createVecLeft(), self._P.createVecRight(), self._P.createVecRight())
        assert self._coarse is not None and self._smoother is not None and self._modes is not None
        if self._coarse_matrix is None or nonzeros != self._nonzeros:
            if self._coarse_matrix is not None:
                self._coarse_matrix.destroy()
            self._coarse_matrix = B.ptap(self._P)
            self._coarse_matrix.setNearNullSpace(self._modes)
        else:
            B.ptap(self._P, result=self._coarse_matrix)
        self._nonzeros = nonzeros
        self._coarse.setOperators(self._coarse_matrix, self._coarse_matrix)
        self._smoother.setOperators(A, B)
        self._coarse.setUp()
        self._smoother.setUp()

    def apply(self, pc: PETSc.PC, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """``y``: pre-smoothing from zero, the coarse correction, post-smoothing."""
        assert self._smoother is not None and self._coarse is not None and self._work is not None
        assert self._P is not None
        smoother, P = self._smoother, self._P
        r, rc, yc = self._work
        A = smoother.getOperators()[0]
        smoother.setInitialGuessNonzero(False)
        smoother.solve(x, y)
        A.mult(y, r)
        r.aypx(-1.0, x)  # r = x - A y
        P.multTranspose(r, rc)
        self._coarse.solve(rc, yc)
        P.multAdd(yc, y, y)
        smoother.setInitialGuessNonzero(True)
        smoother.solve(x, y)

    def destroy(self, pc: PETSc.PC) -> None:
        """Free the PETSc objects of this cycle collectively, where PETSc destroys the preconditioner.

        Left to Python's garbage collector they reached PETSc's garbage list and a later
        ``PETSc.garbage_cleanup`` of 2 ranks could block there. The interpolation belongs to the levels.
        """
        for obj in (self._coarse_matrix, self._smoother, self._coarse, self._modes, *(self._work or ())):
            if obj is not None:
                obj.destroy()
        self._coarse_matrix = self._smoother = self._coarse = self._modes = None
        self._work = None
        self._P = None

    def view(self, pc: PETSc.PC, viewer: PETSc.Viewer | None = None) -> None:
        """What ``-ksp_view`` prints: the levels' sizes and the coarse solver."""
        if self._P is None or viewer is None:
            return
        viewer.printfASCII(f"two-level p-multigrid: fine {self._P.getSize()[0]}, P1 {self._P.getSize()[1]}\n")
        assert self._coarse is not None
        self._coarse.view(viewer)


def _ksp(comm: object, prefix: str) -> PETSc.KSP:
    """A KSP configured from the options under ``prefix``."""
    ksp = PETSc.KSP().create(comm)  # type: ignore[arg-type]  # a petsc4py Comm
    ksp.setOptionsPrefix(prefix)
    ksp.setFromOptions()
    return ksp
