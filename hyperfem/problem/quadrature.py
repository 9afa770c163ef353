r"""Quadrature degrees of the terms of a problem, chosen in one place.

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

import ufl
from ufl.algorithms import estimate_total_polynomial_degree
from ufl.algorithms.apply_algebra_lowering import apply_algebra_lowering

__all__ = ["load_quadrature_degree", "unify_cell_quadrature", "unify_quadrature"]


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

    def rebuild(form):
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
