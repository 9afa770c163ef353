r"""Compressible Neo-Hookean material in the form of the seeds.

.. math::
    \psi(F) = \frac{\mu}{2}(\operatorname{tr} C - d) - \mu \ln J + \frac{\lambda}{2} (\ln J)^2,

with :math:`d` the spatial dimension (plane strain in 2D). Its first
Piola–Kirchhoff stress (seed 000, eq. 2.8) is

.. math::
    P = \mu F + (\lambda \ln J - \mu) F^{-T}.
"""

from __future__ import annotations

import ufl

from hyperfem.kinematics import isochoric_invariants, jacobian, right_cauchy_green
from hyperfem.materials.parameters import LameParameters

__all__ = ["neo_hookean", "neo_hookean_isochoric", "neo_hookean_stress"]


def neo_hookean(F: ufl.core.expr.Expr, params: LameParameters) -> ufl.core.expr.Expr:
    """Strain-energy density of the compressible Neo-Hookean law.

    Args:
        F: Deformation gradient (2×2 plane strain or 3×3).
        params: Lamé parameters.

    Returns:
        :math:`\\psi(F)` per unit reference volume.
    """
    d = F.ufl_shape[0]
    J = jacobian(F)
    lnJ = ufl.ln(J)
    return 0.5 * params.mu * (ufl.tr(right_cauchy_green(F)) - d) - params.mu * lnJ + 0.5 * params.lmbda * lnJ**2


def neo_hookean_stress(F: ufl.core.expr.Expr, params: LameParameters) -> ufl.core.expr.Expr:
    r"""Closed-form :math:`P = \mu F + (\lambda \ln J - \mu) F^{-T}` (for verification only)."""
    J = jacobian(F)
    return params.mu * F + (params.lmbda * ufl.ln(J) - params.mu) * ufl.inv(F).T


def neo_hookean_isochoric(F: ufl.core.expr.Expr, mu: float | ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r"""The isochoric Neo-Hookean part :math:`\frac{\mu}{2}(\bar I_1 - 3)` of a split energy (mixed formulation).

    Args:
        F: Deformation gradient (3×3).
        mu: Shear modulus.
    """
    return 0.5 * mu * (isochoric_invariants(F)[0] - 3.0)
