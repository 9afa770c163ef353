r"""Time integrators written as incremental potentials.

Every scheme expresses the (possibly weighted) acceleration and velocity
that enter the balance of momentum linearly in the unknown displacement
:math:`u = u_{n+1}`,

.. math::
    a_\ast = A\,(u - \tilde u), \qquad v_\ast = B\,(u - \hat u),

with scalars :math:`A, B` and fields :math:`\tilde u, \hat u` built from the
previous state :math:`(u_n, v_n, a_n)`. The step then minimises (for
conservative loads)

.. math::
    \Pi_\Delta(u) = \frac{A}{2}\|u - \tilde u\|_M^2 + \frac{B}{2}\|u - \hat u\|_C^2
      + \frac{1}{1-\alpha_f}\,\Pi\bigl((1-\alpha_f)u + \alpha_f u_n;\ t_{n+1-\alpha_f}\bigr),

whose stationarity condition is
:math:`M a_\ast + C v_\ast + f_\text{int}(u_\ast) = f_\text{ext}(t_\ast)`.

* :class:`BackwardEuler` (seed 000, eq. 2.15): :math:`A = 1/\Delta t^2`,
  :math:`\tilde u = u_n + \Delta t\,v_n`; :math:`B = 1/\Delta t`, :math:`\hat u = u_n`.
  First order, dissipative.
* :class:`Newmark` (seed 003, §2.1, eq. 2.21):
  :math:`u_{n+1} = u_n + \Delta t v_n + \Delta t^2((\tfrac12 - \beta)a_n + \beta a_{n+1})`,
  :math:`v_{n+1} = v_n + \Delta t((1-\gamma)a_n + \gamma a_{n+1})`; the default
  :math:`\beta = 1/4, \gamma = 1/2` (average acceleration) is second order and
  conserves energy for linear problems.
* :class:`GeneralizedAlpha` (Chung & Hulbert 1993) with spectral radius
  :math:`\rho_\infty`: :math:`\alpha_m = (2\rho_\infty - 1)/(\rho_\infty + 1)`,
  :math:`\alpha_f = \rho_\infty/(\rho_\infty + 1)`,
  :math:`\gamma = \tfrac12 - \alpha_m + \alpha_f`,
  :math:`\beta = \tfrac14(1 - \alpha_m + \alpha_f)^2`; the balance holds at
  :math:`x_{n+1-\alpha} = (1-\alpha)x_{n+1} + \alpha x_n`.
* :class:`QuasiStatic`: no inertia; the stepping loop then reduces to load stepping in time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hyperfem.errors import ParameterError
from hyperfem.validation import check_positive, is_finite_number

__all__ = ["BackwardEuler", "GeneralizedAlpha", "Newmark", "QuasiStatic", "TimeIntegrator"]


class TimeIntegrator:
    """Interface of the schemes (see the module docstring for the notation).

    Attributes:
        name: Short name used in output.
        dynamic: Whether the scheme has inertia.
        order: Order of accuracy in time.
        alpha_m, alpha_f: Weights of the generalized-midpoint balance.
    """

    name = "abstract"
    dynamic = True
    order = 1
    alpha_m = 0.0
    alpha_f = 0.0

    def coefficients(
        self, dt: float, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray
    ) -> tuple[float, np.ndarray, float, np.ndarray]:
        r"""Return :math:`(A, \tilde u, B, \hat u)` for a step of size ``dt``."""
        raise NotImplementedError

    def update(
        self, dt: float, u: np.ndarray, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and acceleration at :math:`t_{n+1}` from the converged ``u``."""
        raise NotImplementedError


class QuasiStatic(TimeIntegrator):
    r"""No inertia: each step solves the equilibrium at the new time.

    The velocity kept is the rate :math:`(u_{n+1} - u_n)/\Delta t`; it only
    serves the secant predictor :math:`u_n + \Delta t\,v_n` of the next step.
    """

    name = "quasi-static"
    dynamic = False
    order = 0

    def coefficients(
        self, dt: float, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray
    ) -> tuple[float, np.ndarray, float, np.ndarray]:
        return 0.0, u_n, 0.0, u_n

    def update(
        self, dt: float, u: np.ndarray, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        return (u - u_n) / dt, np.zeros_like(u)


class BackwardEuler(TimeIntegrator):
    r"""Implicit (backward) Euler, seed 000 eq. (2.15): :math:`v_{n+1} = (u - u_n)/\Delta t`."""

    name = "backward-euler"
    order = 1

    def coefficients(
        self, dt: float, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray
    ) -> tuple[float, np.ndarray, float, np.ndarray]:
        return 1.0 / dt**2, u_n + dt * v_n, 1.0 / dt, u_n

    def update(
        self, dt: float, u: np.ndarray, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        v = (u - u_n) / dt
        return v, (v - v_n) / dt


class _AlphaFamily(TimeIntegrator):
    beta: float
    gamma: float

    def _check(self) -> None:
        for name in ("beta", "gamma"):
            check_positive(name, getattr(self, name), type(self).__name__)

    def _predict(
        self, dt: float, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        u_pred = u_n + dt * v_n + dt**2 * (0.5 - self.beta) * a_n
        v_pred = v_n + dt * (1.0 - self.gamma) * a_n
        return u_pred, v_pred

    def coefficients(
        self, dt: float, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray
    ) -> tuple[float, np.ndarray, float, np.ndarray]:
        am, af = self.alpha_m, self.alpha_f
        u_pred, v_pred = self._predict(dt, u_n, v_n, a_n)
        A = (1.0 - am) / (self.beta * dt**2)
        B = (1.0 - af) * self.gamma / (self.beta * dt)
        u_tilde = u_pred - (am / A) * a_n if am else u_pred
        u_hat = u_pred - ((1.0 - af) * v_pred + af * v_n) / B
        return A, u_tilde, B, u_hat

    def update(
        self, dt: float, u: np.ndarray, u_n: np.ndarray, v_n: np.ndarray, a_n: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        u_pred, v_pred = self._predict(dt, u_n, v_n, a_n)
        a = (u - u_pred) / (self.beta * dt**2)
        return v_pred + self.gamma * dt * a, a

    @property
    def unconditionally_stable(self) -> bool:
        r"""Linear stability: :math:`\gamma \ge 1/2` and :math:`\beta \ge (2\gamma + 1)^2/16` (seed 003)."""
        return self.gamma >= 0.5 and self.beta >= (2 * self.gamma + 1) ** 2 / 16 - 1e-15


@dataclass(frozen=True)
class Newmark(_AlphaFamily):
    """Newmark's method; defaults to the average-acceleration rule.

    Attributes:
        beta: Newmark :math:`\\beta` (> 0; explicit :math:`\\beta = 0` is not supported).
        gamma: Newmark :math:`\\gamma`.
    """

    beta: float = 0.25
    gamma: float = 0.5

    def __post_init__(self) -> None:
        self._check()

    @property
    def name(self) -> str:  # type: ignore[override]
        return f"newmark(beta={self.beta:g},gamma={self.gamma:g})"

    @property
    def order(self) -> int:  # type: ignore[override]
        return 2 if abs(self.gamma - 0.5) < 1e-14 else 1


@dataclass(frozen=True)
class GeneralizedAlpha(_AlphaFamily):
    r"""Generalized-:math:`\alpha` (Chung–Hulbert) with high-frequency spectral radius ``rho_inf``.

    ``rho_inf = 1`` gives the (non-dissipative) trapezoidal/midpoint family,
    ``rho_inf = 0`` annihilates the highest frequencies in one step.
    """

    rho_inf: float = 0.8

    def __post_init__(self) -> None:
        if not (is_finite_number(self.rho_inf) and 0.0 <= self.rho_inf <= 1.0):
            raise ParameterError(f"GeneralizedAlpha: rho_inf must lie in [0, 1], got {self.rho_inf!r}")

    name = "generalized-alpha"
    order = 2

    @property
    def alpha_m(self) -> float:  # type: ignore[override]
        return (2.0 * self.rho_inf - 1.0) / (self.rho_inf + 1.0)

    @property
    def alpha_f(self) -> float:  # type: ignore[override]
        return self.rho_inf / (self.rho_inf + 1.0)

    @property
    def gamma(self) -> float:  # type: ignore[override]
        return 0.5 - self.alpha_m + self.alpha_f

    @property
    def beta(self) -> float:  # type: ignore[override]
        return 0.25 * (1.0 - self.alpha_m + self.alpha_f) ** 2
