r"""Gent rubber law: limiting chain extensibility through a logarithm.

.. math::
    \psi(F) = -\frac{\mu J_m}{2}\ln\!\left(1 - \frac{\bar I_1 - 3}{J_m}\right) + U(J),\qquad
    \bar I_1 = J^{-2/3}\operatorname{tr} C

(A. N. Gent, "A new constitutive relation for rubber", *Rubber Chem. Technol.*
69 (1996) 59–61). :math:`\mu` is the small-strain shear modulus and :math:`J_m`
the limiting value of :math:`\bar I_1 - 3`; :math:`J_m \to \infty` gives the
neo-Hookean law :math:`\tfrac{\mu}{2}(\bar I_1 - 3)`.

**At and beyond the lock** (:math:`x = (\bar I_1 - 3)/J_m \ge 1`) the exact law has
no value. Two behaviours, chosen by :attr:`GentParameters.lock_fraction`:

* ``None`` (default, the exact law): the energy, stress and tangent are computed
  as :math:`-\mu J_m\ln\sqrt{1 - x}` and are all NaN there (a square root of a
  negative number; infinite at :math:`x = 1` exactly). Written as :math:`\ln(1 - x)`
  only the energy would be NaN: its derivative :math:`1/(1 - x)` is finite and
  negative beyond the lock, so a residual could vanish at a spurious state there.
  A pure UFL expression cannot raise, so the refusal is
  the solver's: a state beyond the lock has a non-finite energy and residual
  and never passes a convergence test, and a solve whose start lies beyond it
  raises :class:`~hyperfem.errors.ParameterError` naming the stored energy (a
  unit cube with :math:`J_m = 0.3` pulled to stretch 2 in steps of 0.05 stopped
  so at load factor 0.6: that step's boundary increment, carried into the body
  by the predictor, crossed the lock).
* ``lock_fraction = f`` in (0, 1): for :math:`x \ge f` the logarithm
  :math:`-\ln(1 - x)` is continued by its second-order Taylor polynomial at
  :math:`x = f`, so the energy is finite, convex in :math:`\bar I_1` and
  :math:`C^2` everywhere, and equals the exact law wherever :math:`x < f`. The
  stiffness beyond :math:`f J_m` is then that of the lock's onset, not infinite:
  use it to let Newton iterates pass through over-stretched states, and check the
  converged state has :math:`x < f` (the same cube with ``lock_fraction=0.9``
  reached stretch 2, far beyond the lock).

The first Piola–Kirchhoff stress (:func:`gent_stress`, verification only) is

.. math::
    P = 2\psi_1 J^{-2/3}\left(F - \tfrac13\operatorname{tr}C\,F^{-T}\right) + J U'(J) F^{-T},\qquad
    \psi_1 = \frac{\mu}{2}\,\frac{1}{1 - x}\quad(\text{beyond } f\text{: the derivative of the continuation}).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import isochoric_invariants, jacobian, plane_strain_3d
from hyperfem.materials.mooney_rivlin import mooney_rivlin_isochoric_stress
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_positive, is_finite_number

__all__ = ["GentParameters", "gent", "gent_isochoric", "gent_stress"]

Expr = ufl.core.expr.Expr


@dataclass(frozen=True)
class GentParameters:
    r"""Gent (1996) constants.

    Attributes:
        mu: Small-strain shear modulus :math:`\mu > 0` (stress units, e.g. Pa).
        Jm: Limiting value of :math:`\bar I_1 - 3`, :math:`J_m > 0` (dimensionless).
        K: Bulk modulus :math:`K > 0` (stress units).
        volumetric: Volumetric law name (see :mod:`hyperfem.materials.volumetric`).
        lock_fraction: ``None`` for the exact law (NaN beyond the lock), or :math:`f \in (0, 1)`:
            the logarithm is continued quadratically beyond :math:`\bar I_1 - 3 = f J_m`.
    """

    mu: float
    Jm: float
    K: float
    volumetric: str = "log"
    lock_fraction: float | None = None

    def __post_init__(self) -> None:
        where = "GentParameters"
        check_positive("mu", self.mu, where)
        check_positive("Jm", self.Jm, where)
        check_positive("K", self.K, where)
        volumetric_law(self.volumetric)
        f = self.lock_fraction
        if f is not None and not (is_finite_number(f) and 0.0 < f < 1.0):
            raise ParameterError(f"{where}: lock_fraction must be None or a number in (0, 1), got {f!r}")

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus :math:`\mu`."""
        return self.mu


def _minus_log1m(x: Expr, f: float | None) -> Expr:
    r""":math:`-\ln(1 - x)`, continued by its quadratic Taylor polynomial at ``f`` for :math:`x \ge f`."""
    if f is None:
        # 2 ln sqrt(1 - x), not ln(1 - x): the derivative of the plain logarithm, 1/(1 - x), is finite (and
        # negative) beyond the lock; through the square root stress and tangent are NaN there as well.
        return -2.0 * ufl.ln(ufl.sqrt(1.0 - x))
    xc = ufl.min_value(x, f)  # keeps the logarithm finite in the branch not taken
    s = x - f
    taylor = -math.log(1.0 - f) + s / (1.0 - f) + 0.5 * s**2 / (1.0 - f) ** 2
    return ufl.conditional(ufl.lt(x, f), -ufl.ln(1.0 - xc), taylor)


def _minus_log1m_derivative(x: Expr, f: float | None) -> Expr:
    r""":math:`1/(1 - x)`, the derivative of :func:`_minus_log1m` (closed form, for verification)."""
    if f is None:
        return 1.0 / (1.0 - x)
    xc = ufl.min_value(x, f)
    return ufl.conditional(ufl.lt(x, f), 1.0 / (1.0 - xc), 1.0 / (1.0 - f) + (x - f) / (1.0 - f) ** 2)


def gent_isochoric(F: Expr, params: GentParameters) -> Expr:
    r"""Isochoric part :math:`-\tfrac{\mu J_m}{2}\ln(1 - (\bar I_1 - 3)/J_m)` (2×2 ``F``: plane strain)."""
    I1b, _, _ = isochoric_invariants(F)
    x = (I1b - 3.0) / params.Jm
    return 0.5 * params.mu * params.Jm * _minus_log1m(x, params.lock_fraction)


def gent(F: Expr, params: GentParameters) -> Expr:
    """Strain-energy density of the Gent law with its volumetric term.

    Args:
        F: Deformation gradient (3×3, or 2×2 for plane strain).
        params: Material parameters.
    """
    return gent_isochoric(F, params) + volumetric_energy(jacobian(plane_strain_3d(F)), params.K, params.volumetric)


def gent_stress(F: Expr, params: GentParameters) -> Expr:
    r"""Closed-form :math:`P` for the ``"log"`` volumetric law, :math:`p = K\ln J` (3×3 ``F``; verification only)."""
    if params.volumetric != "log":
        raise ParameterError("gent_stress: closed form implemented for the 'log' volumetric law")
    I1b, _, J = isochoric_invariants(F)
    x = (I1b - 3.0) / params.Jm
    psi1 = 0.5 * params.mu * _minus_log1m_derivative(x, params.lock_fraction)
    return mooney_rivlin_isochoric_stress(F, psi1, 0.0) + params.K * ufl.ln(J) * ufl.inv(F).T
