r"""Inversion-robust Neo-Hookean material of seed 000 (eq. 2.9, 2.19).

The logarithm of the Neo-Hookean law is replaced by its cubic Taylor
expansion about :math:`J = 1`,

.. math::
    r(J) = (J - 1) - \frac{(J-1)^2}{2} + \frac{(J-1)^3}{3},

which agrees with :math:`\ln J` to third order but is finite for
:math:`J \le 0`, so inverted elements have finite energy and stress:

.. math::
    \psi(F) = \frac{\mu}{2}(\operatorname{tr} C - d) - \mu\, r(J) + \frac{\lambda}{2} r(J)^2,
    \qquad
    P = \mu F + (\lambda r(J) - \mu)\, r'(J)\, J F^{-T}.
"""

from __future__ import annotations

import ufl

from hyperfem.kinematics import jacobian, right_cauchy_green
from hyperfem.materials.parameters import LameParameters

__all__ = ["log_taylor3", "log_taylor3_derivative", "robust_neo_hookean", "robust_neo_hookean_stress"]


def log_taylor3(J: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r"""Cubic Taylor expansion of :math:`\ln J` about 1, :math:`r(J)`."""
    s = J - 1.0
    return s - s**2 / 2.0 + s**3 / 3.0


def log_taylor3_derivative(J: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r""":math:`r'(J) = 1 - (J-1) + (J-1)^2`."""
    s = J - 1.0
    return 1.0 - s + s**2


def robust_neo_hookean(F: ufl.core.expr.Expr, params: LameParameters) -> ufl.core.expr.Expr:
    """Strain-energy density of the inversion-robust Neo-Hookean law.

    Args:
        F: Deformation gradient (2×2 plane strain or 3×3).
        params: Lamé parameters.

    Returns:
        :math:`\\psi(F)` per unit reference volume.
    """
    d = F.ufl_shape[0]
    r = log_taylor3(jacobian(F))
    return 0.5 * params.mu * (ufl.tr(right_cauchy_green(F)) - d) - params.mu * r + 0.5 * params.lmbda * r**2


def robust_neo_hookean_stress(F: ufl.core.expr.Expr, params: LameParameters) -> ufl.core.expr.Expr:
    r"""Closed-form :math:`P` of seed 000 eq. 2.19 (for verification only)."""
    J = jacobian(F)
    r = log_taylor3(J)
    return params.mu * F + (params.lmbda * r - params.mu) * log_taylor3_derivative(J) * J * ufl.inv(F).T
