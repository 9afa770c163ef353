r"""Linear viscous damping.

The damping force is Rayleigh's :math:`C\dot u` with

.. math::
    C = \alpha M + \beta K_0,

:math:`M` the mass matrix (same density and lumping as the inertia) and
:math:`K_0` the elastic tangent at the reference configuration. Seed 003
(§3.11, §5.7.2) uses a viscous body force :math:`c\,\dot x` with
:math:`c = 0.0004\ \mathrm{s^{-1}}`; with :math:`c` in 1/s that is the
mass-proportional part, :math:`\alpha = c` (:func:`viscous_damping`).

Because :math:`C` is constant and symmetric, and the integrators express the
velocity linearly in the unknown displacement, :math:`v = B(u - \hat u)`,
the damping force derives from the quadratic incremental potential

.. math::
    D(u) = \frac{B}{2}\,(u - \hat u)^T C\,(u - \hat u),

which keeps the energy line search available.
"""

from __future__ import annotations

from dataclasses import dataclass

import ufl
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.validation import check_nonnegative, is_finite_number

__all__ = ["RayleighDamping", "reference_stiffness_form", "viscous_damping"]


@dataclass(frozen=True)
class RayleighDamping:
    r"""Rayleigh damping :math:`C = \alpha M + \beta K_0`.

    Attributes:
        alpha: Mass-proportional coefficient (1/s).
        beta: Stiffness-proportional coefficient (s).
    """

    alpha: float = 0.0
    beta: float = 0.0

    def __post_init__(self) -> None:
        for name in ("alpha", "beta"):
            check_nonnegative(name, getattr(self, name), "RayleighDamping")

    @classmethod
    def from_damping_ratios(cls, zeta1: float, omega1: float, zeta2: float, omega2: float) -> RayleighDamping:
        r"""Coefficients giving damping ratio :math:`\zeta_i` at angular frequency :math:`\omega_i`.

        Solves :math:`\zeta_i = \alpha/(2\omega_i) + \beta\omega_i/2`, :math:`i = 1, 2`.
        """
        where = "RayleighDamping.from_damping_ratios"
        for name, v in (("zeta1", zeta1), ("omega1", omega1), ("zeta2", zeta2), ("omega2", omega2)):
            if not is_finite_number(v):
                raise ParameterError(f"{where}: {name} must be a finite number, got {v!r}")
        if omega1 <= 0 or omega2 <= 0 or omega1 == omega2:
            raise ParameterError(f"{where}: need distinct positive frequencies, got {omega1!r}, {omega2!r}")
        det = omega2 / omega1 - omega1 / omega2
        alpha = 2.0 * (zeta1 * omega2 - zeta2 * omega1) / det
        beta = 2.0 * (zeta2 / omega1 - zeta1 / omega2) / det
        return cls(alpha, beta)

    @property
    def active(self) -> bool:
        """Whether any coefficient is non-zero."""
        return self.alpha > 0 or self.beta > 0


def viscous_damping(c: float) -> RayleighDamping:
    r"""Seed 003's viscous body force :math:`c\,\rho\,\dot u` (``c`` in 1/s): :math:`\alpha = c`."""
    return RayleighDamping(alpha=c)


def reference_stiffness_form(
    energy_internal: ufl.Form, u: fem.Function, a: ufl.core.expr.Expr, b: ufl.core.expr.Expr
) -> ufl.Form:
    r""":math:`K_0[a, b] = \partial^2_u \Pi_\text{int}(0)[a, b]`, the reference elastic tangent.

    ``a`` and ``b`` may be arguments, coefficients or expressions of them.
    """
    V = u.function_space
    wa, wb = fem.Function(V), fem.Function(V)
    zero = fem.Function(V)
    second = ufl.algorithms.expand_derivatives(ufl.derivative(ufl.derivative(energy_internal, u, wa), u, wb))
    return ufl.replace(second, {u: zero, wa: a, wb: b})
