r"""Veronda–Westmann exponential law (skin, soft tissue matrix).

.. math::
    \psi(F) = c_1\left(e^{c_2(\bar I_1 - 3)} - 1\right) - \frac{c_1 c_2}{2}(\bar I_2 - 3) + U(J),\qquad
    \bar I_1 = J^{-2/3}\operatorname{tr} C,\quad \bar I_2 = J^{-4/3} I_2

(D. R. Veronda and R. A. Westmann, "Mechanical characterization of skin—finite
deformations", *J. Biomech.* 3 (1970) 111–124; in the uncoupled form of FEBio's
``Veronda-Westmann`` material). At small strain
:math:`\psi \approx c_1c_2(\bar I_1 - 3) - \tfrac{c_1c_2}{2}(\bar I_2 - 3)`, a
Mooney–Rivlin law with :math:`C_{10} = c_1c_2`, :math:`C_{01} = -c_1c_2/2`, so the
small-strain shear modulus is :math:`\mu_0 = 2(C_{10} + C_{01}) = c_1 c_2`.

The first Piola–Kirchhoff stress (:func:`veronda_westmann_stress`, verification only) is
the Mooney–Rivlin form of :func:`~hyperfem.materials.mooney_rivlin.mooney_rivlin_isochoric_stress`
with :math:`c_1 \to \psi_1 = c_1c_2 e^{c_2(\bar I_1 - 3)}` and
:math:`c_2 \to \psi_2 = -c_1c_2/2`, plus :math:`JU'(J)F^{-T}`.
"""

from __future__ import annotations

from dataclasses import dataclass

import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import isochoric_invariants, jacobian, plane_strain_3d
from hyperfem.materials.mooney_rivlin import mooney_rivlin_isochoric_stress
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_positive

__all__ = [
    "VerondaWestmannParameters",
    "veronda_westmann",
    "veronda_westmann_isochoric",
    "veronda_westmann_stress",
]

Expr = ufl.core.expr.Expr


@dataclass(frozen=True)
class VerondaWestmannParameters:
    r"""Veronda–Westmann (1970) constants.

    Attributes:
        c1: Stress scale :math:`c_1 > 0` (stress units, e.g. Pa).
        c2: Exponent :math:`c_2 > 0` (dimensionless); :math:`\mu_0 = c_1c_2`.
        K: Bulk modulus :math:`K > 0` (stress units).
        volumetric: Volumetric law name (see :mod:`hyperfem.materials.volumetric`).
    """

    c1: float
    c2: float
    K: float
    volumetric: str = "log"

    def __post_init__(self) -> None:
        where = "VerondaWestmannParameters"
        check_positive("c1", self.c1, where)
        check_positive("c2", self.c2, where)
        check_positive("K", self.K, where)
        volumetric_law(self.volumetric)

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus :math:`\mu_0 = c_1 c_2`."""
        return self.c1 * self.c2


def veronda_westmann_isochoric(F: Expr, params: VerondaWestmannParameters) -> Expr:
    r"""Isochoric part :math:`c_1(e^{c_2(\bar I_1-3)} - 1) - \tfrac{c_1c_2}{2}(\bar I_2 - 3)` (2×2 F: plane strain)."""
    I1b, I2b, _ = isochoric_invariants(F)
    c1, c2 = params.c1, params.c2
    return c1 * (ufl.exp(c2 * (I1b - 3.0)) - 1.0) - 0.5 * c1 * c2 * (I2b - 3.0)


def veronda_westmann(F: Expr, params: VerondaWestmannParameters) -> Expr:
    """Strain-energy density of the Veronda–Westmann law with its volumetric term.

    Args:
        F: Deformation gradient (3×3, or 2×2 for plane strain).
        params: Material parameters.
    """
    return veronda_westmann_isochoric(F, params) + volumetric_energy(
        jacobian(plane_strain_3d(F)), params.K, params.volumetric
    )


def veronda_westmann_stress(F: Expr, params: VerondaWestmannParameters) -> Expr:
    r"""Closed-form :math:`P` for the ``"log"`` volumetric law, :math:`p = K\ln J` (3×3 ``F``; verification only)."""
    if params.volumetric != "log":
        raise ParameterError("veronda_westmann_stress: closed form implemented for the 'log' volumetric law")
    I1b, _, J = isochoric_invariants(F)
    c1, c2 = params.c1, params.c2
    psi1 = c1 * c2 * ufl.exp(c2 * (I1b - 3.0))
    return mooney_rivlin_isochoric_stress(F, psi1, -0.5 * c1 * c2) + params.K * ufl.ln(J) * ufl.inv(F).T
