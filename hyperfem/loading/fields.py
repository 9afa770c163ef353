r"""Vector fields of the reference coordinates for loads, as UFL expressions.

* :class:`AffineField` — the vector field :math:`A x + b` as a UFL vector (a
  traction that varies over the surface, e.g. the twist traction
  :math:`5\,(0, z, -y)` kPa of seed 003); what ``hyperfem run --print-python``
  writes for a load value given as ``{matrix, offset}``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import ufl

from hyperfem.errors import ParameterError
from hyperfem.validation import is_finite_number

__all__ = ["AffineField"]


@dataclass(frozen=True)
class AffineField:
    r"""The vector field :math:`f(x) = A x + b` as a UFL vector (terms with zero coefficients left out).

    Attributes:
        matrix: :math:`A`, one row per component.
        offset: :math:`b` (default zero).
    """

    matrix: Sequence[Sequence[float]]
    offset: Sequence[float] | None = None

    def __post_init__(self) -> None:
        A = [list(row) for row in self.matrix]
        n = len(A)
        if n == 0 or any(len(row) != len(A[0]) for row in A):
            raise ParameterError(f"AffineField: matrix must be a non-empty array of equal-length rows, got {A}")
        b = [0.0] * n if self.offset is None else list(self.offset)
        if len(b) != n:
            raise ParameterError(f"AffineField: offset has {len(b)} entries for a matrix of {n} rows")
        if not all(is_finite_number(x) for x in (*b, *(a for row in A for a in row))):
            raise ParameterError("AffineField: matrix and offset must be finite numbers")
        object.__setattr__(self, "matrix", tuple(tuple(float(a) for a in row) for row in A))
        object.__setattr__(self, "offset", tuple(float(x) for x in b))

    def __call__(self, x: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        components = []
        assert self.offset is not None  # __post_init__ fills in the zero offset
        for row, b in zip(self.matrix, self.offset, strict=True):
            terms = [a * x[j] for j, a in enumerate(row) if a != 0.0]
            if b != 0.0 or not terms:
                terms.append(b)
            components.append(sum(terms[1:], terms[0]))
        return ufl.as_vector(components)
