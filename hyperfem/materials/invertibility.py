r"""Which energies are *invertible*: finite, and restoring, for :math:`J = \det F \le 0`.

An invertible energy (seed 004: "allowing :math:`\det F \le 0`"; seed 000's
inversion-robust Neo-Hookean) has finite energy and stress for inverted
elements and drives them back, so Newton may pass through inverted states
and no inversion guard (line-search filtering) is needed. A logarithmic
barrier (Neo-Hookean, Mooney–Rivlin, the muscle law with :math:`J^{-2/3}`)
is not: it is undefined for :math:`J \le 0`.

Decision for Saint Venant–Kirchhoff: *not* invertible. Its energy is finite
for :math:`J \le 0`, but it depends on :math:`F^TF` only, so every
reflection (e.g. :math:`F = \operatorname{diag}(-1, 1, 1)`) is a stress-free
state: it cannot tell an inverted element from a sound one and does not
push it back, so the guard has to stay.

Invertible here: robust Neo-Hookean, stable Neo-Hookean, fixed-corotated,
ARAP, linear elasticity and corotational linear elasticity.

A problem infers its ``invertible`` flag from its energies
(:func:`is_invertible` of every region's ``psi``); mark your own energy
callables with :func:`invertible`, or bind a law and its parameters with
:func:`with_parameters`, which keeps the law's flag.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import ufl

__all__ = ["KNOWN_INVERTIBLE_LAWS", "invertible", "is_invertible", "with_parameters"]

Fn = TypeVar("Fn", bound=Callable)

KNOWN_INVERTIBLE_LAWS = frozenset(
    {
        "hyperfem.materials.robust_neo_hookean.robust_neo_hookean",
        "hyperfem.materials.linear_elastic.linear_elastic",
    }
)
"""Laws ``law(F, params)`` of other modules known to be invertible (by qualified name)."""


def invertible(psi: Fn, value: bool = True) -> Fn:
    """Mark an energy ``psi(F)`` (or a law ``law(F, params)``) as invertible; returns it.

    Usable as a decorator or on a lambda:
    ``invertible(lambda F: robust_neo_hookean(F, params))``.

    Args:
        psi: The callable (it must accept attributes: a function, lambda or object).
        value: The flag (``False`` marks it explicitly not invertible).
    """
    cast(Any, psi).invertible = bool(value)  # functions and lambdas accept attributes
    return psi


def is_invertible(psi: Callable) -> bool:
    """Whether ``psi`` is marked invertible (its ``invertible`` attribute, or a known law)."""
    # Boundary: psi is a user-supplied callable (function, lambda or object), marked or not.
    flag = getattr(psi, "invertible", None)
    if flag is not None:
        return bool(flag)
    name = f"{getattr(psi, '__module__', '')}.{getattr(psi, '__qualname__', '')}"
    return name in KNOWN_INVERTIBLE_LAWS


class _BoundLaw:
    """``psi(F) = law(F, params)`` carrying the law's ``invertible`` flag."""

    def __init__(self, law: Callable, params: object) -> None:
        self.law = law
        self.params = params
        self.invertible = is_invertible(law)

    def __call__(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        return self.law(F, self.params)

    def __repr__(self) -> str:
        return f"with_parameters({getattr(self.law, '__name__', self.law)!r}, {self.params!r})"  # any callable


def with_parameters(law: Callable, params: object) -> Callable[[ufl.core.expr.Expr], ufl.core.expr.Expr]:
    """The energy ``psi(F) = law(F, params)``, invertible exactly when ``law`` is.

    Example: ``HyperelasticProblem(domain, with_parameters(robust_neo_hookean, params))``
    is an invertible problem; the same law behind a plain lambda is not
    (the problem cannot see through it).
    """
    return _BoundLaw(law, params)
