r"""Ogden's N-term rubber on the distortional stretches, with a volumetric term.

.. math::
    \psi(F) = \sum_{p=1}^{N}\frac{\mu_p}{\alpha_p}\big(\bar\lambda_1^{\alpha_p} + \bar\lambda_2^{\alpha_p}
        + \bar\lambda_3^{\alpha_p} - 3\big) + U(J),\qquad \bar\lambda_i = J^{-1/3}\lambda_i,

(seed 003 eq. 4.73d on the distortional stretches, Ogden 1972), with :math:`U`
a law of :mod:`hyperfem.materials.volumetric`. Terms with an even exponent
:math:`\alpha_p = 2k` are :math:`\operatorname{tr}\bar C^k`, polynomials in the
invariants :math:`\bar I_1, \bar I_2` (:math:`\alpha = 2`: neo-Hookean; :math:`(2, -2)`:
Mooney–Rivlin); the others enter through
:func:`~hyperfem.materials.principal_stretches.eigenvalue_power_sum` of
:math:`\bar C = J^{-2/3}C`, whose first and second derivatives (``ufl.derivative``:
residual and tangent) are exact to round-off at coincident stretches too: at
:math:`F = I` and on every uniaxial and equibiaxial state (measured: tangent
errors below 5e-14 there, 2e-12 in the worst state near :math:`F = I`; method,
errors and the compile cost of the tangent, 18 s of CPU for three terms, in
that module). :func:`ogden_isochoric` is the isochoric part for the three-field
formulation (:class:`~hyperfem.problem.mixed.SplitEnergy`).

**Parameters.** :class:`OgdenParameters` stores Ogden's :math:`\mu_p` (shear
modulus :math:`\mu_0 = \frac12\sum_p\mu_p\alpha_p`). Other codes write the same
energy with other coefficients, converted by :meth:`OgdenParameters.from_convention`:

* ``"ogden"``: :math:`\sum_p \frac{\mu_p}{\alpha_p}(\dots)`, the coefficients as given;
* ``"febio"``: :math:`\sum_p \frac{c_p}{m_p^2}(\dots)`, :math:`c_p = \mu_p\alpha_p`;
* ``"abaqus"``: :math:`\sum_p \frac{2\mu_p^A}{\alpha_p^2}(\dots)`, :math:`\mu_p^A = \mu_p\alpha_p/2`
  (so :math:`\mu_0 = \sum_p\mu_p^A`).

Validation asks :math:`\mu_p\alpha_p > 0` for *every* term (Ogden's condition:
each term :math:`\frac{\mu_p}{\alpha_p}(e^{\alpha_p\varepsilon} - 1)` is convex in the
log-stretch :math:`\varepsilon`, and :math:`\mu_0 > 0` follows), not only
:math:`\mu_0 > 0`: fits that trade a negative term against a positive one are
refused. Ogden's and Treloar's classic fits satisfy it.

**Closed forms** (incompressible, nominal stress; verification only):
uniaxial :math:`P = \sum_p\mu_p(\lambda^{\alpha_p-1} - \lambda^{-\alpha_p/2-1})`,
equibiaxial :math:`P = \sum_p\mu_p(\lambda^{\alpha_p-1} - \lambda^{-2\alpha_p-1})`,
pure shear :math:`P = \sum_p\mu_p(\lambda^{\alpha_p-1} - \lambda^{-\alpha_p-1})`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import jacobian, plane_strain_3d, right_cauchy_green
from hyperfem.materials.principal_stretches import (
    eigenvalue_power_sum,
    invariant_power_sum,
    spectral_invariants,
)
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_positive, is_finite_number

__all__ = [
    "CONVENTIONS",
    "OgdenParameters",
    "ogden",
    "ogden_equibiaxial_stress",
    "ogden_isochoric",
    "ogden_pure_shear_stress",
    "ogden_uniaxial_stress",
]

Expr = ufl.core.expr.Expr

CONVENTIONS: tuple[str, ...] = ("abaqus", "febio", "ogden")
"""Names accepted by :meth:`OgdenParameters.from_convention` (module docstring)."""

_TO_OGDEN = {"ogden": 0.0, "febio": 1.0, "abaqus": 2.0}  # mu_p = s k_p / alpha_p (0: k_p as given)


def _terms(values: object, name: str) -> tuple[float, ...]:
    if isinstance(values, (str, bytes)) or not isinstance(values, Sequence):
        raise ParameterError(f"OgdenParameters: {name} must be a sequence of numbers, got {values!r}")
    if not values:
        raise ParameterError(f"OgdenParameters: {name} is empty")
    for i, v in enumerate(values):
        if not is_finite_number(v):
            raise ParameterError(f"OgdenParameters: {name}[{i}] must be a finite number, got {v!r}")
    return tuple(float(v) for v in values)


@dataclass(frozen=True)
class OgdenParameters:
    r"""Ogden's :math:`N` pairs :math:`(\mu_p, \alpha_p)` and the bulk modulus.

    Attributes:
        mu: :math:`\mu_p` in Ogden's convention :math:`\sum_p\frac{\mu_p}{\alpha_p}(\dots)`.
        alpha: Exponents :math:`\alpha_p \ne 0`; :math:`\mu_p\alpha_p > 0` for every term.
        K: Bulk modulus (> 0).
        volumetric: Name of the volumetric law (see :mod:`hyperfem.materials.volumetric`).
    """

    mu: tuple[float, ...]
    alpha: tuple[float, ...]
    K: float
    volumetric: str = "log"

    def __post_init__(self) -> None:
        mu, alpha = _terms(self.mu, "mu"), _terms(self.alpha, "alpha")
        if len(mu) != len(alpha):
            raise ParameterError(f"OgdenParameters: mu and alpha need equal lengths, got {len(mu)} and {len(alpha)}")
        for i, (m, a) in enumerate(zip(mu, alpha, strict=True)):
            if a == 0.0:
                raise ParameterError(f"OgdenParameters: alpha[{i}] must be nonzero")
            if not m * a > 0.0:
                raise ParameterError(
                    f"OgdenParameters: term {i} needs mu*alpha > 0 (Ogden's stability condition), "
                    f"got mu={m!r}, alpha={a!r}"
                )
        check_positive("K", self.K, "OgdenParameters")
        volumetric_law(self.volumetric)
        object.__setattr__(self, "mu", mu)
        object.__setattr__(self, "alpha", alpha)

    @classmethod
    def from_convention(
        cls,
        mu: Sequence[float],
        alpha: Sequence[float],
        K: float,
        convention: str = "ogden",
        volumetric: str = "log",
    ) -> OgdenParameters:
        r"""Build from the coefficients of another code's convention (module docstring).

        Args:
            mu: The coefficients: Ogden's :math:`\mu_p` (``"ogden"``), FEBio's :math:`c_p = \mu_p\alpha_p`
                (``"febio"``) or Abaqus's :math:`\mu_p^A = \mu_p\alpha_p/2` (``"abaqus"``).
            alpha: Exponents :math:`\alpha_p` (the same in every convention).
            K: Bulk modulus.
            convention: ``"ogden"``, ``"febio"`` or ``"abaqus"``.
            volumetric: Name of the volumetric law.

        Raises:
            ParameterError: Unknown convention, or invalid parameters.
        """
        if convention not in _TO_OGDEN:
            raise ParameterError(
                f"OgdenParameters: unknown convention {convention!r} (available: {', '.join(CONVENTIONS)})"
            )
        k, a = _terms(mu, "mu"), _terms(alpha, "alpha")
        scale = _TO_OGDEN[convention]
        if scale and len(k) == len(a) and all(x != 0.0 for x in a):  # else the constructor says what is wrong
            k = tuple(scale * kp / ap for kp, ap in zip(k, a, strict=True))
        return cls(mu=k, alpha=a, K=K, volumetric=volumetric)

    @property
    def shear_modulus(self) -> float:
        r"""Small-strain shear modulus :math:`\mu_0 = \frac12\sum_p\mu_p\alpha_p`."""
        return 0.5 * sum(m * a for m, a in zip(self.mu, self.alpha, strict=True))


def ogden_isochoric(F: Expr, mu: Sequence[float | Expr], alpha: Sequence[float]) -> Expr:
    r"""Isochoric part :math:`\sum_p\frac{\mu_p}{\alpha_p}(\sum_i\bar\lambda_i^{\alpha_p} - 3)` (2×2 F: plane strain).

    Args:
        F: Deformation gradient.
        mu: Ogden's :math:`\mu_p`.
        alpha: Exponents :math:`\alpha_p`.
    """
    terms = list(zip(mu, alpha, strict=True))
    if not terms:
        raise ParameterError("ogden_isochoric: no terms")
    F3 = plane_strain_3d(F)
    inv = spectral_invariants(right_cauchy_green(F3)).scaled(jacobian(F3) ** (-2.0 / 3.0))  # of Cbar = J^(-2/3) C
    parts: list[Expr] = []
    even = [(m, int(a) // 2) for m, a in terms if _is_even_integer(a)]
    if even:  # sum_i lbar_i^(2k) = tr(Cbar^k) by Newton's identities, det Cbar = 1
        I1b, I2b = 3.0 * inv.mean, 3.0 * inv.mean**2 - inv.J2
        parts += [(m / (2.0 * k)) * (invariant_power_sum(I1b, I2b, 1.0, k) - 3.0) for m, k in even]
    spectral = [(m / a, 0.5 * a) for m, a in terms if not _is_even_integer(a)]
    if spectral:
        parts.append(eigenvalue_power_sum(inv, [k for k, _ in spectral], [b for _, b in spectral]))
    energy = parts[0]
    for part in parts[1:]:
        energy = energy + part
    return energy


def _is_even_integer(a: float) -> bool:
    return float(a).is_integer() and int(a) % 2 == 0


def ogden(F: Expr, params: OgdenParameters) -> Expr:
    """Strain-energy density of the compressible (split) Ogden law."""
    return ogden_isochoric(F, params.mu, params.alpha) + volumetric_energy(
        jacobian(plane_strain_3d(F)), params.K, params.volumetric
    )


def _nominal(stretch: float | np.ndarray, mu: Sequence[float], alpha: Sequence[float], lateral: float) -> np.ndarray:
    lam = np.asarray(stretch, dtype=float)
    out = np.zeros_like(lam)
    for m, a in zip(mu, alpha, strict=True):
        out = out + m * (lam ** (a - 1.0) - lam ** (lateral * a - 1.0))
    return out


def ogden_uniaxial_stress(stretch: float | np.ndarray, mu: Sequence[float], alpha: Sequence[float]) -> np.ndarray:
    r"""Incompressible uniaxial nominal stress :math:`\sum_p\mu_p(\lambda^{\alpha_p-1} - \lambda^{-\alpha_p/2-1})`."""
    return _nominal(stretch, mu, alpha, -0.5)


def ogden_equibiaxial_stress(stretch: float | np.ndarray, mu: Sequence[float], alpha: Sequence[float]) -> np.ndarray:
    r"""Incompressible equibiaxial nominal stress :math:`\sum_p\mu_p(\lambda^{\alpha_p-1} - \lambda^{-2\alpha_p-1})`."""
    return _nominal(stretch, mu, alpha, -2.0)


def ogden_pure_shear_stress(stretch: float | np.ndarray, mu: Sequence[float], alpha: Sequence[float]) -> np.ndarray:
    r"""Incompressible pure-shear nominal stress :math:`\sum_p\mu_p(\lambda^{\alpha_p-1} - \lambda^{-\alpha_p-1})`."""
    return _nominal(stretch, mu, alpha, -1.0)
