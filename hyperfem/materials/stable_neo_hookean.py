r"""Stable Neo-Hookean material (Smith, de Goes, Kim 2018), invertible.

The logarithmic barrier of Neo-Hookean is replaced by a quadratic in
:math:`J` and a rest-stability term:

.. math::
    \psi(F) = \frac{\mu'}{2}(I_C - 3) + \frac{\lambda'}{2}(J - \alpha)^2
              - \frac{\mu'}{2}\ln(I_C + 1) - \psi_0,
    \qquad I_C = \operatorname{tr}(F^TF),\quad \alpha = 1 + \frac{3\mu'}{4\lambda'},

finite for every :math:`F` (:math:`I_C + 1 \ge 1`), so inverted elements
(:math:`J \le 0`) have finite energy and are pushed back. :math:`\alpha`
makes :math:`F = I` stress free; the constant
:math:`\psi_0 = \tfrac{\lambda'}{2}(1-\alpha)^2 - \tfrac{\mu'}{2}\ln 4` makes
:math:`\psi(I) = 0`. Its first Piola–Kirchhoff stress is

.. math::
    P = \mu'\Bigl(1 - \frac{1}{I_C + 1}\Bigr) F + \lambda'(J - \alpha)\operatorname{cof} F.

Consistency with linear elasticity: linearising :math:`P` at :math:`I`
gives :math:`\tfrac34\mu'(\delta F + \delta F^T) + (\lambda' - \tfrac58\mu')\operatorname{tr}(\delta F) I`,
which is :math:`2\mu\varepsilon + \lambda\operatorname{tr}(\varepsilon) I` for

.. math::
    \mu' = \tfrac43 \mu,\qquad \lambda' = \lambda + \tfrac56 \mu

(the mapping of Smith et al., eq. 15; seed 004 names the model among the
invertible ones). :func:`stable_neo_hookean` takes the Lamé pair and maps it.
In 2D the law is evaluated in plane strain (:math:`F_{33} = 1`, so
:math:`I_C = \operatorname{tr}(F^TF) + 1`), which keeps the same mapping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import ufl

from hyperfem.kinematics import cofactor, plane_strain_3d
from hyperfem.materials.invertibility import invertible
from hyperfem.materials.parameters import LameParameters
from hyperfem.validation import check_positive

__all__ = ["StableNeoHookeanParameters", "stable_neo_hookean", "stable_neo_hookean_stress"]


@dataclass(frozen=True)
class StableNeoHookeanParameters:
    r"""The constants :math:`(\mu', \lambda')` of the stable Neo-Hookean energy.

    Attributes:
        mu: :math:`\mu' > 0`.
        lmbda: :math:`\lambda' > 0` (it divides :math:`\alpha`).
    """

    mu: float
    lmbda: float

    def __post_init__(self) -> None:
        check_positive("mu", self.mu, "StableNeoHookeanParameters")
        check_positive("lmbda", self.lmbda, "StableNeoHookeanParameters")

    @classmethod
    def from_lame(cls, params: LameParameters) -> StableNeoHookeanParameters:
        r""":math:`\mu' = \tfrac43\mu`, :math:`\lambda' = \lambda + \tfrac56\mu` (consistent with linear elasticity).

        :math:`\lambda' > \mu/6 > 0` for every valid :class:`LameParameters`
        (bulk modulus :math:`\lambda + 2\mu/3 > 0`).
        """
        return cls(mu=4.0 * params.mu / 3.0, lmbda=params.lmbda + 5.0 * params.mu / 6.0)

    @property
    def alpha(self) -> float:
        r""":math:`\alpha = 1 + 3\mu'/(4\lambda')`, the rest value that makes :math:`P(I) = 0`."""
        return 1.0 + 0.75 * self.mu / self.lmbda

    @property
    def rest_offset(self) -> float:
        r""":math:`\psi_0 = \tfrac{\lambda'}{2}(1-\alpha)^2 - \tfrac{\mu'}{2}\ln 4`, so that :math:`\psi(I) = 0`."""
        return 0.5 * self.lmbda * (1.0 - self.alpha) ** 2 - 0.5 * self.mu * math.log(4.0)


def _constants(params: LameParameters | StableNeoHookeanParameters) -> StableNeoHookeanParameters:
    if isinstance(params, StableNeoHookeanParameters):
        return params
    return StableNeoHookeanParameters.from_lame(params)


@invertible
def stable_neo_hookean(
    F: ufl.core.expr.Expr, params: LameParameters | StableNeoHookeanParameters
) -> ufl.core.expr.Expr:
    r"""Strain-energy density of the stable Neo-Hookean law.

    Args:
        F: Deformation gradient (2×2 plane strain or 3×3).
        params: Lamé parameters (mapped by :meth:`StableNeoHookeanParameters.from_lame`)
            or the constants :math:`(\mu', \lambda')` themselves.

    Returns:
        :math:`\psi(F)` per unit reference volume, zero at :math:`F = I`.
    """
    c = _constants(params)
    F3 = plane_strain_3d(F)
    IC = ufl.inner(F3, F3)
    J = ufl.det(F3)
    return (
        0.5 * c.mu * (IC - 3.0)
        + 0.5 * c.lmbda * (J - c.alpha) ** 2
        - 0.5 * c.mu * ufl.ln(IC + 1.0)
        - c.rest_offset
    )


def stable_neo_hookean_stress(
    F: ufl.core.expr.Expr, params: LameParameters | StableNeoHookeanParameters
) -> ufl.core.expr.Expr:
    r"""Closed-form :math:`P = \mu'(1 - 1/(I_C+1)) F + \lambda'(J - \alpha)\operatorname{cof} F` (verification only).

    In 2D (plane strain) :math:`I_C` includes :math:`F_{33}^2 = 1` and
    :math:`\operatorname{cof}` is the 2×2 cofactor.
    """
    c = _constants(params)
    F3 = plane_strain_3d(F)
    IC = ufl.inner(F3, F3)
    J = ufl.det(F)
    return c.mu * (1.0 - 1.0 / (IC + 1.0)) * F + c.lmbda * (J - c.alpha) * cofactor(F)
