r"""Small callables that case files need and the library does not define.

* :class:`Table` — a piecewise-linear time profile through given points, held
  at its end values;
* :class:`Scaled` — a profile times a constant (the angle :math:`\theta(t) =
  \theta_1 f(t)` of a rotating surface);
* :class:`AffineField` — the vector field :math:`A x + b` as a UFL vector (a
  traction that varies over the surface, e.g. the twist traction
  :math:`5\,(0, z, -y)` kPa of seed 003).

They are what ``hyperfem run --print-python`` writes for those entries, so a
script can use them as well.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import ufl

from hyperfem.errors import ParameterError
from hyperfem.materials.parameters import is_finite_number

__all__ = ["AffineField", "Scaled", "Table"]


@dataclass(frozen=True)
class Table:
    r"""Piecewise-linear profile :math:`f(t)` through ``(times[k], values[k])``, constant outside.

    Attributes:
        times: Strictly increasing times.
        values: Profile values at those times.
    """

    times: Sequence[float]
    values: Sequence[float]

    def __post_init__(self) -> None:
        t, v = list(self.times), list(self.values)
        if len(t) < 2 or len(t) != len(v):
            raise ParameterError(f"Table: need as many times as values (at least 2), got {len(t)} and {len(v)}")
        if not all(is_finite_number(x) for x in (*t, *v)):
            raise ParameterError("Table: times and values must be finite numbers")
        if any(b <= a for a, b in zip(t, t[1:])):
            raise ParameterError(f"Table: times must increase strictly, got {t}")
        object.__setattr__(self, "times", tuple(float(x) for x in t))
        object.__setattr__(self, "values", tuple(float(x) for x in v))

    def __call__(self, t: float) -> float:
        return float(np.interp(float(t), self.times, self.values))

    @property
    def kinks(self) -> tuple[float, ...]:
        """Times where the profile is not smooth (every table time)."""
        return self.times


@dataclass(frozen=True)
class Scaled:
    """``factor * profile(t)``.

    Attributes:
        profile: A profile ``f(t)``.
        factor: The constant.
    """

    profile: Callable[[float], float]
    factor: float

    def __post_init__(self) -> None:
        if not callable(self.profile):
            raise ParameterError(f"Scaled: profile must be callable, got {self.profile!r}")
        if not is_finite_number(self.factor):
            raise ParameterError(f"Scaled: factor must be a finite number, got {self.factor!r}")

    def __call__(self, t: float) -> float:
        return self.factor * float(self.profile(t))

    @property
    def kinks(self) -> tuple[float, ...]:
        """The kinks of the profile."""
        return tuple(getattr(self.profile, "kinks", ()))


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

    def __call__(self, x) -> ufl.core.expr.Expr:
        components = []
        for row, b in zip(self.matrix, self.offset):
            terms = [a * x[j] for j, a in enumerate(row) if a != 0.0]
            if b != 0.0 or not terms:
                terms.append(b)
            components.append(sum(terms[1:], terms[0]))
        return ufl.as_vector(components)
