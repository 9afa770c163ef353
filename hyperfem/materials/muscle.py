r"""Active, transversely isotropic muscle and tendon (seed 000, supplement §2).

The strain energy per unit reference volume is

.. math::
    W = c_1(\bar I_1 - 3) + c_2(\bar I_2 - 3) + U(J) + F_2(\bar\lambda, \alpha),
    \qquad \bar\lambda = J^{-1/3}\sqrt{a_0 \cdot C a_0},

with :math:`a_0` the unit fibre direction in the reference configuration,
:math:`\alpha \in [0, 1]` the activation and :math:`U` a volumetric law
(default :math:`\frac{K}{2}(\ln J)^2`, the seed's :math:`p = K \ln J`). The
fibre energy is defined by its fibre stress

.. math::
    \bar\lambda\,\frac{\partial F_2}{\partial \bar\lambda}
    = T_\max\,\left[\alpha f_\text{act}(l) + f_\text{pas}(l)\right]\, l,
    \qquad l = \bar\lambda / \lambda_\text{ofl},

so that, in closed form, :math:`F_2 = T_\max\,[\alpha A(l) + B(l)]` with
:math:`A = \int_0^l f_\text{act}` and :math:`B = \int_0^l f_\text{pas}`
(Blemker-type force–length curves):

.. math::
    f_\text{act}(l) = \begin{cases}
        9(l - 0.4)^2 & 0.4 < l \le 0.6\\ 1 - 4(1 - l)^2 & 0.6 < l < 1.4\\
        9(l - 1.6)^2 & 1.4 \le l < 1.6\\ 0 & \text{otherwise}\end{cases},\qquad
    f_\text{pas}(l) = \begin{cases}
        0 & l \le 1\\ P_1\left(e^{P_2(l-1)} - 1\right) & 1 < l < l^*\\
        f_\text{pas}(l^*) + f_\text{pas}'(l^*)(l - l^*) & l \ge l^* \end{cases}.

Fibres carry no passive compression (:math:`f_\text{pas} = 0` for :math:`l \le 1`).
Everything is written with UFL conditionals, so the energy exists for the
line search and ``ufl.derivative`` gives residual and tangent.

The generic anisotropic form of seed 000 (lecture 1, §3),
:math:`\psi = \psi_\text{iso}(F) + \psi_\text{fibre}(a_0\cdot C a_0)`, is
:func:`transversely_isotropic`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import right_cauchy_green
from hyperfem.materials.mooney_rivlin import mooney_rivlin_isochoric, mooney_rivlin_isochoric_stress
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_positive, is_finite_number

__all__ = [
    "MuscleParameters",
    "check_activation",
    "fibre_energy",
    "fibre_stretch",
    "force_length_active",
    "force_length_active_integral",
    "force_length_passive",
    "force_length_passive_integral",
    "isochoric_fibre_stretch",
    "muscle",
    "muscle_isochoric",
    "muscle_stress",
    "transversely_isotropic",
]

Expr = ufl.core.expr.Expr
Scalar = float | Expr


@dataclass(frozen=True)
class MuscleParameters:
    r"""Parameters of the muscle/tendon energy (consistent units, e.g. Pa).

    Attributes:
        c1: Mooney–Rivlin :math:`c_1 > 0`.
        c2: Mooney–Rivlin :math:`c_2 \ge 0`.
        K: Bulk modulus :math:`K > 0`.
        T_max: Maximum isometric fibre stress :math:`T_\max \ge 0`.
        lambda_ofl: Optimal fibre stretch :math:`\lambda_\text{ofl} > 0`.
        P1: Passive curve scale :math:`P_1 \ge 0`.
        P2: Passive curve exponent :math:`P_2 > 0`.
        l_star: Start of the linear passive branch :math:`l^* > 1`.
        volumetric: Volumetric law name (see :mod:`hyperfem.materials.volumetric`).
    """

    c1: float
    c2: float
    K: float
    T_max: float
    lambda_ofl: float = 1.0
    P1: float = 0.05
    P2: float = 6.6
    l_star: float = 1.4
    volumetric: str = "log"

    def __post_init__(self) -> None:
        where = "MuscleParameters"
        check_positive("c1", self.c1, where)
        for name in ("c2", "T_max", "P1"):
            value = getattr(self, name)
            if not (is_finite_number(value) and value >= 0):
                raise ParameterError(f"{where}: {name} must be a finite number >= 0, got {value!r}")
        check_positive("K", self.K, where)
        check_positive("lambda_ofl", self.lambda_ofl, where)
        check_positive("P2", self.P2, where)
        if not (is_finite_number(self.l_star) and self.l_star > 1.0):
            raise ParameterError(f"{where}: l_star must be a finite number > 1, got {self.l_star!r}")
        volumetric_law(self.volumetric)

    @classmethod
    def muscle(cls, **overrides: Any) -> MuscleParameters:
        """Seed 000 muscle: c1 = 30 kPa, c2 = 10 kPa, K = 60 kPa, T_max = 80 kPa (in Pa)."""
        return dataclasses.replace(cls(c1=30e3, c2=10e3, K=60e3, T_max=80e3), **overrides)

    @classmethod
    def tendon(cls, **overrides: Any) -> MuscleParameters:
        """Seed 000 tendon: c1 = 60 kPa, c2 = 10 kPa, K = 80 kPa, T_max = 80 kPa; use it with α = 0."""
        return dataclasses.replace(cls(c1=60e3, c2=10e3, K=80e3, T_max=80e3), **overrides)

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus of the matrix, :math:`\mu = 2(c_1 + c_2)`."""
        return 2.0 * (self.c1 + self.c2)


def check_activation(alpha: object, where: str = "activation") -> None:
    """Raise :class:`ParameterError` if a numeric ``alpha`` is outside [0, 1] (UFL values pass)."""
    if isinstance(alpha, (int, float)) and not (math.isfinite(alpha) and 0.0 <= alpha <= 1.0):
        raise ParameterError(f"{where}: activation must lie in [0, 1], got {alpha!r}")


# -- force–length curves -------------------------------------------------------
def force_length_active(ell: Expr) -> Expr:
    """Active force–length curve :math:`f_\\text{act}(l)` (piecewise quadratic, zero outside (0.4, 1.6))."""
    return ufl.conditional(
        ufl.le(ell, 0.4),
        0.0,
        ufl.conditional(
            ufl.le(ell, 0.6),
            9.0 * (ell - 0.4) ** 2,
            ufl.conditional(
                ufl.lt(ell, 1.4),
                1.0 - 4.0 * (1.0 - ell) ** 2,
                ufl.conditional(ufl.lt(ell, 1.6), 9.0 * (ell - 1.6) ** 2, 0.0),
            ),
        ),
    )


_A06 = 3.0 * 0.2**3  # int_0.4^0.6 f_act
_A14 = _A06 + 0.8 - (4.0 / 3.0) * 2.0 * 0.4**3  # int_0.4^1.4 f_act
_A16 = _A14 + 3.0 * 0.2**3  # int_0.4^1.6 f_act


def force_length_active_integral(ell: Expr) -> Expr:
    r""":math:`A(l) = \int_0^l f_\text{act}(t)\,dt` in closed form."""
    return ufl.conditional(
        ufl.le(ell, 0.4),
        0.0,
        ufl.conditional(
            ufl.le(ell, 0.6),
            3.0 * (ell - 0.4) ** 3,
            ufl.conditional(
                ufl.lt(ell, 1.4),
                _A06 + (ell - 0.6) + (4.0 / 3.0) * ((1.0 - ell) ** 3 - 0.4**3),
                ufl.conditional(ufl.lt(ell, 1.6), _A14 + 3.0 * ((ell - 1.6) ** 3 + 0.2**3), _A16),
            ),
        ),
    )


def force_length_passive(ell: Expr, P1: float = 0.05, P2: float = 6.6, l_star: float = 1.4) -> Expr:
    """Passive force–length curve :math:`f_\\text{pas}(l)`: exponential, then C¹-linear beyond ``l_star``."""
    lc = ufl.min_value(ufl.max_value(ell, 1.0), l_star)  # keeps exp() finite in every branch
    f_star = P1 * (math.exp(P2 * (l_star - 1.0)) - 1.0)
    df_star = P1 * P2 * math.exp(P2 * (l_star - 1.0))
    return ufl.conditional(
        ufl.le(ell, 1.0),
        0.0,
        ufl.conditional(ufl.lt(ell, l_star), P1 * (ufl.exp(P2 * (lc - 1.0)) - 1.0), f_star + df_star * (ell - l_star)),
    )


def force_length_passive_integral(ell: Expr, P1: float = 0.05, P2: float = 6.6, l_star: float = 1.4) -> Expr:
    r""":math:`B(l) = \int_0^l f_\text{pas}(t)\,dt` in closed form."""
    lc = ufl.min_value(ufl.max_value(ell, 1.0), l_star)
    e_star = math.exp(P2 * (l_star - 1.0))
    f_star = P1 * (e_star - 1.0)
    df_star = P1 * P2 * e_star
    B_star = P1 * ((e_star - 1.0) / P2 - (l_star - 1.0))
    s = ell - l_star
    return ufl.conditional(
        ufl.le(ell, 1.0),
        0.0,
        ufl.conditional(
            ufl.lt(ell, l_star),
            P1 * ((ufl.exp(P2 * (lc - 1.0)) - 1.0) / P2 - (lc - 1.0)),
            B_star + f_star * s + 0.5 * df_star * s**2,
        ),
    )


# -- kinematics of the fibre -----------------------------------------------------
def fibre_stretch(F: Expr, a0: Expr) -> Expr:
    r"""Fibre stretch :math:`\lambda = \sqrt{a_0\cdot C a_0}` (``a0`` unit)."""
    return ufl.sqrt(ufl.dot(a0, right_cauchy_green(F) * a0))


def isochoric_fibre_stretch(F: Expr, a0: Expr) -> Expr:
    r"""Deviatoric fibre stretch :math:`\bar\lambda = J^{-1/3}\sqrt{a_0\cdot C a_0}`."""
    return ufl.det(F) ** (-1.0 / 3.0) * fibre_stretch(F, a0)


# -- energies ----------------------------------------------------------------------
def fibre_energy(lbar: Expr, alpha: Scalar, params: MuscleParameters) -> Expr:
    r"""Fibre energy :math:`F_2 = T_\max[\alpha A(l) + B(l)]`, :math:`l = \bar\lambda/\lambda_\text{ofl}`."""
    check_activation(alpha, "fibre_energy")
    ell = lbar / params.lambda_ofl
    passive = force_length_passive_integral(ell, params.P1, params.P2, params.l_star)
    return params.T_max * (alpha * force_length_active_integral(ell) + passive)


def muscle_isochoric(F: Expr, a0: Expr, alpha: Scalar, params: MuscleParameters) -> Expr:
    r"""Isochoric part :math:`c_1(\bar I_1 - 3) + c_2(\bar I_2 - 3) + F_2(\bar\lambda, \alpha)` (3×3 ``F``)."""
    return mooney_rivlin_isochoric(F, params.c1, params.c2) + fibre_energy(
        isochoric_fibre_stretch(F, a0), alpha, params
    )


def muscle(F: Expr, a0: Expr, alpha: Scalar, params: MuscleParameters) -> Expr:
    """Strain-energy density :math:`W(F; a_0, \\alpha)` of muscle (or tendon, with ``alpha = 0``).

    Args:
        F: Deformation gradient (3×3).
        a0: Unit fibre direction in the reference configuration (UFL vector).
        alpha: Activation in [0, 1] (number or UFL expression).
        params: Material parameters.

    Returns:
        :math:`W` per unit reference volume.
    """
    return muscle_isochoric(F, a0, alpha, params) + volumetric_energy(ufl.det(F), params.K, params.volumetric)


def muscle_stress(F: Expr, a0: Expr, alpha: Scalar, params: MuscleParameters) -> Expr:
    r"""Closed-form first Piola–Kirchhoff stress in the form of seed 000 (verification only).

    .. math::
        P = w_{12}F - w_2 F C + (p - p_f) F^{-T} + \frac{\sigma_f}{\lambda^2} (F a_0)\otimes a_0,\qquad
        p_f = \tfrac13\left(w_{12}\operatorname{tr}C - w_2 \operatorname{tr}C^2 + \sigma_f\right),

    with :math:`\sigma_f = \bar\lambda\,\partial F_2/\partial\bar\lambda = T_\max(\alpha f_\text{act}
    + f_\text{pas})\,l` and :math:`w_1, w_2, w_{12}` as in
    :func:`~hyperfem.materials.mooney_rivlin.mooney_rivlin_isochoric_stress`.

    Where the seed's excerpt is inconsistent, this follows what its energy implies:
    :math:`I_1 = J_{cc} C` must be the scalar :math:`\operatorname{tr} C` inside :math:`w_{12}`;
    :math:`F^3` and :math:`F^{-1}` hold only for diagonal :math:`F` (here :math:`FC`,
    :math:`F^{-T}`); :math:`w_1 = 4J_{cc}c_1` belongs to twice our :math:`F_1`; and the
    seed's fibre term :math:`4J_{cc}T (F f_m) f_m^T` with :math:`T\lambda^2/3` in
    :math:`p_f` is deviatoric only if :math:`T = \sigma_f/(4\bar\lambda^2)` *and* the
    :math:`p_f` term reads :math:`\tfrac43 J_{cc} T\lambda^2 = \sigma_f/3`. Only the
    ``"log"`` volumetric law (:math:`p = K\ln J`) is implemented here.
    """
    if params.volumetric != "log":
        raise ParameterError("muscle_stress: closed form implemented for the 'log' volumetric law")
    check_activation(alpha, "muscle_stress")
    J = ufl.det(F)
    C = right_cauchy_green(F)
    lam2 = ufl.dot(a0, C * a0)
    lbar = J ** (-1.0 / 3.0) * ufl.sqrt(lam2)
    ell = lbar / params.lambda_ofl
    f = alpha * force_length_active(ell) + force_length_passive(ell, params.P1, params.P2, params.l_star)
    sigma_f = params.T_max * f * ell
    p = params.K * ufl.ln(J)
    fibre = (sigma_f / lam2) * ufl.outer(F * a0, a0) - (sigma_f / 3.0) * ufl.inv(F).T
    return mooney_rivlin_isochoric_stress(F, params.c1, params.c2) + p * ufl.inv(F).T + fibre


def transversely_isotropic(
    F: Expr, a0: Expr, psi_iso: Callable[[Expr], Expr], psi_fibre: Callable[[Expr], Expr]
) -> Expr:
    r"""Generic anisotropic energy :math:`\psi_\text{iso}(F) + \psi_\text{fibre}(a_0\cdot C a_0)` (seed 000).

    Args:
        F: Deformation gradient.
        a0: Unit fibre direction (reference configuration).
        psi_iso: Isotropic energy ``psi_iso(F)``.
        psi_fibre: Fibre energy as a function of the squared fibre stretch :math:`I_4 = a_0\cdot C a_0`.
    """
    return psi_iso(F) + psi_fibre(ufl.dot(a0, right_cauchy_green(F) * a0))
