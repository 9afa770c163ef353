"""Checking nested TOML tables against declared keys, with the key path in every message.

A table's keys are declared as :class:`Key` entries (kind, required, range,
choices); :func:`check_table` returns the values that were given (numbers as
``float``, arrays as tuples) and raises :class:`CaseFileError` for

* an unknown key, with a did-you-mean (:func:`suggestion`, :mod:`difflib`) and the
  keys that are allowed there;
* a value of the wrong type (``expected a number, got a string ('1e6')``);
* a missing required key;
* a number outside its range or a string outside its choices.

Every message starts with the key path, e.g. ``material[1].nu``, so that the
user can find the entry; the case file's name is added by :class:`CaseFileError`.
The checks are pure functions of the table: every MPI rank raises the same error.
"""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hyperfem.errors import ParameterError

__all__ = ["KINDS", "CaseFileError", "Key", "check_table", "check_value", "describe", "join", "suggestion"]

KINDS = ("string", "number", "integer", "boolean", "vector", "numbers", "matrix", "table", "tables", "strings", "any")
"""Kinds of :class:`Key` values: ``vector`` is a list of numbers of a given length, ``numbers`` of any
length, ``matrix`` a list of vectors, ``tables`` an array of tables, ``strings`` a list of strings."""


class CaseFileError(ParameterError):
    """A case file (or a ``--set`` override) is invalid: syntax, unknown key, type, range, reference.

    Args:
        message: What is wrong, starting with the key path (``"material[0].nu: ..."``).
        source: The case file, prefixed to the message when given.

    Attributes:
        source: The case file (or ``None``).
        message: The message without the file name.
    """

    def __init__(self, message: str, source: str | Path | None = None):
        self.message = message
        self.source = None if source is None else str(source)
        super().__init__(message if source is None else f"{source}: {message}")

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True)
class Key:
    """Declaration of one key of a table: its check, and its documentation.

    The declarations are the one source of the case-file schema: :func:`check_value`
    checks against the first group of attributes; ``hyperfem schema`` (the commented
    reference) and ``hyperfem schema --json`` (a JSON Schema) are generated from all of
    them by :mod:`hyperfem.app.reference`.

    Attributes:
        kind: One of :data:`KINDS`.
        required: The key must be given.
        choices: Allowed strings (``kind="string"``).
        above: Numbers must be ``> above``.
        minimum: Numbers must be ``>= minimum``.
        below: Numbers must be ``< below``.
        length: Number of entries of a ``vector`` (or of each row of a ``matrix``).
        help: One line for the documentation: what it is, its unit, the class or keyword it feeds.
        hint: Added to the message of a missing required key (``missing required key 'mesh' (HINT)``).
        maximum: Numbers must be ``<= maximum``: checked by the section's function (its message
            names the interval), declared here for the documentation.
        pattern: A regular expression the whole string must match: checked by the section's
            function, declared here for the documentation.
        default: The value the run uses when the key is absent (documentation only: an absent
            key stays absent; ``None``: no fixed default, the help says what happens).
        example: A value shown in the reference (default: ``default``).
        shape: What the value may be, a name of :data:`hyperfem.app.reference.SHAPES`
            (``"profile"``, ``"reactions"``, ...): needed by ``kind="any"``, and by a
            ``table`` whose keys are not declared (``petsc_options``).
    """

    kind: str
    required: bool = False
    choices: tuple[str, ...] = ()
    above: float | None = None
    minimum: float | None = None
    below: float | None = None
    length: int | None = None
    help: str = ""
    hint: str = ""
    maximum: float | None = None
    pattern: str | None = None
    default: object = None
    example: object = None
    shape: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"Key: unknown kind {self.kind!r}")
        if self.kind == "any" and not self.shape:
            raise ValueError("Key: a key of kind 'any' needs a shape (what its value may be)")


def join(where: str, key: str | int) -> str:
    """The key path of ``key`` inside ``where`` (``"bc[0]"``, ``"mesh.file"``)."""
    if isinstance(key, int):
        return f"{where}[{key}]"
    return f"{where}.{key}" if where else key


def suggestion(name: str, candidates: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest candidate, or ``""``."""
    close = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    if not close and name.lower() != name:
        close = difflib.get_close_matches(name.lower(), list(candidates), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def describe(value: object) -> str:
    """A short phrase for the type and value of a TOML value, for messages."""
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if isinstance(value, numbers.Integral):
        return f"an integer ({value})"
    if isinstance(value, numbers.Real):
        return f"a number ({value!r})"
    if isinstance(value, str):
        return f"a string ({value!r})"
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, (list, tuple)):
        return f"an array of {len(value)}"
    return type(value).__name__


def _is_number(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _number(value: object, key: Key, where: str) -> float:
    if not _is_number(value):
        raise CaseFileError(f"{where}: expected a number, got {describe(value)}")
    x = float(value)  # type: ignore[arg-type]  # a numbers.Real (checked above)
    if not math.isfinite(x):
        raise CaseFileError(f"{where}: must be a finite number, got {value!r}")
    if key.above is not None and not x > key.above:
        raise CaseFileError(f"{where}: must be > {key.above:g}, got {value!r}")
    if key.minimum is not None and not x >= key.minimum:
        raise CaseFileError(f"{where}: must be >= {key.minimum:g}, got {value!r}")
    if key.below is not None and not x < key.below:
        raise CaseFileError(f"{where}: must be < {key.below:g}, got {value!r}")
    return x


def _vector(value: object, key: Key, where: str, length: int | None) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple)):
        raise CaseFileError(f"{where}: expected an array of numbers, got {describe(value)}")
    if length is not None and len(value) != length:
        raise CaseFileError(f"{where}: expected {length} numbers, got {len(value)}")
    if not value:
        raise CaseFileError(f"{where}: expected at least one number, got an empty array")
    plain = Key("number", above=key.above, minimum=key.minimum, below=key.below)
    return tuple(_number(v, plain, f"{where}[{i}]") for i, v in enumerate(value))


def check_value(value: object, key: Key, where: str) -> Any:
    """Check one value against its declaration; returns it converted (floats, tuples).

    Raises:
        CaseFileError: Wrong type, out of range, not among the choices.
    """
    kind = key.kind
    if kind == "any":
        return value
    if kind == "string":
        if not isinstance(value, str):
            raise CaseFileError(f"{where}: expected a string, got {describe(value)}")
        if key.choices and value not in key.choices:
            raise CaseFileError(
                f"{where}: unknown value {value!r}{suggestion(value, key.choices)}; "
                f"choose from {', '.join(key.choices)}"
            )
        if not value:
            raise CaseFileError(f"{where}: must not be empty")
        return value
    if kind == "number":
        return _number(value, key, where)
    if kind == "integer":
        if not isinstance(value, numbers.Integral) or isinstance(value, bool):
            raise CaseFileError(f"{where}: expected an integer, got {describe(value)}")
        return int(_number(value, key, where))
    if kind == "boolean":
        if not isinstance(value, bool):
            raise CaseFileError(f"{where}: expected true or false, got {describe(value)}")
        return value
    if kind in ("vector", "numbers"):
        return _vector(value, key, where, key.length if kind == "vector" else None)
    if kind == "matrix":
        if not isinstance(value, (list, tuple)) or not value:
            raise CaseFileError(f"{where}: expected an array of arrays of numbers, got {describe(value)}")
        return tuple(_vector(row, key, f"{where}[{i}]", key.length) for i, row in enumerate(value))
    if kind == "strings":
        if not isinstance(value, (list, tuple)):
            raise CaseFileError(f"{where}: expected an array of strings, got {describe(value)}")
        plain = Key("string", choices=key.choices)
        return tuple(check_value(v, plain, f"{where}[{i}]") for i, v in enumerate(value))
    if kind == "table":
        if not isinstance(value, Mapping):
            raise CaseFileError(f"{where}: expected a table, got {describe(value)}")
        return dict(value)
    if kind == "tables":
        if isinstance(value, Mapping):
            value = [value]  # [x] written instead of [[x]]: one entry
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, Mapping) for v in value):
            raise CaseFileError(f"{where}: expected an array of tables ([[...]]), got {describe(value)}")
        return [dict(v) for v in value]
    raise AssertionError(kind)  # pragma: no cover - Key checks the kind


def check_table(
    table: Mapping[str, object], keys: Mapping[str, Key], where: str, *, what: str | None = None
) -> dict[str, Any]:
    """Check a table: no unknown keys, every required key present, every value valid.

    Args:
        table: The TOML table.
        keys: Its declared keys.
        where: Key path of the table (``""`` for the top level).
        what: How to name the allowed keys in the unknown-key message (default: ``where``).

    Returns:
        The given keys with their checked values (absent optional keys are absent).

    Raises:
        CaseFileError: The first problem found (unknown keys first, in file order).
    """
    if not isinstance(table, Mapping):
        raise CaseFileError(f"{where or 'case'}: expected a table, got {describe(table)}")
    for name in table:
        if name not in keys:
            allowed = ", ".join(keys)
            raise CaseFileError(
                f"{join(where, name)}: unknown key{suggestion(name, keys)}; "
                f"keys of {what or where or 'the case'}: {allowed}"
            )
    for name, key in keys.items():
        if key.required and name not in table:
            hint = f" ({key.hint})" if key.hint else ""
            raise CaseFileError(f"{where or 'case'}: missing required key {name!r}{hint}")
    return {name: check_value(value, keys[name], join(where, name)) for name, value in table.items()}
