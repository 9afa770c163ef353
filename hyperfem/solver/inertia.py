r"""The inertia of a symmetric matrix: how many negative eigenvalues a tangent has.

By Sylvester's law of inertia the negative pivots of an :math:`LDL^T`
factorisation count the negative eigenvalues. A converged state whose
tangent (on the free dofs) has one is unstable under load control; a change
of the count along a path marks a limit or a bifurcation point
(:mod:`~hyperfem.solver.arc_length`, :mod:`hyperfem.stability`).
"""

from __future__ import annotations

from mpi4py import MPI  # noqa: F401  (before petsc4py)
from petsc4py import PETSc

from hyperfem.errors import SolverError

__all__ = ["negative_pivots"]


def negative_pivots(A: PETSc.Mat) -> int:
    r"""Number of negative eigenvalues of the symmetric matrix ``A`` (its inertia; collective).

    The negative pivots of a MUMPS :math:`LDL^T` factorisation (``INFOG(12)``),
    with ``ICNTL(13) = 1`` so that the count is global on several ranks and
    ``ICNTL(24) = 1`` so that a singular matrix (a state at a critical point)
    still factorises. Dirichlet rows (identity rows) count as positive. Of an
    unsymmetric matrix (a follower load's tangent) one triangle is read. Set up
    without PETSc's options database. A blocked (BAIJ) tangent is factorised
    as an AIJ copy (MUMPS has no :math:`LDL^T` of BAIJ).

    Raises:
        SolverError: The factorisation failed.
    """
    blocked = A.getType() in (PETSc.Mat.Type.SEQBAIJ, PETSc.Mat.Type.MPIBAIJ)
    if blocked:
        copy = PETSc.Mat()
        A.convert(PETSc.Mat.Type.AIJ, copy)  # into a new matrix: convert(type) alone would convert A in place
        A = copy
    pc = PETSc.PC().create(A.getComm())
    factor = None
    try:
        pc.setOperators(A, A)
        pc.setType(PETSc.PC.Type.CHOLESKY)
        pc.setFactorSolverType("mumps")
        pc.setFactorSetUpSolverType()
        factor = pc.getFactorMatrix()
        factor.setMumpsIcntl(13, 1)
        factor.setMumpsIcntl(24, 1)
        pc.setUp()
        return int(factor.getMumpsInfog(12))
    except PETSc.Error as exc:
        code = getattr(exc, "ierr", "?")
        message = f"negative_pivots: the LDL^T factorisation (MUMPS) of the tangent failed (PETSc error {code})"
        raise SolverError(message) from None
    finally:
        # Destroyed here, collectively: a factor left to Python would wait as garbage with MUMPS's
        # communicators (hyperfem.solver.garbage).
        if factor is not None:
            factor.destroy()
        pc.destroy()
        if blocked:
            A.destroy()
