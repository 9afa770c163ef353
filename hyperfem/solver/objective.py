r"""The energy objective of :class:`~hyperfem.solver.NewtonSolver`'s line search, with its round-off guard.

For conservative problems the total potential :math:`\Pi` is the SNES
objective, so the backtracking line search judges a step by the energy rather
than by the residual norm. Near convergence the energy change of a Newton
step, :math:`\tfrac12 R\cdot\delta u`, drops below the resolution of the
assembled :math:`\Pi` (round-off and cancellation, e.g. of the inertia term of
an incremental potential). When a trial energy is within
``energy_roundoff_rtol`` of the current one, the step is judged by the
residual norm instead, so tight residual tolerances are still met.
"""

from __future__ import annotations

from collections.abc import Callable

from mpi4py import MPI  # noqa: F401  (before petsc4py)
from petsc4py import PETSc

__all__ = ["EnergyObjective"]


class EnergyObjective:
    r"""SNES objective :math:`\Pi(x)` with the round-off acceptance by residual (module docstring).

    Holds no reference to the solver: it moves the state and evaluates the
    energy through the callables it is given.

    Args:
        rtol: ``energy_roundoff_rtol``: relative energy change (w.r.t. the
            stored plus external energy magnitudes) below which a trial step
            is judged by the residual norm.
        set_state: Moves the problem to a SNES vector and runs the state hooks.
        energies: The assembled (internal, external) energies at the current state (collective).
        template_x: A vector of the unknown's layout.
        template_b: A vector of the residual's layout.

    Attributes:
        roundoff_accepts: Steps the energy could not resolve, accepted by the residual (so far).
    """

    def __init__(
        self,
        rtol: float,
        set_state: Callable[[PETSc.Vec], None],
        energies: Callable[[], tuple[float, float]],
        template_x: PETSc.Vec,
        template_b: PETSc.Vec,
    ):
        self.rtol = float(rtol)
        self._set_state = set_state
        self._energies = energies
        self._work = template_x.duplicate()
        self._residual_work = template_b.duplicate()
        self._ref: tuple[float, float] | None = None
        self._full_step_change: float | None = None
        self._trial = template_x.duplicate()
        self._trial_energy: tuple[float, float] | None = None
        self._judged_x = template_x.duplicate()
        self._judged_valid = False
        self.roundoff_accepts = 0
        self.energies_reused = 0
        """Energies of an iterate taken from its evaluation as the previous line search's trial (so far)."""
        self.residuals_reused = 0
        """Residuals of an accepted step copied from its judgment (:meth:`judged_residual`, so far)."""

    def reset(self) -> None:
        """Forget the reference energy, the last trial's and the judged residual (at the start of a solve)."""
        self._ref = None
        self._trial_energy = None
        self._judged_valid = False

    def judged_residual(self, x: PETSc.Vec, b: PETSc.Vec) -> bool:
        """Copy into ``b`` the residual :meth:`_judge_by_residual` assembled at ``x``, if it was at ``x``.

        SNES assembles the residual of the step it accepted; a step judged by the residual had it
        assembled already (one residual assembly saved per judged step). Used once. Collective.
        """
        if not self._judged_valid:
            return False
        self._judged_valid = False
        if not x.equal(self._judged_x):
            return False
        self._residual_work.copy(b)
        self.residuals_reused += 1
        return True

    def _energy(self, x: PETSc.Vec, current: bool) -> tuple[float, float]:
        r"""(:math:`\Pi(x)`, its scale): the last trial's when ``x`` is that trial, accepted (``current``).

        The line search evaluates the energy of the current iterate first, and that iterate is,
        bit for bit, the trial the previous line search accepted: one energy assembly per Newton
        iteration is saved (of two; 3–4 ms each on the bend at 28.6k unknowns). Collective.
        """
        if current and self._trial_energy is not None and x.equal(self._trial):
            self.energies_reused += 1
            return self._trial_energy
        self._set_state(x)
        internal, external = self._energies()
        energy = (internal - external, abs(internal) + abs(external))
        if not current:
            x.copy(self._trial)
            self._trial_energy = energy
        return energy

    def __call__(self, snes: PETSc.SNES, x: PETSc.Vec) -> float:
        r""":math:`\Pi(x)`, or for an unresolvable trial step the change the linear model predicts."""
        current = x.handle == snes.getSolution().handle
        value, scale = self._energy(x, current)
        if current or self._ref is None:
            self._ref = (value, scale)
            self._full_step_change = None
            return value
        ref, ref_scale = self._ref
        X = snes.getSolution()
        R = snes.getFunction()[0]  # type: ignore[index]  # petsc4py stubs: getFunction returns (Vec, callback)
        self._work.waxpy(-1.0, X, x)
        predicted = abs(R.dot(self._work))  # first-order energy change of the trial step
        if self._full_step_change is None:  # the line search tries the full step first
            self._full_step_change = predicted
        resolution = self.rtol * max(scale, ref_scale)
        if self._full_step_change <= resolution and (abs(value - ref) <= resolution or predicted <= resolution):
            return self._judge_by_residual(snes, x, ref, predicted)
        return value

    def _judge_by_residual(self, snes: PETSc.SNES, x: PETSc.Vec, ref: float, predicted: float) -> float:
        r"""Accept a step the energy cannot resolve if it lowers the residual norm.

        Near convergence the energy cannot resolve the Newton step: its
        observed or its predicted change is at the level of the cancellation
        noise in the assembled sum (the observed change alone is not enough:
        noise of 1e-8 of the scale was measured in a dynamic step whose
        predicted change was 1e-12). Judge it by the residual norm instead; if
        that decreased, report the decrease the linear model predicts,
        :math:`-R(X)\cdot(x - X)`, so the step is accepted. Only when the
        *full* step is below the resolution: a step the line search has merely
        shortened far from the solution is judged by the energy (accepting it
        by a residual dip made a hard step crawl for 50 iterations instead of
        failing fast and being cut back).
        """
        R = snes.getFunction()[0]  # type: ignore[index]  # petsc4py stubs: getFunction returns (Vec, callback)
        snes.computeFunction(x, self._residual_work)
        self._set_state(x)
        x.copy(self._judged_x)
        self._judged_valid = True
        if self._residual_work.norm() < R.norm():
            self.roundoff_accepts += 1
            return ref - predicted
        return ref + predicted
