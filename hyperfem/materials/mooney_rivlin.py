r"""Isochoric Mooney–Rivlin matrix with a volumetric term.

.. math::
    \psi(F) = c_1(\bar I_1 - 3) + c_2(\bar I_2 - 3) + U(J),\qquad
    \bar I_1 = J^{-2/3}\operatorname{tr} C,\quad
    \bar I_2 = J^{-4/3}\tfrac12\left[(\operatorname{tr} C)^2 - \operatorname{tr} C^2\right].

Its first Piola–Kirchhoff stress, in the notation of seed 000 (§2 of the
supplement) with :math:`J_{cc} = J^{-2/3}`, is

.. math::
    P = w_{12} F - w_2 F C - \tfrac13\left(w_{12}\operatorname{tr} C - w_2 \operatorname{tr} C^2\right) F^{-T}
        + J U'(J) F^{-T},\qquad
    w_1 = 2 J_{cc} c_1,\ w_2 = 2 J_{cc}^2 c_2,\ w_{12} = w_1 + \operatorname{tr}(C)\, w_2 .

(The seed writes :math:`w_1 = 4J_{cc}c_1`, i.e. it uses twice this energy.)
"""

from __future__ import annotations

from dataclasses import dataclass

import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import isochoric_invariants, jacobian, plane_strain_3d, right_cauchy_green
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_positive, is_finite_number

__all__ = [
    "MooneyRivlinParameters",
    "mooney_rivlin",
    "mooney_rivlin_isochoric",
    "mooney_rivlin_isochoric_stress",
    "mooney_rivlin_stress",
]

Expr = ufl.core.expr.Expr


@dataclass(frozen=True)
class MooneyRivlinParameters:
    r"""Mooney–Rivlin constants.

    Attributes:
        c1: Coefficient of :math:`\bar I_1 - 3` (> 0).
        c2: Coefficient of :math:`\bar I_2 - 3` (>= 0).
        K: Bulk modulus (> 0).
        volumetric: Name of the volumetric law (see
            :mod:`hyperfem.materials.volumetric`).
    """

    c1: float
    c2: float
    K: float
    volumetric: str = "log"

    def __post_init__(self) -> None:
        check_positive("c1", self.c1, "MooneyRivlinParameters")
        if not (is_finite_number(self.c2) and self.c2 >= 0):
            raise ParameterError(f"MooneyRivlinParameters: c2 must be a finite number >= 0, got {self.c2!r}")
        check_positive("K", self.K, "MooneyRivlinParameters")
        volumetric_law(self.volumetric)

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus :math:`\mu = 2(c_1 + c_2)`."""
        return 2.0 * (self.c1 + self.c2)


def mooney_rivlin_isochoric(F: Expr, c1: float | Expr, c2: float | Expr) -> Expr:
    r"""Isochoric part :math:`c_1(\bar I_1 - 3) + c_2(\bar I_2 - 3)` (2×2 F: plane strain)."""
    I1b, I2b, _ = isochoric_invariants(F)
    return c1 * (I1b - 3.0) + c2 * (I2b - 3.0)


def mooney_rivlin(F: Expr, params: MooneyRivlinParameters) -> Expr:
    """Strain-energy density of the compressible (split) Mooney–Rivlin law."""
    return mooney_rivlin_isochoric(F, params.c1, params.c2) + volumetric_energy(
        jacobian(plane_strain_3d(F)), params.K, params.volumetric
    )


def mooney_rivlin_isochoric_stress(F: Expr, c1: float | Expr, c2: float | Expr) -> Expr:
    r"""Closed-form isochoric :math:`P` (seed 000 notation, 3×3 ``F``; verification only)."""
    J = ufl.det(F)
    C = right_cauchy_green(F)
    Jcc = J ** (-2.0 / 3.0)
    w1 = 2.0 * Jcc * c1
    w2 = 2.0 * Jcc**2 * c2
    trC = ufl.tr(C)
    w12 = w1 + trC * w2
    pf = (w12 * trC - w2 * ufl.tr(C * C)) / 3.0
    return w12 * F - w2 * F * C - pf * ufl.inv(F).T


def mooney_rivlin_stress(F: Expr, params: MooneyRivlinParameters) -> Expr:
    r"""Closed-form :math:`P` for the ``"log"`` volumetric law, :math:`p = K\ln J` (verification only)."""
    if params.volumetric != "log":
        raise ParameterError("mooney_rivlin_stress: closed form implemented for the 'log' volumetric law")
    J = ufl.det(F)
    return mooney_rivlin_isochoric_stress(F, params.c1, params.c2) + params.K * ufl.ln(J) * ufl.inv(F).T
