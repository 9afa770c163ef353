"""A case as Python: the statements ``hyperfem run`` executes and ``--print-python`` prints.

:func:`plan` turns a checked :class:`~hyperfem.app.casefile.Case` into a list of
:class:`Statement` — one assignment (or call) per object, written with the
public API (``hf.read_mesh``, ``hf.HyperelasticProblem``, ``hf.Clamp``, ...) and
tagged with the case key it comes from. :func:`script` prints them as a
runnable program; :func:`hyperfem.app.build.build` evaluates the *same*
statements, one by one, in a namespace with the same imports. So the command
and the script are one code path: what is printed is what runs, and a script
written from the printed one starts from exactly the objects the command
built.

Values enter the source as Python literals (``repr``), never as text spliced
from the case file: every value was type-checked by the schema first.
"""

from __future__ import annotations

import os

import dataclasses
import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from hyperfem.app.spec import LAME_LAWS, BCSpec, Case, LoadSpec, MaterialSpec, Profile
from hyperfem.problem.hyperelastic import default_quadrature_degree

__all__ = [
    "Statement",
    "call",
    "checkpoint_folder",
    "imports",
    "literal",
    "model_hash",
    "must_hit_times",
    "plan",
    "script",
]

LINE = 100
"""Calls longer than this are broken over lines in the printed script."""

SIMULATION = "from hyperfem.simulation import {}"


@dataclass(frozen=True)
class Statement:
    """One statement of the run.

    Attributes:
        key: The case key it comes from (error messages name it).
        target: The variable it assigns, or ``None`` for a call.
        expression: Python source of the value (for a list: ``None``).
        items: For a list: ``(key, expression)`` per entry.
        imports: Import lines the expression needs.
        comment: A comment printed above it.
    """

    key: str
    target: str | None
    expression: str | None = None
    items: tuple[tuple[str, str], ...] | None = None
    imports: tuple[str, ...] = ()
    comment: str = ""

    def source(self, indent: str = "") -> str:
        """The statement as source lines."""
        head = "" if self.target is None else f"{self.target} = "
        lines = [f"{indent}# {self.comment}"] if self.comment else []
        if self.items is None:
            lines.append(_indent(f"{head}{self.expression}", indent))
        elif not self.items:
            lines.append(f"{indent}{head}[]")
        else:
            lines.append(f"{indent}{head}[")
            for key, expr in self.items:
                lines.append(_indent(f"{expr},  # {key}", indent + "    "))
            lines.append(f"{indent}]")
        return "\n".join(lines)


def _indent(text: str, indent: str) -> str:
    return "\n".join(indent + line for line in text.splitlines())


# -- literals and calls -----------------------------------------------------------------------
def literal(value: object) -> str:
    """Python source of a checked TOML value (numbers, strings, booleans, arrays, tables, paths)."""
    if isinstance(value, Path):
        return f"Path({str(value)!r})"
    if isinstance(value, (list, tuple)):
        items = ", ".join(literal(v) for v in value)
        return f"({items},)" if len(value) == 1 else f"({items})"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{literal(k)}: {literal(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (bool, int, float, str)) or value is None:
        return repr(value)
    raise TypeError(f"literal: unsupported value {value!r}")  # pragma: no cover - the schema checks types


def call(function: str, *args: str, **kwargs: str) -> str:
    """``function(args, key=value)``; over :data:`LINE` characters, one argument per line."""
    parts = [*args, *(f"{k}={v}" for k, v in kwargs.items())]
    flat = f"{function}({', '.join(parts)})"
    if len(flat) <= LINE and "\n" not in flat:
        return flat
    body = "\n".join(_indent(f"{p},", "    ") for p in parts)
    return f"{function}(\n{body}\n)"


def _kwargs(values: Mapping[str, object]) -> dict[str, str]:
    return {k: literal(v) for k, v in values.items()}


# -- profiles, fields ---------------------------------------------------------------------------
LOADING = "from hyperfem.loading import {}"


def _profile(profile: Profile | None, explicit: bool = False) -> str | None:
    """Source of a profile; ``None`` for the library default (linear) unless ``explicit``."""
    if profile is None or profile.kind == "linear":
        return "linear_profile" if explicit else None
    if profile.kind == "steady":
        return call("Steady", literal(profile.args["value"]))
    if profile.kind == "ramp":
        return call("Ramp", **_kwargs(profile.args))
    return call("Table", **_kwargs(profile.args))


def _profile_imports(profile: Profile | None, explicit: bool = False) -> tuple[str, ...]:
    """The import line of :func:`_profile`'s source (none for the default unless ``explicit``)."""
    if profile is None or profile.kind == "linear":
        return (LOADING.format("linear_profile"),) if explicit else ()
    return (LOADING.format({"steady": "Steady", "ramp": "Ramp"}.get(profile.kind, "Table")),)


def _vector_value(value: object) -> tuple[str, tuple[str, ...]]:
    if isinstance(value, Mapping):
        return call("AffineField", **_kwargs(value)), (LOADING.format("AffineField"),)
    return literal(value), ()


# -- entries --------------------------------------------------------------------------------------
def _bc(bc: BCSpec) -> tuple[str, tuple[str, ...]]:
    imports = _profile_imports(bc.profile)
    if bc.type == "clamp":
        return call("hf.Clamp", literal(bc.boundary)), imports
    if bc.type == "displacement":
        kwargs = {}
        if bc.components is not None:
            kwargs["components"] = literal(bc.components)
        profile = _profile(bc.profile)
        if profile is not None:
            kwargs["profile"] = profile
        return call("hf.PrescribedDisplacement", literal(bc.boundary), literal(bc.value), **kwargs), imports
    angle = call("Scaled", _profile(bc.profile, explicit=True), literal(bc.angle))
    args = [literal(bc.boundary), literal(bc.axis), angle]
    if bc.center is not None:
        args.append(literal(bc.center))
    imports = (*_profile_imports(bc.profile, explicit=True), LOADING.format("Scaled, rotating_surface"))
    return call("rotating_surface", *args), imports


_LOAD_CLASSES = {
    "dead_traction": "hf.DeadTraction",
    "follower_traction": "hf.FollowerTraction",
    "pressure": "hf.FollowerPressure",
    "body_force": "hf.BodyForce",
}


def _load(load: LoadSpec) -> tuple[str, tuple[str, ...]]:
    value, imports = _vector_value(load.value) if load.type != "pressure" else (literal(load.value), ())
    kwargs = {}
    if load.type == "body_force" and load.region is not None:
        kwargs["region"] = literal(load.region)
    profile = _profile(load.profile)
    if profile is not None:
        kwargs["profile"] = profile
    args = [value] if load.type == "body_force" else [literal(load.boundary), value]
    return call(_LOAD_CLASSES[load.type], *args, **kwargs), imports + _profile_imports(load.profile)


def _lame(m: MaterialSpec) -> tuple[str, str]:
    """Source of the LameParameters of an isotropic law, and a comment."""
    p = m.parameters
    if "E" in p:
        return call("hf.materials.LameParameters.from_youngs", E=literal(p["E"]), nu=literal(p["nu"])), ""
    if "lambda" in p:
        return call("hf.materials.LameParameters", mu=literal(p["mu"]), lmbda=literal(p["lambda"])), ""
    lmbda = p["bulk_modulus"] - 2.0 * p["mu"] / 3.0
    comment = f"lambda = bulk_modulus - 2 mu / 3 = {p['bulk_modulus']!r} - 2 * {p['mu']!r} / 3"
    return call("hf.materials.LameParameters", mu=literal(p["mu"]), lmbda=literal(lmbda)), comment


def _material(m: MaterialSpec, suffix: str, case: Case, activation: str) -> list[Statement]:
    """``params`` and ``material`` statements of one material."""
    mixed = case.mixed
    params, material = f"params{suffix}", f"material{suffix}"
    if m.law in LAME_LAWS:
        if m.law == "arap" and set(m.parameters) == {"mu"}:
            return [Statement(m.key, material, call("hf.materials.ARAP", literal(m.parameters["mu"])))]
        source, comment = _lame(m)
        out = [Statement(m.key, params, source, comment=comment)]
        if mixed:  # neo_hookean: mu/2 (I1bar - 3) + U(theta)
            K = literal(m.parameters["bulk_modulus"]) if "bulk_modulus" in m.parameters else f"{params}.bulk_modulus"
            iso = f"lambda F: 0.5 * {params}.mu * (isochoric_invariants(F)[0] - 3.0)"
            args = [iso, K] + ([literal(m.volumetric)] if m.volumetric else [])
            out.append(
                Statement(
                    m.key,
                    material,
                    call("SplitEnergy", *args),
                    imports=(
                        "from hyperfem.problem import SplitEnergy",
                        "from hyperfem.kinematics import isochoric_invariants",
                    ),
                )
            )
        elif m.law in ("fixed_corotated", "corotational_linear", "arap"):
            cls = {"fixed_corotated": "FixedCorotated", "corotational_linear": "CorotationalLinear", "arap": "ARAP"}
            out.append(Statement(m.key, material, call(f"hf.materials.{cls[m.law]}", params)))
        else:
            energy = call("hf.materials.with_parameters", f"hf.materials.{m.law}", params)
            out.append(Statement(m.key, material, energy))
        return out
    if m.law == "mooney_rivlin":
        kwargs = _kwargs(m.parameters)
        if m.volumetric:
            kwargs["volumetric"] = literal(m.volumetric)
        out = [Statement(m.key, params, call("hf.materials.MooneyRivlinParameters", **kwargs))]
        if mixed:
            iso = f"lambda F: mooney_rivlin_isochoric(F, {params}.c1, {params}.c2)"
            out.append(
                Statement(
                    m.key,
                    material,
                    call("SplitEnergy", iso, f"{params}.K", f"{params}.volumetric"),
                    imports=(
                        "from hyperfem.problem import SplitEnergy",
                        "from hyperfem.materials.mooney_rivlin import mooney_rivlin_isochoric",
                    ),
                )
            )
        else:
            energy = call("hf.materials.with_parameters", "hf.materials.mooney_rivlin", params)
            out.append(Statement(m.key, material, energy))
        return out
    # muscle
    kwargs = _kwargs(m.parameters)
    if m.volumetric:
        kwargs["volumetric"] = literal(m.volumetric)
    maker = f"hf.materials.MuscleParameters.{m.preset}" if m.preset else "hf.materials.MuscleParameters"
    out = [Statement(m.key, params, call(maker, **kwargs))]
    if mixed:
        iso = f"lambda F: hf.materials.muscle_isochoric(F, fibres, {activation}, {params})"
        out.append(
            Statement(
                m.key,
                material,
                call("SplitEnergy", iso, f"{params}.K", f"{params}.volumetric"),
                imports=("from hyperfem.problem import SplitEnergy",),
            )
        )
    else:
        out.append(Statement(m.key, material, f"lambda F: hf.materials.muscle(F, fibres, {activation}, {params})"))
    return out


# -- the plan ----------------------------------------------------------------------------------------
def _quadrature_degree(case: Case) -> str:
    """Source of the volume rule's degree: the case's, else the default for the mesh's cell type."""
    p = case.problem
    if p.quadrature_degree is not None:
        return literal(p.quadrature_degree)
    degree = p.degree or (2 if case.mixed else 1)
    return call("default_quadrature_degree", literal(degree), "domain.mesh.topology.cell_type")


def _plain(spec: object) -> object:
    if dataclasses.is_dataclass(spec):
        return dataclasses.asdict(spec)
    if isinstance(spec, tuple):
        return [_plain(item) for item in spec]
    return spec


def model_hash(case: Case) -> str:
    """SHA-256 of the model sections (mesh, problem, materials, fibres, bcs, loads): what a restart must match.

    Stepping, solver and output may change between a run and its restart (e.g. a later ``t_end``).
    """
    model = [case.mesh, case.problem, case.materials, case.fibres, case.bcs, case.loads]
    text = json.dumps(_plain(tuple(model)), sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def checkpoint_folder(case: Case) -> Path:
    """Where the run writes its checkpoints (and ``--restart`` looks by default)."""
    return case.output.directory / f"{case.name}.checkpoint"


def must_hit_times(case: Case) -> list[float]:
    """Must-hit times of a dynamic run: given ones, profile kinks and VTX output times in (0, t_end)."""
    st = case.stepping
    t_end = float(st.options["t_end"])
    profiles = [bc.profile for bc in case.bcs] + [ld.profile for ld in case.loads]
    profiles += [m.activation for m in case.materials if isinstance(m.activation, Profile)]
    times = set(st.options.get("must_hit", ()))
    times |= {t for p in profiles if p is not None for t in p.kinks}
    times |= set(case.output.times or ())
    return sorted(t for t in times if 0.0 < t <= t_end)


def _output_directory(case: Case) -> Statement:
    return Statement(
        "output.directory",
        "out",
        call("ensure_output_dir", literal(case.output.directory), "comm"),
        imports=("from pathlib import Path", "from hyperfem.io import ensure_output_dir"),
    )


def _case_folder(case: Case) -> Path:
    """The case file's folder (absolute): its relative paths start there."""
    return case.source.expanduser().resolve().parent


def _case_relative(case: Case, path: Path) -> str | None:
    """``path`` relative to the case file's folder (``../meshes/beam_h1.msh``), or ``None`` if it lies far off.

    Files in the case's folder, or beside it (one ``..``), are printed relative to it so that
    the script shows the path as the case file gives it; others keep their absolute path.
    """
    relative = os.path.relpath(Path(path).resolve(), _case_folder(case))
    parts = Path(relative).parts
    ups = len(parts) - len([p for p in parts if p != ".."])
    return relative if ups <= 1 and not Path(relative).is_absolute() else None


def _path_expression(case: Case, path: Path) -> str:
    """Source of a file path: ``case_dir / 'rel'`` when :func:`_case_relative` allows, else the absolute path."""
    relative = _case_relative(case, path)
    return literal(str(path)) if relative is None else f"case_dir / {literal(Path(relative).as_posix())}"


def _uses_case_dir(case: Case) -> bool:
    files = [case.mesh.file]
    if case.fibres is not None and case.fibres.type not in ("laplace", "constant"):
        files.append(_fibre_file(case))
    return any(f is not None and _case_relative(case, f) is not None for f in files)


def _case_dir(case: Case) -> Statement:
    return Statement(
        "mesh.file",
        "case_dir",
        literal(_case_folder(case)),
        imports=("from pathlib import Path",),
        comment=f"the folder of {_docstring_text(str(case.source))}: the paths of the case file are relative to it",
    )


def _mesh(case: Case) -> Statement:
    mesh = case.mesh
    if mesh.file is not None:
        return Statement("mesh.file", "domain", call("hf.read_mesh", _path_expression(case, mesh.file), "comm"))
    kwargs = {}
    if mesh.size is not None:
        kwargs["h"] = literal(mesh.size)
    if mesh.geometry:
        kwargs["geometry"] = call("hf.mesh.FusiformGeometry", **_kwargs(mesh.geometry))
    if mesh.order is not None:
        kwargs["order"] = literal(mesh.order)
    maker = "hf.beam_mesh" if mesh.generator == "beam" else "hf.mesh.fusiform_mesh"
    return Statement("mesh.generator", "domain", call(maker, **kwargs, comm="comm"))


def _fibres(case: Case) -> list[Statement]:
    f = case.fibres
    if f is None:
        return []
    rep = {"representation": literal(f.representation)} if f.representation != "DG0" else {}
    if f.representation == "quadrature":
        rep["quadrature_degree"] = _quadrature_degree(case)
    if f.type == "laplace":
        expr = call("laplace_fibres", "domain", literal(f.options["source"]), literal(f.options["target"]), **rep)
    elif f.type == "constant":
        expr = call("constant_fibres", "domain.mesh", literal(f.options["direction"]), **rep)
    else:
        extra = {"location": literal(f.options["location"])} if "location" in f.options else {}
        path = _path_expression(case, _fibre_file(case))
        expr = call("fibres_from_file", "domain", path, literal(f.options["name"]), **extra)
    function = expr.split("(")[0]
    imports = (f"from hyperfem.fibres import {function}",)
    if "default_quadrature_degree(" in expr:
        imports += ("from hyperfem.problem.hyperelastic import default_quadrature_degree",)
    return [Statement("fibres", "fibres", expr, imports=imports)]


def _fibre_file(case: Case) -> Path:
    """The fibre file of ``[fibres] file`` (absolute)."""
    path = Path(case.fibres.options["file"]).expanduser()
    return path if path.is_absolute() else (case.source.parent / path).resolve()


@dataclass
class _Materials:
    statements: list[Statement]
    name: str  # the variable the problem takes: "material" or "materials"
    activations: list[str | None]  # per material: its Activation variable, or None


def _materials(case: Case) -> _Materials:
    several = len(case.materials) > 1
    statements: list[Statement] = []
    activations: list[str | None] = []
    for i, m in enumerate(case.materials):
        suffix = f"_{i}" if several else ""
        if isinstance(m.activation, Profile):
            variable = f"activation{suffix}"
            value = _profile(m.activation, explicit=True)
            statements.append(
                Statement(
                    f"{m.key}.activation",
                    variable,
                    call("Activation", "domain.mesh", f"value={value}", f"name={literal(m.key + ' activation')}"),
                    imports=(LOADING.format("Activation"), *_profile_imports(m.activation, explicit=True)),
                )
            )
            activations.append(variable)
            alpha = f"{variable}.expr"
        else:
            activations.append(None)
            alpha = literal(float(m.activation or 0.0))
        statements.extend(_material(m, suffix, case, alpha))
    if not several:
        return _Materials(statements, "material", activations)
    regions = ", ".join(f"{literal(m.region)}: material_{i}" for i, m in enumerate(case.materials))
    statements.append(Statement("material", "materials", "{" + regions + "}"))
    return _Materials(statements, "materials", activations)


def _conditions(case: Case) -> list[Statement]:
    bcs = [(bc.key, *_bc(bc)) for bc in case.bcs]
    loads = [(ld.key, *_load(ld)) for ld in case.loads]
    return [
        Statement("bc", "bcs", items=tuple((k, e) for k, e, _ in bcs), imports=sum((i for *_, i in bcs), ())),
        Statement("load", "loads", items=tuple((k, e) for k, e, _ in loads), imports=sum((i for *_, i in loads), ())),
    ]


SCHEMES = {
    "newmark": "dyn.Newmark",
    "backward_euler": "dyn.BackwardEuler",
    "generalized_alpha": "dyn.GeneralizedAlpha",
    "quasi_static": "dyn.QuasiStatic",
}


def _problem(case: Case, materials: _Materials) -> list[Statement]:
    """The problem of the body; for a dynamic run ``base`` and its time step ``problem``."""
    st = case.stepping
    kwargs = {"bcs": "bcs", "loads": "loads"}
    for name in ("degree", "pressure_degree", "quadrature_degree"):
        if getattr(case.problem, name) is not None:
            kwargs[name] = literal(getattr(case.problem, name))
    updaters = [a for a in materials.activations if a is not None]
    if updaters:
        kwargs["updaters"] = "[" + ", ".join(updaters) + "]"
    target = "base" if st.dynamic else "problem"
    if case.mixed:
        body = Statement(
            "problem",
            target,
            call("MixedHyperelasticProblem", "domain", materials.name, **kwargs),
            imports=("from hyperfem.problem import MixedHyperelasticProblem",),
        )
    else:
        body = Statement("problem", target, call("hf.HyperelasticProblem", "domain", materials.name, **kwargs))
    if not st.dynamic:
        return [body]
    args = ["base", call(SCHEMES[st.scheme], **_kwargs(st.scheme_options))]
    if st.scheme != "quasi_static":
        if len(case.materials) == 1:
            rho = literal(case.materials[0].density)
        else:
            rho = literal({m.region: m.density for m in case.materials})
        args.append(call("dyn.MassDensity", rho, **({"lumped": "True"} if st.lumped_mass else {})))
        if st.damping:
            args.append(call("dyn.RayleighDamping", **_kwargs(st.damping)))
    imports = ("from hyperfem import dynamics as dyn",)
    step = Statement("stepping.scheme", "problem", call("dyn.IncrementalProblem", *args), imports=imports)
    return [body, step]


def _solver(case: Case) -> list[Statement]:
    st = case.stepping
    args = ["problem"]
    if case.solver.petsc_options:
        args.append(literal(case.solver.petsc_options))
    out = [Statement("solver", "solver", call("hf.NewtonSolver", *args, **_kwargs(case.solver.options)))]
    if st.dynamic and st.initial_acceleration and st.scheme != "quasi_static":
        out.append(Statement("stepping.initial_acceleration", None, "problem.initial_acceleration()"))
    return out


def _stepping(case: Case) -> Statement:
    st = case.stepping
    if st.dynamic:
        options = dict(st.options)
        hits = must_hit_times(case)
        if hits:
            options["must_hit"] = tuple(hits)
        return Statement("stepping", "stepping", call("dyn.TimeStepping", **_kwargs(options)))
    stepping = call("hf.LoadStepping", **_kwargs(st.options))
    if st.end is not None:
        stepping = f"{stepping}.policy(end={literal(st.end)})"
    return Statement("stepping", "stepping", stepping)


def _outputs(case: Case, materials: _Materials) -> Statement:
    o, name = case.output, case.name
    items: list[tuple[str, str]] = []
    if o.probes:
        items.append(("output.probes", call("Probe", literal(o.probes))))
    if o.reactions is None:
        items.append(("output.reactions", "Reactions()"))
    elif o.reactions:
        items.append(("output.reactions", call("Reactions", literal(o.reactions))))
    if case.dynamic:
        items.append(("stepping.type", "Recorder(dyn.Diagnostics(problem))"))
    if o.csv:
        items.append(("output.csv", call("CSVLog", f"out / {literal(name + '.csv')}")))
    if o.summary:
        kw = {"rows": "False"} if o.csv else {}  # the rows are in the CSV
        items.append(("output.summary", call("JSONSummary", f"out / {literal(name + '.json')}", **kw)))
    if o.convergence:
        items.append(("output.convergence", call("ConvergenceLog", f"out / {literal(name + '_convergence.jsonl')}")))
    if o.fields:
        kw = {}
        if {"cauchy_stress", "von_mises"} & set(o.fields):
            kw["materials"] = materials.name
        kw["fields"] = literal(o.fields)
        if "fibre_stretch" in o.fields:
            kw["fibres"] = "fibres"
        if "activation" in o.fields:
            active = [(m, a) for m, a in zip(case.materials, materials.activations) if a is not None]
            if len(active) == 1 and active[0][0].region is None:
                kw["activation"] = active[0][1]
            else:
                kw["activation"] = "{" + ", ".join(f"{literal(m.region)}: {a}" for m, a in active) + "}"
        if o.format != "vtx":
            kw["format"] = literal(o.format)
        if o.times is not None:
            kw["times"] = literal(o.times)
        kw["name"] = literal(name)
        items.append(("output.fields", call("FieldOutput", "out", **kw)))
    if o.checkpoint_every is not None:
        kw = {"every": literal(o.checkpoint_every)}
        if o.checkpoint_keep is not None:
            kw["keep"] = literal(o.checkpoint_keep)
        items.append(("output.checkpoint_every", call("Checkpoint", f"out / {literal(name + '.checkpoint')}", **kw)))
    imports = []
    if o.progress:
        items.append(("output.progress", "Progress(progress_line)"))
        imports.append("from hyperfem.app.report import progress_line")
    if o.render is not None:
        items.append(("output.render", _render(case, materials, o.render)))
    classes = sorted({expr.split("(")[0] for _, expr in items})
    if classes:
        imports.append(SIMULATION.format(", ".join(classes)))
    return Statement("output", "outputs", items=tuple(items), imports=tuple(imports))


def _render(case: Case, materials: _Materials, render) -> str:
    """``Render(out / 'name.png', scalars=..., <what the field needs>, <the other options as given>)``."""
    options = dict(render.options)
    kw = {}
    if "scalars" in options:
        kw["scalars"] = literal(options.pop("scalars"))
    scalars = render.scalars
    if scalars == "von_mises":
        kw["materials"] = materials.name
    elif scalars == "fibre_stretch":
        kw["fibres"] = "fibres"
    elif scalars == "activation":
        active = [(m, a) for m, a in zip(case.materials, materials.activations, strict=True) if a is not None]
        if len(active) == 1 and active[0][0].region is None:
            kw["activation"] = active[0][1]
        else:
            kw["activation"] = "{" + ", ".join(f"{literal(m.region)}: {a}" for m, a in active) + "}"
    kw.update(_kwargs(options))
    return call("Render", f"out / {literal(case.name + '.png')}", **kw)


def _simulation(case: Case) -> Statement:
    kwargs = {
        "name": literal(case.name),
        "info": literal({"case": str(case.source)}),
        "case": literal({"model": model_hash(case)}),
    }
    if case.stepping.solve_initial:
        kwargs["solve_initial"] = "True"
    return Statement(
        "simulation",
        "simulation",
        call("Simulation", "problem", "solver", "stepping", "outputs", **kwargs),
        imports=(SIMULATION.format("Simulation"),),
        comment="case: a hash of the model sections of the case file; a restart must match it",
    )


def plan(case: Case) -> list[Statement]:
    """The statements that build the run of ``case``, in order; the last one assigns ``simulation``.

    Output folder, mesh, fibres, activations and materials, conditions and
    loads, the problem (and its time step), solver, stepping, outputs, the simulation.
    """
    materials = _materials(case)
    return [
        *([_case_dir(case)] if _uses_case_dir(case) else []),
        _output_directory(case),
        _mesh(case),
        *_fibres(case),
        *materials.statements,
        *_conditions(case),
        *_problem(case, materials),
        *_solver(case),
        _stepping(case),
        _outputs(case, materials),
        _simulation(case),
    ]


# -- imports and the script -----------------------------------------------------------------------------
BASE_IMPORTS = ("from mpi4py import MPI", "import hyperfem as hf")


def imports(statements: Sequence[Statement]) -> list[str]:
    """The import lines of ``statements`` (``from m import a`` lines of one module merged), in order."""
    lines = [*BASE_IMPORTS, *(i for s in statements for i in s.imports)]
    plain: list[str] = []
    names: dict[str, list[str]] = {}
    for line in lines:
        if line.startswith("from ") and " import " in line and " as " not in line:
            module, _, items = line[5:].partition(" import ")
            bucket = names.setdefault(module, [])
            for item in (s.strip() for s in items.split(",")):
                if item not in bucket:
                    bucket.append(item)
        elif line not in plain:
            plain.append(line)
    merged = [f"from {m} import {', '.join(sorted(items, key=_order))}" for m, items in names.items()]
    return list(dict.fromkeys([*plain, *merged]))


def _order(name: str) -> tuple[int, str]:
    """isort's order by type: CONSTANTS, Classes, functions."""
    kind = 0 if name.isupper() and len(name) > 1 else (1 if name[:1].isupper() else 2)
    return kind, name


def _sorted_imports(lines: list[str]) -> list[str]:
    def group(line: str) -> int:
        if line.startswith(("from pathlib", "import math")):
            return 0
        if "mpi4py" in line:
            return 1
        return 2

    def key(line: str) -> tuple[int, str]:
        return (0, line) if line.startswith("import ") else (1, line.split(" import ")[0])

    blocks = [sorted((ln for ln in lines if group(ln) == g), key=key) for g in range(3)]
    return ["\n".join(b) for b in blocks if b]


FOOTER = """    summary = simulation.run({restart})
    if comm.rank == 0:
        print(format_summary(summary), flush=True)
    return summary


if __name__ == "__main__":
    from hyperfem.cli import run

    run(main)
"""


def _docstring_text(text: str) -> str:
    """``text`` safe inside a triple-quoted docstring (no backslashes, no closing quotes)."""
    return text.replace("\\", "/").replace('"' * 3, "'" * 3)


def script(case: Case, restart: str | Path | None = None) -> str:
    """A runnable script that builds and runs ``case`` exactly as ``hyperfem run`` does.

    Args:
        case: The case.
        restart: The checkpoint ``hyperfem run --restart`` continues from, if any.
    """
    statements = plan(case)
    lines = imports(statements) + [SIMULATION.format("format_summary")]
    header = "\n\n".join(_sorted_imports(imports([Statement("", None, "", imports=tuple(lines))])))
    what = _docstring_text(case.description or f"the run {case.name!r}")
    doc = (
        f'"""{case.name}: {what}\n\n'
        f"The Python equivalent of {_docstring_text(str(case.source))} (``hyperfem run --print-python``):\n"
        "running it (``python this.py`` or ``mpiexec -n 2 python this.py``) builds the same\n"
        'objects as ``hyperfem run`` and gives the same result.\n"""\n'
    )
    body = "\n".join(s.source("    ") for s in statements)
    footer = FOOTER.replace("{restart}", "" if restart is None else f"restart={literal(Path(restart))}")
    return f"{doc}\n{header}\n\n\ndef main() -> dict:\n    comm = MPI.COMM_WORLD\n{body}\n{footer}"
