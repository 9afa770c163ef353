"""The case-file schema, generated from the :class:`~hyperfem.app.schema.Key` tables of :mod:`hyperfem.app.sections`.

The key declarations that check a case file are the one source of its documentation:

* :func:`reference` — ``hyperfem schema``: a commented TOML case file listing every
  key of every table with its type, range or choices, default and help; the lines
  without ``#`` form a valid case (the cantilever bend on ``meshes/beam_h2.msh``),
  the other keys and the other ``type``/``law`` variants are commented out;
* :func:`json_schema` — ``hyperfem schema --json``: a JSON Schema (draft 2020-12) for
  editors (taplo / "Even Better TOML" completes and checks case files with it): types,
  ranges, choices, required keys, no unknown keys, the keys of each ``type``/``law``
  as ``if``/``then`` on that key.

What the tables cannot say is written here once: the layout of the case (:data:`LAYOUT`:
which table holds which keys, which key selects the variant), the values a key of
kind ``any`` may take (:data:`SHAPES`), and a few rules between keys (:data:`RULES`,
mirrors of the checks in :mod:`hyperfem.app.sections`). The JSON Schema is a little
more lenient than ``hyperfem check`` (names of mesh groups, vector lengths, conflicting
conditions and the like are checked by hyperfem only).
"""

from __future__ import annotations

import json
import math
import textwrap
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field

from hyperfem.app import sections as S
from hyperfem.app.schema import Key
from hyperfem.app.spec import LAME_LAWS, RUBBER_LAWS, TISSUE_LAWS

__all__ = ["LAYOUT", "RULES", "SHAPES", "Shape", "Table", "dumps", "json_schema", "key_tables", "reference"]

JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"


# -- layout ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Table:
    """A table of the case file and the key tables that declare its keys.

    Attributes:
        path: Its key path (``"mesh"``, ``"mesh.geometry"``, ``"material"``).
        keys: Keys of every entry (for a variant table: the common ones, the selector first).
        array: An array of tables (``[[bc]]``).
        on: The key that selects the variant (``"type"``, ``"law"``), or ``None``.
        variants: ``(values of the selector, their own keys)`` pairs.
        tables: Sub-tables: key name -> :class:`Table` (``mesh.geometry``).
    """

    path: str
    keys: Mapping[str, Key]
    array: bool = False
    on: str | None = None
    variants: tuple[tuple[tuple[str, ...], Mapping[str, Key]], ...] = ()
    tables: Mapping[str, Table] = field(default_factory=dict)

    def variant_keys(self, index: int) -> dict[str, Key]:
        """The keys of an entry of variant ``index``."""
        return {**self.keys, **self.variants[index][1]}

    def all_keys(self) -> dict[str, Key]:
        """Every key any entry may have (the first declaration of each name)."""
        out = dict(self.keys)
        for _, own in self.variants:
            for name, key in own.items():
                out.setdefault(name, key)
        return out


def _by_type(tables: Mapping[str, Mapping[str, Key]]) -> tuple[tuple[tuple[str, ...], Mapping[str, Key]], ...]:
    return tuple(((kind,), keys) for kind, keys in tables.items())


def _without(keys: Mapping[str, Key], name: str) -> dict[str, Key]:
    return {k: v for k, v in keys.items() if k != name}


_PROFILE = Table(
    "profile", {"type": S.PROFILE_TYPE}, on="type",
    variants=_by_type({k: S.PROFILES[k] for k in ("ramp", "table", "steady", "linear")}),
)
_AFFINE = Table("value", S.AFFINE)
_RENDER = Table("output.render", S.RENDER)

LAYOUT: dict[str, Table] = {
    "": Table("", S.TOP),
    "mesh": Table("mesh", S.MESH, tables={"geometry": Table("mesh.geometry", S.GEOMETRY)}),
    "problem": Table("problem", S.PROBLEM),
    "material": Table(
        "material",
        S._COMMON_MATERIAL,
        array=True,
        on="law",
        variants=(
            (LAME_LAWS, S._LAME),
            (("mooney_rivlin",), S._MOONEY),
            (("muscle",), S._MUSCLE),
            *(((law,), S.LAW_KEYS[law]) for law in (*RUBBER_LAWS, *TISSUE_LAWS)),
        ),
        tables={"viscoelastic": Table("material.viscoelastic", S.VISCOELASTIC)},
    ),
    "fibres": Table("fibres", S.FIBRE_COMMON, on="type", variants=_by_type(S.FIBRES)),
    "second_fibres": Table("second_fibres", S.FIBRE_COMMON, on="type", variants=_by_type(S.FIBRES)),
    "bc": Table("bc", S._BC_COMMON, array=True, on="type", variants=_by_type(S.BCS)),
    "load": Table("load", S._LOAD_COMMON, array=True, on="type", variants=_by_type(S.LOADS)),
    "contact": Table("contact", S._CONTACT_COMMON, array=True, on="type", variants=_by_type(S.CONTACTS),
                     tables={"path": Table("contact.path", S.WAYPOINTS),
                             "rotation": Table("contact.rotation", S.CONTACT_ROTATION)}),
    "stepping": Table(
        "stepping",
        {"type": S.QUASI_STATIC["type"]},
        on="type",
        variants=((("quasi-static",), S.QUASI_STATIC), (("dynamic",), S.DYNAMIC), (("arc_length",), S.ARC_LENGTH),
                  (("buckling",), S.BUCKLING)),
        tables={"damping": Table("stepping.damping", S.DAMPING)},
    ),
    "solver": Table("solver", S.SOLVER),
    "output": Table("output", S.OUTPUT),
}
"""The tables of a case file, in the order of :data:`~hyperfem.app.sections.TOP` (``""``: the top level).
A variant's own keys may repeat the selector (``stepping``)."""

ACTIVE: dict[str, tuple[str, ...]] = {
    "": ("name", "description"),
    "mesh": ("file",),
    "problem": ("formulation", "degree"),
    "material": ("law", "E", "nu", "density"),
    "bc": ("type", "boundary"),
    "load": ("type", "boundary", "value", "profile"),
    "stepping": ("type", "increment"),
    "solver": ("rtol", "max_iterations"),
    "output": ("directory", "probes", "reactions", "fields", "format", "checkpoint_every"),
}
"""The keys written without ``#`` in :func:`reference` (with their examples or defaults): a valid case.
A table not named here is commented out; a variant table's active entry is its first variant."""


# -- values of kind "any" ----------------------------------------------------------------------
@dataclass(frozen=True)
class Shape:
    """What a key of kind ``any`` (or an undeclared ``table``) may hold.

    Attributes:
        text: The type column of the reference.
        json: Its JSON Schema.
        table: A table the value may be, listed in the reference after the first active
            table with such a key (``[load.profile]``).
        title: The comment of that table's header.
    """

    text: str
    json: Callable[[], dict]
    table: Table | None = None
    title: str = ""


def _profile_json(number: dict | None = None) -> dict:
    return {"anyOf": [{"enum": ["linear", "steady"]}, number or {"type": "number"}, {"$ref": "#/$defs/profile"}]}


SHAPES: dict[str, Shape] = {
    "profile": Shape(
        '"linear" | "steady" | number | table', _profile_json, _PROFILE,
        "a profile as a table (bc.profile, load.profile, material.activation): its keys depend on type",
    ),
    "activation": Shape(
        "number in [0, 1] | profile", lambda: _profile_json({"type": "number", "minimum": 0, "maximum": 1}), _PROFILE
    ),
    "components": Shape(
        '[0 | 1 | 2 | "x" | "y" | "z", ...]',
        lambda: {"type": "array", "items": {"enum": [0, 1, 2, "x", "y", "z"]}, "minItems": 1, "maxItems": 3,
                 "uniqueItems": True},
    ),
    "field": Shape(
        "[numbers] | {matrix, offset}",
        lambda: {"anyOf": [_key_json(Key("numbers")), _table_json(_AFFINE)]},
        _AFFINE,
        "a load value as a table: the affine field A x + b (hyperfem.loading.AffineField)",
    ),
    "reactions": Shape(
        '"all" | false | [boundaries]',
        lambda: {"anyOf": [{"const": "all"}, {"const": False},
                           {"type": "array", "items": {"type": "string", "minLength": 1}}]},
    ),
    "render": Shape(
        "true | false | table", lambda: {"anyOf": [{"type": "boolean"}, _table_json(_RENDER)]}, _RENDER,
        "render as a table: the options of hyperfem.simulation.Render",
    ),
    "min_jacobian": Shape(
        'number | "auto" | false', lambda: {"anyOf": [{"type": "number"}, {"const": "auto"}, {"const": False}]}
    ),
    "window_size": Shape(
        "[2 integers > 0]",
        lambda: {"type": "array", "items": {"type": "integer", "exclusiveMinimum": 0}, "minItems": 2, "maxItems": 2},
    ),
    "title": Shape("true | false | string", lambda: {"type": ["boolean", "string"]}),
    "petsc_options": Shape(
        "table {option = value}",
        lambda: {"type": "object", "propertyNames": {"pattern": "^[^-]"},
                 "additionalProperties": {"type": ["string", "number", "boolean"]}},
    ),
}
"""The values of the keys of kind ``any`` (and of ``table`` keys whose keys are not declared), by shape name."""


# -- rules between keys ----------------------------------------------------------------------------
def _required(*names: str) -> dict:
    return {"required": list(names)}


def _none_of(*names: str) -> dict:
    return {"not": {"anyOf": [_required(n) for n in names]}}


def _is(name: str, value: object) -> dict:
    return {"properties": {name: {"const": value}}, "required": [name]}


_ELASTIC = ("E", "nu", "mu", "lambda", "bulk_modulus")


def _pairs(*pairs: tuple[str, ...]) -> dict:
    return {"oneOf": [{**_required(*p), **_none_of(*(n for n in _ELASTIC if n not in p))} for p in pairs]}


RULES: dict[str, tuple[dict, ...]] = {
    "mesh": (
        {"oneOf": [_required("file"), _required("generator")]},
        {"if": _required("file"), "then": _none_of("size", "order", "geometry")},
        {"if": {"not": {"properties": {"generator": {"enum": ["fusiform", "spherical_shell"]}},
                        "required": ["generator"]}},
         "then": _none_of("geometry")},
    ),
    "material[0]": (
        {"if": _is("law", "arap"),
         "then": _pairs(("E", "nu"), ("mu", "lambda"), ("mu", "bulk_modulus"), ("mu",)),
         "else": _pairs(("E", "nu"), ("mu", "lambda"), ("mu", "bulk_modulus"))},
        {"if": {"not": _is("law", "neo_hookean")}, "then": _none_of("viscoelastic")},
    ),
    "material[2]": ({"if": {"not": _required("preset")}, "then": _required("c1", "c2", "K", "T_max")},
                    _none_of("viscoelastic")),
    "stepping[1]": (
        {"if": {"properties": {"scheme": {"not": {"const": "newmark"}}}, "required": ["scheme"]},
         "then": _none_of("beta", "gamma")},
        {"if": {"not": _is("scheme", "generalized_alpha")}, "then": _none_of("rho_inf")},
    ),
    "contact[2]": ({"properties": {"boundaries": {"minItems": 1, "uniqueItems": True}}},),
    "contact[3]": ({"properties": {"boundaries": {"minItems": 2, "maxItems": 2, "uniqueItems": True}}},),
    "contact[4]": ({"properties": {"boundaries": {"minItems": 1, "uniqueItems": True}}},),
    "output": (
        {"not": _required("times", "every")},
        {"if": _is("checkpoint", False), "then": _none_of("checkpoint_every", "checkpoint_keep")},
    ),
}
"""Rules between keys that :mod:`hyperfem.app.sections` checks in code, as JSON Schema, by table path
(``material[2]``: of its third variant): mesh file or generator; the elastic constants as one pair;
muscle parameters without a preset; viscoelasticity only for the laws of
:data:`~hyperfem.app.spec.VISCOELASTIC_LAWS`; scheme parameters; the boundaries of a self, pair (two) or tool contact;
output times or every; checkpoints off."""


# -- the key tables --------------------------------------------------------------------------------
def _tables(table: Table) -> Iterator[Table]:
    yield table
    for sub in table.tables.values():
        yield from _tables(sub)
    for key in table.all_keys().values():
        shape = SHAPES.get(key.shape)
        if shape is not None and shape.table is not None:
            yield from _tables(shape.table)


def key_tables() -> Iterator[tuple[str, Mapping[str, Key]]]:
    """Every declared key table of :data:`LAYOUT` as ``(path, keys)`` (variants as ``path[i]``), once."""
    seen: set[tuple[str, int]] = set()
    for top in LAYOUT.values():
        for table in _tables(top):
            parts = [(table.path, table.keys)] + [
                (f"{table.path}[{i}]", own) for i, (_, own) in enumerate(table.variants)
            ]
            for path, keys in parts:
                if (path, id(keys)) not in seen:
                    seen.add((path, id(keys)))
                    yield path, keys


# -- text ----------------------------------------------------------------------------------------
def _number(x: float) -> str:
    """An integer as it is; a float as Python writes it, large round ones as ``1e6``, ``3.8e5``."""
    if isinstance(x, int):
        return str(x)
    text = repr(float(x))
    if "e" not in text and abs(x) >= 1e5 and float(x).is_integer():
        mantissa, exponent = f"{x:.12e}".split("e")
        text = f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"
    return text


def toml_value(value: object) -> str:
    """A TOML literal of a value (strings, numbers, booleans, arrays, inline tables)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return _number(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML literal for {value!r}")


def _interval(key: Key) -> str:
    low: tuple[str, float, str] | None
    high: tuple[str, float, str] | None
    low = (f"> {key.above:g}", key.above, "(") if key.above is not None else None
    if key.minimum is not None:
        low = (f">= {key.minimum:g}", key.minimum, "[")
    high = (f"< {key.below:g}", key.below, ")") if key.below is not None else None
    if key.maximum is not None:
        high = (f"<= {key.maximum:g}", key.maximum, "]")
    if low and high:
        return f" in {low[2]}{low[1]:g}, {high[1]:g}{high[2]}"
    bound = low or high
    return f" {bound[0]}" if bound else ""


def type_text(key: Key) -> str:
    """The type column of the reference: ``number > 0``, ``"vtx" | "xdmf"``, ``[3 numbers]``, ..."""
    kind = key.kind
    if key.shape:
        return SHAPES[key.shape].text
    if kind == "string":
        if key.choices:
            return " | ".join(json.dumps(c) for c in key.choices)
        return f"string of {key.pattern}" if key.pattern else "string"
    if kind in ("number", "integer"):
        return kind + _interval(key)
    if kind == "boolean":
        return "true | false"
    if kind == "vector":
        return f"[{key.length} numbers{_interval(key)}]"
    if kind == "numbers":
        return f"[numbers{_interval(key)}]"
    if kind == "matrix":
        return f"[[{key.length} numbers], ...]" if key.length else "[[numbers], ...]"
    if kind == "strings":
        return "[" + (" | ".join(json.dumps(c) for c in key.choices) if key.choices else "strings") + ", ...]"
    return {"table": "table", "tables": "array of tables"}[kind]


def _doc(key: Key) -> str:
    """``TYPE, default D, required: HELP``."""
    parts = [type_text(key)]
    if key.default is not None:
        parts.append(f"default {toml_value(key.default)}")
    if key.required:
        parts.append("required")
    return ", ".join(parts) + (f": {key.help}" if key.help else "")


def _value(key: Key) -> object:
    if key.example is not None:
        return key.example
    if key.default is not None:
        return key.default
    raise ValueError(f"no example or default to show for {key}")  # pragma: no cover - tests check every key


COLUMN = 40
"""Where the comments of the reference start."""
WIDTH = 118


def _line(code: str, comment: str) -> list[str]:
    """``code  # comment``, the comment wrapped into ``#`` lines at :data:`COLUMN`."""
    pad = max(COLUMN, len(code) + 2)
    wrapped = textwrap.wrap(comment, WIDTH - pad - 2, break_on_hyphens=False) or [""]
    lines = [f"{code:<{pad}}# {wrapped[0]}".rstrip()]
    lines += [f"{'':<{COLUMN}}#   {w}" for w in wrapped[1:]]
    return lines


class _Writer:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.shown: set[int] = set()  # ids of the shape tables already listed

    def blank(self) -> None:
        if self.lines and self.lines[-1] != "":
            self.lines.append("")

    def keys(self, keys: Mapping[str, Key], active: tuple[str, ...], on: bool, values: Mapping | None = None) -> None:
        for name, key in keys.items():
            if key.kind == "tables" or (key.kind == "table" and not key.shape):
                continue  # a sub-table: listed after the table
            value = (values or {}).get(name, _value(key))
            commented = not (on and name in active)
            self.lines += _line(f"{'# ' if commented else ''}{name} = {toml_value(value)}", _doc(key))

    def table(self, table: Table, key: Key | None, active: tuple[str, ...], on: bool) -> None:
        """A table (with its variants and sub-tables); ``on``: not commented out."""
        header = f"[[{table.path}]]" if table.array else f"[{table.path}]"
        if not table.variants:
            if table.path:
                self.blank()
                self.lines += _line(("" if on else "# ") + header, key.help if key else "")
            self.keys(table.keys, active, on)
            self.subtables(table, on)
            return
        assert table.on is not None  # a table with variants names its selector
        for i, (values, own) in enumerate(table.variants):
            first = i == 0
            live = on and first
            self.blank()
            selector = table.keys[table.on]
            if first:
                self.lines += _line(("" if live else "# ") + header, key.help if key else "")
                self.keys({table.on: selector}, active, live, {table.on: values[0]})
            else:
                self.lines += _line(("" if live else "# ") + header, f"{table.on} {json.dumps(values[0])}")
                self.lines.append(f"# {table.on} = {json.dumps(values[0])}")
            if first:
                common = _without(table.keys, table.on)
            else:
                common = {n: k for n, k in table.keys.items() if k.required and n != table.on}
            self.keys(common, active, live)
            self.keys(_without(own, table.on), active, live)
            for name, sub in table.tables.items():
                if name in own or (first and name in table.keys):  # a common key's table: once, at the first
                    self.table(sub, {**table.keys, **own}[name], (), False)
            if live:
                self.shapes({**table.keys, **own}, table.path)

    def subtables(self, table: Table, on: bool) -> None:
        for name, sub in table.tables.items():
            self.table(sub, table.keys[name], (), False)
        if on:
            self.shapes(table.keys, table.path)

    def shapes(self, keys: Mapping[str, Key], path: str) -> None:
        """The tables the keys of an active entry may hold (``[load.profile]``), each listed once."""
        for name, key in keys.items():
            shape = SHAPES.get(key.shape)
            if shape is None or shape.table is None or id(shape.table) in self.shown:
                continue
            self.shown.add(id(shape.table))
            sub = shape.table
            moved = Table(f"{path}.{name}", sub.keys, on=sub.on, variants=sub.variants, tables=sub.tables)
            self.table(moved, Key("table", help=shape.title), (), False)


HEADER = """\
# hyperfem case file: every key, generated from the declarations that check it (hyperfem schema).
# The lines without '#' form a valid case, the cantilever bend on meshes/beam_h2.msh (saved in cases/);
# '# key = value' lines are the other keys, '# [[bc]]' blocks the other variants, commented out.
# Each comment: type or choices, default, then what the key is and the class or keyword it feeds.
# Units are SI (m, Pa, kg/m^3, s). A profile f(t) scales a value with the load factor (quasi-static)
# or the time in s (dynamic): "linear" f = t, "steady" f = 1, a number c, or a table (see [load.profile]).
# As a JSON Schema, for editors: hyperfem schema --json. Examples: cases/*.toml."""


def reference() -> str:
    """The commented reference case file of ``hyperfem schema`` (valid TOML and a valid case)."""
    w = _Writer()
    w.lines += HEADER.splitlines()
    w.blank()
    w.keys(LAYOUT[""].keys, ACTIVE[""], True)
    for name, table in LAYOUT.items():
        if name:
            w.table(table, S.TOP[name], ACTIVE.get(name, ()), name in ACTIVE)
    return "\n".join(w.lines) + "\n"


# -- JSON Schema --------------------------------------------------------------------------------
def _plain(value: object) -> object:
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _bounds(key: Key) -> dict:
    out: dict = {}
    for name, attr in (("exclusiveMinimum", "above"), ("minimum", "minimum"), ("exclusiveMaximum", "below"),
                       ("maximum", "maximum")):
        value = getattr(key, attr)
        if value is not None:
            out[name] = int(value) if float(value).is_integer() and math.isfinite(value) else value
    return out


def _key_json(key: Key) -> dict:
    """The JSON Schema of a key's value, without annotations."""
    kind = key.kind
    if key.shape:
        return SHAPES[key.shape].json()
    if kind == "string":
        out: dict = {"type": "string", "minLength": 1}
        if key.choices:
            out["enum"] = list(key.choices)
        if key.pattern:
            out["pattern"] = f"^(?:{key.pattern})$"
        return out
    if kind in ("number", "integer"):
        return {"type": kind, **_bounds(key)}
    if kind == "boolean":
        return {"type": "boolean"}
    number = {"type": "number", **_bounds(key)}
    if kind == "vector":
        return {"type": "array", "items": number, "minItems": key.length, "maxItems": key.length}
    if kind == "numbers":
        return {"type": "array", "items": number, "minItems": 1}
    if kind == "matrix":
        row = {"type": "array", "items": number, "minItems": key.length or 1}
        if key.length:
            row["maxItems"] = key.length
        return {"type": "array", "items": row, "minItems": 1}
    if kind == "strings":
        item: dict = {"type": "string", "minLength": 1}
        if key.choices:
            item["enum"] = list(key.choices)
        return {"type": "array", "items": item}
    return {"type": "object"} if kind == "table" else {"type": "array", "items": {"type": "object"}}


def _annotated(schema: dict, key: Key) -> dict:
    out = dict(schema)
    text = key.help
    if key.default is not None:
        text = f"{text}; default {toml_value(key.default)}" if text else f"default {toml_value(key.default)}"
    if text:
        out["description"] = text
    if key.default is not None:
        out["default"] = _plain(key.default)
    if key.example is not None:
        out["examples"] = [_plain(key.example)]
    return out


def _property(table: Table, name: str, key: Key) -> dict:
    if name in table.tables:
        return _annotated(_table_json(table.tables[name]), key)
    return _annotated(_key_json(key), key)


def _closed(table: Table, keys: Mapping[str, Key], rules: tuple[dict, ...] = ()) -> dict:
    out: dict = {
        "type": "object",
        "properties": {n: _property(table, n, k) for n, k in keys.items()},
        "additionalProperties": False,
    }
    required = [n for n, k in keys.items() if k.required]
    if required:
        out["required"] = required
    if rules:
        out["allOf"] = list(rules)
    return out


def _bare(schema: object) -> object:
    """A schema without its annotations (to compare two declarations of one key)."""
    if isinstance(schema, dict):
        return {k: _bare(v) for k, v in schema.items() if k not in ("description", "default", "examples")}
    if isinstance(schema, list):
        return [_bare(v) for v in schema]
    return schema


def _narrowed(schema: dict, union: dict) -> dict | bool:
    """What a variant adds to the union's schema of a key: nothing, its own description, or its own schema."""
    if schema == union:
        return True
    if _bare(schema) == _bare(union):
        return {k: v for k, v in schema.items() if k in ("description", "default", "examples")}
    return schema


def _table_json(table: Table) -> dict:
    """The JSON Schema of one entry of a table; a variant table: the union of its keys (for completion)
    and, per variant, ``if`` the selector has its value ``then`` exactly its keys."""
    if not table.variants:
        return _closed(table, table.keys, RULES.get(table.path, ()))
    assert table.on is not None  # a table with variants names its selector
    selector = table.keys[table.on]
    default = selector.default
    union: dict[str, dict] = {}
    branches: list[dict] = []
    per_variant = [_closed(table, table.variant_keys(i), RULES.get(f"{table.path}[{i}]", ()))
                   for i in range(len(table.variants))]
    for closed in per_variant:
        for name, schema in closed["properties"].items():
            if name not in union:
                union[name] = schema
            elif _bare(union[name]) != _bare(schema):
                union[name] = {"description": union[name].get("description", "")}
    for (values, _), closed in zip(table.variants, per_variant, strict=True):
        then = dict(closed)
        then["properties"] = {n: _narrowed(s, union[n]) for n, s in closed["properties"].items()}
        cond: dict = {"properties": {table.on: {"enum": list(values)} if len(values) > 1 else {"const": values[0]}}}
        if default not in values:
            cond["required"] = [table.on]
        branches.append({"if": cond, "then": then})
    out: dict = {"type": "object", "properties": union, "additionalProperties": False, "allOf": branches}
    if selector.required:
        out["required"] = [table.on]
    return out


def _array(name: str, key: Key) -> dict:
    """``[[x]]``: an array of tables (one table written as ``[x]`` is read as one entry)."""
    entry = {"$ref": f"#/$defs/{name}"}
    out: dict[str, object] = {"type": ["array", "object"], "items": entry, "if": {"type": "object"}, "then": entry}
    if key.required:
        out["minItems"] = 1
    return out


def json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a case file: ``hyperfem schema --json``."""
    properties: dict = {}
    defs: dict = {}
    for name, key in S.TOP.items():
        table = LAYOUT.get(name)
        if table is None:
            properties[name] = _annotated(_key_json(key), key)
        elif table.array:
            defs[name] = _table_json(table)
            properties[name] = _annotated(_array(name, key), key)
        else:
            properties[name] = _annotated(_table_json(table), key)
    defs["profile"] = _table_json(_PROFILE)
    return {
        "$schema": JSON_SCHEMA_DIALECT,
        "title": "hyperfem case file",
        "description": "A TOML case file of `hyperfem run`, generated by `hyperfem schema --json` from the "
        "declarations that check it; `hyperfem check CASE` checks the rest (mesh groups, vector lengths, conflicts).",
        "type": "object",
        "properties": properties,
        "required": [n for n, k in S.TOP.items() if k.required],
        "additionalProperties": False,
        "$defs": defs,
    }


def dumps(schema: object, indent: int = 0, width: int = 110, used: int = 0) -> str:
    """JSON text with two-space indents, arrays and objects that fit in ``width`` kept on one line.

    ``used``: characters already on the line (the key) besides the indent.
    """
    flat = json.dumps(schema, ensure_ascii=False)
    if not isinstance(schema, (dict, list)) or not schema or indent + used + len(flat) <= width:
        return flat
    pad = " " * (indent + 2)
    if isinstance(schema, list):
        items = [pad + dumps(v, indent + 2, width) for v in schema]
    else:
        items = [f"{pad}{json.dumps(k)}: {dumps(v, indent + 2, width, len(json.dumps(k)) + 2)}"
                 for k, v in schema.items()]
    close = "]" if isinstance(schema, list) else "}"
    return ("[" if isinstance(schema, list) else "{") + "\n" + ",\n".join(items) + "\n" + " " * indent + close
