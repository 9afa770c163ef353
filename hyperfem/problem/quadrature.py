r"""Quadrature degrees of the terms of a problem, chosen in one place.

* :func:`volume_quadrature_degree` — the volume rule of a degree-:math:`k`
  Lagrange displacement. On simplices: one point for P1 (:math:`F` is
  constant per cell), :math:`2k` otherwise. On quadrilaterals and hexahedra
  (tensor-product cells) a quadrature degree counts per direction (basix's
  Gauss–Jacobi rule of degree :math:`m` has :math:`\lfloor m/2\rfloor + 1`
  points per direction) and :math:`F` of :math:`Q_k` is never constant, not
  even for :math:`Q_1` (and the Jacobian of a trilinear map is not either):
  the rule is :math:`2k`, the :math:`(k+1)^d` Gauss points of full
  integration. The one-point rule on :math:`Q_1` has hourglass modes — the
  tangent is singular and the bend cantilever "converges" to nonsense.
* :func:`load_quadrature_degree` — a load term is integrated exactly where it
  is polynomial: its degree comes from UFL's estimate of the integrand (after
  algebra lowering, so :math:`\det` and cofactors count as the polynomials
  they are), at least the volume rule and at most a cap for non-polynomial
  integrands. The volume rule alone is exact only for constant dead loads:
  on P1 the twist traction :math:`t(x)\cdot v` with :math:`x = X + u` is
  quadratic and a one-point rule lost 9 % of its torque on the h = 2 beam.
* :func:`unify_quadrature` — FFCx 0.11 assembles a form wrongly when
  integrals of one type that end up in one kernel use different quadrature
  rules and share a basis table (e.g. :math:`\int u\cdot w` at degree 2 plus
  :math:`\int u\cdot u` at degree 1 assembles to neither sum; the canary test
  ``tests/test_quadrature.py`` fails once FFCx is fixed). Every form handed
  to the form compiler goes through it, so all integrals of a type share the
  highest degree among them.
"""

from __future__ import annotations

from typing import overload

import ufl
from dolfinx import mesh as dmesh
from ufl.algorithms import estimate_total_polynomial_degree
from ufl.algorithms.apply_algebra_lowering import apply_algebra_lowering

from hyperfem.errors import ParameterError

__all__ = [
    "SIMPLEX_CELLS",
    "check_volume_quadrature",
    "is_simplex",
    "load_quadrature_degree",
    "unify_cell_quadrature",
    "unify_quadrature",
    "volume_quadrature_degree",
]

SIMPLEX_CELLS = (dmesh.CellType.interval, dmesh.CellType.triangle, dmesh.CellType.tetrahedron)
"""Cell types on which a quadrature degree is a total degree and P1 has a constant gradient."""


def is_simplex(cell_type: dmesh.CellType | None) -> bool:
    """Whether ``cell_type`` is an interval, triangle or tetrahedron (``None``: assumed a simplex)."""
    return cell_type is None or cell_type in SIMPLEX_CELLS


def volume_quadrature_degree(degree: int, cell_type: dmesh.CellType | None = None) -> int:
    """Quadrature degree of the volume rule for Lagrange displacement degree ``degree``.

    Args:
        degree: Lagrange degree :math:`k` of the displacement.
        cell_type: The mesh's cell type; ``None`` means a simplex.

    Returns:
        Simplices: 1 for P1 (one point), ``2 * degree`` otherwise.
        Quadrilaterals and hexahedra: ``2 * degree`` for every degree
        (:math:`(k+1)^d` Gauss points; see the module docstring).
    """
    if is_simplex(cell_type) and degree == 1:
        return 1
    return 2 * degree


def check_volume_quadrature(degree: int, quadrature_degree: int, cell_type: dmesh.CellType, where: str) -> None:
    """Refuse a reduced volume rule on quadrilaterals and hexahedra.

    A Gauss rule of fewer than :math:`k + 1` points per direction on
    :math:`Q_k` (quadrature degree below :math:`2k`) leaves hourglass modes:
    the tangent is singular and the answer arbitrary. Simplices are not
    checked.

    Raises:
        ParameterError: On a tensor-product cell with ``quadrature_degree < 2 * degree``.
    """
    if is_simplex(cell_type) or quadrature_degree >= 2 * degree:
        return
    points = quadrature_degree // 2 + 1
    raise ParameterError(
        f"{where}: quadrature_degree={quadrature_degree} on {cell_type.name} cells integrates Q{degree} with "
        f"{points} Gauss point(s) per direction, which leaves hourglass modes (singular tangent); "
        f"use quadrature_degree >= {2 * degree} (the default)"
    )


def load_quadrature_degree(integrand: ufl.core.expr.Expr, volume_degree: int, cap: int) -> int:
    """Quadrature degree for a load integrand.

    Args:
        integrand: The UFL integrand (e.g. :math:`t\\cdot v`).
        volume_degree: Degree of the volume rule (a lower bound).
        cap: Upper bound, reached only by non-polynomial integrands.

    Returns:
        ``max(volume_degree, min(estimate, cap))``.
    """
    estimate = estimate_total_polynomial_degree(apply_algebra_lowering(integrand))
    return int(max(volume_degree, min(estimate, max(cap, volume_degree))))


def unify_quadrature(*forms: ufl.Form | None) -> tuple[ufl.Form | None, ...]:
    """Give all integrals of each integral type, across ``forms``, the highest degree among them.

    The forms are treated together because they are summed or differentiated
    into one form later (energy, residual, tangent must agree). Integrals
    without an explicit ``quadrature_degree`` are left alone; ``None`` passes
    through.

    Returns:
        The forms, in order.
    """
    highest: dict[str, int] = {}
    for form in forms:
        for itg in () if form is None else form.integrals():
            q = itg.metadata().get("quadrature_degree")
            if q is not None:
                t = itg.integral_type()
                highest[t] = max(highest.get(t, q), q)

    def rebuild(form: ufl.Form | None) -> ufl.Form | None:
        if form is None:
            return None
        out = []
        for itg in form.integrals():
            md = itg.metadata()
            q = md.get("quadrature_degree")
            if q is not None and q != highest[itg.integral_type()]:
                itg = itg.reconstruct(metadata={**md, "quadrature_degree": highest[itg.integral_type()]})
            out.append(itg)
        return ufl.Form(out)

    return tuple(rebuild(f) for f in forms)


@overload
def unify_cell_quadrature(form: ufl.Form, metadata: dict) -> ufl.Form: ...
@overload
def unify_cell_quadrature(form: None, metadata: dict) -> None: ...
def unify_cell_quadrature(form: ufl.Form | None, metadata: dict) -> ufl.Form | None:
    """Put every cell integral of ``form`` on the rule ``metadata`` (e.g. the mass rule of dynamics).

    Used where one rule must win regardless of degree (the vertex rule of a
    lumped mass); other integral types are left alone.
    """
    if form is None:
        return None
    return ufl.Form(
        [i.reconstruct(metadata=dict(metadata)) if i.integral_type() == "cell" else i for i in form.integrals()]
    )
