r"""Volumetric (bulk) energies :math:`U(J)` for nearly incompressible solids.

Each law is penalised by the bulk modulus :math:`K` and satisfies
:math:`U(1) = U'(1) = 0`, :math:`U''(1) = K`:

* ``"log"`` (default, seed 000's :math:`p = K \ln J`):
  :math:`U = \frac{K}{2} (\ln J)^2`,
* ``"quadratic"``: :math:`U = \frac{K}{2} (J - 1)^2`,
* ``"simo_taylor"``: :math:`U = \frac{K}{4} (J^2 - 1 - 2 \ln J)`.

The first two have the form :math:`U = \frac{K}{2} g(J)^2`, which the mixed
displacement–pressure formulation uses as
:math:`\Pi(u, p) = \int \psi_\text{iso} + p\, g(J) - p^2/(2K)`; eliminating
:math:`p = K g(J)` gives back :math:`U(J)`.
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
        energy: ``energy(J, K) -> U``.
        pressure_measure: :math:`g(J)` with :math:`U = \\tfrac{K}{2} g^2`, or
            ``None`` if the law is not of that form (then it cannot be used
            by the mixed formulation).
    """

    name: str
    energy: Callable[[Expr, Expr | float], Expr]
    pressure_measure: Callable[[Expr], Expr] | None = None


VOLUMETRIC_LAWS: dict[str, VolumetricLaw] = {
    "log": VolumetricLaw("log", lambda J, K: 0.5 * K * ufl.ln(J) ** 2, ufl.ln),
    "quadratic": VolumetricLaw("quadratic", lambda J, K: 0.5 * K * (J - 1.0) ** 2, lambda J: J - 1.0),
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
        J: Volume ratio :math:`\det F`.
        K: Bulk modulus.
        law: Name of the law, see :data:`VOLUMETRIC_LAWS`.
    """
    return volumetric_law(law).energy(J, K)
