r"""Yeoh and reduced-polynomial rubber laws (isochoric :math:`\bar I_1` series plus :math:`U(J)`).

The reduced polynomial of order :math:`N` (Abaqus's name for the :math:`\bar I_2`-free
polynomial) is

.. math::
    \psi(F) = \sum_{i=1}^{N} C_{i0}\,(\bar I_1 - 3)^i + U(J),\qquad
    \bar I_1 = J^{-2/3}\operatorname{tr} C,

and the Yeoh law is its cubic case :math:`N = 3`,
:math:`\psi = C_{10}(\bar I_1 - 3) + C_{20}(\bar I_1 - 3)^2 + C_{30}(\bar I_1 - 3)^3 + U(J)`
(O. H. Yeoh, "Some forms of the strain energy function for rubber",
*Rubber Chem. Technol.* 66 (1993) 754–771). :math:`N = 1` is the isochoric
neo-Hookean law. The small-strain shear modulus is :math:`\mu_0 = 2C_{10}`.
Yeoh's fits typically have :math:`C_{20} < 0 < C_{30}`; the parameter classes
accept any sign of the higher coefficients (only :math:`C_{10} > 0` is required),
so a fit whose :math:`\partial\psi/\partial\bar I_1` turns negative at large
:math:`\bar I_1` (a loss of stability) is the user's to check.

The first Piola–Kirchhoff stress (:func:`reduced_polynomial_stress`, verification only) is

.. math::
    P = 2\psi_1 J^{-2/3}\left(F - \tfrac13\operatorname{tr}C\,F^{-T}\right) + J U'(J) F^{-T},\qquad
    \psi_1 = \sum_{i=1}^{N} i\,C_{i0}(\bar I_1 - 3)^{i-1}.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import isochoric_invariants, jacobian, plane_strain_3d
from hyperfem.materials.mooney_rivlin import mooney_rivlin_isochoric_stress
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_positive, is_finite_number

__all__ = [
    "ReducedPolynomialParameters",
    "YeohParameters",
    "reduced_polynomial",
    "reduced_polynomial_isochoric",
    "reduced_polynomial_stress",
    "yeoh",
    "yeoh_isochoric",
    "yeoh_stress",
]

Expr = ufl.core.expr.Expr


@dataclass(frozen=True)
class ReducedPolynomialParameters:
    r"""Coefficients of the reduced polynomial :math:`\sum_i C_{i0}(\bar I_1 - 3)^i` (stress units, e.g. Pa).

    Attributes:
        coefficients: :math:`(C_{10}, C_{20}, \dots, C_{N0})`, at least one; :math:`C_{10} > 0`,
            the others any finite numbers.
        K: Bulk modulus :math:`K > 0`.
        volumetric: Volumetric law name (see :mod:`hyperfem.materials.volumetric`).
    """

    coefficients: tuple[float, ...]
    K: float
    volumetric: str = "log"

    def __post_init__(self) -> None:
        where = "ReducedPolynomialParameters"
        if isinstance(self.coefficients, (str, bytes)) or not isinstance(self.coefficients, Sequence):
            raise ParameterError(f"{where}: coefficients must be a sequence of numbers, got {self.coefficients!r}")
        if len(self.coefficients) == 0:
            raise ParameterError(f"{where}: coefficients must hold at least C10, got an empty sequence")
        for i, c in enumerate(self.coefficients):
            if not is_finite_number(c):
                raise ParameterError(f"{where}: coefficients[{i}] (C{i + 1}0) must be a finite number, got {c!r}")
        check_positive("coefficients[0] (C10)", self.coefficients[0], where)
        object.__setattr__(self, "coefficients", tuple(float(c) for c in self.coefficients))
        check_positive("K", self.K, where)
        volumetric_law(self.volumetric)

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus :math:`\mu_0 = 2C_{10}`."""
        return 2.0 * self.coefficients[0]


@dataclass(frozen=True)
class YeohParameters:
    r"""Yeoh (1993) constants (stress units, e.g. Pa).

    Attributes:
        c10: :math:`C_{10} > 0` (half the small-strain shear modulus).
        c20: :math:`C_{20}` (any finite number; usually negative).
        c30: :math:`C_{30}` (any finite number; usually positive and small).
        K: Bulk modulus :math:`K > 0`.
        volumetric: Volumetric law name (see :mod:`hyperfem.materials.volumetric`).
    """

    c10: float
    c20: float
    c30: float
    K: float
    volumetric: str = "log"

    def __post_init__(self) -> None:
        where = "YeohParameters"
        check_positive("c10", self.c10, where)
        for name in ("c20", "c30"):
            value = getattr(self, name)
            if not is_finite_number(value):
                raise ParameterError(f"{where}: {name} must be a finite number, got {value!r}")
        check_positive("K", self.K, where)
        volumetric_law(self.volumetric)

    @property
    def coefficients(self) -> tuple[float, float, float]:
        r""":math:`(C_{10}, C_{20}, C_{30})`."""
        return (self.c10, self.c20, self.c30)

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus :math:`\mu_0 = 2C_{10}`."""
        return 2.0 * self.c10


Params = ReducedPolynomialParameters | YeohParameters


def _series(x: Expr, coefficients: Sequence[float]) -> Expr:
    r""":math:`\sum_i C_{i0} x^i` in Horner form."""
    out: Expr = ufl.as_ufl(0.0)
    for c in reversed(coefficients):
        out = (out + c) * x
    return out


def _series_derivative(x: Expr, coefficients: Sequence[float]) -> Expr:
    r""":math:`\sum_i i\,C_{i0} x^{i-1}` in Horner form."""
    out: Expr = ufl.as_ufl(0.0)
    for i in range(len(coefficients), 0, -1):
        out = out * x + i * coefficients[i - 1]
    return out


def reduced_polynomial_isochoric(F: Expr, params: Params) -> Expr:
    r"""Isochoric part :math:`\sum_i C_{i0}(\bar I_1 - 3)^i` (2×2 ``F``: plane strain)."""
    I1b, _, _ = isochoric_invariants(F)
    return _series(I1b - 3.0, params.coefficients)


def reduced_polynomial(F: Expr, params: Params) -> Expr:
    """Strain-energy density of the reduced polynomial (or Yeoh) law with its volumetric term.

    Args:
        F: Deformation gradient (3×3, or 2×2 for plane strain).
        params: :class:`ReducedPolynomialParameters` or :class:`YeohParameters`.
    """
    return reduced_polynomial_isochoric(F, params) + volumetric_energy(
        jacobian(plane_strain_3d(F)), params.K, params.volumetric
    )


def reduced_polynomial_stress(F: Expr, params: Params) -> Expr:
    r"""Closed-form :math:`P` for the ``"log"`` volumetric law, :math:`p = K\ln J` (3×3 ``F``; verification only)."""
    if params.volumetric != "log":
        raise ParameterError("reduced_polynomial_stress: closed form implemented for the 'log' volumetric law")
    I1b, _, J = isochoric_invariants(F)
    psi1 = _series_derivative(I1b - 3.0, params.coefficients)
    return mooney_rivlin_isochoric_stress(F, psi1, 0.0) + params.K * ufl.ln(J) * ufl.inv(F).T


def yeoh_isochoric(F: Expr, params: YeohParameters) -> Expr:
    r"""Isochoric Yeoh part :math:`C_{10}(\bar I_1-3) + C_{20}(\bar I_1-3)^2 + C_{30}(\bar I_1-3)^3`."""
    return reduced_polynomial_isochoric(F, params)


def yeoh(F: Expr, params: YeohParameters) -> Expr:
    """Strain-energy density of the Yeoh law (the cubic reduced polynomial) with its volumetric term."""
    return reduced_polynomial(F, params)


def yeoh_stress(F: Expr, params: YeohParameters) -> Expr:
    """Closed-form first Piola–Kirchhoff stress of :func:`yeoh` (``"log"`` volumetric law; verification only)."""
    return reduced_polynomial_stress(F, params)
