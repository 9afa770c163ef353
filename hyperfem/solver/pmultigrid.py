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
  :math:`\Pi^T K_{uu} \Pi` (PETSc's ``pc_mg_galerkin``): what the P1
  elements would assemble for a linear tangent, without a second form;
* the coarse operator gets one GAMG V-cycle, with the rigid-body modes built
  by GAMG from the P1 node coordinates (``PCSetCoordinates``).

PETSc creates the field split's sub-solvers only when the split is first set
up, inside the Krylov solve. :class:`PMultigridHook`, installed as the outer
KSP's pre-solve hook, sets the split up early (a no-op once it is) and hands
the interpolation to the displacement block's ``PCMG`` whenever that block
has none: on the first solve, and again after a reset.

Measured (the mixed bend of ``benchmarks/scale.py --formulation mixed``,
P2/P1/P1, full load in one Newton solve, quiet 2-core machine, interleaved;
the same 5 Newton iterations and the same test point, to 1e-15 at 962k):

==========================  ===========================  ===========================
case                        GAMG on the P2 block         p-multigrid
==========================  ===========================  ===========================
31k unknowns, serial        9.1–10.0 s (231)             7.3–7.9 s (287)
100k, serial                35.3–36.4 s (247)            29.3–30.7 s (310)
100k, 2 ranks               20.8–21.2 s; 18.8–20.4 s     14.3–16.7 s; 16.6–17.6 s
                            (247), 1.22 GB               (306), 1.06 GB
962k, 2 ranks               236 s (285), 10.4 GB         192 s (336), 8.5 GB
==========================  ===========================  ===========================

(Krylov iterations in brackets: more of them, each cheaper; the second
100k pair and the 962k row are ``scale.py --variants hyperfem-iterative
hyperfem-gamg-u``, ``results/issue20_pmg_s34.jsonl``, memory the peak
resident set of both ranks.) At 962k the block's set-up takes 12.7 s
instead of 33.3 s and the Krylov solve 121 s instead of 149 s. With two
Chebyshev steps on the fine level the Krylov count drops (290 at 100k) but
each costs more, 31–33 s serial; SOR smoothing 64 s. On the displacement
problem the same two levels do not beat GAMG on the P3/P4 tangent
(``benchmarks/linear_degree.py --variants pmg``).
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc
from dolfinx import fem

__all__ = ["GAMG_U", "P_MULTIGRID_U", "PMultigridHook", "p_multigrid_options"]


def p_multigrid_options(prefix: str = "") -> dict[str, object]:
    """The options of the two-level p-multigrid (module docstring) of the preconditioner under ``prefix``."""
    own: dict[str, object] = {
        "pc_type": "mg",
        "pc_mg_levels": 2,
        "pc_mg_galerkin": "both",
        "mg_levels_ksp_type": "chebyshev",
        "mg_levels_ksp_max_it": 1,
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


def _has_interpolation(pc: PETSc.PC) -> bool:
    """Whether the two-level ``PCMG`` ``pc`` has its interpolation (PETSc may raise where it has none)."""
    try:
        return bool(pc.getMGInterpolation(1))  # a null Mat is false
    except PETSc.Error:
        return False


class PMultigridHook:
    """The KSP's pre-solve hook that gives its (or its field split's displacement block's) ``PCMG`` its P1 level.

    Args:
        space: The displacement space (P\\ :sub:`k`, blocked; collapsed from a mixed space).
        rows: Positions, in ``space``'s local (unrolled) dof array, of the
            owned dofs of the preconditioned block, in that block's order
            (``None``: the space itself, in its own order).
        nodal: Whether those dofs come in node triples (pairs in 2D) on every
            rank, so the interpolation's rows are node blocks.

    The interpolation is built at the first solve that needs it.
    """

    def __init__(self, space: fem.FunctionSpace, rows: np.ndarray | None = None, nodal: bool = True) -> None:
        self._space = space
        if rows is None:
            rows = np.arange(space.dofmap.index_map.size_local * space.dofmap.index_map_bs)
        self._rows = rows
        self._nodal = nodal
        self._levels: tuple[PETSc.Mat, np.ndarray] | None = None

    def _coarse_level(self) -> tuple[PETSc.Mat, np.ndarray]:
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

    def __call__(self, ksp: PETSc.KSP, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """Give the two-level ``PCMG`` the P1 level where it has none (setting a field split up first)."""
        block = ksp.getPC()
        if block.getType() == PETSc.PC.Type.FIELDSPLIT:
            block.setUp()  # creates the sub-solvers (a no-op once set up)
            block = block.getFieldSplitSubKSP()[0].getPC()
        if block.getType() != PETSc.PC.Type.MG or block.getMGLevels() != 2 or _has_interpolation(block):
            return  # options chose another preconditioner, or the level is in place
        P, X = self._coarse_level()
        block.setMGInterpolation(1, P)
        block.getMGCoarseSolve().getPC().setCoordinates(X)  # type: ignore[arg-type]  # petsc4py takes an array
