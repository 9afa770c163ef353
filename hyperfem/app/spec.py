"""The checked case: one frozen dataclass per section of a TOML case file.

:func:`hyperfem.app.casefile.load_case` returns a :class:`Case`; its sections
hold the values that were given (absent optional keys stay ``None`` or absent,
so the library's defaults apply), already checked.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hyperfem.loading.motion import Waypoints

__all__ = [
    "FIBRE_LAWS",
    "LAME_LAWS",
    "LAWS",
    "MIXED_LAWS",
    "RUBBER_LAWS",
    "SECOND_FIBRE_LAWS",
    "TISSUE_LAWS",
    "VISCOELASTIC_LAWS",
    "BCSpec",
    "ContactSpec",
    "ContactRotationSpec",
    "Case",
    "FibreSpec",
    "LoadSpec",
    "MaterialSpec",
    "MeshSpec",
    "OutputSpec",
    "RenderSpec",
    "ProblemSpec",
    "Profile",
    "SolverSpec",
    "SteppingSpec",
    "ViscoelasticSpec",
]

# -- laws ------------------------------------------------------------------------------
LAME_LAWS = (
    "neo_hookean",
    "robust_neo_hookean",
    "saint_venant_kirchhoff",
    "linear_elastic",
    "stable_neo_hookean",
    "fixed_corotated",
    "corotational_linear",
    "arap",
    "hencky",
    "saint_venant_kirchhoff_principal",
)
"""Isotropic laws with the elastic constants E/nu, mu/lambda or mu/bulk_modulus."""

RUBBER_LAWS = ("yeoh", "reduced_polynomial", "gent", "arruda_boyce", "veronda_westmann", "ogden")
"""Isotropic rubber laws with a bulk modulus ``K`` (issue 21): of the isochoric invariants, and Ogden's
of the distortional principal stretches."""

TISSUE_LAWS = ("holzapfel_gasser_ogden", "weiss", "fung_orthotropic")
"""Fibre-reinforced tissue laws with a bulk modulus ``K`` (issue 21)."""

LAWS = (*LAME_LAWS, "mooney_rivlin", "muscle", *RUBBER_LAWS, *TISSUE_LAWS)
"""Every ``law`` a ``[[material]]`` can name."""

MIXED_LAWS = ("neo_hookean", "mooney_rivlin", "muscle", *RUBBER_LAWS, *TISSUE_LAWS)
"""Laws with an isochoric/volumetric split, usable with ``formulation = "mixed"``."""

VISCOELASTIC_LAWS = ("neo_hookean", "mooney_rivlin", *RUBBER_LAWS, *TISSUE_LAWS)
"""Laws that take a ``[material.viscoelastic]`` Prony series: those with an isochoric/volumetric split
(:class:`~hyperfem.problem.SplitEnergy`, whose isochoric part relaxes), but ``muscle``, whose isochoric
part holds the active fibre stress (a Prony series would relax the activation too)."""

FIBRE_LAWS = ("muscle", *TISSUE_LAWS)
"""Laws that need the fibre directions of ``[fibres]``."""

SECOND_FIBRE_LAWS = ("holzapfel_gasser_ogden", "fung_orthotropic")
"""Laws that also need the second direction of ``[second_fibres]`` (HGO's second family, Fung's second axis)."""

FORMULATIONS = ("displacement", "mixed")
SCHEMES = ("newmark", "backward_euler", "generalized_alpha", "quasi_static")
FIBRE_TYPES = ("laplace", "constant", "file")
REPRESENTATIONS = ("DG0", "P1", "quadrature")
BC_TYPES = ("clamp", "displacement", "rotation")
CONTACT_TYPES = ("plane", "sphere", "cylinder", "self", "pair", "tool", "tie")
MESH_CONTACT_TYPES = ("self", "pair", "tool", "tie")
"""Contacts of boundary surfaces (triangles and edges) rather than of boundary nodes: ``boundaries``; 3D, and
self and pair also on 2D meshes of triangles or quadrilaterals (boundary segments)."""
LOAD_TYPES = ("dead_traction", "follower_traction", "pressure", "body_force")
PROFILE_TYPES = ("linear", "steady", "ramp", "table")
AXES = {"x": 0, "y": 1, "z": 2}



# -- the checked case ----------------------------------------------------------------------
@dataclass(frozen=True)
class Profile:
    """A time profile :math:`f(t)` (module docstring).

    Attributes:
        kind: ``"linear"``, ``"steady"``, ``"ramp"`` or ``"table"``.
        args: The given arguments (``value``; ``t1``, ``final``, ``initial``, ``t0``; ``times``, ``values``).
    """

    kind: str
    args: Mapping[str, Any] = field(default_factory=dict)

    @property
    def kinks(self) -> tuple[float, ...]:
        """Times where :math:`f` is not smooth: must-hit times of a dynamic run."""
        if self.kind == "ramp":
            return (float(self.args.get("t0", 0.0)), float(self.args["t1"]))
        if self.kind == "table":
            return tuple(self.args["times"])
        return ()


@dataclass(frozen=True)
class MeshSpec:
    """``[mesh]``: a file or a generator.

    Attributes:
        file: The gmsh file (absolute), or ``None``.
        generator: ``"beam"`` or ``"fusiform"``, or ``None``.
        size: Element size of the generator (``None``: its default).
        order: Geometric order of the generated tetrahedra.
        geometry: Fusiform dimensions (:class:`~hyperfem.mesh.FusiformGeometry` fields).
    """

    file: Path | None = None
    generator: str | None = None
    size: float | None = None
    order: int | None = None
    geometry: Mapping[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class ProblemSpec:
    """``[problem]``: formulation and discretisation (``None``: the library default)."""

    formulation: str = "displacement"
    degree: int | None = None
    pressure_degree: int | None = None
    quadrature_degree: int | None = None


@dataclass(frozen=True)
class ViscoelasticSpec:
    """``[material.viscoelastic]``: the Prony series of the isochoric part.

    Attributes:
        g: Relative moduli :math:`g_i` (:class:`~hyperfem.materials.PronySeries` ``g``).
        tau: Relaxation times :math:`\tau_i` in s, one per modulus.
        time_scale: Seconds per unit of the run's time (load factor or s), or ``None``: 1
            (:class:`~hyperfem.materials.Viscoelastic` ``time_scale``).
    """

    g: tuple[float, ...]
    tau: tuple[float, ...]
    time_scale: float | None = None


@dataclass(frozen=True)
class MaterialSpec:
    """One ``[[material]]``.

    Attributes:
        key: Key path (``"material[0]"``).
        law: One of :data:`LAWS`.
        region: Cell group, or ``None`` for the whole domain.
        parameters: The law's constants as given (``E``, ``nu``, ``c1``, ...); for the laws of
            :data:`RUBBER_LAWS` and :data:`TISSUE_LAWS` and ``mooney_rivlin`` the keyword arguments of
            their parameter class, ``volumetric`` aside (``ogden``: of ``OgdenParameters.from_convention``,
            ``convention`` included).
        density: Mass density, or ``None``.
        volumetric: Volumetric law name, or ``None`` (the law's default).
        preset: ``"muscle"``/``"tendon"`` parameter set of the muscle law, or ``None``.
        activation: Muscle activation: a number, a :class:`Profile`, or ``None`` (passive).
        viscoelastic: The Prony series of a viscoelastic material, or ``None`` (elastic).
    """

    key: str
    law: str
    region: str | None = None
    parameters: Mapping[str, Any] = field(default_factory=dict)
    density: float | None = None
    volumetric: str | None = None
    preset: str | None = None
    activation: float | Profile | None = None
    viscoelastic: ViscoelasticSpec | None = None


@dataclass(frozen=True)
class FibreSpec:
    """``[fibres]`` (or ``[second_fibres]``): how a unit direction field is made.

    Attributes:
        type: ``"laplace"``, ``"constant"`` or ``"file"``.
        options: The given keys of that type (``source``, ``target``; ``direction``; ``file``, ``name``, ``location``).
        representation: ``"DG0"``, ``"P1"`` or ``"quadrature"``.
    """

    type: str
    options: Mapping[str, Any] = field(default_factory=dict)
    representation: str = "DG0"


@dataclass(frozen=True)
class BCSpec:
    """One ``[[bc]]`` (the given keys of its type)."""

    key: str
    type: str
    boundary: str
    value: tuple[float, ...] | None = None
    components: tuple[int, ...] | None = None
    axis: tuple[float, ...] | None = None
    center: tuple[float, ...] | None = None
    angle: float | None = None
    profile: Profile | None = None

    @property
    def constrained(self) -> frozenset[int] | None:
        """Constrained components (``None``: all of them)."""
        return None if self.components is None else frozenset(self.components)


@dataclass(frozen=True)
class LoadSpec:
    """One ``[[load]]``.

    Attributes:
        key: Key path.
        type: One of :data:`LOAD_TYPES`.
        boundary: Facet group (tractions, pressure).
        region: Cell group of a body force (``None``: everywhere).
        value: A vector, a number (pressure), or ``{"matrix", "offset"}`` of an affine field.
        profile: The time profile, or ``None`` (linear).
    """

    key: str
    type: str
    boundary: str | None = None
    region: str | None = None
    value: tuple[float, ...] | float | Mapping[str, Any] | None = None
    profile: Profile | None = None


@dataclass(frozen=True)
class ContactRotationSpec:
    """A rigid obstacle's ``rotation = {axis, center, angle, profile}``: :class:`~hyperfem.loading.RigidRotation`
    about ``center`` by ``angle * profile(t)``, composed with the translation (:mod:`~hyperfem.contact.obstacles`).

    Attributes:
        axis: The rotation axis (non-zero).
        center: The pivot, a point of the axis in the obstacle's reference placement.
        angle: The angle in radians at profile 1.
        profile: Its time profile, or ``None`` (linear).
    """

    axis: tuple[float, ...]
    center: tuple[float, ...]
    angle: float
    profile: Profile | None = None


@dataclass(frozen=True)
class ContactSpec:
    """One ``[[contact]]``: a boundary that may touch an obstacle, itself or another body (intersection-free).

    Attributes:
        key: Key path (``"contact[0]"``).
        type: One of :data:`CONTACT_TYPES` (``"plane"``: :class:`~hyperfem.contact.PlaneContact`,
            ``"sphere"``: :class:`~hyperfem.contact.SphereContact`, ``"cylinder"``:
            :class:`~hyperfem.contact.CylinderContact`, ``"self"`` and ``"pair"``:
            :class:`~hyperfem.contact.SurfaceContact`, ``"tool"``: :class:`~hyperfem.contact.ToolContact`,
            ``"tie"``: :class:`~hyperfem.contact.TieContact`).
        boundary: Facet group whose nodes may touch (plane, sphere); ``None`` for the others.
        boundaries: Facet groups whose triangles may touch (self, pair, tool) or are glued (tie: the slave,
            then the master); ``None`` for plane and sphere.
        tolerance: A tie's largest reference distance between the glued groups, or ``None`` (the default).
        file: The tool's surface file (absolute); ``None`` but for a tool.
        offset: Translation applied once to the tool's points, or ``None``.
        scale: Factor applied once to the tool's points, or ``None`` (1).
        safety: The collision filter's safety factor, or ``None`` (the library default).
        name: Prefix of the output columns as given, or ``None`` (``contact``, or ``contact_0``, ... when
            there are several contacts).
        point: A point of the plane (at profile 0); ``None`` for a sphere.
        normal: The plane's normal, pointing to the body's side; ``None`` for a sphere.
        dhat: Barrier width, or ``None`` (the library default).
        stiffness: Barrier stiffness, or ``None`` (the library default).
        motion: Translation of the obstacle at profile 1, or ``None`` (it stays).
        profile: Time profile of the motion, or ``None`` (linear).
        path: A moving obstacle's or tool's translation through waypoints (instead of motion and profile), or ``None``.
        rotation: A sphere's, cylinder's or tool's rotation, composed with the translation, or ``None``.
        center: The sphere's centre (at profile 0); ``None`` for a plane.
        radius: The sphere's or cylinder's radius; ``None`` for a plane.
        axis: The cylinder's axis direction; ``None`` otherwise.
        friction: Coulomb coefficient (0: frictionless).
        friction_epsilon: Friction's slip length, or ``None`` (the library default).
        subdivision: A surface contact's collision proxy, or ``None`` (the library default).
    """

    key: str
    type: str
    boundary: str | None = None
    point: tuple[float, ...] | None = None
    normal: tuple[float, ...] | None = None
    dhat: float | None = None
    stiffness: float | None = None
    motion: tuple[float, ...] | None = None
    profile: Profile | None = None
    center: tuple[float, ...] | None = None
    radius: float | None = None
    friction: float = 0.0
    friction_epsilon: float | None = None
    boundaries: tuple[str, ...] | None = None
    file: Path | None = None
    offset: tuple[float, ...] | None = None
    scale: float | None = None
    safety: float | None = None
    name: str | None = None
    tolerance: float | None = None
    axis: tuple[float, ...] | None = None
    path: Waypoints | None = None
    rotation: ContactRotationSpec | None = None
    subdivision: int | None = None


@dataclass(frozen=True)
class SteppingSpec:
    """``[stepping]``.

    Attributes:
        type: ``"quasi-static"``, ``"dynamic"``, ``"arc_length"`` or ``"buckling"``.
        options: The given keyword arguments of :class:`~hyperfem.LoadStepping`,
            :class:`~hyperfem.dynamics.TimeStepping` or :class:`~hyperfem.solver.ArcLength`
            (case names translated).
        end: Final load factor of a quasi-static ramp (``None``: 1).
        solve_initial: Solve for equilibrium at the start (quasi-static).
        scheme: Time integrator (dynamic).
        scheme_options: ``beta``/``gamma`` (Newmark), ``rho_inf`` (generalized-alpha).
        lumped_mass: Lumped (vertex-rule) mass.
        damping: Rayleigh ``alpha``/``beta`` as given.
        initial_acceleration: Solve for the initial acceleration (dynamic).
    """

    type: str = "quasi-static"
    options: Mapping[str, Any] = field(default_factory=dict)
    end: float | None = None
    solve_initial: bool = False
    scheme: str = "newmark"
    scheme_options: Mapping[str, float] = field(default_factory=dict)
    lumped_mass: bool = False
    damping: Mapping[str, float] = field(default_factory=dict)
    initial_acceleration: bool = True

    @property
    def dynamic(self) -> bool:
        """Whether the run is a time integration."""
        return self.type == "dynamic"

    @property
    def continuation(self) -> bool:
        """Whether the run is an arc-length continuation."""
        return self.type == "arc_length"

    @property
    def buckling(self) -> bool:
        """Whether the run is a linearised buckling analysis."""
        return self.type == "buckling"


@dataclass(frozen=True)
class SolverSpec:
    """``[solver]``.

    Attributes:
        petsc_options: SNES/KSP options (sugar keys translated, ``petsc_options`` merged).
        options: Other :class:`~hyperfem.NewtonSolver` keyword arguments as given.
    """

    petsc_options: Mapping[str, object] = field(default_factory=dict)
    options: Mapping[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class RenderSpec:
    """``[output] render``: a :class:`~hyperfem.simulation.render.Render` of the final state (and every k steps).

    Attributes:
        options: The keyword arguments of ``Render`` that the case gives, in the order of
            :data:`hyperfem.app.sections.RENDER`
            (``undeformed = "none"`` as ``None``).
    """

    options: tuple[tuple[str, object], ...] = ()

    @property
    def scalars(self) -> str:
        """What colours the surface (default ``"displacement"``)."""
        return str(dict(self.options).get("scalars", "displacement"))


@dataclass(frozen=True)
class OutputSpec:
    """``[output]``.

    Attributes:
        directory: Output folder.
        fields: Fields of the ParaView time series (:data:`hyperfem.simulation.fields.FIELDS`); empty: none.
        format: ``"vtx"`` (ADIOS2) or ``"xdmf"``.
        times: Write field frames only at these times (``None``: every step).
        csv: One CSV line per step.
        summary: The JSON summary (rewritten after every step).
        convergence: The Newton residuals of every step (JSON lines).
        probes: Reference points whose displacement is recorded.
        reactions: Dirichlet boundaries whose reaction force and moment are recorded
            (``None``: every one; empty: none).
        checkpoint_every: Steps between checkpoints (``None``: no checkpoints).
        checkpoint_keep: Checkpoints kept.
        progress: Print a line per step (rank 0).
        render: Picture(s) of the deformed body (:class:`~hyperfem.simulation.render.Render`), or ``None``.
        stability: Lowest eigenvalues of the tangent per state (:class:`~hyperfem.simulation.Stability`); 0: off.
    """

    directory: Path
    fields: tuple[str, ...] = ("displacement",)
    format: str = "vtx"
    times: tuple[float, ...] | None = None
    csv: bool = True
    summary: bool = True
    convergence: bool = True
    probes: tuple[tuple[float, ...], ...] = ()
    reactions: tuple[str, ...] | None = None
    checkpoint_every: int | None = 10
    checkpoint_keep: int | None = None
    progress: bool = True
    render: RenderSpec | None = None
    stability: int = 0


@dataclass(frozen=True)
class Case:
    """A checked case file.

    Attributes:
        source: The case file.
        name: Name of the run (output files).
        description: Free text.
        mesh, problem, materials, fibres, bcs, loads, stepping, solver, output, contacts: The sections.
        second_fibres: ``[second_fibres]``, the second direction of :data:`SECOND_FIBRE_LAWS`, or ``None``.
    """

    source: Path
    name: str
    description: str
    mesh: MeshSpec
    problem: ProblemSpec
    materials: tuple[MaterialSpec, ...]
    fibres: FibreSpec | None
    bcs: tuple[BCSpec, ...]
    loads: tuple[LoadSpec, ...]
    stepping: SteppingSpec
    solver: SolverSpec
    output: OutputSpec
    contacts: tuple[ContactSpec, ...] = ()
    second_fibres: FibreSpec | None = None

    @property
    def dynamic(self) -> bool:
        """Whether the run is a time integration."""
        return self.stepping.dynamic

    @property
    def mixed(self) -> bool:
        """Whether the problem is the three-field (mixed) one."""
        return self.problem.formulation == "mixed"
