r"""Eigenpairs of a matrix pencil nearest a target: SLEPc Krylov–Schur with shift-and-invert.

:func:`solve_pencil` finds the eigenpairs of :math:`A\phi = \lambda B\phi`
nearest the target :math:`\sigma` by running Krylov–Schur on
:math:`(A - \sigma B)^{-1}B`, whose largest eigenvalues
:math:`\theta = 1/(\lambda - \sigma)` are those wanted; the inner solves use
one sparse factorisation of :math:`A - \sigma B` by MUMPS (both install
routes ship SLEPc and MUMPS). Symmetric pencils with a positive
semi-definite :math:`B` are solved as generalized Hermitian problems
(``GHEP``, :math:`B`-orthogonal eigenvectors, real eigenvalues, an
:math:`LDL^T` factorisation whose negative pivots count the eigenvalues
below :math:`\sigma`); other pencils as general problems (``GNHEP``, LU).
Infinite eigenvalues (the rows where :math:`B` vanishes) map to
:math:`\theta = 0` and are never found.

The options live under a unique prefix and are removed from PETSc's options
database once the solver is set up.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mpi4py import MPI  # noqa: F401  (before petsc4py)
from petsc4py import PETSc
from slepc4py import SLEPc

from hyperfem.errors import SolverError
from hyperfem.solver.linear import unique_prefix

__all__ = ["PencilEigenpairs", "solve_pencil"]


@dataclass
class PencilEigenpairs:
    """Converged eigenpairs of a pencil, nearest the target first as SLEPc ordered them.

    Attributes:
        values: Eigenvalues (complex for a general pencil; real parts are what the callers use).
        vectors: Real parts of the eigenvectors (vectors of the pencil's layout).
        converged: Eigenpairs SLEPc converged (may exceed the number requested).
        below_target: Eigenvalues of the pencil below the target, from the
            :math:`LDL^T` inertia of :math:`A - \\sigma B` (``None`` for a general pencil).
        iterations: Krylov–Schur restarts.
    """

    values: list[complex] = field(default_factory=list)
    vectors: list[PETSc.Vec] = field(default_factory=list)
    converged: int = 0
    below_target: int | None = None
    iterations: int = 0

    def destroy(self) -> None:
        """Free the eigenvectors."""
        for v in self.vectors:
            v.destroy()
        self.vectors = []


def solve_pencil(
    A: PETSc.Mat,
    B: PETSc.Mat,
    n: int,
    *,
    symmetric: bool,
    target: float = 0.0,
    tol: float = 1e-10,
    max_it: int = 1000,
    vectors: bool = True,
    kind: str = "eigen",
) -> PencilEigenpairs:
    """The ``n`` eigenpairs of :math:`A\\phi = \\lambda B\\phi` nearest ``target`` (collective).

    Args:
        A: Left matrix (the factorised one, shifted by ``target``).
        B: Right matrix, of ``A``'s nonzero pattern.
        n: Number of eigenpairs wanted.
        symmetric: Whether ``A`` and ``B`` are symmetric and ``B`` is positive
            semi-definite (``GHEP``, counted inertia); else a general pencil.
        target: The shift :math:`\\sigma`.
        tol: Relative residual tolerance of SLEPc.
        max_it: Krylov–Schur restarts at most.
        vectors: Whether to return the eigenvectors.
        kind: Middle part of the options prefix.

    Raises:
        SolverError: SLEPc or MUMPS failed (e.g. :math:`A - \\sigma B` is exactly singular).
    """
    comm = A.getComm()
    prefix = unique_prefix(kind)
    options: dict[str, object] = {
        "st_type": "sinvert",
        "st_ksp_type": "preonly",
        "st_pc_type": "cholesky" if symmetric else "lu",
        "st_pc_factor_mat_solver_type": "mumps",
        "st_mat_mumps_icntl_13": 1,  # no ScaLAPACK root: the negative pivots are counted on every rank
    }
    eps = SLEPc.EPS().create(comm)
    opts = PETSc.Options()
    try:
        eps.setOptionsPrefix(prefix)
        eps.setOperators(A, B)
        eps.setProblemType(SLEPc.EPS.ProblemType.GHEP if symmetric else SLEPc.EPS.ProblemType.GNHEP)
        eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
        eps.setDimensions(nev=n)
        eps.setTarget(target)
        eps.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
        eps.setTolerances(tol=tol, max_it=max_it)
        eps.getST().setMatStructure(PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        for key, value in options.items():
            opts[f"{prefix}{key}"] = value  # type: ignore[index]  # petsc4py stubs lack Options.__setitem__
        try:
            eps.setFromOptions()
            eps.setUp()
        finally:
            for key in options:
                opts.delValue(f"{prefix}{key}")
        eps.solve()
        return _eigenpairs(eps, A, symmetric, vectors)
    except PETSc.Error as exc:
        raise SolverError(f"eigenvalue solve failed in SLEPc/MUMPS (PETSc error {getattr(exc, 'ierr', '?')})") from None
    finally:
        eps.destroy()


def _eigenpairs(eps: SLEPc.EPS, A: PETSc.Mat, symmetric: bool, vectors: bool) -> PencilEigenpairs:
    converged = int(eps.getConverged())
    result = PencilEigenpairs(converged=converged, iterations=int(eps.getIterationNumber()))
    vr, vi = A.createVecRight(), A.createVecRight()
    try:
        for i in range(converged):
            value = complex(eps.getEigenpair(i, vr, vi) if vectors else eps.getEigenvalue(i))
            result.values.append(value)
            if vectors:
                result.vectors.append(vr.copy())
    finally:
        vr.destroy()
        vi.destroy()
    if symmetric:
        factor = eps.getST().getKSP().getPC().getFactorMatrix()
        result.below_target = int(factor.getMumpsInfog(12))
    return result
