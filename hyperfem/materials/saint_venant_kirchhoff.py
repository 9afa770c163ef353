r"""Saint Venant–Kirchhoff material.

.. math::
    \psi(F) = \mu\, E : E + \frac{\lambda}{2} (\operatorname{tr} E)^2,
    \qquad P = F\,[2\mu E + \lambda (\operatorname{tr} E) I].

Not polyconvex: it softens and can collapse under strong compression.
"""

from __future__ import annotations

import ufl

from hyperfem.kinematics import green_lagrange
from hyperfem.materials.parameters import LameParameters

__all__ = ["saint_venant_kirchhoff", "saint_venant_kirchhoff_stress"]


def saint_venant_kirchhoff(F: ufl.core.expr.Expr, params: LameParameters) -> ufl.core.expr.Expr:
    """Strain-energy density of the Saint Venant–Kirchhoff law."""
    E = green_lagrange(F)
    return params.mu * ufl.inner(E, E) + 0.5 * params.lmbda * ufl.tr(E) ** 2


def saint_venant_kirchhoff_stress(F: ufl.core.expr.Expr, params: LameParameters) -> ufl.core.expr.Expr:
    r"""Closed-form :math:`P = F S`, :math:`S = 2\mu E + \lambda \operatorname{tr}(E) I`."""
    d = F.ufl_shape[0]
    E = green_lagrange(F)
    return F * (2.0 * params.mu * E + params.lmbda * ufl.tr(E) * ufl.Identity(d))
