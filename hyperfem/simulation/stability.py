r"""The stability of every recorded state: the lowest eigenvalues of the tangent as columns of a run (issue 22).

:class:`Stability` is an output of a :class:`~hyperfem.simulation.Simulation`:
after every accepted step (and for the initial state) it solves
:math:`K\varphi = \mu B\varphi` for the ``n`` eigenvalues of smallest
magnitude of the tangent (:class:`~hyperfem.stability.TangentEigensolver`:
SLEPc shift-and-invert, Dirichlet rows out of the spectrum, the mixed
problem's displacement Schur complement) and adds the columns
``lowest_eigenvalues`` (ascending), ``negative_eigenvalues`` (exact: the
inertia of an :math:`LDL^T` factorisation for a symmetric tangent) and
``stable``. A converged state that is not stable draws a
:class:`UnstableStateWarning` once per run of unstable states (rank 0): under
load control it would not be observed (a column past its Euler load, the
descending branch of a balloon's pressure). The summary holds the last
state's values and the first unstable load factor.

A dynamic run is analysed on its body's tangent (the static stability of the
current configuration, without inertia). Contact energies are not in the
tangent form and are left out.
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING, Any

from hyperfem.simulation.outputs import Output
from hyperfem.validation import check_count

if TYPE_CHECKING:
    from hyperfem.simulation.runner import Simulation
    from hyperfem.solver.stepping import StepRecord
    from hyperfem.stability.spectrum import TangentEigensolver

__all__ = ["Stability", "UnstableStateWarning"]


class UnstableStateWarning(UserWarning):
    """A converged state whose tangent has a negative eigenvalue (unstable under load control)."""


class Stability(Output):
    """The lowest eigenvalues of the tangent at every recorded state (module docstring).

    Args:
        n: Eigenvalues per state (those of smallest magnitude).
        metric: ``"mass"`` (the displacement mass matrix: eigenvalues that do
            not depend on the mesh) or ``"euclidean"``.

    Raises:
        ParameterError: ``n`` not an integer >= 1 (and, when the run starts, an
            unknown metric).
    """

    def __init__(self, n: int = 3, metric: str = "mass") -> None:
        check_count("n", n, "Stability")
        self.n = int(n)
        self.metric = metric
        self._solver: TangentEigensolver | None = None
        self._unstable = False
        self._first_unstable: float | None = None

    def start(self, sim: Simulation) -> None:
        """Compile the tangent and metric forms of the run's body (collective)."""
        from hyperfem.stability.spectrum import TangentEigensolver

        base = sim.fields.base  # the body (a dynamic run: its static tangent)
        self._solver = TangentEigensolver(base, self.n, metric=self.metric)

    def measure(self, sim: Simulation, step: StepRecord | None) -> dict[str, Any]:
        """The eigenvalues, the negative count and stability of the state just recorded (collective)."""
        assert self._solver is not None  # compiled by start
        spectrum = self._solver.solve()
        stable = bool(spectrum.stable)
        if not stable and self._first_unstable is None:
            self._first_unstable = float(sim.time)
        if not stable and not self._unstable and sim.comm.rank == 0:
            warnings.warn(
                f"{sim.name}: the state at t = {sim.time:g} is unstable: its tangent has "
                f"{spectrum.negative} negative eigenvalue(s), the lowest {spectrum.lowest:.4g} (under load control "
                "it would not be observed: a limit or bifurcation point was passed)",
                UnstableStateWarning,
                stacklevel=2,
            )
        self._unstable = not stable
        return {
            "lowest_eigenvalues": [float(v) for v in spectrum.eigenvalues],
            "negative_eigenvalues": int(spectrum.negative),
            "stable_state": stable,
        }

    def summary(self, sim: Simulation, summary: dict) -> dict:
        """The last state's eigenvalues and the first load factor (time) found unstable."""
        if not sim.rows or "lowest_eigenvalues" not in sim.rows[-1]:
            return {}
        last = sim.rows[-1]
        return {
            "stability": {
                "lowest_eigenvalues": last["lowest_eigenvalues"],
                "negative_eigenvalues": last["negative_eigenvalues"],
                "first_unstable_time": self._first_unstable,
            }
        }

    def close(self, sim: Simulation) -> None:
        """Free the eigensolver's matrices."""
        if self._solver is not None:
            self._solver.destroy()
            self._solver = None
