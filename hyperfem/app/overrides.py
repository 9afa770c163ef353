"""``--set key=value``: changes to the raw TOML data of a case before it is checked."""

from __future__ import annotations

import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hyperfem.app.schema import CaseFileError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["apply_overrides"]

_TOKEN = re.compile(r"(?P<name>[A-Za-z_][A-Za-z0-9_-]*)(?P<index>(\[\d+\])*)$")


def _parse_path(text: str) -> list[str | int]:
    parts: list[str | int] = []
    for piece in text.split("."):
        if piece.isdigit():
            parts.append(int(piece))
            continue
        m = _TOKEN.match(piece)
        if not m:
            raise ValueError(piece)
        parts.append(m["name"])
        parts.extend(int(i) for i in re.findall(r"\[(\d+)\]", m["index"]))
    return parts


def _parse_value(text: str, source: str | Path | None) -> object:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        if text.strip()[:1] in "[{\"'":
            raise CaseFileError(f"--set: cannot parse the value {text!r} as TOML", source) from None
        return text  # a bare word: a string


def apply_overrides(data: dict, overrides: Sequence[str], source: str | Path | None = None) -> dict:
    """Set ``key=value`` entries in the raw TOML data (before it is checked).

    The key is a path such as ``stepping.dt``, ``material[0].E`` (or
    ``material.0.E``) or ``solver.petsc_options.ksp_type``; the value is a
    TOML value (``2e6``, ``true``, ``[0, 1, 0]``, ``"text"``), or else a bare
    string (``--set mesh.file=beam.msh``). Missing tables are created.

    Raises:
        CaseFileError: A malformed override, or an index past the end of an array.
    """
    for item in overrides:
        if "=" not in item:
            raise CaseFileError(f"--set {item!r}: expected key=value", source)
        key, text = (s.strip() for s in item.split("=", 1))
        try:
            parts = _parse_path(key)
        except ValueError:
            raise CaseFileError(
                f"--set {item!r}: malformed key {key!r} (use e.g. stepping.dt or material[0].E)", source
            ) from None
        if not parts or not isinstance(parts[0], str):
            raise CaseFileError(f"--set {item!r}: the key must start with a name", source)
        value = _parse_value(text, source)
        node: Any = data
        for i, part in enumerate(parts):
            last = i == len(parts) - 1
            here = ".".join(str(p) for p in parts[: i + 1])
            if isinstance(part, int):
                if not isinstance(node, list) or part >= len(node):
                    size = len(node) if isinstance(node, list) else 0
                    raise CaseFileError(f"--set {item!r}: {here}: there are {size} entries", source)
            elif not isinstance(node, dict):
                raise CaseFileError(f"--set {item!r}: {here}: the parent is not a table", source)
            if last:
                node[part] = value
            else:
                nxt = node[part] if (isinstance(part, int) or part in node) else None
                if nxt is None:
                    nxt = {} if not isinstance(parts[i + 1], int) else []
                    node[part] = nxt
                node = nxt
    return data
