r"""Time profiles: how a load, a prescribed displacement or an angle follows the load factor or time.

Loads and :class:`~hyperfem.problem.PrescribedDisplacement` values are scaled
by ``profile(s)``, ``s`` the load factor of a quasi-static ramp or the time
:math:`t` of a dynamic run. A profile is any callable of ``s``; those here:

* :func:`linear_profile` — :math:`f(s) = s` (the default: the value ramps with the load);
* :class:`Steady` — :math:`f(t) = c` (on from :math:`t = 0`);
* :class:`Ramp` — linear from ``t0`` to ``t1``, held at its end values;
* :class:`Table` — piecewise linear through given points, held at its end values;
* :class:`Scaled` — a profile times a constant (the angle :math:`\theta(t) =
  \theta_1 f(t)` of a rotating surface).

``kinks`` (of :class:`Ramp`, :class:`Table`, :class:`Scaled`) are the times
where a profile is not smooth: natural must-hit times of a run. These are what
``hyperfem run --print-python`` writes for the profiles of a case file.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hyperfem.errors import ParameterError
from hyperfem.validation import is_finite_number

__all__ = ["Ramp", "Scaled", "Steady", "Table", "linear_profile"]


def linear_profile(s: float) -> float:
    """The identity profile: the value is scaled by the load factor ``s``."""
    return s


@dataclass(frozen=True)
class Steady:
    """The profile :math:`f(t) = c` (a load that is on from :math:`t = 0`)."""

    value: float = 1.0

    def __post_init__(self) -> None:
        if not is_finite_number(self.value):
            raise ParameterError(f"Steady: value must be a finite number, got {self.value!r}")

    def __call__(self, t: float) -> float:
        return float(self.value)


@dataclass(frozen=True)
class Ramp:
    r"""Linear ramp held at its end value.

    .. math::
        f(t) = f_0 + (f_1 - f_0)\,\min\bigl(\max((t - t_0)/(t_1 - t_0), 0), 1\bigr).

    Attributes:
        t1: Time at which the ramp ends (a natural must-hit time).
        final: Value from ``t1`` on.
        initial: Value up to ``t0``.
        t0: Time at which the ramp starts.
    """

    t1: float
    final: float = 1.0
    initial: float = 0.0
    t0: float = 0.0

    def __post_init__(self) -> None:
        for name in ("t1", "final", "initial", "t0"):
            value = getattr(self, name)
            if not is_finite_number(value):
                raise ParameterError(f"Ramp: {name} must be a finite number, got {value!r}")
        if not self.t1 > self.t0:
            raise ParameterError(f"Ramp: need t1 > t0, got t0={self.t0!r}, t1={self.t1!r}")

    def __call__(self, t: float) -> float:
        xi = min(max((float(t) - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        return self.initial + (self.final - self.initial) * xi

    @property
    def kinks(self) -> tuple[float, float]:
        """Times where the profile is not smooth (``t0``, ``t1``)."""
        return (self.t0, self.t1)


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
        if any(b <= a for a, b in itertools.pairwise(t)):
            raise ParameterError(f"Table: times must increase strictly, got {t}")
        object.__setattr__(self, "times", tuple(float(x) for x in t))
        object.__setattr__(self, "values", tuple(float(x) for x in v))

    def __call__(self, t: float) -> float:
        return float(np.interp(float(t), self.times, self.values))

    @property
    def kinks(self) -> tuple[float, ...]:
        """Times where the profile is not smooth (every table time)."""
        return tuple(self.times)


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
