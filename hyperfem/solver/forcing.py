r"""The Krylov tolerance of the Newton iteration predicted to be the last.

The iterative linear solvers stop at a fixed relative tolerance
(``ksp_rtol``, :mod:`hyperfem.solver.linear`): once Newton is in its
quadratic regime, the residual after a step is the Krylov solve's error,
about ``ksp_rtol`` times the residual before it times a factor of order 10
(the preconditioned norm CG measures is not the residual norm). Whether that
lands below the Newton tolerance :math:`\max(\text{atol}, \text{rtol}\,\|r_0\|)`
is luck: measured on the bend (P1, 212k unknowns, full load in one solve),
``‖r₃‖ = 0.355`` became ``2.05e-6`` on one rank (converged, tolerance
``2.46e-6``) and ``6.27e-6`` on two ranks (a fifth Newton iteration: a tangent
assembly, a Krylov solve and a line search for the last factor of 2.5).

:class:`FinalStepForcing` predicts the next residual from the last two,
:math:`\|r_{k+1}\| \approx \|r_k\|^3/\|r_{k-1}\|^2` (quadratic convergence,
its constant estimated from the last step). When that exact-Newton
prediction lies well below the tolerance, the step about to be solved is the
last one that the nonlinear convergence needs, and only the Krylov error can
keep it from being so: its ``ksp_rtol`` is lowered to
:data:`MARGIN` × tolerance / ‖r_k‖ (not below :data:`DEEPEST`), which
costs a few Krylov iterations instead of a Newton iteration. Every other
step keeps the configured tolerance, so the early iterations are not
over-solved (the reason a plain Eisenstat–Walker forcing
was not taken, see :mod:`hyperfem.solver.linear`). The configured value is
restored at the start and at the end of every solve.
"""

from __future__ import annotations

from petsc4py import PETSc

__all__ = ["DEEPEST", "MARGIN", "FinalStepForcing"]

MARGIN = 0.01
"""The last step's Krylov tolerance, as a fraction of the Newton tolerance over the current residual.

The margin covers the factor between the Krylov solver's (preconditioned)
relative residual and the nonlinear residual after the step: 6–18 measured on
the bend above."""

DEEPEST = 1e-9
"""The lowest last-step ``ksp_rtol`` (a Krylov solve near the round-off floor must not run into its iteration limit).

An absolute value, not a fraction of the configured ``ksp_rtol``: the last
step needs the same accuracy whatever the earlier ones were solved to. As a
fraction (10⁻³ of it) a configured ``ksp_rtol`` of 10⁻⁴ floored the last
step at 10⁻⁷ where it asked for 6.8·10⁻⁸, and the 92k bend (P1, serial) took
a fifth Newton iteration for ‖r₄‖ = 4.8·10⁻⁶ against the tolerance
3.3·10⁻⁶ (10⁻⁶: 1.25·10⁻⁶ in four)."""

PREDICTED = 0.1
"""The exact-Newton prediction of the next residual must lie below this fraction of the Newton tolerance."""


class FinalStepForcing:
    """Lowers ``ksp_rtol`` for the Newton step predicted to be the last (module docstring).

    Called from the solver's SNES convergence test with the residual norm of
    each iterate; does nothing for direct solvers (``preonly``).

    Args:
        snes: The Newton solver's SNES; its KSP is the one adjusted.
    """

    def __init__(self, snes: PETSc.SNES):
        self._ksp = snes.getKSP()
        self._configured: float | None = None
        self._norms: list[float] = []
        self.tightened = 0
        """Krylov solves whose tolerance was lowered so far."""

    def __call__(self, snes: PETSc.SNES, it: int, fnorm: float, reason: int) -> None:
        """Set the tolerance of the next Krylov solve (the configured one unless it is predicted to be the last).

        Args:
            snes: The SNES being solved.
            it: Newton iteration of ``fnorm`` (0: the start of a solve).
            fnorm: Residual norm of the current iterate (identical on every rank).
            reason: The convergence test's verdict on it; a nonzero one ends the solve, and the configured tolerance
                is restored.
        """
        if it == 0:
            self.restore()
            self._norms = []
        self._norms.append(float(fnorm))
        if reason != 0 or it == 0 or self._ksp.getType() == PETSc.KSP.Type.PREONLY:
            if reason != 0:
                self.restore()
            return
        previous, current = self._norms[-2], self._norms[-1]
        rtol, atol, _, _ = snes.getTolerances()
        target = max(atol, rtol * self._norms[0])
        if not (0 < current < 0.5 * previous) or current**3 / previous**2 > PREDICTED * target:
            self.restore()
            return
        configured = self._remember()
        wanted = min(configured, max(MARGIN * target / current, DEEPEST))
        if wanted < configured:
            self.tightened += 1
        self._set(wanted)

    def _remember(self) -> float:
        """The configured ``ksp_rtol`` (read once per solve, before anything lowers it)."""
        if self._configured is None:
            self._configured = float(self._ksp.getTolerances()[0])
        return self._configured

    def _set(self, rtol: float) -> None:
        _, atol, divtol, max_it = self._ksp.getTolerances()
        self._ksp.setTolerances(rtol=rtol, atol=atol, divtol=divtol, max_it=max_it)

    def restore(self) -> None:
        """Give the KSP its configured tolerance back (no-op when it was not changed)."""
        if self._configured is not None:
            self._set(self._configured)
            self._configured = None
