r"""Small-strain (linear) isotropic elasticity written as an energy of :math:`F`.

.. math::
    \psi(F) = \mu\, \varepsilon : \varepsilon + \frac{\lambda}{2} (\operatorname{tr} \varepsilon)^2,
    \qquad \varepsilon = \operatorname{sym}(F) - I.

Only valid for small displacement gradients; not objective under finite rotation.
"""

from __future__ import annotations

import ufl

from hyperfem.kinematics import small_strain
from hyperfem.materials.parameters import LameParameters

__all__ = ["linear_elastic", "linear_elastic_stress"]


def linear_elastic(F: ufl.core.expr.Expr, params: LameParameters) -> ufl.core.expr.Expr:
    """Strain-energy density of small-strain isotropic elasticity."""
    eps = small_strain(F)
    return params.mu * ufl.inner(eps, eps) + 0.5 * params.lmbda * ufl.tr(eps) ** 2


def linear_elastic_stress(F: ufl.core.expr.Expr, params: LameParameters) -> ufl.core.expr.Expr:
    r"""Closed-form :math:`\sigma = 2\mu\varepsilon + \lambda \operatorname{tr}(\varepsilon) I`."""
    d = F.ufl_shape[0]
    eps = small_strain(F)
    return 2.0 * params.mu * eps + params.lmbda * ufl.tr(eps) * ufl.Identity(d)
