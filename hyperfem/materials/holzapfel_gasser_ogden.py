r"""Holzapfel–Gasser–Ogden arterial law: neo-Hookean matrix, two dispersed collagen fibre families.

.. math::
    \psi(F) = \frac{\mu}{2}(\bar I_1 - 3)
      + \sum_{i=4,6}\frac{k_1}{2k_2}\left[e^{k_2 E_i^2} - 1\right] + U(J),\qquad
    E_i = \kappa(\bar I_1 - 3) + (1 - 3\kappa)(\bar I_i - 1),

with :math:`\bar I_1 = J^{-2/3}\operatorname{tr}C`, :math:`\bar I_4 = J^{-2/3}\,a_{01}\cdot C a_{01}`,
:math:`\bar I_6 = J^{-2/3}\,a_{02}\cdot C a_{02}` (unit reference directions
:math:`a_{01}, a_{02}`) and the dispersion :math:`\kappa \in [0, 1/3]`
(:math:`\kappa = 0`: aligned fibres, the law of Holzapfel, Gasser & Ogden 2000;
:math:`\kappa = 1/3`: isotropic distribution). T. C. Gasser, R. W. Ogden and
G. A. Holzapfel, "Hyperelastic modelling of arterial layers with distributed
collagen fibre orientations", *J. R. Soc. Interface* 3 (2006) 15–35.

**Fibres act in tension only.** The exact switch is chosen by
:attr:`HolzapfelGasserOgdenParameters.switch`:

* ``"strain"`` (default): a family contributes only while :math:`E_i > 0`, i.e.
  :math:`E_i` enters through the Macaulay bracket :math:`\langle E_i\rangle = \max(E_i, 0)`.
  This is the switch of FEBio's ``Holzapfel-Gasser-Ogden`` material
  (``FEHolzapfelGasserOgden.cpp``: ``if (E >= 0)``). Since
  :math:`\tfrac{d}{dE}[e^{k_2E^2} - 1] = 0` at :math:`E = 0` the energy is
  :math:`C^1` across the switch (the tangent jumps there). With :math:`\kappa > 0`
  a family in compression (:math:`\bar I_i < 1`) can still have :math:`E_i > 0`
  under large isochoric strain and then carries stress.
* ``"stretch"``: a family contributes only while :math:`\bar I_i > 1` (the fibre
  itself is extended), the criterion Holzapfel & Ogden argue for with dispersed
  fibres ("On the tension–compression switch in soft fibrous solids",
  *Eur. J. Mech. A/Solids* 49 (2015) 561–569). For :math:`\kappa = 0` this is the
  ``"strain"`` switch; for :math:`\kappa > 0` the energy *jumps* at
  :math:`\bar I_i = 1` by :math:`\tfrac{k_1}{2k_2}[e^{k_2\kappa^2(\bar I_1 - 3)^2} - 1]`.
* ``"none"``: no switch (fibres resist compression too).

**Optional smoothing** (``smoothing = ε > 0``) makes either switch :math:`C^\infty`
with the weight :math:`H(y) = \tfrac12(1 + \tanh y)`: ``"strain"`` replaces
:math:`\langle E\rangle` by :math:`E\,H(E/\varepsilon)` (zero energy and stress at
:math:`E = 0`, bounded energy for :math:`E < 0`, the exact law for
:math:`|E| \gg \varepsilon`); ``"stretch"`` multiplies the family's energy by
:math:`H((\bar I_i - 1)/\varepsilon)`. At :math:`F = I` the smoothed tangent is
well defined (the exact one depends on the sign of round-off in :math:`E_i`):
:math:`\partial^2\psi_f/\partial E^2 = k_1/4` for ``"strain"``, :math:`k_1/2` for ``"stretch"``.

The closed-form stress (:func:`holzapfel_gasser_ogden_stress`, verification only) is

.. math::
    P = F\,J^{-2/3}\left[\bar S - \tfrac13(\bar S : C)\,C^{-1}\right] + K\ln J\,F^{-T},\qquad
    \bar S = 2\frac{\partial\psi}{\partial\bar C}
      = \mu I + 2\sum_i\left(\psi_{,\bar I_1}^{(i)} I + \psi_{,\bar I_i}^{(i)}\,a_{0i}\otimes a_{0i}\right).

Fibre directions are UFL vectors, as for :func:`~hyperfem.materials.muscle.muscle`:
a :class:`dolfinx.fem.Constant`, a ``ufl.as_vector`` or a field from
:mod:`hyperfem.fibres` (``constant_fibres``, ``laplace_fibres``, …). 3×3 ``F`` only.
"""

from __future__ import annotations

from dataclasses import dataclass

import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import isochoric_invariants, right_cauchy_green
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_nonnegative, check_positive, is_finite_number

__all__ = [
    "HGO_SWITCHES",
    "HolzapfelGasserOgdenParameters",
    "fibre_strain",
    "hgo_fibre_energy",
    "holzapfel_gasser_ogden",
    "holzapfel_gasser_ogden_isochoric",
    "holzapfel_gasser_ogden_stress",
    "smooth_step",
]

Expr = ufl.core.expr.Expr

HGO_SWITCHES = ("strain", "stretch", "none")
"""Tension-only switches: on :math:`E_i > 0`, on :math:`\\bar I_i > 1`, or none."""

_Y_MAX = 30.0  # tanh(30) == 1.0 in double precision; clamping keeps UFL's tanh derivative (cosh ratios) finite


@dataclass(frozen=True)
class HolzapfelGasserOgdenParameters:
    r"""Holzapfel–Gasser–Ogden (2006) constants.

    Attributes:
        mu: Shear modulus of the neo-Hookean matrix :math:`\mu > 0` (stress units, e.g. Pa).
        k1: Fibre stiffness :math:`k_1 \ge 0` (stress units).
        k2: Fibre exponent :math:`k_2 > 0` (dimensionless).
        kappa: Dispersion :math:`\kappa \in [0, 1/3]` (dimensionless).
        K: Bulk modulus :math:`K > 0` (stress units).
        volumetric: Volumetric law name (see :mod:`hyperfem.materials.volumetric`).
        switch: Tension-only switch, one of :data:`HGO_SWITCHES` (module docstring).
        smoothing: Width :math:`\varepsilon \ge 0` of the smoothed switch (0: exact), in units of
            :math:`E_i` (``"strain"``) or of :math:`\bar I_i - 1` (``"stretch"``).
    """

    mu: float
    k1: float
    k2: float
    kappa: float
    K: float
    volumetric: str = "log"
    switch: str = "strain"
    smoothing: float = 0.0

    def __post_init__(self) -> None:
        where = "HolzapfelGasserOgdenParameters"
        check_positive("mu", self.mu, where)
        check_nonnegative("k1", self.k1, where)
        check_positive("k2", self.k2, where)
        if not (is_finite_number(self.kappa) and 0.0 <= self.kappa <= 1.0 / 3.0):
            raise ParameterError(f"{where}: kappa must be a number in [0, 1/3], got {self.kappa!r}")
        check_positive("K", self.K, where)
        volumetric_law(self.volumetric)
        if self.switch not in HGO_SWITCHES:
            raise ParameterError(f"{where}: switch must be one of {', '.join(HGO_SWITCHES)}, got {self.switch!r}")
        check_nonnegative("smoothing", self.smoothing, where)

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus of the matrix, :math:`\mu` (shear in a plane containing the fibres)."""
        return self.mu


def smooth_step(y: Expr) -> Expr:
    r"""Smooth Heaviside :math:`H(y) = \tfrac12(1 + \tanh y)`, ``y`` clamped to :math:`[-30, 30]`."""
    return 0.5 * (1.0 + ufl.tanh(ufl.max_value(ufl.min_value(y, _Y_MAX), -_Y_MAX)))


def _smooth_step_derivative(y: Expr) -> Expr:
    r""":math:`H'(y) = \tfrac12(1 - \tanh^2 y)` inside the clamp, 0 outside (closed form, for verification)."""
    t = ufl.tanh(ufl.max_value(ufl.min_value(y, _Y_MAX), -_Y_MAX))
    inside = ufl.And(ufl.gt(y, -_Y_MAX), ufl.lt(y, _Y_MAX))
    return ufl.conditional(inside, 0.5 * (1.0 - t**2), 0.0)


def fibre_strain(I1b: Expr, I4b: Expr, kappa: float) -> Expr:
    r"""Fibre strain :math:`E = \kappa(\bar I_1 - 3) + (1 - 3\kappa)(\bar I_4 - 1)`."""
    return kappa * (I1b - 3.0) + (1.0 - 3.0 * kappa) * (I4b - 1.0)


def _g(E: Expr, params: HolzapfelGasserOgdenParameters) -> Expr:
    return params.k1 / (2.0 * params.k2) * (ufl.exp(params.k2 * E**2) - 1.0)


def _dg(E: Expr, params: HolzapfelGasserOgdenParameters) -> Expr:
    return params.k1 * E * ufl.exp(params.k2 * E**2)


def hgo_fibre_energy(I1b: Expr, I4b: Expr, params: HolzapfelGasserOgdenParameters) -> Expr:
    r"""Energy of one fibre family, :math:`\tfrac{k_1}{2k_2}[e^{k_2E^2} - 1]` behind the tension-only switch."""
    E = fibre_strain(I1b, I4b, params.kappa)
    eps = params.smoothing
    if params.switch == "none":
        return _g(E, params)
    if params.switch == "strain":
        return _g(E * smooth_step(E / eps) if eps > 0 else ufl.max_value(E, 0.0), params)
    if eps > 0:  # "stretch"
        return smooth_step((I4b - 1.0) / eps) * _g(E, params)
    return ufl.conditional(ufl.gt(I4b, 1.0), _g(E, params), 0.0)


def _fibre_partials(I1b: Expr, I4b: Expr, params: HolzapfelGasserOgdenParameters) -> tuple[Expr, Expr]:
    r""":math:`(\partial\psi_f/\partial\bar I_1, \partial\psi_f/\partial\bar I_4)` of :func:`hgo_fibre_energy`."""
    kappa, eps = params.kappa, params.smoothing
    E = fibre_strain(I1b, I4b, kappa)
    if params.switch == "none":
        dE = _dg(E, params)
    elif params.switch == "strain" and eps > 0:
        y = E / eps
        s = E * smooth_step(y)
        dE = _dg(s, params) * (smooth_step(y) + y * _smooth_step_derivative(y))
    elif params.switch == "strain":
        dE = ufl.conditional(ufl.gt(E, 0.0), _dg(E, params), 0.0)
    elif eps > 0:  # "stretch", smooth: H(y) g(E), y = (I4 - 1)/eps
        y = (I4b - 1.0) / eps
        H, dH = smooth_step(y), _smooth_step_derivative(y) / eps
        return H * kappa * _dg(E, params), H * (1.0 - 3.0 * kappa) * _dg(E, params) + dH * _g(E, params)
    else:  # "stretch", exact
        dE = ufl.conditional(ufl.gt(I4b, 1.0), _dg(E, params), 0.0)
    return kappa * dE, (1.0 - 3.0 * kappa) * dE


def holzapfel_gasser_ogden_isochoric(F: Expr, a01: Expr, a02: Expr, params: HolzapfelGasserOgdenParameters) -> Expr:
    r"""Isochoric part :math:`\tfrac{\mu}{2}(\bar I_1 - 3) + \sum_i \psi_f(E_i)` (3×3 ``F``)."""
    I1b, _, J = isochoric_invariants(F)
    C = right_cauchy_green(F)
    out = 0.5 * params.mu * (I1b - 3.0)
    for a in (a01, a02):
        out = out + hgo_fibre_energy(I1b, J ** (-2.0 / 3.0) * ufl.dot(a, C * a), params)
    return out


def holzapfel_gasser_ogden(F: Expr, a01: Expr, a02: Expr, params: HolzapfelGasserOgdenParameters) -> Expr:
    """Strain-energy density of the Holzapfel–Gasser–Ogden law with its volumetric term.

    Args:
        F: Deformation gradient (3×3).
        a01: Unit direction of the first fibre family (reference configuration, UFL vector).
        a02: Unit direction of the second family (``a02 = a01`` with :math:`k_1/2`: one family of :math:`k_1`).
        params: Material parameters.
    """
    return holzapfel_gasser_ogden_isochoric(F, a01, a02, params) + volumetric_energy(
        ufl.det(F), params.K, params.volumetric
    )


def holzapfel_gasser_ogden_stress(F: Expr, a01: Expr, a02: Expr, params: HolzapfelGasserOgdenParameters) -> Expr:
    r"""Closed-form first Piola–Kirchhoff stress, ``"log"`` volumetric law (verification only; module docstring)."""
    if params.volumetric != "log":
        raise ParameterError("holzapfel_gasser_ogden_stress: closed form implemented for the 'log' volumetric law")
    I1b, _, J = isochoric_invariants(F)
    C = right_cauchy_green(F)
    Id = ufl.Identity(3)
    Sbar = params.mu * Id
    for a in (a01, a02):
        d1, d4 = _fibre_partials(I1b, J ** (-2.0 / 3.0) * ufl.dot(a, C * a), params)
        Sbar = Sbar + 2.0 * (d1 * Id + d4 * ufl.outer(a, a))
    Cinv = ufl.inv(C)
    S = J ** (-2.0 / 3.0) * (Sbar - ufl.inner(Sbar, C) / 3.0 * Cinv)
    return F * S + params.K * ufl.ln(J) * ufl.inv(F).T
