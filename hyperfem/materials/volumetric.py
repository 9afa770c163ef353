r"""Volumetric (bulk) energies :math:`U(J)` for nearly incompressible solids.

Each law is penalised by the bulk modulus :math:`K` and satisfies
:math:`U(1) = U'(1) = 0`, :math:`U''(1) = K`:

* ``"log"`` (default, seed 000's :math:`p = K \ln J`):
  :math:`U = \frac{K}{2} (\ln J)^2`,
* ``"quadratic"``: :math:`U = \frac{K}{2} (J - 1)^2`,
* ``"simo_taylor"``: :math:`U = \frac{K}{4} (J^2 - 1 - 2 \ln J)`.

The pure displacement formulation evaluates :math:`U(\det F)`; the mixed
three-field formulation (:class:`~hyperfem.problem.MixedHyperelasticProblem`)
evaluates :math:`U(\theta)` on a volume field :math:`\theta` that is the
:math:`L^2` projection of :math:`J`, so every law can be used with either.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import ufl

from hyperfem.errors import ParameterError

__all__ = ["VOLUMETRIC_LAWS", "VolumetricLaw", "volumetric_energy", "volumetric_law"]

Expr = ufl.core.expr.Expr


@dataclass(frozen=True)
class VolumetricLaw:
    """A volumetric energy :math:`U(J; K)`.

    Attributes:
        name: Key in :data:`VOLUMETRIC_LAWS`.
        energy: ``energy(J, K) -> U`` (a UFL expression).
    """

    name: str
    energy: Callable[[Expr, Expr | float], Expr]


VOLUMETRIC_LAWS: dict[str, VolumetricLaw] = {
    "log": VolumetricLaw("log", lambda J, K: 0.5 * K * ufl.ln(J) ** 2),
    "quadratic": VolumetricLaw("quadratic", lambda J, K: 0.5 * K * (J - 1.0) ** 2),
    "simo_taylor": VolumetricLaw("simo_taylor", lambda J, K: 0.25 * K * (J**2 - 1.0 - 2.0 * ufl.ln(J))),
}
"""Available volumetric laws by name."""


def volumetric_law(name: str) -> VolumetricLaw:
    """Look up a volumetric law by name.

    Raises:
        ParameterError: For an unknown name.
    """
    if name not in VOLUMETRIC_LAWS:
        raise ParameterError(f"unknown volumetric law {name!r} (available: {', '.join(sorted(VOLUMETRIC_LAWS))})")
    return VOLUMETRIC_LAWS[name]


def volumetric_energy(J: Expr, K: Expr | float, law: str = "log") -> Expr:
    r"""Volumetric energy :math:`U(J)` of the named law (default :math:`\frac{K}{2}(\ln J)^2`).

    Args:
        J: Volume ratio :math:`\det F` (or the volume field :math:`\theta` of the mixed formulation).
        K: Bulk modulus.
        law: Name of the law, see :data:`VOLUMETRIC_LAWS`.
    """
    return volumetric_law(law).energy(J, K)
