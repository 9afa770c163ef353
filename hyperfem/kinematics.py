r"""Kinematic quantities of finite deformation as UFL helpers.

All functions take UFL expressions and return UFL expressions; they work in
two (plane strain) and three dimensions.

.. math::
    F = I + \nabla_X u,\quad C = F^T F,\quad E = \tfrac12 (C - I),\quad J = \det F.
"""

from __future__ import annotations

import ufl

__all__ = [
    "cofactor",
    "deformation_gradient",
    "green_lagrange",
    "invariants",
    "isochoric_invariants",
    "jacobian",
    "plane_strain_3d",
    "right_cauchy_green",
    "small_strain",
]


def deformation_gradient(u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r"""Deformation gradient :math:`F = I + \nabla_X u`.

    Args:
        u: Displacement field (vector valued).

    Returns:
        The deformation gradient as a UFL tensor.
    """
    d = len(u)
    return ufl.Identity(d) + ufl.grad(u)


def cofactor(F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r"""Cofactor :math:`\operatorname{cof} F = J F^{-T}`, written as the polynomial it is.

    In 3D its columns are :math:`F_{:,1}\times F_{:,2}`, :math:`F_{:,2}\times
    F_{:,0}`, :math:`F_{:,0}\times F_{:,1}`; in 2D it is
    :math:`\begin{pmatrix}F_{11} & -F_{10}\\ -F_{01} & F_{00}\end{pmatrix}`.
    Unlike ``det(F) * inv(F).T`` it has no division, so UFL estimates its
    polynomial degree exactly (quadrature of Nanson's formula).
    """
    d = F.ufl_shape[0]
    if d == 2:
        return ufl.as_matrix([[F[1, 1], -F[1, 0]], [-F[0, 1], F[0, 0]]])
    if d != 3:
        raise ValueError(f"cofactor: need a 2x2 or 3x3 tensor, got shape {F.ufl_shape}")
    cols = [ufl.cross(F[:, 1], F[:, 2]), ufl.cross(F[:, 2], F[:, 0]), ufl.cross(F[:, 0], F[:, 1])]
    return ufl.as_matrix([[cols[j][i] for j in range(3)] for i in range(3)])


def right_cauchy_green(F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r"""Right Cauchy–Green tensor :math:`C = F^T F`."""
    return F.T * F


def green_lagrange(F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r"""Green–Lagrange strain :math:`E = \tfrac12 (F^T F - I)`."""
    d = F.ufl_shape[0]
    return 0.5 * (F.T * F - ufl.Identity(d))


def small_strain(F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r"""Linearised strain :math:`\varepsilon = \operatorname{sym}(F) - I`."""
    d = F.ufl_shape[0]
    return ufl.sym(F) - ufl.Identity(d)


def jacobian(F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r"""Volume ratio :math:`J = \det F`."""
    return ufl.det(F)


def plane_strain_3d(F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    r"""Embed a 2×2 plane-strain deformation gradient in 3D (:math:`F_{33} = 1`).

    A 3×3 tensor is returned unchanged, so 3D-only laws (isochoric
    invariants, fibre models) can call this on any input.
    """
    if F.ufl_shape[0] == 3:
        return F
    return ufl.as_matrix(
        [[F[0, 0], F[0, 1], 0.0], [F[1, 0], F[1, 1], 0.0], [0.0, 0.0, 1.0]]
    )


def invariants(C: ufl.core.expr.Expr) -> tuple:
    r"""Principal invariants of a (3×3) tensor.

    .. math::
        I_1 = \operatorname{tr} C,\quad
        I_2 = \tfrac12\left[(\operatorname{tr} C)^2 - \operatorname{tr}(C^2)\right],\quad
        I_3 = \det C.

    Args:
        C: Right Cauchy–Green tensor (pass ``C`` of a 3D or plane-strain-embedded
            ``F`` for the 3D invariants).

    Returns:
        ``(I1, I2, I3)``.
    """
    I1 = ufl.tr(C)
    I2 = 0.5 * (I1**2 - ufl.tr(C * C))
    I3 = ufl.det(C)
    return I1, I2, I3


def isochoric_invariants(F: ufl.core.expr.Expr) -> tuple:
    r"""Isochoric invariants of the 3D deformation :math:`\bar F = J^{-1/3} F`.

    .. math::
        \bar I_1 = J^{-2/3} I_1,\qquad \bar I_2 = J^{-4/3} I_2.

    A 2×2 ``F`` is treated as plane strain (:math:`F_{33} = 1`).

    Returns:
        ``(Ibar1, Ibar2, J)``.
    """
    F3 = plane_strain_3d(F)
    J = ufl.det(F3)
    I1, I2, _ = invariants(right_cauchy_green(F3))
    return J ** (-2.0 / 3.0) * I1, J ** (-4.0 / 3.0) * I2, J
