r"""When Newton's preconditioner is built again: lagged, and rebuilt early when the Krylov count doubles.

An AMG hierarchy (or p-multigrid, or field split) costs as much to set up
as many Krylov iterations: at 28.6k P1 unknowns on this 2-core machine one
Galerkin re-set-up of GAMG takes 0.04–0.05 s, about 18 CG iterations. And
one built on an older tangent of the same solve preconditions the later ones
nearly as well. On the bend (P1, 28.6k, full load in one solve, 2 ranks) the
hierarchy of the first tangent (:math:`F = I`) took 11, 14, 15, 18 and 16
CG iterations over the five Newton iterations, one rebuilt at every tangent
11, 13, 14, 17 and 14; on the twist 12–15 against 12–13.

So SNES lags the preconditioner (``snes_lag_preconditioner``): it is built
at the first Newton iteration of every solve and then at the multiples of
the lag. :class:`PreconditionerLag` adds one rule that SNES has not: a
lagged preconditioner whose last Krylov solve took more than
:data:`REBUILD_GROWTH` times the iterations of the first converged solve
with it plus :data:`REBUILD_SLACK` is rebuilt at the next tangent, for the tangent has
moved away from the one it was built on (a contact pair that entered, a
material that stiffened). A solve that failed is handled where it fails
(``NewtonSolver._recover_direction`` rebuilds and solves again), and
:meth:`PreconditionerLag.rebuilt` tells the rule.

The rule decides in the SNES convergence test, which runs after each
residual and before the next tangent, by setting SNES's lag to 1 (rebuild
now) or back to the configured one: SNES itself then sets the KSP's
reuse flag (``SNESComputeJacobian``), so the rebuilds are SNES's own and
:func:`preconditioner_rebuilt` tells which tangents they were. petsc4py has
no binding of ``SNESSetLagPreconditioner``; :func:`set_snes_lag` calls the C
function of the PETSc that petsc4py is linked to (``ctypes``).
"""

from __future__ import annotations

import ctypes
import functools
import warnings
from typing import Any

import numpy as np
from petsc4py import PETSc

__all__ = ["REBUILD_GROWTH", "REBUILD_SLACK", "PreconditionerLag", "preconditioner_rebuilt", "set_snes_lag", "snes_lag"]

REBUILD_GROWTH = 2.0
"""A lagged preconditioner is rebuilt once a Krylov solve with it took more than this times its first solve's count."""

REBUILD_SLACK = 5
"""Krylov iterations added to the growth threshold (a first solve of 1–3 iterations would otherwise trip it)."""


@functools.cache
def _petsc_functions() -> tuple[Any, Any, Any]:
    """``SNESSetLagPreconditioner``, ``SNESGetLagPreconditioner`` and the C type of ``PetscInt``.

    Looked up through petsc4py's extension module, whose dependencies include the PETSc it was built with.
    """
    lib = ctypes.CDLL(PETSc.__file__)
    integer = ctypes.c_int64 if np.dtype(PETSc.IntType).itemsize == 8 else ctypes.c_int32
    setter, getter = lib.SNESSetLagPreconditioner, lib.SNESGetLagPreconditioner
    setter.argtypes, setter.restype = [ctypes.c_void_p, integer], ctypes.c_int
    getter.argtypes, getter.restype = [ctypes.c_void_p, ctypes.POINTER(integer)], ctypes.c_int
    return setter, getter, integer


def set_snes_lag(snes: PETSc.SNES, lag: int) -> None:
    """``SNESSetLagPreconditioner(snes, lag)`` (not bound by petsc4py).

    Raises:
        RuntimeError: PETSc refused the value (it takes -2, -1 or a positive integer).
    """
    setter, _, integer = _petsc_functions()
    if setter(ctypes.c_void_p(snes.handle), integer(lag)) != 0:
        raise RuntimeError(f"SNESSetLagPreconditioner({lag}) failed")


def snes_lag(snes: PETSc.SNES) -> int:
    """``SNESGetLagPreconditioner(snes)``: the lag SNES applies at its next tangent."""
    _, getter, integer = _petsc_functions()
    value = integer(0)
    if getter(ctypes.c_void_p(snes.handle), ctypes.byref(value)) != 0:
        raise RuntimeError("SNESGetLagPreconditioner failed")
    return int(value.value)


def preconditioner_rebuilt(iteration: int, lag: int) -> bool:
    """Whether SNES sets the preconditioner up again after the tangent of Newton iteration ``iteration``.

    SNES's rule for ``snes_lag_preconditioner`` = ``lag`` (``SNESComputeJacobian``): -1 never (after the
    first), ``lag`` > 1 at the iterations that are multiples of it, else always. The AIJ copy of a blocked
    tangent (AMG's preconditioning matrix) is only read when the preconditioner is set up, so inside the
    SNES solve it is updated only then: the other iterations' copies changed nothing (measured: the same
    Krylov iterations and displacements to the last bit) and cost 7–15 % of a P1 or P2 tangent assembly
    (bend, 28.6k unknowns: 9 of 64 ms serial, 7 of 45 ms on 2 ranks; P2 22 of 320 ms). A shifted
    preconditioning matrix (the mixed field split) is updated at every tangent, as before.
    """
    if lag == -1:
        return iteration == 0
    if lag > 1:
        return iteration % lag == 0
    return True


class PreconditionerLag:
    """SNES's preconditioner lag with an early rebuild when the Krylov count has grown (module docstring).

    Args:
        snes: The Newton solver's SNES; its lag is set before each tangent.
        lag: The configured ``snes_lag_preconditioner`` (1: every tangent, ``k`` > 1: every ``k``-th of a solve,
            -1: built once, never again, also not in later solves).

    Attributes:
        early_rebuilds: Preconditioners rebuilt before the lag asked for it, since construction.
    """

    def __init__(self, snes: PETSc.SNES, lag: int):
        self._snes = snes
        self.lag = int(lag)
        self.early_rebuilds = 0
        self._first: int | None = None  # Krylov iterations of the first solve with the current preconditioner
        self._fresh = True  # the current preconditioner has not solved yet
        self._reused = False  # SNES's decision at its last tangent
        self._built = False  # a preconditioner was built (lag -1: SNES never builds another)
        self._rtol: float | None = None  # the KSP's tolerance at the start of the solve (the configured one)
        self.adaptive = self.lagged
        """Whether the early rebuild is on (it needs ``SNESSetLagPreconditioner``, looked up here)."""
        if self.adaptive:
            try:
                _petsc_functions()
            except (OSError, AttributeError) as exc:
                warnings.warn(
                    f"PreconditionerLag: SNESSetLagPreconditioner not found ({exc}); the lag stays fixed",
                    RuntimeWarning,
                    stacklevel=2,
                )
                self.adaptive = False

    @property
    def lagged(self) -> bool:
        """Whether the preconditioner may be older than the tangent at all (the configured lag is not 1)."""
        return self.lag > 1 or self.lag == -1

    @property
    def reused(self) -> bool:
        """Whether SNES's last tangent kept a preconditioner built on an earlier one (the KSP's reuse flag)."""
        return self._reused

    def __call__(self, iteration: int, reason: int) -> None:
        """Decide whether the tangent of Newton iteration ``iteration`` rebuilds the preconditioner.

        Called before the final-step forcing changes the next solve's tolerance. The reference count is
        taken from the first converged solve with a preconditioner; a solve that the forcing tightened
        (its tolerance below the one the solve started with) is not compared with it.

        Args:
            iteration: The Newton iteration whose residual was just tested (0: the start of a solve).
            reason: The convergence test's verdict; a nonzero one ends the solve (nothing to decide).
        """
        if not self.lagged:
            return
        if reason != 0:  # the solve ends
            self.restore()
            return
        ksp = self._snes.getKSP()
        count = int(ksp.getIterationNumber())
        rtol = float(ksp.getTolerances()[0])
        if iteration == 0:
            self._rtol = rtol
        converged = int(ksp.getConvergedReason()) > 0  # type: ignore[call-overload]  # petsc4py: an int
        if iteration > 0 and self._fresh and converged:
            self._first, self._fresh = count, False
        scheduled = (not self._built) if self.lag == -1 else preconditioner_rebuilt(iteration, self.lag)
        grown = (
            self.adaptive
            and iteration > 0
            and not scheduled
            and self._first is not None
            and (self._rtol is None or rtol >= self._rtol)
            and count > REBUILD_GROWTH * self._first + REBUILD_SLACK
        )
        if self.adaptive:
            set_snes_lag(self._snes, 1 if grown else self.lag)
        if grown:
            self.early_rebuilds += 1
        if grown or scheduled:
            self.rebuilt()
        self._reused = not (grown or scheduled)

    def rebuilt(self) -> None:
        """The preconditioner is (being) built on the current tangent: its next solve sets the reference count."""
        self._fresh, self._first, self._reused, self._built = True, None, False, True

    def rebuild_now(self) -> None:
        """Make SNES rebuild the preconditioner at the tangent being assembled (SNES reads its lag after it)."""
        if self.adaptive:  # lagged, and SNES's lag can be set
            set_snes_lag(self._snes, 1)
            self.rebuilt()

    def restore(self) -> None:
        """Give SNES its configured lag back (an early rebuild sets it to 1 for one tangent)."""
        if self.adaptive:
            set_snes_lag(self._snes, self.lag)
