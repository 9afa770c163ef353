"""The case-file schema is written once: the Key tables of sections check a case, and the reference
(``hyperfem schema``) and the JSON Schema (``hyperfem schema --json``) are generated from them.

The JSON Schema accepts every example case and rejects what ``hyperfem check`` rejects (for the
errors it can see); every key of every table is in both documents, so that they cannot drift.
"""

from __future__ import annotations

import copy
import json
import re
import sys
from collections.abc import Mapping

import pytest
from mpi4py import MPI

from hyperfem.app import sections
from hyperfem.app.casefile import CaseFileError, check_case, parse_toml
from hyperfem.app.reference import LAYOUT, SHAPES, json_schema, key_tables, reference, toml_value
from hyperfem.app.schema import Key, check_value

from case_texts import BASE, ROOT

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

CASES = ROOT / "cases"
EXAMPLES = sorted(CASES.glob("*.toml"))


@pytest.fixture(scope="module")
def validator():
    jsonschema = pytest.importorskip("jsonschema")  # the 'test' extra; the reference tests run without it
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def _declared_tables() -> list[tuple[str, Mapping[str, Key]]]:
    """Every table of Keys that sections declares at module level (dicts of Keys, or of such dicts)."""
    out = []
    for name, value in vars(sections).items():
        if not isinstance(value, Mapping) or not value:
            continue
        if all(isinstance(v, Key) for v in value.values()):
            out.append((name, value))
        elif all(isinstance(v, Mapping) and all(isinstance(k, Key) for k in v.values()) for v in value.values()):
            out += [(f"{name}[{kind!r}]", keys) for kind, keys in value.items() if keys]
    return out


def _all_keys() -> list[tuple[str, str, Key]]:
    return [(path, name, key) for path, keys in key_tables() for name, key in keys.items()]


# -- the JSON Schema ----------------------------------------------------------------------------------
@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_json_schema_accepts_every_example_case(validator, path):
    data = tomllib.loads(path.read_text())
    errors = [f"{'/'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(data)]
    assert errors == []


def _base() -> dict:
    return tomllib.loads(BASE)


def _set(path: str, value: object):
    """An edit of the base case: set (or with ``value=None`` delete) the key at a dotted path (``bc.0.type``)."""

    def edit(data: dict) -> None:
        *parents, last = path.split(".")
        node = data
        for part in parents:
            node = node[int(part)] if part.isdigit() else node.setdefault(part, {})
        if value is None:
            del node[last]
        else:
            node[last] = value

    return edit


BAD = {
    "unknown key": ([_set("material.0.densty", 1000.0)], "material[0].densty: unknown key"),
    "unknown table": ([_set("materials", [{"law": "neo_hookean"}])], "materials: unknown key"),
    "wrong type": ([_set("material.0.E", "1e6")], "material[0].E: expected a number"),
    "wrong type of a vector": ([_set("load.0.value", "down")], "load[0].value: expected an array"),
    "out of range": ([_set("material.0.nu", 0.5)], "material[0].nu: Poisson's ratio must lie in (-1, 0.5)"),
    "negative density": ([_set("material.0.density", -1.0)], "material[0].density: must be > 0"),
    "integer range": ([_set("output", {"checkpoint_every": 0})], "output.checkpoint_every: must be >= 1"),
    "bad choice": ([_set("material.0.law", "neohookean")], "material[0].law: unknown value 'neohookean'"),
    "bad bc type": ([_set("bc.0.type", "clamped")], "bc[0].type: unknown value 'clamped'"),
    "missing required key": ([_set("bc.0.boundary", None)], "bc[0]: missing required key 'boundary'"),
    "missing mesh": ([_set("mesh", None)], "case: missing required key 'mesh'"),
    "clamp with a value": ([_set("bc.0.value", [0.0, 0.0, 0.0])], "bc[0].value: unknown key"),
    "pressure with a vector": ([_set("load.0.type", "pressure")], "load[0].value: expected a number"),
    "a dynamic key in a ramp": ([_set("stepping", {"dt": 0.1})], "stepping.dt: a key of dynamic stepping"),
    "dynamic without t_end": ([_set("stepping", {"type": "dynamic", "dt": 0.1})],
                              "stepping: missing required key 't_end'"),
    "rho_inf of newmark": ([_set("stepping", {"type": "dynamic", "dt": 0.1, "t_end": 1.0, "rho_inf": 0.5})],
                           "stepping.rho_inf: not a parameter of scheme 'newmark'"),
    "rho_inf above 1": ([_set("stepping", {"type": "dynamic", "scheme": "generalized_alpha", "dt": 0.1,
                                           "t_end": 1.0, "rho_inf": 1.5})], "stepping.rho_inf: must lie in [0, 1]"),
    "file and generator": ([_set("mesh.generator", "beam")], "mesh: give either file"),
    "size with a file": ([_set("mesh.size", 1.0)], "mesh.size: only used with a generator"),
    "two elastic pairs": ([_set("material.0.mu", 1.0)], "material[0]: give the elastic constants as"),
    "bad profile": ([_set("load.0.profile", "ramp")], "load[0].profile: unknown profile 'ramp'"),
    "bad profile table": ([_set("load.0.profile", {"type": "ramp", "t2": 1.0})], "load[0].profile.t2: unknown key"),
    "times and every": ([_set("output", {"times": [1.0], "every": 0.5})], "output.every: give either times or every"),
    "bad name": ([_set("name", "my run")], "name: use letters, digits and _.+- only"),
    "empty components": ([_set("bc.0.type", "displacement"), _set("bc.0.value", [1.0]), _set("bc.0.components", [])],
                         "bc[0].components: expected a non-empty array"),
}


@pytest.mark.parametrize("edits, expected", BAD.values(), ids=BAD.keys())
def test_json_schema_rejects_what_hyperfem_rejects(validator, edits, expected):
    data = copy.deepcopy(_base())
    for edit in edits:
        edit(data)
    assert not validator.is_valid(data)
    with pytest.raises(CaseFileError) as info:
        check_case(data, CASES / "bad.toml")
    assert expected in str(info.value)


def test_json_schema_names_the_unexpected_key_of_a_variant(validator):
    data = _base()
    data["bc"][0]["value"] = [0.0, 0.0, 0.0]
    messages = [e.message for e in validator.iter_errors(data)]
    assert any("'value'" in m and "unexpected" in m for m in messages), messages


def test_json_schema_takes_one_table_for_an_array_of_tables(validator):
    """``[bc]`` instead of ``[[bc]]`` is read as one entry by hyperfem; the schema agrees."""
    data = _base()
    data["bc"] = data["bc"][0]
    assert validator.is_valid(data)
    check_case(data, CASES / "one.toml")


def test_json_schema_accepts_the_other_variants(validator):
    """A case with a dynamic step, a muscle, a rotation, a pressure, profiles and render options passes both."""
    data = _base()
    data["problem"] = {"formulation": "mixed", "degree": 2}
    data["fibres"] = {"type": "constant", "direction": [1.0, 0.0, 0.0]}
    data["material"] = [{"law": "muscle", "c1": 1.0, "c2": 0.0, "K": 10.0, "T_max": 1.0, "density": 1.0,
                         "activation": {"type": "ramp", "t1": 0.5}}]
    data["bc"].append({"type": "rotation", "boundary": "free_end", "axis": [1, 0, 0], "angle": 0.1,
                       "profile": {"type": "table", "times": [0.0, 1.0], "values": [0.0, 1.0]}})
    data["load"] = [{"type": "pressure", "boundary": "surface", "value": 1.0, "profile": 0.5},
                    {"type": "body_force", "value": {"matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}}]
    data["stepping"] = {"type": "dynamic", "scheme": "generalized_alpha", "rho_inf": 0.5, "dt": 0.1, "t_end": 1.0,
                        "damping": {"alpha": 0.1}}
    data["solver"] = {"min_jacobian": False, "petsc_options": {"ksp_type": "preonly"}}
    data["output"] = {"reactions": ["clamped"], "render": {"scalars": "von_mises", "window_size": [400, 300]},
                      "checkpoint": False}
    assert [e.message for e in validator.iter_errors(data)] == []
    check_case(data, CASES / "variants.toml")


# -- one source -----------------------------------------------------------------------------------------
def test_every_declared_table_is_in_the_layout():
    """A new table of Keys in sections must be placed in reference.LAYOUT (or reached from it)."""
    covered = {id(keys) for _, keys in key_tables()}
    missing = [name for name, keys in _declared_tables() if id(keys) not in covered]
    assert missing == []


def test_every_key_has_a_help_a_shown_value_and_a_known_shape():
    for path, name, key in _all_keys():
        where = f"{path}.{name}"
        assert key.help and "\n" not in key.help, where
        assert not key.shape or key.shape in SHAPES, where
        if key.kind == "table" and not key.shape:
            continue  # a sub-table: its own keys are shown
        if key.kind == "tables":
            continue  # [[material]], [[bc]], [[load]]
        value = key.example if key.example is not None else key.default
        assert value is not None, f"{where}: no example or default to show"
        if key.kind not in ("any", "table"):
            for shown in (value, key.default):
                if shown is not None:
                    check_value(shown, key, where)


def test_every_key_is_in_the_reference():
    text = reference()
    for path, name, key in _all_keys():
        if key.kind == "tables" or (key.kind == "table" and not key.shape):
            assert re.search(rf"^(# )?\[\[?([\w.]*\.)?{name}\]", text, flags=re.M), f"{path}.{name}"
        else:
            assert re.search(rf"^(# )?{re.escape(name)} = ", text, flags=re.M), f"{path}.{name}"
        first_words = " ".join(key.help.split()[:4])
        assert first_words in " ".join(text.replace("#", " ").split()), f"{path}.{name}: {first_words}"


def _resolve(schema: dict, root: dict) -> dict:
    while "$ref" in schema:
        schema = root["$defs"][schema["$ref"].rsplit("/", 1)[-1]]
    return schema


def test_every_key_is_in_the_json_schema():
    root = json_schema()
    for name, table in LAYOUT.items():
        node = root if not name else _resolve(root["properties"][name], root)
        if "items" in node:  # an array of tables: [[x]] (or one [x])
            node = _resolve(node["items"], root)
        assert set(table.all_keys()) - set(table.tables) <= set(node["properties"]), name
        for sub, inner in table.tables.items():
            assert set(inner.keys) == set(node["properties"][sub]["properties"]), f"{name}.{sub}"
    names: set[str] = set()

    def walk(node: object) -> None:
        if isinstance(node, dict):
            names.update(node.get("properties", {}))
            for value in node.values():
                walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)

    walk(root)
    assert {name for _, name, _ in _all_keys()} <= names
    described = json.dumps(root)
    for path, name, key in _all_keys():
        assert json.dumps(key.help)[1:-1] in described, f"{path}.{name}"


# -- the reference --------------------------------------------------------------------------------------
def test_reference_is_valid_toml_and_every_commented_line_too():
    text = reference()
    data = tomllib.loads(text)
    assert data["name"] == "bend" and data["output"]["checkpoint_every"] == 10
    for line in text.splitlines():
        m = re.match(r"^# (\w+ = .*?)(\s+#.*)?$", line)
        if m:
            tomllib.loads(m.group(1))  # uncommented, a line is valid TOML
        m = re.match(r"^# (\[\[?[\w.]+\]\]?)", line)
        if m:
            tomllib.loads(m.group(1).replace("[[", "[").replace("]]", "]"))


def test_toml_values():
    assert toml_value(1.0e6) == "1e6" and toml_value(0.3) == "0.3" and toml_value(10) == "10"
    assert toml_value(("x", True)) == '["x", true]' and toml_value({"a": 1}) == "{ a = 1 }"
    assert tomllib.loads(f"x = {toml_value(3.8e5)}")["x"] == 3.8e5


def _printed(capsys, argv: list[str]) -> str:
    from hyperfem.app.main import dispatch

    dispatch(argv)
    return MPI.COMM_WORLD.bcast(capsys.readouterr().out, root=0)


def test_schema_command_prints_the_reference_and_the_json_schema(capsys):
    text = _printed(capsys, ["schema"])
    assert text == reference()
    case = check_case(parse_toml(text), CASES / "schema.toml")
    assert case.name == "bend"
    assert json.loads(_printed(capsys, ["schema", "--json"])) == json_schema()
