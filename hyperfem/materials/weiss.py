r"""Transversely isotropic Mooney–Rivlin law for ligament and tendon (Weiss, Maker & Govindjee 1996).

.. math::
    \psi(F) = c_1(\bar I_1 - 3) + c_2(\bar I_2 - 3) + F_2(\bar\lambda) + U(J),\qquad
    \bar\lambda = J^{-1/3}\sqrt{a_0\cdot C a_0},

with :math:`a_0` the unit fibre direction in the reference configuration. The
fibre energy is defined by its fibre stress (J. A. Weiss, B. N. Maker and
S. Govindjee, "Finite element implementation of incompressible, transversely
isotropic hyperelasticity", *Comput. Methods Appl. Mech. Engrg.* 135 (1996)
107–128; FEBio's ``trans iso Mooney-Rivlin``):

.. math::
    \bar\lambda\frac{\partial F_2}{\partial\bar\lambda} = \begin{cases}
      0 & \bar\lambda \le 1 \quad\text{(no fibre stress in compression)}\\
      c_3\left(e^{c_4(\bar\lambda - 1)} - 1\right) & 1 < \bar\lambda < \lambda^*
        \quad\text{(toe region: crimped fibres straightening)}\\
      c_5\bar\lambda + c_6 & \bar\lambda \ge \lambda^* \quad\text{(straightened fibres)}
    \end{cases},\qquad
    c_6 = c_3\left(e^{c_4(\lambda^* - 1)} - 1\right) - c_5\lambda^*,

:math:`c_6` making the fibre stress continuous at :math:`\lambda^*` (its slope
jumps there unless :math:`c_5 = c_3c_4e^{c_4(\lambda^*-1)}`). The energy is :math:`C^1`.

Integrated, :math:`F_2 = c_3 G(\bar\lambda)` in the toe region with
:math:`G(\lambda) = \int_1^\lambda (e^{c_4(t-1)} - 1)\,t^{-1}\,dt
= e^{-c_4}[\mathrm{Ei}(c_4\lambda) - \mathrm{Ei}(c_4)] - \ln\lambda` (the exponential
integral, which FEBio evaluates; UFL has none), and
:math:`F_2 = c_3G(\lambda^*) + c_5(\bar\lambda - \lambda^*) + c_6\ln(\bar\lambda/\lambda^*)`
beyond :math:`\lambda^*`. Here :math:`G` is an :math:`n`-point Gauss–Legendre rule on
:math:`[1, \bar\lambda]`, :math:`n = \min(64, 8 + \lceil (c_4 + 4)(\lambda^* - 1)\rceil)`
(:attr:`WeissParameters.quadrature_points`). Its UFL derivative is the same rule applied to
:math:`\tfrac{d}{dx}[x f(1 + sx)]`, whose exact integral is the fibre stress itself;
against a 200-point rule the energy and its derivative agree to 1e-14 relative for
:math:`c_4(\lambda^*-1) \le 10` and 5e-13 for :math:`\le 100`.

The closed-form stress (:func:`weiss_stress`, verification only) is, with
:math:`\sigma_f = \bar\lambda\,\partial F_2/\partial\bar\lambda` and :math:`\lambda^2 = a_0\cdot Ca_0`,

.. math::
    P = P_\text{MR} + \frac{\sigma_f}{\lambda^2}(Fa_0)\otimes a_0 - \frac{\sigma_f}{3}F^{-T} + K\ln J\,F^{-T}.

Fibre directions are UFL vectors, as for :func:`~hyperfem.materials.muscle.muscle`. 3×3 ``F`` only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import right_cauchy_green
from hyperfem.materials.mooney_rivlin import mooney_rivlin_isochoric, mooney_rivlin_isochoric_stress
from hyperfem.materials.muscle import isochoric_fibre_stretch
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_nonnegative, check_positive, is_finite_number

__all__ = [
    "WeissParameters",
    "weiss",
    "weiss_fibre_energy",
    "weiss_fibre_stress",
    "weiss_isochoric",
    "weiss_stress",
]

Expr = ufl.core.expr.Expr


@dataclass(frozen=True)
class WeissParameters:
    r"""Constants of the transversely isotropic Mooney–Rivlin law (Weiss et al. 1996).

    Attributes:
        c1: Mooney–Rivlin :math:`c_1 > 0` (stress units, e.g. Pa).
        c2: Mooney–Rivlin :math:`c_2 \ge 0` (stress units).
        c3: Scale of the exponential fibre stress :math:`c_3 \ge 0` (stress units).
        c4: Rate of fibre uncrimping :math:`c_4 > 0` (dimensionless).
        c5: Modulus of the straightened fibres :math:`c_5 \ge 0` (stress units).
        lambda_star: Stretch :math:`\lambda^* > 1` at which the fibres are straight (dimensionless).
        K: Bulk modulus :math:`K > 0` (stress units).
        volumetric: Volumetric law name (see :mod:`hyperfem.materials.volumetric`).
    """

    c1: float
    c2: float
    c3: float
    c4: float
    c5: float
    lambda_star: float
    K: float
    volumetric: str = "log"

    def __post_init__(self) -> None:
        where = "WeissParameters"
        check_positive("c1", self.c1, where)
        check_nonnegative("c2", self.c2, where)
        check_nonnegative("c3", self.c3, where)
        check_positive("c4", self.c4, where)
        check_nonnegative("c5", self.c5, where)
        if not (is_finite_number(self.lambda_star) and self.lambda_star > 1.0):
            raise ParameterError(f"{where}: lambda_star must be a finite number > 1, got {self.lambda_star!r}")
        check_positive("K", self.K, where)
        volumetric_law(self.volumetric)

    @property
    def c6(self) -> float:
        r""":math:`c_6 = c_3(e^{c_4(\lambda^*-1)} - 1) - c_5\lambda^*`, continuity of the fibre stress."""
        return self.c3 * math.expm1(self.c4 * (self.lambda_star - 1.0)) - self.c5 * self.lambda_star

    @property
    def quadrature_points(self) -> int:
        r"""Gauss–Legendre points of the toe integral, :math:`\min(64, 8 + \lceil(c_4 + 4)(\lambda^* - 1)\rceil)`."""
        return min(64, 8 + math.ceil((self.c4 + 4.0) * (self.lambda_star - 1.0)))

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus of the matrix, :math:`2(c_1 + c_2)`."""
        return 2.0 * (self.c1 + self.c2)


def _toe_integral(s: Expr, params: WeissParameters) -> Expr:
    r""":math:`G(1 + s) = \int_0^1 s\,(e^{c_4 s x} - 1)/(1 + s x)\,dx` by Gauss–Legendre."""
    xi, w = np.polynomial.legendre.leggauss(params.quadrature_points)
    terms = [
        0.5 * wq * (ufl.exp(params.c4 * s * xq) - 1.0) / (1.0 + s * xq)
        for xq, wq in zip(0.5 * (xi + 1.0), w, strict=True)
    ]
    return s * sum(terms[1:], terms[0])


def _toe_integral_value(params: WeissParameters) -> float:
    r""":math:`G(\lambda^*)` as a number (the same rule)."""
    xi, w = np.polynomial.legendre.leggauss(params.quadrature_points)
    s, x = params.lambda_star - 1.0, 0.5 * (xi + 1.0)
    return float(s * np.sum(0.5 * w * np.expm1(params.c4 * s * x) / (1.0 + s * x)))


def weiss_fibre_energy(lbar: Expr, params: WeissParameters) -> Expr:
    r"""Fibre energy :math:`F_2(\bar\lambda)` (zero for :math:`\bar\lambda \le 1`)."""
    ls = params.lambda_star
    s = ufl.min_value(ufl.max_value(lbar, 1.0), ls) - 1.0  # clamped: the toe integral stops at lambda*
    linear = params.c5 * (lbar - ls) + params.c6 * ufl.ln(lbar / ls)
    # ge, not gt: at lbar = lambda* exactly UFL differentiates min_value as its second (constant) argument,
    # so the linear branch must be the one switched on there, or the fibre stress would vanish at that point.
    return params.c3 * _toe_integral(s, params) + ufl.conditional(ufl.ge(lbar, ls), linear, 0.0)


def weiss_fibre_stress(lbar: Expr, params: WeissParameters) -> Expr:
    r"""Fibre stress :math:`\sigma_f = \bar\lambda\,\partial F_2/\partial\bar\lambda` in closed form."""
    ls = params.lambda_star
    lc = ufl.min_value(ufl.max_value(lbar, 1.0), ls)  # keeps exp() finite in every branch
    return ufl.conditional(
        ufl.le(lbar, 1.0),
        0.0,
        ufl.conditional(
            ufl.lt(lbar, ls), params.c3 * (ufl.exp(params.c4 * (lc - 1.0)) - 1.0), params.c5 * lbar + params.c6
        ),
    )


def weiss_isochoric(F: Expr, a0: Expr, params: WeissParameters) -> Expr:
    r"""Isochoric part :math:`c_1(\bar I_1 - 3) + c_2(\bar I_2 - 3) + F_2(\bar\lambda)` (3×3 ``F``)."""
    return mooney_rivlin_isochoric(F, params.c1, params.c2) + weiss_fibre_energy(isochoric_fibre_stretch(F, a0), params)


def weiss(F: Expr, a0: Expr, params: WeissParameters) -> Expr:
    """Strain-energy density of the transversely isotropic Mooney–Rivlin law with its volumetric term.

    Args:
        F: Deformation gradient (3×3).
        a0: Unit fibre direction in the reference configuration (UFL vector).
        params: Material parameters.
    """
    return weiss_isochoric(F, a0, params) + volumetric_energy(ufl.det(F), params.K, params.volumetric)


def weiss_stress(F: Expr, a0: Expr, params: WeissParameters) -> Expr:
    """Closed-form first Piola–Kirchhoff stress, ``"log"`` volumetric law (verification only; module docstring)."""
    if params.volumetric != "log":
        raise ParameterError("weiss_stress: closed form implemented for the 'log' volumetric law")
    J = ufl.det(F)
    lam2 = ufl.dot(a0, right_cauchy_green(F) * a0)
    sigma_f = weiss_fibre_stress(J ** (-1.0 / 3.0) * ufl.sqrt(lam2), params)
    fibre = (sigma_f / lam2) * ufl.outer(F * a0, a0) - (sigma_f / 3.0) * ufl.inv(F).T
    return mooney_rivlin_isochoric_stress(F, params.c1, params.c2) + fibre + params.K * ufl.ln(J) * ufl.inv(F).T
