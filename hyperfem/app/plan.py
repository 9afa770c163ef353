"""A case as a plan of calls: the objects ``hyperfem run`` builds, in order, as data.

:func:`plan` turns a checked :class:`~hyperfem.app.spec.Case` into a list of
:class:`Statement` — one assignment per object, its value a
:class:`~hyperfem.app.calls.Call` of the library constructor itself
(``Call.of(Clamp, "clamped")``), tagged with the case key it comes from.
:func:`hyperfem.app.build.build` calls them (:func:`~hyperfem.app.calls.evaluate`);
:func:`hyperfem.app.script.script` prints the same statements as a runnable
program (``--print-python``). No source text is generated to be run: every
constructor is named here as a Python object, so a rename in the library fails
at import, and "go to definition" on a builder below lands on the class a
case-file key feeds (``[[bc]] type = "clamp"`` → :func:`_bc` → :class:`~hyperfem.Clamp`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hyperfem import dynamics as dyn
from hyperfem.app.calls import Attr, Call, Energy, Join, Ref
from hyperfem.app.report import progress_line
from hyperfem.app.spec import (
    LAME_LAWS,
    BCSpec,
    Case,
    ContactSpec,
    FibreSpec,
    LoadSpec,
    MaterialSpec,
    Profile,
    RenderSpec,
)
from hyperfem.contact import (
    ContactField,
    CylinderContact,
    PlaneContact,
    SphereContact,
    SurfaceContact,
    TieContact,
    ToolContact,
)
from hyperfem.fibres import constant_fibres, fibres_from_file, laplace_fibres
from hyperfem.io import ensure_output_dir
from hyperfem.loading import (
    Activation,
    AffineField,
    Ramp,
    RigidRotation,
    Scaled,
    Steady,
    Table,
    Waypoints,
    linear_profile,
    rotating_surface,
)
from hyperfem.materials import (
    ARAP,
    ArrudaBoyceParameters,
    CorotationalLinear,
    FixedCorotated,
    FungOrthotropicParameters,
    GentParameters,
    HolzapfelGasserOgdenParameters,
    LameParameters,
    MooneyRivlinParameters,
    MuscleParameters,
    OgdenParameters,
    PronySeries,
    ReducedPolynomialParameters,
    VerondaWestmannParameters,
    Viscoelastic,
    WeissParameters,
    YeohParameters,
    arruda_boyce,
    arruda_boyce_isochoric,
    fung_orthotropic,
    fung_orthotropic_isochoric,
    gent,
    gent_isochoric,
    hencky,
    holzapfel_gasser_ogden,
    holzapfel_gasser_ogden_isochoric,
    linear_elastic,
    muscle,
    muscle_isochoric,
    neo_hookean,
    ogden,
    ogden_isochoric,
    reduced_polynomial,
    reduced_polynomial_isochoric,
    robust_neo_hookean,
    saint_venant_kirchhoff,
    saint_venant_kirchhoff_principal,
    stable_neo_hookean,
    veronda_westmann,
    veronda_westmann_isochoric,
    weiss,
    weiss_isochoric,
    with_parameters,
    yeoh,
    yeoh_isochoric,
)
from hyperfem.materials.mooney_rivlin import mooney_rivlin, mooney_rivlin_isochoric
from hyperfem.materials.neo_hookean import neo_hookean_isochoric
from hyperfem.mesh import FusiformGeometry, beam_mesh, fusiform_mesh, read_mesh, spherical_shell_mesh
from hyperfem.problem import (
    BodyForce,
    Clamp,
    DeadTraction,
    FollowerPressure,
    FollowerTraction,
    HyperelasticProblem,
    MixedHyperelasticProblem,
    PrescribedDisplacement,
    SplitEnergy,
    default_quadrature_degree,
)
from hyperfem.simulation import (
    Checkpoint,
    ConvergenceLog,
    CSVLog,
    FieldOutput,
    JSONSummary,
    Probe,
    Progress,
    Reactions,
    Recorder,
    Render,
    Simulation,
    Stability,
)
from hyperfem.solver import ArcLength, LoadStepping, NewtonSolver
from hyperfem.stability.run import Buckling, BucklingRun

__all__ = ["Statement", "checkpoint_folder", "model_hash", "must_hit_times", "plan"]


@dataclass(frozen=True)
class Statement:
    """One statement of the run: ``target = value`` (or a call), or ``target = [items]``.

    Attributes:
        key: The case key it comes from (error messages name it).
        target: The variable it assigns, or ``None`` for a call made for its effect.
        value: The value (a node of :mod:`hyperfem.app.calls`), or ``None`` for a list.
        items: For a list: ``(key, node)`` per entry.
        comment: A comment printed above it.
    """

    key: str
    target: str | None
    value: object = None
    items: tuple[tuple[str, object], ...] | None = None
    comment: str = ""


# -- profiles, fields ---------------------------------------------------------------------------
def _profile(profile: Profile | None, explicit: bool = False) -> object:
    """A profile object; ``None`` for the library default (linear) unless ``explicit``."""
    if profile is None or profile.kind == "linear":
        return linear_profile if explicit else None
    if profile.kind == "steady":
        return Call.of(Steady, profile.args["value"])
    if profile.kind == "ramp":
        return Call.of(Ramp, **profile.args)
    return Call.of(Table, **profile.args)


def _vector_value(value: object) -> object:
    return Call.of(AffineField, **value) if isinstance(value, dict) else value


# -- entries --------------------------------------------------------------------------------------
def _bc(bc: BCSpec) -> Call:
    """``[[bc]]``: :class:`~hyperfem.Clamp`, :class:`~hyperfem.PrescribedDisplacement` or a rotating surface."""
    if bc.type == "clamp":
        return Call.of(Clamp, bc.boundary)
    if bc.type == "displacement":
        kwargs: dict[str, object] = {}
        if bc.components is not None:
            kwargs["components"] = bc.components
        profile = _profile(bc.profile)
        if profile is not None:
            kwargs["profile"] = profile
        return Call.of(PrescribedDisplacement, bc.boundary, bc.value, **kwargs)
    angle = Call.of(Scaled, _profile(bc.profile, explicit=True), bc.angle)
    args = [bc.boundary, bc.axis, angle] + ([bc.center] if bc.center is not None else [])
    return Call.of(rotating_surface, *args)


_LOAD_CLASSES = {
    "dead_traction": DeadTraction,
    "follower_traction": FollowerTraction,
    "pressure": FollowerPressure,
    "body_force": BodyForce,
}


def _load(load: LoadSpec) -> Call:
    """``[[load]]``: a traction, pressure or body force with its profile."""
    value = _vector_value(load.value) if load.type != "pressure" else load.value
    kwargs: dict[str, object] = {}
    if load.type == "body_force" and load.region is not None:
        kwargs["region"] = load.region
    profile = _profile(load.profile)
    if profile is not None:
        kwargs["profile"] = profile
    args = [value] if load.type == "body_force" else [load.boundary, value]
    return Call.of(_LOAD_CLASSES[load.type], *args, **kwargs)


def _lame(m: MaterialSpec) -> tuple[Call, str]:
    """The :class:`~hyperfem.materials.LameParameters` of an isotropic law, and a comment."""
    p = m.parameters
    if "E" in p:
        return Call.of(LameParameters.from_youngs, E=p["E"], nu=p["nu"]), ""
    if "lambda" in p:
        return Call.of(LameParameters, mu=p["mu"], lmbda=p["lambda"]), ""
    lmbda = p["bulk_modulus"] - 2.0 * p["mu"] / 3.0
    comment = f"lambda = bulk_modulus - 2 mu / 3 = {p['bulk_modulus']!r} - 2 * {p['mu']!r} / 3"
    return Call.of(LameParameters, mu=p["mu"], lmbda=lmbda), comment


_ENERGIES = {
    "neo_hookean": neo_hookean,
    "robust_neo_hookean": robust_neo_hookean,
    "saint_venant_kirchhoff": saint_venant_kirchhoff,
    "linear_elastic": linear_elastic,
    "stable_neo_hookean": stable_neo_hookean,
    "hencky": hencky,
    "saint_venant_kirchhoff_principal": saint_venant_kirchhoff_principal,
}
"""The energy ψ(F, params) of each isotropic law without a polar rotation."""

_ROTATION_LAWS = {"fixed_corotated": FixedCorotated, "corotational_linear": CorotationalLinear, "arap": ARAP}


def _lame_material(m: MaterialSpec, params: str, material: str, split: bool) -> list[Statement]:
    """``params`` and ``material`` of an isotropic law (:data:`~hyperfem.app.spec.LAME_LAWS`);
    ``split``: its :class:`~hyperfem.problem.SplitEnergy` (mixed or viscoelastic; neo_hookean only)."""
    if m.law == "arap" and set(m.parameters) == {"mu"}:
        return [Statement(m.key, material, Call.of(ARAP, m.parameters["mu"]))]
    lame, comment = _lame(m)
    out = [Statement(m.key, params, lame, comment=comment)]
    if split:  # neo_hookean: mu/2 (I1bar - 3) + U(theta)
        K = m.parameters["bulk_modulus"] if "bulk_modulus" in m.parameters else Attr(Ref(params), "bulk_modulus")
        iso = Energy(neo_hookean_isochoric, (Attr(Ref(params), "mu"),))
        args = [iso, K] + ([m.volumetric] if m.volumetric else [])
        out.append(Statement(m.key, material, Call.of(SplitEnergy, *args)))
    elif m.law in _ROTATION_LAWS:
        out.append(Statement(m.key, material, Call.of(_ROTATION_LAWS[m.law], Ref(params))))
    else:
        out.append(Statement(m.key, material, Call.of(with_parameters, _ENERGIES[m.law], Ref(params))))
    return out


@dataclass(frozen=True)
class _Law:
    """A law whose case-file keys are the fields of its parameter class.

    Attributes:
        parameters: The parameter class (the keys are its keyword arguments).
        energy: ``psi(F, *directions, params)`` with its volumetric term.
        isochoric: Its isochoric part, same arguments (the ``SplitEnergy`` of ``formulation = "mixed"``).
        directions: The direction fields after ``F``: ``fibres`` (``[fibres]``), ``second_fibres``.
    """

    parameters: type
    energy: Callable
    isochoric: Callable
    directions: tuple[str, ...] = ()


_LAWS = {
    "yeoh": _Law(YeohParameters, yeoh, yeoh_isochoric),
    "reduced_polynomial": _Law(ReducedPolynomialParameters, reduced_polynomial, reduced_polynomial_isochoric),
    "gent": _Law(GentParameters, gent, gent_isochoric),
    "arruda_boyce": _Law(ArrudaBoyceParameters, arruda_boyce, arruda_boyce_isochoric),
    "veronda_westmann": _Law(VerondaWestmannParameters, veronda_westmann, veronda_westmann_isochoric),
    "holzapfel_gasser_ogden": _Law(
        HolzapfelGasserOgdenParameters,
        holzapfel_gasser_ogden,
        holzapfel_gasser_ogden_isochoric,
        ("fibres", "second_fibres"),
    ),
    "weiss": _Law(WeissParameters, weiss, weiss_isochoric, ("fibres",)),
    "fung_orthotropic": _Law(
        FungOrthotropicParameters, fung_orthotropic, fung_orthotropic_isochoric, ("fibres", "second_fibres")
    ),
}
"""The rubber and tissue laws (:data:`~hyperfem.app.spec.RUBBER_LAWS`, :data:`~hyperfem.app.spec.TISSUE_LAWS`)
but ``ogden``, whose coefficients may be written in another code's convention (:func:`_material`)."""


def _material(m: MaterialSpec, suffix: str, case: Case, activation: object) -> list[Statement]:
    """``params`` and ``material`` statements of one material; a viscoelastic one wraps its split law."""
    out = _elastic_material(m, suffix, case, activation)
    if m.viscoelastic is None:
        return out
    material, elastic = f"material{suffix}", f"elastic{suffix}"
    split = out.pop()  # the SplitEnergy, renamed
    out.append(Statement(split.key, elastic, split.value, comment=split.comment))
    visco = m.viscoelastic
    prony = Call.of(PronySeries, g=visco.g, tau=visco.tau)
    kwargs: dict[str, object] = {}
    if visco.time_scale is not None:
        kwargs["time_scale"] = visco.time_scale
    if suffix:  # names of its history fields and checkpoint entries
        kwargs["name"] = f"viscoelastic{suffix}"
    comment = ("the problem's time is in s" if visco.time_scale is None else
               f"{visco.time_scale!r} s per unit of the problem's time")
    value = Call.of(Viscoelastic, Ref(elastic), prony, **kwargs)
    out.append(Statement(f"{m.key}.viscoelastic", material, value, comment=comment))
    return out


def _elastic_material(m: MaterialSpec, suffix: str, case: Case, activation: object) -> list[Statement]:
    """``params`` and ``material`` statements of one elastic law (its SplitEnergy when mixed or viscoelastic)."""
    params, material = f"params{suffix}", f"material{suffix}"
    split_law = case.mixed or m.viscoelastic is not None
    if m.law in LAME_LAWS:
        return _lame_material(m, params, material, split_law)
    kwargs: dict[str, object] = dict(m.parameters)
    if m.volumetric:
        kwargs["volumetric"] = m.volumetric
    iso: Energy
    whole: Call | Energy
    if m.law in _LAWS:
        law = _LAWS[m.law]
        out = [Statement(m.key, params, Call.of(law.parameters, **kwargs))]
        bound = (*(Ref(d) for d in law.directions), Ref(params))
        iso = Energy(law.isochoric, bound)
        whole = Energy(law.energy, bound) if law.directions else Call.of(with_parameters, law.energy, Ref(params))
    elif m.law == "ogden":  # Ogden's mu_p as given, else FEBio's or Abaqus's coefficients converted
        if kwargs.get("convention", "ogden") == "ogden":
            kwargs.pop("convention", None)
            out = [Statement(m.key, params, Call.of(OgdenParameters, **kwargs))]
        else:
            out = [Statement(m.key, params, Call.of(OgdenParameters.from_convention, **kwargs))]
        iso = Energy(ogden_isochoric, (Attr(Ref(params), "mu"), Attr(Ref(params), "alpha")))
        whole = Call.of(with_parameters, ogden, Ref(params))
    elif m.law == "mooney_rivlin":
        out = [Statement(m.key, params, Call.of(MooneyRivlinParameters, **kwargs))]
        iso = Energy(mooney_rivlin_isochoric, (Attr(Ref(params), "c1"), Attr(Ref(params), "c2")))
        whole = Call.of(with_parameters, mooney_rivlin, Ref(params))
    else:  # muscle
        maker = getattr(MuscleParameters, m.preset) if m.preset else MuscleParameters
        out = [Statement(m.key, params, Call.of(maker, **kwargs))]
        iso = Energy(muscle_isochoric, (Ref("fibres"), activation, Ref(params)))
        whole = Energy(muscle, (Ref("fibres"), activation, Ref(params)))
    if split_law:
        # (Ogden: its known shear modulus spares compiling its tangent at F = I for the Schur preconditioner)
        known = {"shear_modulus": Attr(Ref(params), "shear_modulus")} if m.law == "ogden" else {}
        split = Call.of(SplitEnergy, iso, Attr(Ref(params), "K"), Attr(Ref(params), "volumetric"), **known)
        out.append(Statement(m.key, material, split))
    else:
        out.append(Statement(m.key, material, whole))
    return out


# -- the plan ----------------------------------------------------------------------------------------
def _quadrature_degree(case: Case) -> object:
    """The volume rule's degree: the case's, else the default for the mesh's cell type."""
    p = case.problem
    if p.quadrature_degree is not None:
        return p.quadrature_degree
    degree = p.degree or (2 if case.mixed else 1)
    cell_type = Attr(Attr(Attr(Ref("domain"), "mesh"), "topology"), "cell_type")
    return Call.of(default_quadrature_degree, degree, cell_type)


def _plain(spec: object) -> object:
    if dataclasses.is_dataclass(spec) and not isinstance(spec, type):
        return dataclasses.asdict(spec)
    if isinstance(spec, tuple):
        return [_plain(item) for item in spec]
    return spec


def model_hash(case: Case) -> str:
    """SHA-256 of the model sections (mesh, problem, materials, fibres, bcs, loads, contacts): a restart must match it.

    Stepping, solver and output may change between a run and its restart (e.g. a later ``t_end``).
    """
    # (an elastic material keeps the hash it had before viscoelasticity existed)
    materials = [{k: v for k, v in dataclasses.asdict(m).items() if k != "viscoelastic" or v is not None}
                 for m in case.materials]
    model: list[object] = [case.mesh, case.problem, materials, case.fibres, case.bcs, case.loads]
    if case.contacts:  # (cases without contact keep the hash they had before contact existed)
        # (and contacts without a path or rotation the hash they had before those existed)
        model.append([{k: v for k, v in dataclasses.asdict(c).items() if k not in ("path", "rotation") or v is not None}
                      for c in case.contacts])
    if case.second_fibres is not None:  # (likewise the cases without a second direction)
        model.append(case.second_fibres)
    text = json.dumps(_plain(tuple(model)), sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def checkpoint_folder(case: Case) -> Path:
    """Where the run writes its checkpoints (and ``--restart`` looks by default)."""
    return case.output.directory / f"{case.name}.checkpoint"


def must_hit_times(case: Case) -> list[float]:
    """Must-hit times of a dynamic run: given ones, profile kinks and VTX output times in (0, t_end)."""
    st = case.stepping
    t_end = float(st.options["t_end"])
    profiles: list[Profile | Waypoints | None] = [bc.profile for bc in case.bcs]
    profiles += [ld.profile for ld in case.loads]
    profiles += [m.activation for m in case.materials if isinstance(m.activation, Profile)]
    profiles += [c.profile for c in case.contacts] + [c.path for c in case.contacts]
    profiles += [c.rotation.profile for c in case.contacts if c.rotation is not None]
    times = set(st.options.get("must_hit", ()))
    times |= {t for p in profiles if p is not None for t in p.kinks}
    times |= set(case.output.times or ())
    return sorted(t for t in times if 0.0 < t <= t_end)


def _output_directory(case: Case) -> Statement:
    return Statement("output.directory", "out", Call.of(ensure_output_dir, Path(case.output.directory), Ref("comm")))


def case_folder(case: Case) -> Path:
    """The case file's folder (absolute): its relative paths start there."""
    return case.source.expanduser().resolve().parent


def _case_relative(case: Case, path: Path) -> str | None:
    """``path`` relative to the case file's folder (``../meshes/beam_h1.msh``), or ``None`` if it lies far off.

    Files in the case's folder, or beside it (one ``..``), are written relative to it so that
    the script shows the path as the case file gives it; others keep their absolute path.
    """
    relative = os.path.relpath(Path(path).resolve(), case_folder(case))
    parts = Path(relative).parts
    ups = len(parts) - len([p for p in parts if p != ".."])
    return relative if ups <= 1 and not Path(relative).is_absolute() else None


def _path(case: Case, path: Path) -> object:
    """A file path: ``case_dir / 'rel'`` when :func:`_case_relative` allows, else the absolute path as text."""
    relative = _case_relative(case, path)
    return str(path) if relative is None else Join(Ref("case_dir"), Path(relative).as_posix())


def _uses_case_dir(case: Case) -> bool:
    files = [case.mesh.file]
    for fibres in (case.fibres, case.second_fibres):
        if fibres is not None and fibres.type not in ("laplace", "constant"):
            files.append(_fibre_file(case, fibres))
    files += [c.file for c in case.contacts if c.file is not None]
    return any(f is not None and _case_relative(case, f) is not None for f in files)


def _case_dir(case: Case) -> Statement:
    return Statement(
        "mesh.file",
        "case_dir",
        case_folder(case),
        comment=f"the folder of {case.source}: the paths of the case file are relative to it",
    )


def _mesh(case: Case) -> Statement:
    """``[mesh]``: :func:`~hyperfem.read_mesh` of the file, or a generator."""
    mesh = case.mesh
    if mesh.file is not None:
        return Statement("mesh.file", "domain", Call.of(read_mesh, _path(case, mesh.file), Ref("comm")))
    kwargs: dict[str, object] = {}
    if mesh.size is not None:
        kwargs["h"] = mesh.size
    if mesh.generator == "spherical_shell":
        kwargs.update({{"inner_radius": "inner", "outer_radius": "outer"}[k]: v for k, v in mesh.geometry.items()})
    elif mesh.geometry:
        kwargs["geometry"] = Call.of(FusiformGeometry, **mesh.geometry)
    if mesh.order is not None:
        kwargs["order"] = mesh.order
    makers = {"beam": beam_mesh, "fusiform": fusiform_mesh, "spherical_shell": spherical_shell_mesh}
    maker = makers[str(mesh.generator)]  # a generator when there is no file
    return Statement("mesh.generator", "domain", Call.of(maker, **kwargs, comm=Ref("comm")))


def _fibres(case: Case) -> list[Statement]:
    """``[fibres]`` and ``[second_fibres]``: Laplace, constant or from a file."""
    out = []
    for name, f in (("fibres", case.fibres), ("second_fibres", case.second_fibres)):
        if f is None:
            continue
        rep: dict[str, object] = {"representation": f.representation} if f.representation != "DG0" else {}
        if f.representation == "quadrature":
            rep["quadrature_degree"] = _quadrature_degree(case)
        if f.type == "laplace":
            value = Call.of(laplace_fibres, Ref("domain"), f.options["source"], f.options["target"], **rep)
        elif f.type == "constant":
            value = Call.of(constant_fibres, Attr(Ref("domain"), "mesh"), f.options["direction"], **rep)
        else:
            extra = {"location": f.options["location"]} if "location" in f.options else {}
            file = _path(case, _fibre_file(case, f))
            value = Call.of(fibres_from_file, Ref("domain"), file, f.options["name"], **extra)
        out.append(Statement(name, name, value))
    return out


def _fibre_file(case: Case, fibres: FibreSpec | None = None) -> Path:
    """The fibre file of ``[fibres] file`` (or of ``fibres``: ``[second_fibres]``), absolute."""
    spec = case.fibres if fibres is None else fibres
    assert spec is not None
    path = Path(spec.options["file"]).expanduser()
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
        alpha: object
        if isinstance(m.activation, Profile):
            variable = f"activation{suffix}"
            value = _profile(m.activation, explicit=True)
            activation = Call.of(Activation, Attr(Ref("domain"), "mesh"), value=value, name=f"{m.key} activation")
            statements.append(Statement(f"{m.key}.activation", variable, activation))
            activations.append(variable)
            alpha = Attr(Ref(variable), "expr")
        else:
            activations.append(None)
            alpha = float(m.activation or 0.0)
        statements.extend(_material(m, suffix, case, alpha))
    if not several:
        return _Materials(statements, "material", activations)
    regions = {m.region: Ref(f"material_{i}") for i, m in enumerate(case.materials)}
    statements.append(Statement("material", "materials", regions))
    return _Materials(statements, "materials", activations)


def _conditions(case: Case) -> list[Statement]:
    return [
        Statement("bc", "bcs", items=tuple((bc.key, _bc(bc)) for bc in case.bcs)),
        Statement("load", "loads", items=tuple((ld.key, _load(ld)) for ld in case.loads)),
    ]


SCHEMES = {
    "newmark": dyn.Newmark,
    "backward_euler": dyn.BackwardEuler,
    "generalized_alpha": dyn.GeneralizedAlpha,
    "quasi_static": dyn.QuasiStatic,
}
"""The time integrator of each ``[stepping] scheme``."""


def _problem(case: Case, materials: _Materials) -> list[Statement]:
    """The problem of the body; for a dynamic run ``base`` and its time step ``problem``."""
    st = case.stepping
    kwargs: dict[str, object] = {"bcs": Ref("bcs"), "loads": Ref("loads")}
    for name in ("degree", "pressure_degree", "quadrature_degree"):
        if getattr(case.problem, name) is not None:
            kwargs[name] = getattr(case.problem, name)
    updaters = [Ref(a) for a in materials.activations if a is not None]
    if updaters:
        kwargs["updaters"] = updaters
    target = "base" if st.dynamic else "problem"
    kind = MixedHyperelasticProblem if case.mixed else HyperelasticProblem
    body = Statement("problem", target, Call.of(kind, Ref("domain"), Ref(materials.name), **kwargs))
    if not st.dynamic:
        return [body]
    args: list[object] = [Ref("base"), Call.of(SCHEMES[st.scheme], **st.scheme_options)]
    if st.scheme != "quasi_static":
        if len(case.materials) == 1:
            rho: object = case.materials[0].density
        else:
            rho = {m.region: m.density for m in case.materials}
        args.append(Call.of(dyn.MassDensity, rho, **({"lumped": True} if st.lumped_mass else {})))
        if st.damping:
            args.append(Call.of(dyn.RayleighDamping, **st.damping))
    return [body, Statement("stepping.scheme", "problem", Call.of(dyn.IncrementalProblem, *args))]


def _contact_names(case: Case) -> list[str]:
    """The variables of the bound contacts: ``contact``, or ``contact_0``, ``contact_1``, ..."""
    several = len(case.contacts) > 1
    return [f"contact_{i}" if several else "contact" for i in range(len(case.contacts))]


def _rotation(contact: ContactSpec) -> Call | None:
    """A rigid obstacle's ``rotation``: :class:`~hyperfem.loading.RigidRotation` by ``Scaled(profile, angle)``."""
    r = contact.rotation
    if r is None:
        return None
    return Call.of(RigidRotation, r.axis, Call.of(Scaled, _profile(r.profile, explicit=True), r.angle), r.center)


def _motion(contact: ContactSpec, kwargs: dict[str, object]) -> None:
    """A moving obstacle's or tool's ``motion``: the vector, or its ``path`` as :class:`~hyperfem.loading.Waypoints`."""
    if contact.motion is not None:
        kwargs["motion"] = contact.motion
    if contact.path is not None:
        kwargs["motion"] = Call.of(Waypoints, times=contact.path.times, points=contact.path.points)


def _surface_contact(case: Case, contact: ContactSpec, name: str) -> Call:
    """``[[contact]]`` of ``type = "self"`` or ``"pair"``: :class:`~hyperfem.contact.SurfaceContact`;
    ``"tool"``: :class:`~hyperfem.contact.ToolContact` (its file relative to the case file), bound to the problem."""
    assert contact.boundaries is not None
    tool = contact.type == "tool"
    kwargs: dict[str, object] = {}
    if tool:
        assert contact.file is not None
        kwargs["file"] = _path(case, contact.file)
        _motion(contact, kwargs)
        profile = _profile(contact.profile)
        if profile is not None:
            kwargs["profile"] = profile
        for key in ("offset", "scale"):
            if getattr(contact, key) is not None:
                kwargs[key] = getattr(contact, key)
        if contact.rotation is not None:
            kwargs["rotation"] = _rotation(contact)
    for key in ("dhat", "stiffness", "safety", "subdivision"):
        if getattr(contact, key) is not None:
            kwargs[key] = getattr(contact, key)
    if contact.friction > 0.0:
        kwargs["friction"] = contact.friction
        if contact.friction_epsilon is not None:
            kwargs["friction_epsilon"] = contact.friction_epsilon
    kind = ToolContact if tool else SurfaceContact
    if name != kind.name:  # the output columns: contact_force, contact_0_force, ... (the class's default: tool)
        kwargs["name"] = name
    return Call.of(Attr(Call.of(kind, list(contact.boundaries), **kwargs), "bind"), Ref("problem"))


def _contact(case: Case, contact: ContactSpec, name: str, several: bool) -> Call:
    """``[[contact]]``: :class:`~hyperfem.contact.PlaneContact` (``type = "plane"``) or
    :class:`~hyperfem.contact.SphereContact` (``"sphere"``) or :class:`~hyperfem.contact.CylinderContact`
    (``"cylinder"``) bound to the problem; the surface
    contacts (``"self"``, ``"pair"``, ``"tool"``): :func:`_surface_contact`."""
    if contact.type == "tie":
        assert contact.boundaries is not None
        tie: dict[str, object] = {k: getattr(contact, k) for k in ("stiffness", "tolerance") if getattr(contact, k)}
        tie["name"] = contact.name or name
        return Call.of(Attr(Call.of(TieContact, *contact.boundaries, **tie), "bind"), Ref("problem"))
    if contact.boundaries is not None:
        return _surface_contact(case, contact, contact.name or name)
    shapes: dict[str, tuple[type, dict[str, object]]] = {
        "sphere": (SphereContact, {"center": contact.center, "radius": contact.radius}),
        "cylinder": (CylinderContact, {"point": contact.point, "axis": contact.axis, "radius": contact.radius}),
        "plane": (PlaneContact, {"point": contact.point, "normal": contact.normal}),
    }
    obstacle, kwargs = shapes[contact.type]
    for key in ("dhat", "stiffness"):
        if getattr(contact, key) is not None:
            kwargs[key] = getattr(contact, key)
    _motion(contact, kwargs)
    if contact.friction > 0.0:
        kwargs["friction"] = contact.friction
        if contact.friction_epsilon is not None:
            kwargs["friction_epsilon"] = contact.friction_epsilon
    profile = _profile(contact.profile)
    if profile is not None:
        kwargs["profile"] = profile
    if contact.rotation is not None:
        kwargs["rotation"] = _rotation(contact)
    if several:
        kwargs["name"] = name  # the output columns: contact_0_force, ...
    return Call.of(Attr(Call.of(obstacle, contact.boundary, **kwargs), "bind"), Ref("problem"))


def _contacts(case: Case) -> list[Statement]:
    """The contacts of the body, each bound to the problem (an external energy of the solver)."""
    names = _contact_names(case)
    several = len(names) > 1
    return [Statement(c.key, n, _contact(case, c, n, several)) for c, n in zip(case.contacts, names, strict=True)]


def _solver(case: Case) -> list[Statement]:
    """``[solver]``: the :class:`~hyperfem.NewtonSolver` (and the initial acceleration of a dynamic run)."""
    st = case.stepping
    args: list[object] = [Ref("problem")]
    if case.solver.petsc_options:
        args.append(dict(case.solver.petsc_options))
    kwargs: dict[str, object] = dict(case.solver.options)
    if case.contacts:
        kwargs["external_energies"] = [Ref(n) for n in _contact_names(case)]
    out = [Statement("solver", "solver", Call.of(NewtonSolver, *args, **kwargs))]
    if st.dynamic and st.initial_acceleration and st.scheme != "quasi_static":
        # contact pushes a body that starts within reach of an obstacle from the start
        external = {"external": Attr(Attr(Ref("solver"), "external"), "gradient_array")} if case.contacts else {}
        start = Call.of(Attr(Ref("problem"), "initial_acceleration"), **external)
        out.append(Statement("stepping.initial_acceleration", None, start))
    return out


def _stepping(case: Case) -> Statement:
    """``[stepping]``: :class:`~hyperfem.dynamics.TimeStepping`, :class:`~hyperfem.LoadStepping` or
    :class:`~hyperfem.solver.ArcLength`."""
    st = case.stepping
    if st.dynamic:
        options = dict(st.options)
        hits = must_hit_times(case)
        if hits:
            options["must_hit"] = tuple(hits)
        return Statement("stepping", "stepping", Call.of(dyn.TimeStepping, **options))
    if st.continuation:
        return Statement("stepping", "stepping", Call.of(ArcLength, **st.options))
    if st.buckling:
        return Statement("stepping", "stepping", Call.of(Buckling, **st.options))
    stepping = Call.of(LoadStepping, **st.options)
    if st.end is not None:
        stepping = Call.of(Attr(stepping, "policy"), end=st.end)
    return Statement("stepping", "stepping", stepping)


def _activation_argument(case: Case, materials: _Materials) -> object:
    """The ``activation`` of a field output or render: one Activation, or one per region."""
    active = [(m, a) for m, a in zip(case.materials, materials.activations, strict=True) if a is not None]
    if len(active) == 1 and active[0][0].region is None:
        return Ref(active[0][1])
    return {m.region: Ref(a) for m, a in active}


def _field_output(case: Case, materials: _Materials) -> Call:
    o = case.output
    kw: dict[str, object] = {}
    if {"cauchy_stress", "von_mises"} & set(o.fields):
        kw["materials"] = Ref(materials.name)
    kw["fields"] = o.fields
    if "fibre_stretch" in o.fields:
        kw["fibres"] = Ref("fibres")
    if "activation" in o.fields:
        kw["activation"] = _activation_argument(case, materials)
    if o.format != "vtx":
        kw["format"] = o.format
    if o.times is not None:
        kw["times"] = o.times
    kw["name"] = case.name
    return Call.of(FieldOutput, Ref("out"), **kw)


def _outputs(case: Case, materials: _Materials) -> Statement:
    """``[output]``: the observers of the :class:`~hyperfem.simulation.Simulation`."""
    o, name, out = case.output, case.name, Ref("out")
    items: list[tuple[str, object]] = []
    if o.probes:
        items.append(("output.probes", Call.of(Probe, o.probes)))
    if o.stability:
        items.append(("output.stability", Call.of(Stability, o.stability)))
    if o.reactions is None:
        items.append(("output.reactions", Call.of(Reactions)))
    elif o.reactions:
        items.append(("output.reactions", Call.of(Reactions, o.reactions)))
    if case.dynamic:
        items.append(("stepping.type", Call.of(Recorder, Call.of(dyn.Diagnostics, Ref("problem")))))
    for contact, variable in zip(case.contacts, _contact_names(case), strict=True):
        items.append((contact.key, Call.of(Recorder, Ref(variable))))
    if o.csv:
        items.append(("output.csv", Call.of(CSVLog, Join(out, f"{name}.csv"))))
    if o.summary:
        kw: dict[str, object] = {"rows": False} if o.csv else {}  # the rows are in the CSV
        items.append(("output.summary", Call.of(JSONSummary, Join(out, f"{name}.json"), **kw)))
    if o.convergence:
        items.append(("output.convergence", Call.of(ConvergenceLog, Join(out, f"{name}_convergence.jsonl"))))
    if o.fields:
        items.append(("output.fields", _field_output(case, materials)))
        if case.contacts:  # the contacts' nodal forces and tractions beside the fields
            barriers = [Ref(variable) for variable in _contact_names(case)]
            items.append(("contact", Call.of(ContactField, Join(out, f"{name}_contact.bp"), barriers)))
    if o.checkpoint_every is not None:
        kw = {"every": o.checkpoint_every}
        if o.checkpoint_keep is not None:
            kw["keep"] = o.checkpoint_keep
        items.append(("output.checkpoint_every", Call.of(Checkpoint, Join(out, f"{name}.checkpoint"), **kw)))
    if o.progress:
        items.append(("output.progress", Call.of(Progress, progress_line)))
    if o.render is not None:
        items.append(("output.render", _render(case, materials, o.render)))
    return Statement("output", "outputs", items=tuple(items))


def _render(case: Case, materials: _Materials, render: RenderSpec) -> Call:
    """``Render(out / 'name.png', scalars=..., <what the field needs>, <the other options as given>)``."""
    options = dict(render.options)
    kw: dict[str, object] = {}
    if "scalars" in options:
        kw["scalars"] = options.pop("scalars")
    scalars = render.scalars
    if scalars == "von_mises":
        kw["materials"] = Ref(materials.name)
    elif scalars == "fibre_stretch":
        kw["fibres"] = Ref("fibres")
    elif scalars == "activation":
        kw["activation"] = _activation_argument(case, materials)
    kw.update(options)
    return Call.of(Render, Join(Ref("out"), f"{case.name}.png"), **kw)


def _simulation(case: Case) -> Statement:
    if case.stepping.buckling:  # no steps and no outputs: the critical load factors and the modes, written
        run = Call.of(BucklingRun, Ref("problem"), Ref("solver"), Ref("stepping"), Ref("out"), name=case.name)
        return Statement("simulation", "simulation", run, comment="a linearised buckling analysis")
    kwargs: dict[str, object] = {
        "name": case.name,
        "info": {"case": str(case.source)},
        "case": {"model": model_hash(case)},
    }
    if case.stepping.solve_initial:
        kwargs["solve_initial"] = True
    simulation = Call.of(Simulation, Ref("problem"), Ref("solver"), Ref("stepping"), Ref("outputs"), **kwargs)
    return Statement(
        "simulation",
        "simulation",
        simulation,
        comment="case: a hash of the model sections of the case file; a restart must match it",
    )


def plan(case: Case) -> list[Statement]:
    """The statements that build the run of ``case``, in order; the last one assigns ``simulation``.

    Case folder (when a path is relative to it), output folder, mesh, fibres, activations and
    materials, conditions and loads, the problem (and its time step), solver, stepping,
    outputs, the simulation.
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
        *_contacts(case),
        *_solver(case),
        _stepping(case),
        *([] if case.stepping.buckling else [_outputs(case, materials)]),
        _simulation(case),
    ]
