"""Generic checks of user input: finite numbers and vectors, positive values, counts, names, callables.

Every check raises :class:`~hyperfem.errors.ParameterError` with a one-line
message naming the object (``where``) and the offending entry, before any form
is compiled or assembled. The checks are deterministic functions of their
arguments, so every MPI rank raises the same error.

This module sits at the bottom of the package (it imports nothing of hyperfem
but :mod:`hyperfem.errors`). The checks of one concept stay with that concept:
a material's parameters in :mod:`hyperfem.materials`, the energy of a problem
and the coverage of its regions in :mod:`hyperfem.problem.energy`, the key
types of a case file in :mod:`hyperfem.app.schema`.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable
from typing import cast

from hyperfem.errors import ParameterError

__all__ = [
    "check_callable",
    "check_count",
    "check_finite_scalar",
    "check_finite_vector",
    "check_name",
    "check_nonnegative",
    "check_positive",
    "is_finite_number",
    "is_real",
]

_AXES = "xyz"


def is_real(value: object) -> bool:
    """Whether ``value`` is a real number (Python or NumPy; ``bool`` is not a number here), finite or not."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_finite_number(value: object) -> bool:
    """Whether ``value`` is a finite real number (Python or NumPy; ``bool`` is not a number here)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(float(value))


def check_positive(name: str, value: float, where: str) -> None:
    """Raise :class:`ParameterError` unless ``value`` is a finite number > 0 (rejects nan and inf)."""
    if not (is_finite_number(value) and value > 0):
        raise ParameterError(f"{where}: {name} must be a finite number > 0, got {value!r}")


def check_nonnegative(name: str, value: float, where: str) -> None:
    """Raise :class:`ParameterError` unless ``value`` is a finite number >= 0 (rejects nan and inf)."""
    if not (is_finite_number(value) and value >= 0):
        raise ParameterError(f"{where}: {name} must be a finite number >= 0, got {value!r}")


def check_count(name: str, value: object, where: str) -> None:
    """Raise :class:`ParameterError` unless ``value`` is an integer >= 1 (Python or NumPy; not ``bool``)."""
    if not (isinstance(value, numbers.Integral) and not isinstance(value, bool) and int(value) >= 1):
        raise ParameterError(f"{where}: {name} must be an integer >= 1, got {value!r}")


def check_finite_scalar(value: object, where: str, what: str = "value") -> float:
    """Return ``float(value)``; raise unless it is a finite real number."""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        raise ParameterError(f"{where}: {what} must be a finite number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise ParameterError(f"{where}: {what} must be a finite number, got {number!r}")
    return number


def check_finite_vector(value: object, where: str, what: str = "value") -> tuple[float, ...]:
    """Return the components of ``value`` as floats; raise unless each is a finite real number."""
    if isinstance(value, (str, bytes)) or is_real(value):
        raise ParameterError(f"{where}: {what} must be a sequence of numbers or a callable, got {value!r}")
    try:
        items = list(cast(Iterable[object], value))  # list() raises TypeError on a non-iterable
    except TypeError:
        raise ParameterError(
            f"{where}: {what} must be a sequence of numbers or a callable, got {type(value).__name__}"
        ) from None
    if not items:
        raise ParameterError(f"{where}: {what} is empty")
    out = []
    for i, v in enumerate(items):
        label = f"component {i} ({_AXES[i]})" if i < len(_AXES) else f"component {i}"
        if not is_finite_number(v):
            raise ParameterError(f"{where}: {what} {label} must be a finite number, got {v!r}")
        out.append(float(cast(float, v)))
    return tuple(out)


def check_name(name: object, what: str, where: str, optional: bool = False) -> None:
    """A physical-group name must be a non-empty string (or ``None`` if ``optional``)."""
    if optional and name is None:
        return
    if not (isinstance(name, str) and name):
        kind = "a physical-group name (str) or None" if optional else "a physical-group name (non-empty str)"
        raise ParameterError(f"{where}: {what} must be {kind}, got {name!r}")


def check_callable(value: object, where: str, what: str) -> None:
    """``value`` must be callable."""
    if not callable(value):
        raise ParameterError(f"{where}: {what} must be callable, got {value!r}")
