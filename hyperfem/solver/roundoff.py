r"""The round-off stop of :class:`~hyperfem.solver.NewtonSolver`: the floor estimate and the convergence test.

Near convergence the assembled residual stops shrinking at a level set by
floating point, not by the tolerance. Once Newton stops making progress
(:math:`\|r_k\| > \tfrac12\|r_{k-1}\|`) with :math:`\|r_k\|` within
:data:`ROUNDOFF_FACTOR` of the estimate :math:`\varepsilon\,\|\,|K|\,(|x| + h)\,\|`
(:meth:`RoundoffStop.floor`; :math:`h`: the identity parts of :math:`F` and, in
the three-field problem, of :math:`\theta`), the solve is *converged at round-off*
(``SolveRecord.reason_name == "CONVERGED_ROUNDOFF"``) instead of wandering in
noise until a lucky dip or ``snes_max_it``; a tolerance below that floor draws
a :class:`RoundoffWarning` (once per solver).
"""

from __future__ import annotations

import warnings

import numpy as np
from mpi4py import MPI
from dolfinx import mesh as dmesh
from petsc4py import PETSc

from hyperfem.problem.protocol import MixedProblemProtocol, SolidProblem, TimeStepState

__all__ = [
    "CONVERGED_ROUNDOFF",
    "REFERENCE_SCALE_FRACTION",
    "ROUNDOFF_FACTOR",
    "VOLUME_REFERENCE",
    "RoundoffStop",
    "RoundoffWarning",
    "reference_scale",
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
r"""The identity part of :math:`F` enters the floor as a displacement of this fraction of the largest cell.

(:meth:`RoundoffStop.floor`, the vector :func:`reference_scale`.)

Measured (cantilever bend and twist, beam_h2 and beam_h1, P1 and P2, load
factors 1e-6, 1e-3 and 1, MUMPS, tolerances 1e-15 and no round-off stop): the
residual stagnates at 0.6e-9 to 2e-8 at every load, while
:math:`\varepsilon\|\,|K||x|\,\|` falls with the load from about 1e-8 to 1e-15 (the
noise was up to 4e5 times the old estimate: solves at small loads wandered
to ``snes_max_it``). With the cell-size term at full size the noise band is
0.0017–0.17 of the estimate; this fraction puts it at 0.03–2.7, the band the
factor :data:`ROUNDOFF_FACTOR` was chosen for."""

VOLUME_REFERENCE = 1.0
r"""The identity part of :math:`\theta = 1 + w_\theta` in each volume dof of the three-field problem.

(:meth:`RoundoffStop.floor`, the vector :func:`reference_scale`.)

The volume block stores the dilatation :math:`w_\theta`, but :math:`U'(\theta)` and
:math:`J - \theta` are evaluated at :math:`\theta` of size 1: the :math:`\theta` rows carry a
round-off of :math:`\varepsilon K` (:math:`\varepsilon\,|H_{\theta\theta}|\cdot 1`), which the
Schur complement spreads as a pressure error :math:`\varepsilon K` into the
displacement rows. Without it the estimate fell with :math:`|w_\theta|` and was
up to :math:`1.6\times10^6` below the noise at :math:`K/\mu = 10^8` (its homogeneous
Ogden test stagnated at :math:`|r| \approx 10^{-9}` for ``snes_max_it`` iterations
against an estimate :math:`4\times10^{-16}`). Measured with it
(``benchmarks/roundoff_floor.py --mixed``: P2/P1/P1, a uniaxial cube and a
clamped bar, :math:`K/\mu = 10^2, 10^4, 10^8`, every load step): the noise band
at 0.009–0.96 of the estimate on 1 and 2 ranks (without: 0.36 to :math:`1.6\times10^6`); the
solves with the stop end CONVERGED_ROUNDOFF or by a tolerance in 3–5 iterations where
the plain ones ran to ``snes_max_it``, their solutions within 8e-16 of each other."""

CONVERGED_ROUNDOFF = int(PETSc.SNES.ConvergedReason.CONVERGED_ITS)
"""SNES reason returned when the floor ends a solve (the record names it ``CONVERGED_ROUNDOFF``)."""


class RoundoffWarning(UserWarning):
    """The requested residual tolerance is below what floating point can resolve."""


def reference_scale(problem: SolidProblem, template: PETSc.Vec) -> PETSc.Vec:
    """The vector :math:`h` of :meth:`RoundoffStop.floor`: the identity parts of the unknown's fields.

    :data:`REFERENCE_SCALE_FRACTION` of the largest cell size in each
    displacement dof, :data:`VOLUME_REFERENCE` in each volume dof of a
    three-field problem, 0 in the pressure dofs. Collective (the cell size is
    the largest over the ranks).

    Args:
        problem: The problem (its mesh, and ``field_dofs`` for a mixed unknown: its own, or those of the
            body of a time step).
        template: A vector of the unknown's layout.
    """
    mesh = problem.domain.mesh
    tdim = mesh.topology.dim
    cells = np.arange(mesh.topology.index_map(tdim).size_local, dtype=np.int32)
    nodes = mesh.geometry.x[dmesh.entities_to_geometry(mesh, tdim, cells)]  # (cells, nodes per cell, 3)
    diagonals = np.linalg.norm(nodes.max(axis=1) - nodes.min(axis=1), axis=1)  # bounding boxes of the cells
    h = mesh.comm.allreduce(float(np.max(diagonals, initial=0.0)), op=MPI.MAX)
    scale = template.duplicate()
    owned = scale.getLocalSize()
    values = np.zeros(owned)
    base = problem.base if isinstance(problem, TimeStepState) else problem  # a time step: the body's fields
    fields = base.field_dofs() if isinstance(base, MixedProblemProtocol) else {"displacement": np.arange(owned)}
    dofs = fields["displacement"]
    values[dofs[dofs < owned]] = REFERENCE_SCALE_FRACTION * h
    volume = fields.get("volume", np.zeros(0, dtype=np.int64))
    values[volume[volume < owned]] = VOLUME_REFERENCE
    scale.array[:] = values
    return scale


class RoundoffStop:
    """The SNES convergence test of a solver: PETSc's default criteria, then the round-off floor.

    Built once per solver; :meth:`reset` at the start of every solve. Holds
    the SNES (not the solver), so no reference cycle goes through PETSc.

    Args:
        snes: The solver's SNES (its last tangent and current solution are read).
        problem: The problem (for :func:`reference_scale`).
        template_x: A vector of the unknown's layout.
        template_b: A vector of the residual's layout.
        factor: :data:`ROUNDOFF_FACTOR`; ``0`` disables the stop.

    Attributes:
        factor: The factor of the stop.
        floor_value: The last floor estimate of the current solve (``nan`` until needed).
        stopped: Whether the current solve was ended at the floor.
        tolerance: The residual tolerance of the current solve, :math:`\\max(atol, rtol\\,\\|r_0\\|)`.
    """

    def __init__(
        self, snes: PETSc.SNES, problem: SolidProblem, template_x: PETSc.Vec, template_b: PETSc.Vec, factor: float
    ):
        self.snes = snes
        self.factor = float(factor)
        self._reference_scale = reference_scale(problem, template_x)
        self._reference_scale_norm = float(self._reference_scale.norm())  # type: ignore[arg-type]  # petsc4py: 2-norm
        self._work = template_x.duplicate()
        self._residual_work = template_b.duplicate()
        self._abs_jacobian: PETSc.Mat | None = None
        self._warned = False
        self.tolerance = float("nan")
        self._fnorm0 = float("nan")
        self._fnorms: list[float] = []
        self.reset()

    def reset(self) -> None:
        """Forget the previous solve's floor and stop."""
        self.floor_value = float("nan")
        self.stopped = False

    def floor(self) -> float:
        r"""Round-off estimate :math:`\varepsilon\,\|\,|K|\,(|x| + h)\,\|` of the residual norm.

        :math:`|K|` is the entrywise absolute value of the last assembled
        tangent (with the Dirichlet rows), :math:`|x|` of the current state:
        every term summed into a residual entry is bounded by the
        corresponding entry of :math:`|K||x|` for a linear response, and a
        state is only known to :math:`\varepsilon|x|`. The residual is
        evaluated from :math:`F = I + \nabla u`, though: its stress terms are
        of the size the identity part gives them (:math:`\mu F` and
        :math:`\mu F^{-T}` cancel at :math:`F \approx I`), which in a cell of
        size :math:`h` is that of a displacement of a fraction of :math:`h`
        (:data:`REFERENCE_SCALE_FRACTION`). Without :math:`h` (in every
        displacement dof: :func:`reference_scale`) the estimate vanished with
        the load: a bend at load factor 1e-4 (CG + GAMG, P2, beam_h1)
        stagnated at ``|r| = 1.1e-9``, just above its tolerance, for 50
        iterations while the estimate said 1e-13. Likewise :math:`\theta = 1 +
        w_\theta` of the three-field problem (:data:`VOLUME_REFERENCE`).
        """
        A = self.snes.getJacobian()[0]
        if self._abs_jacobian is None:
            self._abs_jacobian = A.duplicate(copy=True)
        else:
            A.copy(self._abs_jacobian, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)  # type: ignore[arg-type]  # petsc4py: int enums
        B = self._abs_jacobian
        ai, aj, av = B.getValuesCSR()
        B.setValuesCSR(ai, aj, np.abs(av))  # type: ignore[arg-type]  # petsc4py takes arrays
        B.assemble()
        x = self._work
        self.snes.getSolution().copy(x)
        x.abs()
        x.axpy(1.0, self._reference_scale)
        y = self._residual_work
        B.mult(x, y)
        return float(np.finfo(float).eps * y.norm())  # type: ignore[operator]  # petsc4py: the 2-norm is a float

    def bound(self) -> float:
        r"""Cheap upper bound :math:`\varepsilon\|K\|_F(\|x\|_2 + \|h\|_2)` of :meth:`floor` (no copy)."""
        A = self.snes.getJacobian()[0]
        size = self.snes.getSolution().norm() + self._reference_scale_norm  # type: ignore[operator]  # petsc4py: float
        frobenius = A.norm(PETSc.NormType.FROBENIUS)  # type: ignore[arg-type]  # petsc4py: int enums
        return float(np.finfo(float).eps * frobenius * size)  # type: ignore[operator]  # petsc4py: a float

    def __call__(self, snes: PETSc.SNES, it: int, norms: tuple[float, float, float]) -> int:
        """SNES convergence test: PETSc's default criteria, then the round-off floor."""
        xnorm, snorm, fnorm = (float(v) for v in norms)
        rtol, atol, stol, _ = snes.getTolerances()
        R = PETSc.SNES.ConvergedReason
        if it == 0:
            self.tolerance = max(atol, rtol * fnorm)
            self._fnorm0 = fnorm
            self._fnorms = [fnorm]
        if not np.isfinite(fnorm):
            return int(R.DIVERGED_FUNCTION_NANORINF)
        if fnorm < atol:
            return int(R.CONVERGED_FNORM_ABS)
        if it == 0:
            return int(R.ITERATING)
        if fnorm <= self.tolerance:
            return int(R.CONVERGED_FNORM_RELATIVE)
        if snorm < stol * xnorm:
            return int(R.CONVERGED_SNORM_RELATIVE)
        divtol = snes.getDivergenceTolerance()
        if divtol > 0 and fnorm > divtol * self._fnorm0:
            return int(R.DIVERGED_DTOL)
        return self._floor_test(fnorm)

    def _floor_test(self, fnorm: float) -> int:
        """:data:`CONVERGED_ROUNDOFF` when the residual stagnates within :attr:`factor` of the floor."""
        previous = self._fnorms[-1] if self._fnorms else np.inf
        self._fnorms.append(fnorm)
        if self.factor > 0 and fnorm > 0.5 * previous and fnorm <= self.factor * self.bound():
            self.floor_value = self.floor()
            if fnorm <= self.factor * self.floor_value:
                self.stopped = True
                return CONVERGED_ROUNDOFF
        return int(PETSc.SNES.ConvergedReason.ITERATING)

    def warn_below_floor(self, comm: MPI.Comm, norms: list[float], stacklevel: int) -> None:
        """Warn (rank 0, once per solver) when the solve stopped at a floor above the tolerance asked for.

        Args:
            comm: The solver's communicator.
            norms: The residual norms of the solve (the last one is reported).
            stacklevel: Of the caller, as for :func:`warnings.warn`.
        """
        if not self.stopped or self._warned or not self.tolerance < self.floor_value:
            return
        self._warned = True  # once per solver
        if comm.rank == 0:
            warnings.warn(
                f"NewtonSolver: residual tolerance {self.tolerance:.3g} is below the round-off floor "
                f"{self.floor_value:.3g} of this problem; stopped at |r| = {norms[-1]:.3g} "
                "(converged at round-off)",
                RoundoffWarning,
                stacklevel=stacklevel + 1,
            )
