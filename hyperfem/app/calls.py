"""A plan of calls: the objects of a run as data that is called directly, and printed as Python.

A case file becomes a list of :class:`~hyperfem.app.plan.Statement`, each one
value made of these nodes:

* :class:`Call` — ``function(*args, **kwargs)``, where ``function`` is the library
  object itself (``Call(Clamp, ("clamped",))``), never its name in a string;
* :class:`Ref` — a variable assigned by an earlier statement (``domain``, ``params``)
  or the communicator ``comm``;
* :class:`Attr` — an attribute of a value (``params.mu``, ``domain.mesh``);
* :class:`Join` — a path under a folder variable (``out / 'bend.csv'``);
* :class:`Energy` — the energy ``lambda F: law(F, *args)`` of a law bound to its arguments.

:func:`evaluate` turns a node into its value by calling the functions
(``hyperfem run``); :func:`source` writes the same node as Python source
(``hyperfem run --print-python``), naming each function by the public path it
is exported under (:func:`public_name`), and :func:`imports` lists the import
lines those names need. So what is printed is what runs, and "go to
definition" on a plan builder lands on the constructor a case-file key feeds.
"""

from __future__ import annotations

import importlib
import inspect
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

__all__ = ["Attr", "Call", "Energy", "Join", "Ref", "evaluate", "imports", "public_name", "source"]

LINE = 100
"""Calls longer than this are broken over lines in the printed script."""


@dataclass(frozen=True)
class Ref:
    """A variable of the plan (assigned by an earlier statement), or ``comm``."""

    name: str


@dataclass(frozen=True)
class Attr:
    """The attribute ``name`` of a value (``params.mu``)."""

    value: object
    name: str


@dataclass(frozen=True)
class Join:
    """The path ``folder / name`` under a folder variable (``out / 'bend.csv'``)."""

    folder: Ref
    name: str


@dataclass(frozen=True)
class Call:
    """``function(*args, **kwargs)``; ``function`` is a library callable or a node (a bound method)."""

    function: object
    args: tuple = ()
    kwargs: Mapping[str, object] = field(default_factory=lambda: MappingProxyType({}))

    @staticmethod
    def of(function: object, *args: object, **kwargs: object) -> Call:
        """``Call(function, args, kwargs)`` written as the call it stands for."""
        return Call(function, tuple(args), MappingProxyType(dict(kwargs)))


@dataclass(frozen=True)
class Energy:
    """The energy ``lambda F: law(F, *args)``: ``law`` bound to arguments after the deformation gradient."""

    law: Callable
    args: tuple = ()


# -- evaluation -----------------------------------------------------------------------------------------
def evaluate(node: object, variables: Mapping[str, object]) -> object:
    """The value of ``node``: calls made, references looked up in ``variables``, containers evaluated.

    Raises:
        KeyError: A :class:`Ref` to a variable not (yet) assigned — a defect of the plan.
    """
    if isinstance(node, Ref):
        return variables[node.name]
    if isinstance(node, Call):
        function: Any = node.function if _is_named(node.function) else evaluate(node.function, variables)
        args = [evaluate(a, variables) for a in node.args]
        kwargs = {k: evaluate(v, variables) for k, v in node.kwargs.items()}
        return function(*args, **kwargs)
    if isinstance(node, Attr):
        return getattr(evaluate(node.value, variables), node.name)
    if isinstance(node, Join):
        folder = evaluate(node.folder, variables)
        assert isinstance(folder, Path)
        return folder / node.name
    if isinstance(node, Energy):
        law, bound = node.law, tuple(evaluate(a, variables) for a in node.args)
        return lambda F: law(F, *bound)
    if isinstance(node, tuple):
        return tuple(evaluate(v, variables) for v in node)
    if isinstance(node, list):
        return [evaluate(v, variables) for v in node]
    if isinstance(node, Mapping):
        return {k: evaluate(v, variables) for k, v in node.items()}
    return node


# -- source -------------------------------------------------------------------------------------------------
_PREFIXED = (("hyperfem", "hf"), ("hyperfem.materials", "hf.materials"), ("hyperfem.mesh", "hf.mesh"),
             ("hyperfem.dynamics", "dyn"))
"""Namespaces printed with a prefix (``hf.Clamp``, ``dyn.Newmark``)."""

_IMPORTED = ("hyperfem.loading", "hyperfem.simulation", "hyperfem.problem", "hyperfem.fibres", "hyperfem.io",
             "hyperfem.kinematics")
"""Packages whose names are imported (``from hyperfem.loading import Ramp``)."""

_PREFIX_IMPORTS = {"hf": "import hyperfem as hf", "dyn": "from hyperfem import dynamics as dyn"}


def _is_named(value: object) -> bool:
    """Whether ``value`` is printed by its name: a function, class or method of a module."""
    return (inspect.isroutine(value) or inspect.isclass(value)) and hasattr(value, "__qualname__")


def _owner(value: Any) -> tuple[object, str]:
    """The module-level object ``value`` belongs to (itself, or the class of a method) and its dotted tail."""
    head, _, tail = value.__qualname__.partition(".")
    module = sys.modules[value.__module__]
    return getattr(module, head), tail


def public_name(value: Any) -> tuple[str, str]:
    """``(source, import line)`` of a library function or class: the public path it is exported under.

    ``hyperfem.problem.boundary_conditions.Clamp`` is ``("hf.Clamp", "import hyperfem as hf")``;
    ``hyperfem.loading.profiles.Ramp`` is ``("Ramp", "from hyperfem.loading import Ramp")``. Searched in
    order: the package ``hyperfem``, the object's own package (``hyperfem.loading``), the other public
    packages, its own module.

    Raises:
        TypeError: ``value`` is not a named function, class or method.
    """
    if not _is_named(value):
        raise TypeError(f"public_name: {value!r} has no name to print")
    owner, tail = _owner(value)
    head = value.__qualname__.partition(".")[0]
    dotted = f".{tail}" if tail else ""
    package = ".".join(value.__module__.split(".")[:2])  # the object's own room: hyperfem.loading, ...
    prefixes = dict(_PREFIXED)
    for module in dict.fromkeys(["hyperfem", package, *prefixes, *_IMPORTED, value.__module__]):
        if getattr(importlib.import_module(module), head, None) is not owner:
            continue
        if module in prefixes:
            prefix = prefixes[module]
            return f"{prefix}.{head}{dotted}", _PREFIX_IMPORTS[prefix.split(".")[0]]
        return f"{head}{dotted}", f"from {module} import {head}"
    raise TypeError(f"public_name: {value!r} is not reachable from its module")  # pragma: no cover


def _leaf(value: object) -> str:
    """Python source of a plain value that holds no other: a number, string, boolean, ``None`` or path."""
    if isinstance(value, Path):
        return f"Path({str(value)!r})"
    if isinstance(value, (bool, int, float, str)) or value is None:
        return repr(value)
    raise TypeError(f"source: unsupported value {value!r}")


def _indent(text: str, indent: str) -> str:
    return "\n".join(indent + line for line in text.splitlines())


def _call_source(function: str, parts: Sequence[str]) -> str:
    flat = f"{function}({', '.join(parts)})"
    if len(flat) <= LINE and "\n" not in flat:
        return flat
    body = "\n".join(_indent(f"{p},", "    ") for p in parts)
    return f"{function}(\n{body}\n)"


def source(node: object) -> str:
    """Python source of ``node`` or of a plain value (numbers, strings, paths, arrays, tables).

    Functions are named by :func:`public_name`; calls longer than :data:`LINE` get one argument per line.
    """
    if isinstance(node, Ref):
        return node.name
    if isinstance(node, Call):
        function = public_name(node.function)[0] if _is_named(node.function) else source(node.function)
        parts = [*(source(a) for a in node.args), *(f"{k}={source(v)}" for k, v in node.kwargs.items())]
        return _call_source(function, parts)
    if isinstance(node, Attr):
        return f"{source(node.value)}.{node.name}"
    if isinstance(node, Join):
        return f"{source(node.folder)} / {node.name!r}"
    if isinstance(node, Energy):
        return f"lambda F: {public_name(node.law)[0]}({', '.join(['F', *(source(a) for a in node.args)])})"
    if _is_named(node):
        return public_name(node)[0]
    if isinstance(node, (list, tuple)):
        items = ", ".join(source(v) for v in node)
        if isinstance(node, list):
            return f"[{items}]"
        return f"({items},)" if len(node) == 1 else f"({items})"
    if isinstance(node, Mapping):
        return "{" + ", ".join(f"{_leaf(k)}: {source(v)}" for k, v in node.items()) + "}"
    return _leaf(node)


def _walk(node: object) -> Iterator[object]:
    """Every node and value inside ``node`` (itself included), depth first."""
    yield node
    if isinstance(node, Call):
        if not _is_named(node.function):
            yield from _walk(node.function)
        for value in (*node.args, *node.kwargs.values()):
            yield from _walk(value)
    elif isinstance(node, Attr):
        yield from _walk(node.value)
    elif isinstance(node, Energy):
        for value in node.args:
            yield from _walk(value)
    elif isinstance(node, (list, tuple)):
        for value in node:
            yield from _walk(value)
    elif isinstance(node, Mapping):
        for value in node.values():
            yield from _walk(value)


def _named(node: object) -> Iterator[object]:
    """Every function or class ``node`` names."""
    for item in _walk(node):
        if isinstance(item, Call) and _is_named(item.function):
            yield item.function
        elif isinstance(item, Energy):
            yield item.law
        elif _is_named(item):
            yield item


def imports(node: object) -> list[str]:
    """The import lines the source of ``node`` needs (``from pathlib import Path`` for paths included)."""
    lines = [public_name(f)[1] for f in _named(node)]
    if any(isinstance(v, Path) for v in _walk(node)):
        lines.append("from pathlib import Path")
    return list(dict.fromkeys(lines))
