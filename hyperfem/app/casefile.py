r"""TOML case files: reading, ``--set`` overrides and validation into a :class:`~hyperfem.app.spec.Case`.

A case file describes one run and maps one to one onto the objects a Python
script builds (``hyperfem run CASE --print-python`` writes that script): a
``[mesh]``, ``[problem]``, one or more ``[[material]]``, optionally
``[fibres]`` (and ``[second_fibres]``), ``[[bc]]``, ``[[load]]``, ``[stepping]``, ``[solver]`` and
``[output]``; each key is the keyword of the same name (or the one its help
names) of the class that table builds. Examples: ``cases/*.toml``.

The keys are declared once, in the :class:`~hyperfem.app.schema.Key` tables of
:mod:`hyperfem.app.sections`, which check them; ``hyperfem schema`` prints the
reference generated from those tables (:func:`hyperfem.app.reference.reference`:
a commented case file with every key, its type, range or choices, default and
help; the other ``type``/``law`` variants commented out), and ``hyperfem schema
--json`` a JSON Schema for editors (:func:`hyperfem.app.reference.json_schema`).

Validation happens before anything is computed (:func:`load_case`): TOML
syntax errors with line and column, unknown keys with a did-you-mean, wrong
types, missing keys, out-of-range parameters (negative density, Poisson's
ratio :math:`\nu \ge 1/2`, ...), conflicting Dirichlet conditions on one
boundary. Every message is a :class:`~hyperfem.app.schema.CaseFileError`
that names the file and the key path (``bend.toml: material[0].nu: ...``).
Names of physical groups and vector lengths are checked against the mesh
once it is read (:func:`hyperfem.app.build.check_mesh`).

Load and boundary-condition *profiles* :math:`f(t)` scale the value with the
load factor (quasi-static) or the time (dynamic); the default ``"linear"`` is
the library's :math:`f(t) = t` (:func:`~hyperfem.loading.linear_profile`). ``"steady"`` is :math:`f = 1`; a number
``c`` is :math:`f = c`; ``{type = "ramp", t1, final, initial, t0}`` is
:class:`~hyperfem.loading.Ramp`; ``{type = "table", times, values}`` is
:class:`~hyperfem.loading.Table`. The ends of ramps, the table times and
the field output times are must-hit times of a dynamic run.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from hyperfem.app import sections
from hyperfem.app.overrides import apply_overrides
from hyperfem.app.schema import CaseFileError, check_table
from hyperfem.app.spec import (
    LAWS,
    MIXED_LAWS,
    BCSpec,
    Case,
    FibreSpec,
    LoadSpec,
    MaterialSpec,
    MeshSpec,
    OutputSpec,
    ProblemSpec,
    Profile,
    SolverSpec,
    SteppingSpec,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = [
    "LAWS",
    "MIXED_LAWS",
    "BCSpec",
    "Case",
    "CaseFileError",
    "FibreSpec",
    "LoadSpec",
    "MaterialSpec",
    "MeshSpec",
    "OutputSpec",
    "ProblemSpec",
    "Profile",
    "SolverSpec",
    "SteppingSpec",
    "apply_overrides",
    "check_case",
    "load_case",
    "parse_toml",
]


# -- reading --------------------------------------------------------------------------------
_AT = re.compile(r"^(?P<msg>.*?)\s*\(at line (?P<line>\d+), column (?P<col>\d+)\)$")


def parse_toml(text: str, source: str | Path = "<case>") -> dict:
    """Parse TOML text; a syntax error becomes ``FILE:LINE:COLUMN: TOML syntax error: ...``.

    Raises:
        CaseFileError: On a syntax error.
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        text = str(exc)
        m = _AT.match(text)
        if m:
            where = f"{source}:{m['line']}:{m['col']}"
            raise CaseFileError(f"{where}: TOML syntax error: {m['msg']}") from None
        raise CaseFileError(f"{source}: TOML syntax error: {text}") from None


def load_case(
    path: str | Path, overrides: Sequence[str] = (), *, output: str | Path | None = None
) -> Case:
    """Read, override and check a case file (on every rank: the checks are deterministic).

    Args:
        path: The ``.toml`` file.
        overrides: ``key=value`` strings (:func:`apply_overrides`).
        output: Output folder replacing ``[output] directory``.

    Raises:
        CaseFileError: The file is missing, unreadable or invalid.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CaseFileError(f"case file not found: {path}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CaseFileError(f"{path}: cannot read the case file: {getattr(exc, 'strerror', None) or exc}") from None
    data = parse_toml(text, path)
    data = apply_overrides(data, overrides, path)
    return check_case(data, path, output=output)


def check_case(data: Mapping, source: str | Path = "<case>", *, output: str | Path | None = None) -> Case:
    """Check the parsed TOML of a case and return the :class:`Case`.

    Args:
        data: Parsed TOML.
        source: The case file (messages, relative mesh paths).
        output: Output folder replacing ``[output] directory``.

    Raises:
        CaseFileError: The first problem found, with the file name and the key path.
    """
    source = Path(source)
    try:
        top = check_table(data, sections.TOP, "", what="the case")
        name = top.get("name", re.sub(r"[^A-Za-z0-9_.+-]", "_", source.stem) or "case")
        if not sections.NAME.fullmatch(name):
            raise CaseFileError(f"name: use letters, digits and _.+- only (it names the output files), got {name!r}")
        problem = sections.check_problem(top.get("problem", {}))
        fibres = sections.check_fibres(top["fibres"]) if "fibres" in top else None
        second = sections.check_fibres(top["second_fibres"], "second_fibres") if "second_fibres" in top else None
        mixed = problem.formulation == "mixed"
        materials = sections.check_materials(top["material"], mixed, fibres is not None, second is not None)
        sections.check_fibre_use(materials, fibres, second)
        bcs = sections.check_bcs(top.get("bc", []))
        loads = sections.check_loads(top.get("load", []))
        contacts = sections.check_contacts(top.get("contact", []), source)
        stepping = sections.check_stepping(top.get("stepping", {}))
        sections.check_viscoelastic_use(materials, stepping)
        if stepping.dynamic and stepping.scheme != "quasi_static":
            for m in materials:
                if m.density is None:
                    raise CaseFileError(
                        f"{m.key}: missing required key 'density' (a dynamic run needs the mass density)"
                    )
        degree = problem.degree or (2 if problem.formulation == "mixed" else 1)
        if stepping.lumped_mass and degree != 1:
            raise CaseFileError(
                "stepping.lumped_mass: the lumped mass needs degree-1 displacements (problem.degree = 1)"
            )
        mesh = sections.check_mesh_table(top["mesh"], source)
        solver = sections.check_solver(top.get("solver", {}))
        output_spec = sections.check_output(top.get("output", {}), name, output, stepping, bcs, fibres, materials)
        return Case(
            source=source,
            name=name,
            description=top.get("description", ""),
            mesh=mesh,
            problem=problem,
            materials=materials,
            fibres=fibres,
            second_fibres=second,
            bcs=bcs,
            loads=loads,
            contacts=contacts,
            stepping=stepping,
            solver=solver,
            output=output_spec,
        )
    except CaseFileError as exc:
        if exc.source is not None:
            raise
        raise CaseFileError(exc.message, source) from None
