r"""Stability of a state: the lowest eigenvalues of the tangent and the count of negative ones.

A converged state :math:`u` of :math:`\Pi` is stable when the second
variation is positive for every admissible variation,
:math:`\delta^2\Pi = \phi^T K\phi > 0` for :math:`\phi \ne 0` with
:math:`\phi = 0` on the Dirichlet boundary; equivalently, every eigenvalue of

.. math::
    K\phi = \lambda B\phi

is positive, :math:`B` any symmetric positive definite metric on the free
displacement dofs (Sylvester's law of inertia: the count of negative
eigenvalues does not depend on :math:`B`). :class:`TangentEigensolver`
computes the ``n`` eigenvalues of smallest magnitude with SLEPc (Krylov–Schur,
shift-and-invert at :math:`\sigma = 0`, MUMPS) — the ones that change sign at a
limit or bifurcation point, and the lowest ones whenever the state is stable
— and the *exact* number of negative eigenvalues from the negative pivots of
the :math:`LDL^T` factorisation of :math:`K` that the shift-and-invert needs
anyway. See :mod:`hyperfem.stability.pencil` for the metric, for how the
Dirichlet conditions leave the spectrum, and for the mixed (u, p, θ) problem,
whose stability is that of the displacement-reduced (Schur complement)
tangent.

Follower loads make :math:`K` non-symmetric: the eigenvalues may be complex,
there is no inertia, and a real eigenvalue crossing zero (divergence) is the
only instability this detects (not flutter). The negative count is then the
number of computed eigenvalues with negative real part (``negative_counted =
"computed"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import ufl
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import SolidProblem
from hyperfem.stability.eigensolver import solve_pencil
from hyperfem.stability.pencil import TangentPencil
from hyperfem.validation import check_count, check_positive

__all__ = ["TangentEigensolver", "TangentSpectrum", "lowest_eigenvalues"]


@dataclass(frozen=True)
class TangentSpectrum:
    """The spectrum of the tangent at one state.

    Attributes:
        eigenvalues: The computed eigenvalues (real parts), ascending: the
            ``n`` of smallest magnitude (fewer if SLEPc converged fewer).
        negative: Number of negative eigenvalues of the (displacement-reduced)
            tangent: exact (``negative_counted == "inertia"``) for symmetric
            tangents, else among :attr:`eigenvalues`.
        converged: Eigenpairs SLEPc converged.
        requested: Eigenpairs asked for.
        time: The load factor (time) of the state.
        metric: The metric :math:`B` (``"mass"`` or ``"euclidean"``).
        negative_counted: ``"inertia"`` or ``"computed"``.
        max_imaginary: Largest imaginary part among the eigenvalues (0 for symmetric tangents).
        modes: Eigenvectors as displacement functions, in the order of
            :attr:`eigenvalues` (empty unless asked for).
    """

    eigenvalues: tuple[float, ...]
    negative: int
    converged: int
    requested: int
    time: float = 0.0
    metric: str = "mass"
    negative_counted: str = "inertia"
    max_imaginary: float = 0.0
    modes: tuple[fem.Function, ...] = field(default=(), repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.negative < 0 or self.converged < 0 or self.requested < 1:
            raise ParameterError(
                f"TangentSpectrum: counts must be >= 0 (requested >= 1), got negative={self.negative}, "
                f"converged={self.converged}, requested={self.requested}"
            )
        if self.negative_counted not in ("inertia", "computed"):
            raise ParameterError(
                f"TangentSpectrum: negative_counted must be 'inertia' or 'computed', got {self.negative_counted!r}"
            )

    @property
    def stable(self) -> bool:
        """Whether no eigenvalue is negative (a state exactly at a critical point counts as stable)."""
        return self.negative == 0

    @property
    def lowest(self) -> float:
        """The lowest computed eigenvalue (``nan`` when none converged)."""
        return self.eigenvalues[0] if self.eigenvalues else float("nan")

    def as_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (without the modes)."""
        return {
            "eigenvalues": list(self.eigenvalues),
            "negative": self.negative,
            "stable": self.stable,
            "converged": self.converged,
            "requested": self.requested,
            "time": self.time,
            "metric": self.metric,
            "negative_counted": self.negative_counted,
            "max_imaginary": self.max_imaginary,
        }


class TangentEigensolver:
    """The lowest eigenvalues of a problem's tangent, at any number of states (forms compiled once).

    Args:
        problem: A :class:`~hyperfem.problem.protocol.SolidProblem` (displacement or mixed).
        n: Number of eigenvalues (those of smallest magnitude).
        metric: ``"mass"`` (default) or ``"euclidean"``; see :mod:`hyperfem.stability.pencil`.
        tol: Relative residual tolerance of the eigenpairs.
        max_it: Krylov–Schur restarts at most.
        modes: Whether :meth:`solve` returns the eigenvectors as displacement functions.
        jacobian: The tangent form (default ``problem.jacobian``; external
            energies such as a contact barrier are not in it).
        form_compiler_options: FFCx options of the compiled forms.
        jit_options: JIT options of the compiled forms.

    Raises:
        ParameterError: ``n`` not an integer >= 1, ``tol`` not in (0, 1),
            ``max_it`` < 1, an unknown metric, or Dirichlet conditions that
            leave a rigid-body motion free.
    """

    def __init__(
        self,
        problem: SolidProblem,
        n: int = 6,
        *,
        metric: str = "mass",
        tol: float = 1e-10,
        max_it: int = 1000,
        modes: bool = False,
        jacobian: ufl.Form | None = None,
        form_compiler_options: dict[str, Any] | None = None,
        jit_options: dict[str, Any] | None = None,
    ) -> None:
        where = "TangentEigensolver"
        check_count("n", n, where)
        check_positive("tol", tol, where)
        if tol >= 1.0:
            raise ParameterError(f"{where}: tol must be < 1, got {tol!r}")
        check_count("max_it", max_it, where)
        if not isinstance(modes, bool):
            raise ParameterError(f"{where}: modes must be True or False, got {modes!r}")
        self.n = int(n)
        self.tol = float(tol)
        self.max_it = int(max_it)
        self.modes = modes
        self.pencil = TangentPencil(
            problem,
            metric,
            jacobian=jacobian,
            form_compiler_options=form_compiler_options,
            jit_options=jit_options,
            where=where,
        )

    @property
    def problem(self) -> SolidProblem:
        """The problem whose tangent is analysed."""
        return self.pencil.problem

    def solve(self) -> TangentSpectrum:
        """The spectrum of the tangent at the problem's current state (collective)."""
        pencil = self.pencil
        K = pencil.assemble()
        pairs = solve_pencil(
            K, pencil.B, self.n, symmetric=pencil.symmetric, tol=self.tol, max_it=self.max_it,
            vectors=self.modes, kind="stability",
        )
        try:
            values = np.array(pairs.values[: max(self.n, 0)], dtype=complex)
            order = np.argsort(values.real, kind="stable")
            eigenvalues = tuple(float(v) for v in values.real[order])
            if pairs.below_target is not None:
                negative = pairs.below_target - pencil.constraint_negatives(K)
                counted = "inertia"
            else:
                negative = int(np.count_nonzero(values.real < 0.0))
                counted = "computed"
            modes = tuple(
                pencil.mode(pairs.vectors[int(i)], f"tangent_mode_{k}") for k, i in enumerate(order)
            ) if self.modes else ()
        finally:
            pairs.destroy()
        return TangentSpectrum(
            eigenvalues=eigenvalues,
            negative=negative,
            converged=pairs.converged,
            requested=self.n,
            time=float(self.problem.time),
            metric=str(pencil.metric),
            negative_counted=counted,
            max_imaginary=float(np.abs(values.imag).max(initial=0.0)),
            modes=modes,
        )

    def destroy(self) -> None:
        """Free the matrices."""
        self.pencil.destroy()


def lowest_eigenvalues(
    problem: SolidProblem,
    n: int = 6,
    *,
    metric: str = "mass",
    tol: float = 1e-10,
    modes: bool = False,
) -> TangentSpectrum:
    r"""The ``n`` eigenvalues of smallest magnitude of the tangent at the current state, and its stability.

    One-off form of :class:`TangentEigensolver` (which compiles the forms once
    for many states): solves :math:`K\phi = \lambda B\phi` (module docstring),
    with the Dirichlet dofs removed from the spectrum, for the displacement
    and the mixed problem alike.

    Args:
        problem: The problem, at the state to analyse.
        n: Number of eigenvalues.
        metric: ``"mass"`` or ``"euclidean"``.
        tol: Relative residual tolerance.
        modes: Whether to return the eigenvectors as displacement functions.

    Raises:
        ParameterError: See :class:`TangentEigensolver`.
    """
    check_count("n", n, "lowest_eigenvalues")
    solver = TangentEigensolver(problem, n, metric=metric, tol=tol, modes=modes)
    try:
        return solver.solve()
    finally:
        solver.destroy()
