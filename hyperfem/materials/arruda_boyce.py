r"""Arruda–Boyce eight-chain rubber law, in its five-term series form.

.. math::
    \psi(F) = \mu\sum_{i=1}^{5}\frac{C_i}{\lambda_m^{2i-2}}\left(\bar I_1^{\,i} - 3^i\right) + U(J),\qquad
    C_i = \tfrac12,\ \tfrac1{20},\ \tfrac{11}{1050},\ \tfrac{19}{7000},\ \tfrac{519}{673750},

with :math:`\bar I_1 = J^{-2/3}\operatorname{tr} C`. The series is the first five
terms of the inverse-Langevin expansion of the eight-chain energy of E. M. Arruda
and M. C. Boyce, "A three-dimensional constitutive model for the large stretch
behavior of rubber elastic materials", *J. Mech. Phys. Solids* 41 (1993) 389–412,
in the form and notation of the Abaqus Theory Manual ("Arruda–Boyce form":
:math:`\mu`, locking stretch :math:`\lambda_m`, :math:`\lambda_m^2 = N` the number of
chain links). :math:`\lambda_m \to \infty` gives the neo-Hookean law
:math:`\tfrac{\mu}{2}(\bar I_1 - 3)`.

:math:`\mu` is *not* the small-strain shear modulus; that is (:attr:`ArrudaBoyceParameters.initial_shear_modulus`)

.. math::
    \mu_0 = 2\,\partial_{\bar I_1}\psi\big|_{\bar I_1 = 3}
    = \mu\left(1 + \frac{3}{5\lambda_m^2} + \frac{99}{175\lambda_m^4}
      + \frac{513}{875\lambda_m^6} + \frac{42039}{67375\lambda_m^8}\right).

(FEBio's ``Arruda-Boyce`` material, ``FEArrudaBoyce.cpp``, uses the coefficients
:math:`i\,C_i`, i.e. 1/2, 1/10, 11/350, 19/1750, 519/134750: its :math:`\mu` and
:math:`N` do not give the same energy as the values here beyond the first term.)

The first Piola–Kirchhoff stress (:func:`arruda_boyce_stress`, verification only) is

.. math::
    P = 2\psi_1 J^{-2/3}\left(F - \tfrac13\operatorname{tr}C\,F^{-T}\right) + J U'(J) F^{-T},\qquad
    \psi_1 = \mu\sum_{i=1}^{5} \frac{i\,C_i}{\lambda_m^{2i-2}}\,\bar I_1^{\,i-1}.
"""

from __future__ import annotations

from dataclasses import dataclass

import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import isochoric_invariants, jacobian, plane_strain_3d
from hyperfem.materials.mooney_rivlin import mooney_rivlin_isochoric_stress
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_positive, is_finite_number

__all__ = [
    "ARRUDA_BOYCE_COEFFICIENTS",
    "ArrudaBoyceParameters",
    "arruda_boyce",
    "arruda_boyce_isochoric",
    "arruda_boyce_stress",
]

Expr = ufl.core.expr.Expr

ARRUDA_BOYCE_COEFFICIENTS: tuple[float, ...] = (1.0 / 2.0, 1.0 / 20.0, 11.0 / 1050.0, 19.0 / 7000.0, 519.0 / 673750.0)
r"""The series coefficients :math:`C_1, \dots, C_5` (Arruda & Boyce 1993; Abaqus)."""


@dataclass(frozen=True)
class ArrudaBoyceParameters:
    r"""Arruda–Boyce (1993) constants, five-term series as in Abaqus.

    Attributes:
        mu: Modulus :math:`\mu > 0` of the series (stress units, e.g. Pa); the small-strain
            shear modulus is :attr:`initial_shear_modulus`.
        lambda_m: Locking stretch :math:`\lambda_m > 1` (dimensionless; :math:`\lambda_m^2 = N`).
        K: Bulk modulus :math:`K > 0` (stress units).
        volumetric: Volumetric law name (see :mod:`hyperfem.materials.volumetric`).
    """

    mu: float
    lambda_m: float
    K: float
    volumetric: str = "log"

    def __post_init__(self) -> None:
        where = "ArrudaBoyceParameters"
        check_positive("mu", self.mu, where)
        if not (is_finite_number(self.lambda_m) and self.lambda_m > 1.0):
            raise ParameterError(f"{where}: lambda_m must be a finite number > 1, got {self.lambda_m!r}")
        check_positive("K", self.K, where)
        volumetric_law(self.volumetric)

    @property
    def initial_shear_modulus(self) -> float:
        r"""Small-strain shear modulus :math:`\mu_0 = 2\mu\sum_i i\,C_i\,3^{i-1}/\lambda_m^{2i-2}`."""
        return 2.0 * self.mu * _series_derivative_value(3.0, self.lambda_m)

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus (same as :attr:`initial_shear_modulus`)."""
        return self.initial_shear_modulus

    @classmethod
    def from_initial_shear_modulus(
        cls, mu0: float, lambda_m: float, K: float, volumetric: str = "log"
    ) -> ArrudaBoyceParameters:
        r"""The parameters whose small-strain shear modulus is ``mu0`` (:math:`\mu = \mu_0/(\mu_0/\mu)`)."""
        check_positive("mu0", mu0, "ArrudaBoyceParameters.from_initial_shear_modulus")
        unit = cls(mu=1.0, lambda_m=lambda_m, K=K, volumetric=volumetric)
        return cls(mu=mu0 / unit.initial_shear_modulus, lambda_m=lambda_m, K=K, volumetric=volumetric)


def _series_derivative_value(I1: float, lambda_m: float) -> float:
    r""":math:`\sum_i i\,C_i\,\bar I_1^{i-1}/\lambda_m^{2i-2}` for a number :math:`\bar I_1`."""
    return sum((i + 1) * c * I1**i / lambda_m ** (2 * i) for i, c in enumerate(ARRUDA_BOYCE_COEFFICIENTS))


def arruda_boyce_isochoric(F: Expr, params: ArrudaBoyceParameters) -> Expr:
    r"""Isochoric part :math:`\mu\sum_i C_i\lambda_m^{2-2i}(\bar I_1^i - 3^i)` (2×2 ``F``: plane strain)."""
    I1b, _, _ = isochoric_invariants(F)
    terms = [
        c / params.lambda_m ** (2 * i) * (I1b ** (i + 1) - 3.0 ** (i + 1))
        for i, c in enumerate(ARRUDA_BOYCE_COEFFICIENTS)
    ]
    return params.mu * sum(terms[1:], terms[0])


def arruda_boyce(F: Expr, params: ArrudaBoyceParameters) -> Expr:
    """Strain-energy density of the Arruda–Boyce law (five-term series) with its volumetric term.

    Args:
        F: Deformation gradient (3×3, or 2×2 for plane strain).
        params: Material parameters.
    """
    return arruda_boyce_isochoric(F, params) + volumetric_energy(
        jacobian(plane_strain_3d(F)), params.K, params.volumetric
    )


def arruda_boyce_stress(F: Expr, params: ArrudaBoyceParameters) -> Expr:
    r"""Closed-form :math:`P` for the ``"log"`` volumetric law, :math:`p = K\ln J` (3×3 ``F``; verification only)."""
    if params.volumetric != "log":
        raise ParameterError("arruda_boyce_stress: closed form implemented for the 'log' volumetric law")
    I1b, _, J = isochoric_invariants(F)
    y = I1b / params.lambda_m**2
    series: Expr | float = 0.0
    for i in range(len(ARRUDA_BOYCE_COEFFICIENTS), 0, -1):  # Horner: sum_i i C_i y^(i-1)
        series = series * y + i * ARRUDA_BOYCE_COEFFICIENTS[i - 1]
    psi1 = params.mu * series
    return mooney_rivlin_isochoric_stress(F, psi1, 0.0) + params.K * ufl.ln(J) * ufl.inv(F).T
