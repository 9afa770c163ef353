r"""Fung orthotropic exponential law (arteries, myocardium, skin) on the isochoric Green strain.

.. math::
    \psi(F) = \frac{c}{2}\left(e^{Q} - 1\right) + U(J),\qquad
    \tilde E = \tfrac12\left(J^{-2/3}C - I\right),\quad E_{ab} = a_a\cdot\tilde E\,a_b,

.. math::
    Q = b_1E_{11}^2 + b_2E_{22}^2 + b_3E_{33}^2 + 2b_4E_{11}E_{22} + 2b_5E_{22}E_{33} + 2b_6E_{33}E_{11}
      + 2b_7E_{12}^2 + 2b_8E_{23}^2 + 2b_9E_{31}^2,

in the orthonormal material axes :math:`a_1, a_2, a_3 = a_1\times a_2` of the
reference configuration. This is the exponential law of Y. C. Fung, K. Fronek and
P. Patitucci ("Pseudoelasticity of arteries and the choice of its mathematical
expression", *Am. J. Physiol.* 237 (1979) H620–H631) in its three-dimensional form
(normal terms :math:`b_1 \dots b_6` of C. J. Chuong and Y. C. Fung, *J. Biomech. Eng.*
105 (1983) 268–274; shear terms :math:`b_7E_{12}^2 + b_7E_{21}^2` etc. as in
J. D. Humphrey, *Cardiovascular Solid Mechanics*, Springer 2002), written on the
isochoric strain :math:`\tilde E` with a separate :math:`U(J)` as in FEBio's
uncoupled ``Fung orthotropic`` material (whose :math:`\mu_a, \lambda_{ab}` are
:math:`b_{aa} = (2\mu_a + \lambda_{aa})/c`, :math:`b_{ab} = \lambda_{ab}/c`, shear
:math:`(\mu_a + \mu_b)/c`).

At small strain :math:`\psi \approx \tfrac c2 Q`: the shear moduli are
:math:`G_{12} = cb_7/2`, :math:`G_{23} = cb_8/2`, :math:`G_{31} = cb_9/2`
(:attr:`FungOrthotropicParameters.shear_moduli`), and
:meth:`FungOrthotropicParameters.isotropic` (:math:`cb_{1,2,3} = \lambda + 2\mu`,
:math:`cb_{4,5,6} = \lambda`, :math:`cb_{7,8,9} = 2\mu`) has shear modulus :math:`\mu`.

The closed-form stress (:func:`fung_orthotropic_stress`, verification only) is

.. math::
    P = F\,J^{-2/3}\left[\tilde S - \tfrac13(\tilde S : C)\,C^{-1}\right] + K\ln J\,F^{-T},\qquad
    \tilde S = \frac{\partial\psi}{\partial\tilde E}
      = \frac c2 e^Q\sum_{a,b}\frac{\partial Q}{\partial E_{ab}}\,a_a\otimes a_b.

Directions are UFL vectors (:class:`dolfinx.fem.Constant`, ``ufl.as_vector`` or a
field from :mod:`hyperfem.fibres`), as for :func:`~hyperfem.materials.muscle.muscle`;
``a1`` and ``a2`` must be orthonormal. 3×3 ``F`` only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import right_cauchy_green
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.validation import check_positive, is_finite_number

__all__ = [
    "FungOrthotropicParameters",
    "fung_orthotropic",
    "fung_orthotropic_isochoric",
    "fung_orthotropic_stress",
    "fung_q",
]

Expr = ufl.core.expr.Expr


@dataclass(frozen=True)
class FungOrthotropicParameters:
    r"""Fung orthotropic constants.

    Attributes:
        c: Stress scale :math:`c > 0` (stress units, e.g. Pa).
        b1, b2, b3: Normal coefficients of :math:`E_{11}^2, E_{22}^2, E_{33}^2` (dimensionless).
        b4, b5, b6: Couplings of :math:`E_{11}E_{22}`, :math:`E_{22}E_{33}`, :math:`E_{33}E_{11}`
            (dimensionless); the normal block :math:`[[b_1, b_4, b_6], [b_4, b_2, b_5], [b_6, b_5, b_3]]`
            must be positive definite.
        b7, b8, b9: Shear coefficients of :math:`E_{12}^2, E_{23}^2, E_{31}^2` (dimensionless, > 0).
        K: Bulk modulus :math:`K > 0` (stress units).
        volumetric: Volumetric law name (see :mod:`hyperfem.materials.volumetric`).
    """

    c: float
    b1: float
    b2: float
    b3: float
    b4: float
    b5: float
    b6: float
    b7: float
    b8: float
    b9: float
    K: float
    volumetric: str = "log"

    def __post_init__(self) -> None:
        where = "FungOrthotropicParameters"
        check_positive("c", self.c, where)
        for name in ("b1", "b2", "b3", "b4", "b5", "b6"):
            value = getattr(self, name)
            if not is_finite_number(value):
                raise ParameterError(f"{where}: {name} must be a finite number, got {value!r}")
        for name in ("b7", "b8", "b9"):
            check_positive(name, getattr(self, name), where)
        eig = np.linalg.eigvalsh(np.array(self.normal_block, dtype=float))
        if eig.min() <= 0.0:
            raise ParameterError(
                f"{where}: the normal block [[b1, b4, b6], [b4, b2, b5], [b6, b5, b3]] must be positive definite "
                f"(Q > 0 for every nonzero strain), its eigenvalues are {', '.join(f'{e:.6g}' for e in eig)}"
            )
        check_positive("K", self.K, where)
        volumetric_law(self.volumetric)

    @classmethod
    def isotropic(
        cls, c: float, mu: float, lmbda: float, K: float, volumetric: str = "log"
    ) -> FungOrthotropicParameters:
        r"""The isotropic special case: :math:`cQ = \lambda(\operatorname{tr}\tilde E)^2 + 2\mu\,\tilde E:\tilde E`."""
        check_positive("c", c, "FungOrthotropicParameters.isotropic")
        n, m, s = (lmbda + 2.0 * mu) / c, lmbda / c, 2.0 * mu / c
        return cls(c, n, n, n, m, m, m, s, s, s, K, volumetric)

    @property
    def normal_block(self) -> tuple[tuple[float, float, float], ...]:
        r"""The symmetric matrix :math:`L` with :math:`\sum_{ab} L_{ab}E_{aa}E_{bb}` the normal part of :math:`Q`."""
        return ((self.b1, self.b4, self.b6), (self.b4, self.b2, self.b5), (self.b6, self.b5, self.b3))

    @property
    def shear_moduli(self) -> tuple[float, float, float]:
        r"""Small-strain shear moduli :math:`(G_{12}, G_{23}, G_{31}) = \tfrac c2(b_7, b_8, b_9)`."""
        return (0.5 * self.c * self.b7, 0.5 * self.c * self.b8, 0.5 * self.c * self.b9)


def _axes(a1: Expr, a2: Expr) -> list[Expr]:
    return [a1, a2, ufl.cross(a1, a2)]


def _isochoric_green_strain(F: Expr) -> Expr:
    r""":math:`\tilde E = \tfrac12(J^{-2/3}C - I)`."""
    return 0.5 * (ufl.det(F) ** (-2.0 / 3.0) * right_cauchy_green(F) - ufl.Identity(3))


def _local(E: Expr, axes: list[Expr]) -> list[list[Expr]]:
    return [[ufl.dot(axes[a], E * axes[b]) for b in range(3)] for a in range(3)]


def _shear(params: FungOrthotropicParameters) -> dict[tuple[int, int], float]:
    return {(0, 1): params.b7, (1, 2): params.b8, (0, 2): params.b9}


def fung_q(F: Expr, a1: Expr, a2: Expr, params: FungOrthotropicParameters) -> Expr:
    r"""The exponent :math:`Q(\tilde E)` in the axes ``a1``, ``a2``, ``a1 × a2``."""
    E = _local(_isochoric_green_strain(F), _axes(a1, a2))
    L = params.normal_block
    Q = sum((L[a][b] * E[a][a] * E[b][b] for a in range(3) for b in range(3)), ufl.as_ufl(0.0))
    for (a, b), coeff in _shear(params).items():
        Q = Q + 2.0 * coeff * E[a][b] ** 2
    return Q


def fung_orthotropic_isochoric(F: Expr, a1: Expr, a2: Expr, params: FungOrthotropicParameters) -> Expr:
    r"""Isochoric part :math:`\tfrac c2(e^Q - 1)` (3×3 ``F``)."""
    return 0.5 * params.c * (ufl.exp(fung_q(F, a1, a2, params)) - 1.0)


def fung_orthotropic(F: Expr, a1: Expr, a2: Expr, params: FungOrthotropicParameters) -> Expr:
    """Strain-energy density of the Fung orthotropic law with its volumetric term.

    Args:
        F: Deformation gradient (3×3).
        a1: First material axis (unit, reference configuration; UFL vector).
        a2: Second material axis (unit, orthogonal to ``a1``); the third is ``a1 × a2``.
        params: Material parameters.
    """
    return fung_orthotropic_isochoric(F, a1, a2, params) + volumetric_energy(ufl.det(F), params.K, params.volumetric)


def fung_orthotropic_stress(F: Expr, a1: Expr, a2: Expr, params: FungOrthotropicParameters) -> Expr:
    """Closed-form first Piola–Kirchhoff stress, ``"log"`` volumetric law (verification only; module docstring)."""
    if params.volumetric != "log":
        raise ParameterError("fung_orthotropic_stress: closed form implemented for the 'log' volumetric law")
    axes = _axes(a1, a2)
    E = _local(_isochoric_green_strain(F), axes)
    L = params.normal_block
    shear = _shear(params)
    D = [[ufl.as_ufl(0.0)] * 3 for _ in range(3)]  # dQ/dE_ab, E_ab and E_ba counted as independent
    for a in range(3):
        D[a][a] = 2.0 * sum((L[a][b] * E[b][b] for b in range(3)), ufl.as_ufl(0.0))
    for (a, b), coeff in shear.items():
        D[a][b] = D[b][a] = 2.0 * coeff * E[a][b]
    Q = fung_q(F, a1, a2, params)
    S_tilde = (
        0.5
        * params.c
        * ufl.exp(Q)
        * sum((D[a][b] * ufl.outer(axes[a], axes[b]) for a in range(3) for b in range(3)), ufl.zero(3, 3))
    )
    J = ufl.det(F)
    C = right_cauchy_green(F)
    S = J ** (-2.0 / 3.0) * (S_tilde - ufl.inner(S_tilde, C) / 3.0 * ufl.inv(C))
    return F * S + params.K * ufl.ln(J) * ufl.inv(F).T
