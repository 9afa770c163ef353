r"""Analytic first bending frequency of a clamped–free beam (verification of the dynamics).

Euler–Bernoulli: :math:`\omega_1 = (\beta_1 L)^2\sqrt{EI/(\rho A L^4)}`,
:math:`\beta_1 L = 1.8751040687`.

Timoshenko (shear deformation and rotary inertia): with
:math:`w = \sum C_k e^{s_k x}` and rotation :math:`\psi`, the equations

.. math::
    EI\psi'' + \kappa G A (w' - \psi) + \rho I \omega^2 \psi = 0,\qquad
    \kappa G A (w'' - \psi') + \rho A \omega^2 w = 0

give :math:`\psi = (s + q/s)\,e^{sx}`, :math:`q = \rho A\omega^2/(\kappa G A)`, and
:math:`EI s^4 + (EI q + \rho I\omega^2) s^2 + (\rho I\omega^2 - \kappa G A) q = 0`.
Below the cut-off frequency the roots are :math:`\pm\lambda_1, \pm i\lambda_2`;
the clamped (:math:`w = \psi = 0`) and free (:math:`\psi' = 0`,
:math:`w' - \psi = 0`) conditions give a real 4 × 4 determinant whose first
zero is :math:`\omega_1`.
"""

from __future__ import annotations

import math

import numpy as np

from hyperfem.errors import ParameterError

__all__ = ["cowper_shear_coefficient", "euler_bernoulli_cantilever", "timoshenko_cantilever"]

BETA1_L = 1.8751040687119611


def cowper_shear_coefficient(nu: float) -> float:
    r"""Cowper's shear coefficient of a rectangular section, :math:`10(1+\nu)/(12+11\nu)`."""
    return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)


def euler_bernoulli_cantilever(E: float, rho: float, L: float, b: float, h: float) -> float:
    """First angular frequency (rad/s) of a clamped–free Euler–Bernoulli beam, section b × h (bending about b)."""
    A, Iy = b * h, b * h**3 / 12.0
    return BETA1_L**2 * math.sqrt(E * Iy / (rho * A * L**4))


def _determinant(
    omega: float, E: float, G: float, rho: float, L: float, A: float, Iy: float, kappa: float
) -> float:
    kGA = kappa * G * A
    q = rho * A * omega**2 / kGA
    a, bq, c = E * Iy, E * Iy * q + rho * Iy * omega**2, (rho * Iy * omega**2 - kGA) * q
    disc = math.sqrt(bq * bq - 4 * a * c)
    S1, S2 = (-bq + disc) / (2 * a), (-bq - disc) / (2 * a)
    l1, l2 = math.sqrt(S1), math.sqrt(-S2)
    a1, a2 = l1 + q / l1, l2 - q / l2
    ch, sh, co, si = math.cosh(l1 * L), math.sinh(l1 * L), math.cos(l2 * L), math.sin(l2 * L)
    # Unknowns (A1, A2, A3, A4) of w = A1 ch + A2 sh + A3 cos + A4 sin.
    M = np.array(
        [
            [1.0, 0.0, 1.0, 0.0],  # w(0) = 0
            [0.0, a1, 0.0, a2],  # psi(0) = 0
            [a1 * l1 * ch, a1 * l1 * sh, -a2 * l2 * co, -a2 * l2 * si],  # psi'(L) = 0
            [(l1 - a1) * sh, (l1 - a1) * ch, -(l2 - a2) * si, (l2 - a2) * co],  # w'(L) - psi(L) = 0
        ]
    )
    return float(np.linalg.det(M) / ch)


def timoshenko_cantilever(
    E: float,
    nu: float,
    rho: float,
    L: float,
    b: float,
    h: float,
    kappa: float | None = None,
    *,
    bracket: tuple[float, float] = (0.3, 1.05),
    samples: int = 400,
    bisections: int = 100,
) -> float:
    r"""First angular frequency (rad/s) of a clamped–free Timoshenko beam, section b × h.

    The first zero of the frequency determinant is searched on ``samples``
    equally spaced frequencies in ``bracket`` (multiples of the
    Euler–Bernoulli frequency :math:`\omega_\text{EB}`: shear deformation and
    rotary inertia lower the frequency, to 0.90 :math:`\omega_\text{EB}` for
    the stubby 10 × 4 × 4 beam of seed 003), then refined by ``bisections``
    halvings of the interval with the first sign change (100 reach the
    floating-point resolution of the frequency).

    Args:
        E, nu, rho: Young's modulus, Poisson's ratio, density.
        L: Length.
        b, h: Width and height (bending about the width axis).
        kappa: Shear coefficient (default Cowper's for a rectangle).
        bracket: Search interval as multiples of :math:`\omega_\text{EB}`.
        samples: Frequencies sampled in the bracket to find the first sign change.
        bisections: Halvings of the bracketing interval.

    Raises:
        ParameterError: If the determinant has no sign change in the bracket.
    """
    lo_factor, hi_factor = bracket
    if not 0 < lo_factor < hi_factor or samples < 2 or bisections < 0:
        raise ParameterError(
            f"timoshenko_cantilever: need 0 < bracket[0] < bracket[1], samples >= 2, bisections >= 0; "
            f"got {bracket!r}, {samples!r}, {bisections!r}"
        )
    kappa = cowper_shear_coefficient(nu) if kappa is None else kappa
    G = E / (2 * (1 + nu))
    A, Iy = b * h, b * h**3 / 12.0
    w_eb = euler_bernoulli_cantilever(E, rho, L, b, h)
    f = lambda w: _determinant(w, E, G, rho, L, A, Iy, kappa)  # noqa: E731
    grid = np.linspace(lo_factor * w_eb, hi_factor * w_eb, samples)
    vals = [f(w) for w in grid]
    for k in range(len(grid) - 1):
        if vals[k] == 0 or vals[k] * vals[k + 1] < 0:
            lo, hi = grid[k], grid[k + 1]
            for _ in range(bisections):
                mid = 0.5 * (lo + hi)
                if f(lo) * f(mid) <= 0:
                    hi = mid
                else:
                    lo = mid
            return 0.5 * (lo + hi)
    raise ParameterError(
        f"timoshenko_cantilever: no root between {lo_factor:g} and {hi_factor:g} x the Euler-Bernoulli frequency"
    )
