"""The sections of a case file: their declared keys and the checks that turn each into its spec.

One function per section (``mesh``, ``material``, ``bc``, ``load``, ``stepping``,
``solver``, ``output``, profiles): each checks its table with
:func:`~hyperfem.app.schema.check_table` against the keys declared here
(which depend on the entry's ``type`` or ``law``) and adds the checks that
involve several keys (elastic constants given as one pair, conflicting
conditions on one boundary, ...). :func:`hyperfem.app.casefile.check_case`
calls them in order.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from typing import Any
from pathlib import Path

from hyperfem.app.schema import CaseFileError, Key, check_table, check_value, describe, join, suggestion
from hyperfem.app.spec import (
    AXES,
    BC_TYPES,
    CONTACT_TYPES,
    FIBRE_LAWS,
    FIBRE_TYPES,
    FORMULATIONS,
    LAME_LAWS,
    MESH_CONTACT_TYPES,
    LAWS,
    LOAD_TYPES,
    MIXED_LAWS,
    PROFILE_TYPES,
    REPRESENTATIONS,
    SCHEMES,
    SECOND_FIBRE_LAWS,
    VISCOELASTIC_LAWS,
    BCSpec,
    ContactRotationSpec,
    ContactSpec,
    FibreSpec,
    LoadSpec,
    MaterialSpec,
    MeshSpec,
    OutputSpec,
    ProblemSpec,
    Profile,
    RenderSpec,
    SolverSpec,
    SteppingSpec,
    ViscoelasticSpec,
)
from hyperfem.errors import ParameterError
from hyperfem.loading.motion import Waypoints
from hyperfem.materials import (
    ArrudaBoyceParameters,
    FungOrthotropicParameters,
    GentParameters,
    HolzapfelGasserOgdenParameters,
    MooneyRivlinParameters,
    OgdenParameters,
    PronySeries,
    ReducedPolynomialParameters,
    VerondaWestmannParameters,
    WeissParameters,
    YeohParameters,
)
from hyperfem.materials.holzapfel_gasser_ogden import HGO_SWITCHES
from hyperfem.materials.ogden import CONVENTIONS
from hyperfem.materials.volumetric import VOLUMETRIC_LAWS
from hyperfem.simulation.fields import FIELDS, FORMATS
from hyperfem.simulation.render import DEFAULT_VIEW, RENDER_SCALARS, UNDEFORMED, check_render_options

__all__ = [
    "RENDER",
    "TOP",
    "check_bcs",
    "check_contacts",
    "check_fibre_use",
    "check_fibres",
    "check_loads",
    "check_materials",
    "check_mesh_table",
    "check_output",
    "check_problem",
    "check_profile",
    "check_solver",
    "check_stepping",
    "check_viscoelastic_use",
]

VOLUMETRIC = tuple(VOLUMETRIC_LAWS)
NAME = re.compile(r"[A-Za-z0-9_.+-]+")
"""Allowed run names (they name the output files)."""

# -- the schema ---------------------------------------------------------------------------------
# Every key of a case file, declared once: the checks below use these tables, and `hyperfem schema`
# (the commented reference) and `hyperfem schema --json` (a JSON Schema) are generated from them
# (hyperfem.app.reference). A help says what the key is, its unit, the class or keyword it feeds.
TOP = {
    "name": Key("string", pattern=NAME.pattern, example="bend",
                help="name of the run, names the output files (NAME.csv, NAME.json, NAME.bp); default: the case "
                "file's stem"),
    "description": Key("string", example="cantilever bend under a dead end traction",
                       help="one line about the run, for the reader"),
    "mesh": Key("table", required=True, hint="a [mesh] table with file or generator",
                help="the mesh: a gmsh file (hf.read_mesh) or a generator (hf.beam_mesh, hf.mesh.fusiform_mesh); "
                "give file or generator"),
    "problem": Key("table", help="formulation and discretisation (hf.HyperelasticProblem, "
                   "hf.MixedHyperelasticProblem)"),
    "material": Key("tables", required=True, hint="at least one [[material]]",
                    help="the strain energy: one [[material]] for the whole body, or one per region; its keys "
                    "depend on law"),
    "fibres": Key("table", help="fibre directions, needed by the laws muscle, holzapfel_gasser_ogden (a01), weiss "
                  "and fung_orthotropic (a1) (hf.fibres); its keys depend on type"),
    "second_fibres": Key("table", help="a second direction field, the keys of [fibres]: the second fibre family a02 "
                         "of holzapfel_gasser_ogden, the second material axis a2 of fung_orthotropic (orthogonal to "
                         "a1; a3 = a1 x a2)"),
    "bc": Key("tables", help="Dirichlet conditions, one [[bc]] each; its keys depend on type"),
    "load": Key("tables", help="loads, one [[load]] each; its keys depend on type"),
    "contact": Key("tables", help="contact with obstacles, one [[contact]] each: a rigid plane, sphere or triangulated "
                   "tool, self-contact, two bodies of one mesh (intersection-free, with friction), or two glued groups "
                   "(hyperfem.contact; needs pip install 'hyperfem[contact]'); its keys depend on type"),
    "stepping": Key("table", help="a load ramp (type = \"quasi-static\", the default) or a time integration "
                    "(type = \"dynamic\"); its keys depend on type"),
    "solver": Key("table", help="Newton's method (hf.NewtonSolver) and PETSc options"),
    "output": Key("table", help="what the run writes, into one folder (hyperfem.simulation outputs)"),
}

MESH = {
    "file": Key("string", example="../meshes/beam_h2.msh",
                help="gmsh .msh file with named physical groups, relative to the case file (hf.read_mesh)"),
    "generator": Key("string", choices=("beam", "fusiform", "spherical_shell"), example="beam",
                     help="generate the mesh instead: beam (hf.beam_mesh, the 10 x 4 x 4 m beam), fusiform "
                     "(hf.mesh.fusiform_mesh, the spindle muscle) or spherical_shell (hf.mesh.spherical_shell_mesh, "
                     "one eighth of a thick sphere: groups wall, inner, outer, x0, y0, z0)"),
    "size": Key("number", above=0.0, example=2.0,
                help="generator only: target element size h in m; default 1.0 (beam), 0.004 (fusiform), "
                "0.35 (spherical_shell)"),
    "order": Key("integer", minimum=1, below=3, default=1,
                 help="generator only: geometric order of the tetrahedra (order)"),
    "geometry": Key("table", help="fusiform generator only: its dimensions (hf.mesh.FusiformGeometry)"),
}

GEOMETRY = {
    "belly_length": Key("number", above=0.0, default=0.06, help="length of the muscle belly in m"),
    "belly_radius": Key("number", above=0.0, default=0.012, help="largest radius of the belly in m"),
    "tendon_radius": Key("number", above=0.0, default=0.004, help="tendon radius in m, below belly_radius"),
    "tendon_length": Key("number", above=0.0, default=0.015, help="length of each tendon in m"),
    "sections": Key("integer", minimum=3, default=9, help="lofted cross-sections of the belly (odd)"),
    "inner_radius": Key("number", above=0.0, default=1.0, help="spherical_shell only: the inner radius A"),
    "outer_radius": Key("number", above=0.0, default=2.0, help="spherical_shell only: the outer radius B > A"),
}
SHELL_GEOMETRY = ("inner_radius", "outer_radius")
"""The keys of ``[mesh.geometry]`` of the spherical_shell generator (the others are the fusiform's)."""

PROBLEM = {
    "formulation": Key("string", choices=FORMULATIONS, default="displacement",
                       help="displacement: hf.HyperelasticProblem (u); mixed: hf.MixedHyperelasticProblem (u, p, "
                       "theta), for nearly incompressible solids"),
    "degree": Key("integer", minimum=1, example=1,
                  help="polynomial degree of the displacement (degree); default 1 (displacement), 2 (mixed)"),
    "pressure_degree": Key("integer", minimum=1, example=1,
                           help="mixed only: degree of pressure and volume ratio (pressure_degree); default degree "
                           "- 1"),
    "quadrature_degree": Key("integer", minimum=1, example=4,
                             help="quadrature degree of the energy (quadrature_degree); default: from the degree "
                             "and the cell type"),
}

_COMMON_MATERIAL = {
    "law": Key("string", required=True, choices=LAWS, example="neo_hookean",
               help="the strain energy (hf.materials): isotropic laws take two elastic constants, mooney_rivlin "
               "c1, c2, K, muscle a preset or c1, c2, K, T_max; the rubber and tissue laws the fields of their "
               "parameter class (YeohParameters, ...), ogden the lists mu and alpha, K and a convention; hencky "
               "and saint_venant_kirchhoff_principal are laws of the principal stretches (seed 003 4.5.1) with "
               "two elastic constants"),
    "region": Key("string", example="muscle",
                  help="cell group of the mesh this material fills; needed with several materials; default: the "
                  "whole body"),
    "density": Key("number", above=0.0, example=1000.0,
                   help="mass density in kg/m^3 (dyn.MassDensity); needed by a dynamic run"),
    "viscoelastic": Key("table", help="finite-strain viscoelasticity: a Prony series relaxes the isochoric stress "
                        "(hf.materials.Viscoelastic around the law's SplitEnergy; Simo 1987), the volumetric one "
                        "stays elastic; laws " + ", ".join(VISCOELASTIC_LAWS) + " (neo_hookean: its split mu/2 "
                        "(I1bar - 3) + U(J), as with formulation = \"mixed\", not the compressible law); "
                        "default none (elastic)"),
}
_LAME = {
    "E": Key("number", above=0.0, example=1.0e6,
             help="Young's modulus in Pa, with nu (hf.materials.LameParameters.from_youngs)"),
    "nu": Key("number", above=-1.0, below=0.5, example=0.3, help="Poisson's ratio, with E"),
    "mu": Key("number", above=0.0, example=3.8e5,
              help="shear modulus in Pa, with lambda or bulk_modulus, or alone for arap (LameParameters mu)"),
    "lambda": Key("number", example=5.8e5, help="first Lame parameter in Pa, with mu (LameParameters lmbda)"),
    "bulk_modulus": Key("number", above=0.0, example=8.3e5,
                        help="bulk modulus K in Pa, with mu (lambda = K - 2 mu / 3; mixed: the K of U(theta))"),
    "volumetric": Key("string", choices=VOLUMETRIC, default="log",
                      help="formulation = \"mixed\" or a viscoelastic neo_hookean only: the volumetric energy "
                      "U(theta) (SplitEnergy volumetric)"),
}
_MOONEY = {
    "c1": Key("number", above=0.0, required=True, example=3.0e4,
              help="Mooney-Rivlin c1 in Pa (hf.materials.MooneyRivlinParameters)"),
    "c2": Key("number", minimum=0.0, required=True, example=1.0e4, help="Mooney-Rivlin c2 in Pa"),
    "K": Key("number", above=0.0, required=True, example=3.0e6, help="bulk modulus in Pa"),
    "volumetric": Key("string", choices=VOLUMETRIC, default="log", help="the volumetric energy U(J)"),
}
_MUSCLE = {
    "preset": Key("string", choices=("muscle", "tendon"), example="muscle",
                  help="seed 000 parameters (MuscleParameters.muscle: c1 30 kPa, c2 10 kPa, K 60 kPa, T_max 80 kPa; "
                  ".tendon: c1 60 kPa), the keys given override them"),
    "c1": Key("number", above=0.0, example=3.0e4,
              help="matrix Mooney-Rivlin c1 in Pa (hf.materials.MuscleParameters); needed without preset"),
    "c2": Key("number", minimum=0.0, example=1.0e4, help="matrix Mooney-Rivlin c2 in Pa; needed without preset"),
    "K": Key("number", above=0.0, example=3.0e6, help="bulk modulus in Pa; needed without preset"),
    "T_max": Key("number", minimum=0.0, example=8.0e4,
                 help="maximum isometric fibre stress in Pa; needed without preset"),
    "lambda_ofl": Key("number", above=0.0, default=1.0, help="optimal fibre stretch"),
    "P1": Key("number", minimum=0.0, default=0.05, help="scale of the passive fibre curve"),
    "P2": Key("number", above=0.0, default=6.6, help="exponent of the passive fibre curve"),
    "l_star": Key("number", above=1.0, default=1.4, help="fibre stretch where the passive curve turns linear"),
    "volumetric": Key("string", choices=VOLUMETRIC, default="log", help="the volumetric energy U(J)"),
    "activation": Key("any", shape="activation", example="linear",
                      help="active fraction alpha in [0, 1]: a number, or a profile f(t) (\"linear\": alpha = load "
                      "factor); default 0 (passive)"),
}

_VOLUMETRIC = Key("string", choices=VOLUMETRIC, default="log",
                  help="the volumetric energy U(J), with formulation = \"mixed\" U(theta) (the class's volumetric)")
_BULK = Key("number", above=0.0, required=True, example=5.0e7, help="bulk modulus K in Pa")
_YEOH = {
    "c10": Key("number", above=0.0, required=True, example=2.0e5,
               help="Yeoh C10 in Pa, half the small-strain shear modulus (hf.materials.YeohParameters; "
               "O. H. Yeoh, Rubber Chem. Technol. 66 (1993) 754)"),
    "c20": Key("number", required=True, example=-2.0e3, help="Yeoh C20 in Pa, any sign (usually negative)"),
    "c30": Key("number", required=True, example=1.0e2, help="Yeoh C30 in Pa, any sign (usually small and positive)"),
    "K": _BULK,
    "volumetric": _VOLUMETRIC,
}
_REDUCED_POLYNOMIAL = {
    "coefficients": Key("numbers", required=True, example=(2.0e5, -2.0e3, 1.0e2),
                        help="C10, C20, ..., CN0 in Pa of the sum of Ci0 (I1bar - 3)^i, C10 > 0, the others any "
                        "sign (hf.materials.ReducedPolynomialParameters; N = 3 is yeoh)"),
    "K": _BULK,
    "volumetric": _VOLUMETRIC,
}
_GENT = {
    "mu": Key("number", above=0.0, required=True, example=4.0e5,
              help="small-strain shear modulus in Pa (hf.materials.GentParameters; A. N. Gent, Rubber Chem. "
              "Technol. 69 (1996) 59)"),
    "Jm": Key("number", above=0.0, required=True, example=30.0,
              help="limiting value of I1bar - 3, the lock (dimensionless)"),
    "K": _BULK,
    "volumetric": _VOLUMETRIC,
    "lock_fraction": Key("number", above=0.0, below=1.0, example=0.9,
                         help="continue the logarithm quadratically from I1bar - 3 = lock_fraction Jm on, so that "
                         "Newton iterates may pass over-stretched states; default: the exact law (no value beyond "
                         "the lock)"),
}
_ARRUDA_BOYCE = {
    "mu": Key("number", above=0.0, required=True, example=4.0e5,
              help="modulus mu of the five-term series in Pa, not quite the small-strain shear modulus "
              "(hf.materials.ArrudaBoyceParameters, Abaqus form; E. M. Arruda, M. C. Boyce, J. Mech. Phys. Solids "
              "41 (1993) 389)"),
    "lambda_m": Key("number", above=1.0, required=True, example=3.0,
                    help="locking stretch lambda_m (lambda_m^2 = N, the links per chain)"),
    "K": _BULK,
    "volumetric": _VOLUMETRIC,
}
_VERONDA_WESTMANN = {
    "c1": Key("number", above=0.0, required=True, example=2.0e3,
              help="stress scale c1 in Pa; small-strain shear modulus c1 c2 (hf.materials.VerondaWestmannParameters; "
              "D. R. Veronda, R. A. Westmann, J. Biomech. 3 (1970) 111)"),
    "c2": Key("number", above=0.0, required=True, example=10.0, help="exponent c2 of exp(c2 (I1bar - 3))"),
    "K": _BULK,
    "volumetric": _VOLUMETRIC,
}
_HOLZAPFEL_GASSER_OGDEN = {
    "mu": Key("number", above=0.0, required=True, example=7.64e3,
              help="shear modulus of the neo-Hookean matrix in Pa (hf.materials.HolzapfelGasserOgdenParameters; "
              "T. C. Gasser, R. W. Ogden, G. A. Holzapfel, J. R. Soc. Interface 3 (2006) 15); the families: "
              "[fibres] (a01) and [second_fibres] (a02)"),
    "k1": Key("number", minimum=0.0, required=True, example=9.966e5, help="fibre stiffness k1 in Pa"),
    "k2": Key("number", above=0.0, required=True, example=524.6, help="fibre exponent k2 (dimensionless)"),
    "kappa": Key("number", minimum=0.0, maximum=1.0 / 3.0, required=True, example=0.226,
                 help="fibre dispersion: 0 aligned, 1/3 isotropic"),
    "K": _BULK,
    "switch": Key("string", choices=HGO_SWITCHES, default="strain",
                  help="fibres in tension only: a family acts while its strain E > 0 (strain, as FEBio), while "
                  "I4bar > 1 (stretch), or always (none)"),
    "smoothing": Key("number", minimum=0.0, default=0.0,
                     help="width of a tanh-smoothed switch, in units of E (strain) or I4bar - 1 (stretch); 0: exact"),
    "volumetric": _VOLUMETRIC,
}
_WEISS = {
    "c1": Key("number", above=0.0, required=True, example=1.44e6,
              help="Mooney-Rivlin c1 of the matrix in Pa (hf.materials.WeissParameters; J. A. Weiss, B. N. Maker, "
              "S. Govindjee, Comput. Methods Appl. Mech. Engrg. 135 (1996) 107); the fibres: [fibres]"),
    "c2": Key("number", minimum=0.0, required=True, example=0.0, help="Mooney-Rivlin c2 of the matrix in Pa"),
    "c3": Key("number", minimum=0.0, required=True, example=5.7e5,
              help="scale of the exponential fibre stress of the toe region in Pa"),
    "c4": Key("number", above=0.0, required=True, example=48.0, help="rate of fibre uncrimping (dimensionless)"),
    "c5": Key("number", minimum=0.0, required=True, example=4.671e8, help="modulus of the straightened fibres in Pa"),
    "lambda_star": Key("number", above=1.0, required=True, example=1.062,
                       help="fibre stretch at which the fibres are straight (the toe region ends)"),
    "K": _BULK,
    "volumetric": _VOLUMETRIC,
}
_FUNG = {
    "c": Key("number", above=0.0, required=True, example=1.0e4,
             help="stress scale c in Pa of c/2 (exp(Q) - 1) (hf.materials.FungOrthotropicParameters; Y. C. Fung, "
             "K. Fronek, P. Patitucci, Am. J. Physiol. 237 (1979) H620); the axes: [fibres] (a1), [second_fibres] "
             "(a2), a3 = a1 x a2"),
    "b1": Key("number", required=True, example=10.0,
              help="coefficient of E11^2 (dimensionless); [[b1, b4, b6], [b4, b2, b5], [b6, b5, b3]] must be "
              "positive definite"),
    "b2": Key("number", required=True, example=5.0, help="coefficient of E22^2"),
    "b3": Key("number", required=True, example=5.0, help="coefficient of E33^2"),
    "b4": Key("number", required=True, example=1.0, help="coupling of E11 E22 (its term 2 b4 E11 E22)"),
    "b5": Key("number", required=True, example=1.0, help="coupling of E22 E33"),
    "b6": Key("number", required=True, example=1.0, help="coupling of E33 E11"),
    "b7": Key("number", above=0.0, required=True, example=3.0, help="shear coefficient of E12^2 (its term 2 b7 E12^2)"),
    "b8": Key("number", above=0.0, required=True, example=3.0, help="shear coefficient of E23^2"),
    "b9": Key("number", above=0.0, required=True, example=3.0, help="shear coefficient of E31^2"),
    "K": _BULK,
    "volumetric": _VOLUMETRIC,
}
_OGDEN = {
    "mu": Key("numbers", required=True, example=(6.3e5, 1.2e3, -1.0e4),
              help="coefficients in Pa, one per term, written in the convention of key convention (Ogden's mu_p of "
              "psi = sum mu_p / alpha_p (lbar1^alpha_p + lbar2^alpha_p + lbar3^alpha_p - 3) + U(J), lbar_i the "
              "distortional stretches; hf.materials.OgdenParameters; R. W. Ogden, Proc. R. Soc. Lond. A 326 (1972) "
              "565); mu_p alpha_p > 0 for every term; small-strain shear modulus sum mu_p alpha_p / 2"),
    "alpha": Key("numbers", required=True, example=(1.3, 5.0, -2.0),
                 help="exponents alpha_p (dimensionless, nonzero), one per term of mu, the same in every convention"),
    "convention": Key("string", choices=CONVENTIONS, default="ogden",
                      help="how mu is written (OgdenParameters.from_convention): ogden, Ogden's mu_p; febio, FEBio's "
                      "c_p = mu_p alpha_p (psi = sum c_p / alpha_p^2 (...)); abaqus, Abaqus's mu_i = mu_p alpha_p / 2 "
                      "(psi = sum 2 mu_i / alpha_i^2 (...), shear modulus sum mu_i)"),
    "K": _BULK,
    "volumetric": _VOLUMETRIC,
}
LAW_KEYS = {
    **dict.fromkeys(LAME_LAWS, _LAME),
    "mooney_rivlin": _MOONEY,
    "muscle": _MUSCLE,
    "yeoh": _YEOH,
    "reduced_polynomial": _REDUCED_POLYNOMIAL,
    "gent": _GENT,
    "arruda_boyce": _ARRUDA_BOYCE,
    "veronda_westmann": _VERONDA_WESTMANN,
    "ogden": _OGDEN,
    "holzapfel_gasser_ogden": _HOLZAPFEL_GASSER_OGDEN,
    "weiss": _WEISS,
    "fung_orthotropic": _FUNG,
}
"""The own keys of a ``[[material]]`` of each law (besides :data:`_COMMON_MATERIAL`)."""
PARAMETER_CLASSES: dict[str, Callable[..., object]] = {
    "mooney_rivlin": MooneyRivlinParameters,
    "yeoh": YeohParameters,
    "reduced_polynomial": ReducedPolynomialParameters,
    "gent": GentParameters,
    "arruda_boyce": ArrudaBoyceParameters,
    "veronda_westmann": VerondaWestmannParameters,
    "ogden": OgdenParameters.from_convention,
    "holzapfel_gasser_ogden": HolzapfelGasserOgdenParameters,
    "weiss": WeissParameters,
    "fung_orthotropic": FungOrthotropicParameters,
}
"""Laws whose keys are the fields of a parameter class (ogden: the arguments of
``OgdenParameters.from_convention``): made once while checking, so that its one-line
:class:`~hyperfem.errors.ParameterError` names the entry before anything is built."""

VISCOELASTIC = {
    "g": Key("numbers", minimum=0.0, required=True, example=(0.3, 0.2),
             help="relative moduli g_i >= 0 of the relaxation function g(t) = g_inf + sum g_i exp(-t/tau_i) of the "
             "isochoric stress, sum g_i < 1 (g_inf = 1 - sum g_i is what is left after a long hold; "
             "hf.materials.PronySeries)"),
    "tau": Key("numbers", above=0.0, required=True, example=(0.1, 1.0),
               help="relaxation times tau_i in s, one per g_i"),
    "time_scale": Key("number", above=0.0, default=1.0,
                      help="seconds per unit of the run's time (Viscoelastic time_scale). Quasi-static: the load "
                      "factor is the clock, so how fast the ramp goes decides how much relaxes: 1 reads it in s "
                      "(a ramp profile t1 = 0.5 then stepping.end = 3: pulled in 0.5 s, held to 3 s); T: the load "
                      "factor 0 -> 1 lasts T s. Dynamic: the time is in s, so 1 only. Steps should land on the ends "
                      "of ramps (growth = 1 and an increment that divides them): a kink inside a step costs the "
                      "second order in time"),
}
"""Keys of ``[material.viscoelastic]``: :class:`~hyperfem.materials.PronySeries` and the time scale."""

FIBRE_COMMON = {
    "type": Key("string", required=True, choices=FIBRE_TYPES, example="laplace",
                help="laplace: hf.fibres.laplace_fibres (along the gradient of a potential from source to target); "
                "constant: constant_fibres; file: fibres_from_file"),
    "representation": Key("string", choices=REPRESENTATIONS, default="DG0",
                          help="laplace and constant: the space of the fibre field (representation)"),
}
"""Keys of every ``[fibres]`` table; :data:`FIBRES` adds those of each ``type``."""
FIBRES = {
    "laplace": {
        "source": Key("string", required=True, example="origin", help="boundary where the fibres start (phi = 0)"),
        "target": Key("string", required=True, example="insertion", help="boundary where they end (phi = 1)"),
    },
    "constant": {"direction": Key("numbers", required=True, example=(1.0, 0.0, 0.0),
                                  help="the fibre direction (normalised)")},
    "file": {
        "file": Key("string", required=True, example="fibres.vtu",
                    help="mesh file with the fibre vectors (read by meshio), relative to the case file"),
        "name": Key("string", required=True, example="fibres", help="name of the point or cell data array"),
        "location": Key("string", choices=("point", "cell"), default="point",
                        help="point data (a P1 field) or cell data (DG0)"),
    },
}

_BC_COMMON = {
    "type": Key("string", required=True, choices=BC_TYPES, example="clamp",
                help="clamp: hf.Clamp (u = 0); displacement: hf.PrescribedDisplacement; rotation: rotating_surface "
                "(a rigid rotation)"),
    "boundary": Key("string", required=True, example="clamped", help="facet group of the mesh it holds"),
}
BCS = {
    "clamp": {},
    "displacement": {
        "value": Key("numbers", required=True, example=(-0.5,),
                     help="displacement in m at f = 1: three values, or one per entry of components"),
        "components": Key("any", shape="components", example=("y",),
                          help="the components it prescribes (0, 1, 2 or \"x\", \"y\", \"z\"); default all"),
        "profile": Key("any", shape="profile", default="linear", help="time profile f(t) scaling value"),
    },
    "rotation": {
        "axis": Key("vector", length=3, required=True, example=(1.0, 0.0, 0.0), help="the rotation axis"),
        "center": Key("vector", length=3, default=(0.0, 0.0, 0.0), help="a point on the axis, in m"),
        "angle": Key("number", required=True, hint="angle in radians, scaled by the profile", example=1.57,
                     help="rotation angle in radians at f = 1"),
        "profile": Key("any", shape="profile", default="linear", help="time profile f(t) scaling angle"),
    },
}

_CONTACT_COMMON = {
    "type": Key("string", required=True, choices=CONTACT_TYPES, example="plane",
                help="plane: a rigid half-space (hyperfem.contact.PlaneContact); sphere: a rigid ball, an indenter "
                "or spherical tool (hyperfem.contact.SphereContact); cylinder: a rigid roller or rod "
                "(hyperfem.contact.CylinderContact); self: self-contact of surfaces and pair: two bodies of one mesh "
                "(hyperfem.contact.SurfaceContact); tool: a rigid triangulated tool read from a file "
                "(hyperfem.contact.ToolContact); tie: two surface groups glued, non-matching meshes allowed "
                "(hyperfem.contact.TieContact)"),
}
_NODE_BOUNDARY = Key("string", required=True, example="bottom",
                     help="facet group of the mesh whose nodes may touch the obstacle")


def _barrier_keys(obstacle: str) -> dict[str, Key]:
    """The keys of every obstacle: the barrier's width and stiffness, the motion, friction."""
    return {
        "dhat": Key("number", above=0.0, example=0.001,
                    help="barrier width in m: the distance below which contact forces act; default 1 % of the "
                    "mean facet size of the boundary"),
        "stiffness": Key("number", above=0.0, example=1.0e6,
                         help="barrier stiffness kappa; default the mean normal diagonal of the elastic tangent at "
                         "the contact nodes"),
        "motion": Key("numbers", example=(0.0, 0.0, 0.1),
                      help=f"translation of the {obstacle} in m at f = 1 (a moving tool); default none"),
        "profile": Key("any", shape="profile", default="linear", help="time profile f(t) scaling motion"),
        "path": Key("table", help=f"instead of motion and profile: the {obstacle}'s translation through waypoints "
                    "(hf.loading.Waypoints: piecewise linear, held at its ends; pressed in, then dragged)"),
        "friction": Key("number", minimum=0.0, default=0.0,
                        help="Coulomb coefficient mu >= 0 (0: frictionless); smoothed and lagged per step as in IPC"),
        "friction_epsilon": Key("number", above=0.0, example=1.0e-4,
                                help="friction's slip length in m below which a node sticks elastically; "
                                "default 0.1 dhat"),
    }


def _rotation_key(obstacle: str) -> Key:
    """An obstacle's ``rotation`` table (:data:`CONTACT_ROTATION`)."""
    return Key("table", help=f"a rigid rotation of the {obstacle} {{axis, center, angle, profile}} composed with its "
               "translation (turned about center, which then moves with the translation; hf.loading.RigidRotation); "
               "default none")


def _surface_keys(default_name: str) -> dict[str, Key]:
    """The keys of the contacts of triangulated surfaces (self, pair, tool): barrier, filter, output name."""
    return {
        "dhat": Key("number", above=0.0, example=0.001,
                    help="barrier width in m: the distance below which contact forces act; default 1 % of the "
                    "smallest mean facet size of the boundaries"),
        "stiffness": Key("number", above=0.0, example=1.0e6,
                         help="ipctk's barrier stiffness kappa, on squared distances; default from the mean "
                         "diagonal of the elastic tangent at the surface nodes (over the collision proxy's vertices "
                         "per node)"),
        "safety": Key("number", above=0.0, below=1.0, default=0.9,
                      help="the collision filter's safety factor s in (0, 1): a Newton step goes at most s of the "
                      "way to the first touch"),
        "name": Key("string", pattern=NAME.pattern, example=default_name,
                    help="prefix of the output columns (NAME_force, NAME_active, NAME_min_distance); default "
                    "contact, or contact_0, contact_1, ... when there are several contacts"),
        "friction": Key("number", minimum=0.0, default=0.0,
                        help="Coulomb coefficient mu >= 0 (0: frictionless); smoothed and lagged per step as in IPC "
                        "(ipctk's friction potential); adds the column NAME_friction_force"),
        "friction_epsilon": Key("number", above=0.0, example=1.0e-4,
                                help="friction's slip length in m below which a pair sticks elastically; "
                                "default 0.1 dhat"),
        "subdivision": Key("integer", minimum=1, maximum=8, example=2,
                           help="the collision proxy: the barrier acts on a lattice of points that follow each "
                           "facet's shape functions, a facet edge cut into degree x subdivision segments (1: on the "
                           "nodes); default 2 for degree-2 displacements (a uniform pressure's consistent nodal "
                           "loads differ between their nodes) and hexahedra, else 1 (hyperfem.contact.proxy)"),
    }


CONTACTS = {
    "plane": {
        "boundary": _NODE_BOUNDARY,
        "point": Key("numbers", required=True, example=(0.0, 0.0, 0.0),
                     help="a point of the plane in m (where it is at profile 0)"),
        "normal": Key("numbers", required=True, example=(0.0, 0.0, 1.0),
                      help="the plane's normal, pointing to the body's side (any length > 0)"),
        **_barrier_keys("plane"),
        "rotation": _rotation_key("plane (it turns the normal)"),
    },
    "sphere": {
        "boundary": _NODE_BOUNDARY,
        "center": Key("numbers", required=True, example=(0.5, 0.5, 1.3),
                      help="the sphere's centre in m (where it is at profile 0); the body stays outside it"),
        "radius": Key("number", required=True, above=0.0, example=0.3, help="the sphere's radius in m"),
        **_barrier_keys("sphere"),
        "rotation": _rotation_key("sphere (about its own centre it matters only with friction)"),
    },
    "cylinder": {
        "boundary": _NODE_BOUNDARY,
        "point": Key("vector", length=3, required=True, example=(0.5, 0.0, 1.3),
                     help="a point of the cylinder's axis in m (where it is at profile 0)"),
        "axis": Key("vector", length=3, required=True, example=(0.0, 1.0, 0.0),
                    help="the axis direction (any length > 0); the cylinder is infinite, the body stays outside it"),
        "radius": Key("number", required=True, above=0.0, example=0.2, help="the cylinder's radius in m"),
        **_barrier_keys("cylinder"),
        "rotation": _rotation_key("cylinder (it turns the axis)"),
    },
    "self": {
        "boundaries": Key("strings", required=True, example=("surface",),
                          help="facet groups whose triangles may touch each other and themselves (self-contact), "
                          "one or more"),
        **_surface_keys("contact"),
    },
    "pair": {
        "boundaries": Key("strings", required=True, example=("lower_top", "upper_bottom"),
                          help="the two facet groups of two bodies of one mesh that may touch (each may touch "
                          "itself too); the force output is the force on the first"),
        **_surface_keys("contact"),
    },
    "tie": {
        "boundaries": Key("strings", required=True, example=("upper_bottom", "lower_top"),
                          help="the two facet groups glued together (non-matching meshes allowed; they must face "
                          "each other): the nodes of each are tied to the triangles (in 2D: segments) of the other "
                          "(two-pass penalty); the force output is the force on the first"),
        "stiffness": Key("number", above=0.0, example=1.0e8,
                         help="the tie's penalty k; default 1e8 times the mean diagonal of the elastic tangent at "
                         "the glued nodes (for direct solvers; lower it for iterative ones)"),
        "tolerance": Key("number", above=0.0, example=0.001,
                         help="the largest reference distance in m of a node of one group from the other group; "
                         "default 1 % of their mean edge (farther: the groups do not face each other)"),
        "name": Key("string", pattern=NAME.pattern, example="tie",
                    help="prefix of the output columns (NAME_force, NAME_max_gap); default contact, or "
                    "contact_0, contact_1, ... when there are several contacts"),
    },
    "tool": {
        "boundaries": Key("strings", required=True, example=("top",),
                          help="facet groups of the body that the rigid tool may touch, one or more; "
                          "the force output is the tool's force on the body"),
        "file": Key("string", required=True, example="spatula.stl",
                    help="the tool's triangulated surface (STL, OBJ, PLY, VTK/VTU or gmsh, read by meshio), "
                    "relative to the case file; on a 2D mesh a polyline: a file of line segments at z = 0"),
        "motion": Key("numbers", example=(0.0, 0.0, -0.3),
                      help="translation of the tool in m at f = 1 (a moving tool; one entry per coordinate of the "
                      "mesh); default none"),
        "profile": Key("any", shape="profile", default="linear", help="time profile f(t) scaling motion"),
        "path": Key("table", help="instead of motion and profile: the tool's translation through waypoints "
                    "(hf.loading.Waypoints: piecewise linear, held at its ends)"),
        "offset": Key("numbers", example=(0.0, 0.0, 1.0),
                      help="translation applied once to the file's points in m (placing the tool; one entry per "
                      "coordinate of the mesh); default none"),
        "scale": Key("number", above=0.0, default=1.0,
                     help="factor applied once to the file's points (before offset; 1e-3 for a file in mm)"),
        "rotation": _rotation_key("tool (center in the placed tool's coordinates, after scale and offset)"),
        **_surface_keys("indenter"),
    },
}

_LOAD_COMMON = {
    "type": Key("string", required=True, choices=LOAD_TYPES, example="dead_traction",
                help="dead_traction: hf.DeadTraction; follower_traction: hf.FollowerTraction (turns with the "
                "surface); pressure: hf.FollowerPressure; body_force: hf.BodyForce"),
}
_PROFILE = Key("any", shape="profile", default="linear", help="time profile f(t) scaling value")
LOADS = {
    "dead_traction": {
        "boundary": Key("string", required=True, example="free_end", help="facet group it acts on"),
        "value": Key("any", required=True, shape="field", example=(0.0, -5.0e3, 0.0),
                     help="traction in Pa per reference area at f = 1, fixed direction: a vector or {matrix, offset} "
                     "(A X + b of the reference position, AffineField)"),
        "profile": _PROFILE,
    },
    "follower_traction": {
        "boundary": Key("string", required=True, example="free_end", help="facet group it acts on"),
        "value": Key("any", required=True, shape="field", example=(0.0, -5.0e3, 0.0),
                     help="traction in Pa per reference area at f = 1: a vector or {matrix, offset} (A x + b of the "
                     "current position, AffineField)"),
        "profile": _PROFILE,
    },
    "pressure": {
        "boundary": Key("string", required=True, example="free_end", help="facet group it acts on"),
        "value": Key("number", required=True, example=1.0e4,
                     help="pressure in Pa per current area on the current normal at f = 1; positive compresses"),
        "profile": _PROFILE,
    },
    "body_force": {
        "region": Key("string", example="muscle", help="cell group it acts on; default: the whole body"),
        "value": Key("any", required=True, shape="field", example=(0.0, -9810.0, 0.0),
                     help="force in N/m^3 per reference volume at f = 1: a vector or {matrix, offset} (AffineField)"),
        "profile": _PROFILE,
    },
}
WAYPOINTS = {
    "times": Key("numbers", required=True, example=(0.0, 0.5, 1.0),
                 help="strictly increasing times (load factors or s), at least 2"),
    "points": Key("matrix", required=True, example=((0.0, 0.0, 0.0), (0.0, 0.0, -0.1), (0.4, 0.0, -0.1)),
                  help="the translation in m at each time, one [x, y, z] per time"),
}
"""Keys of a tool's ``path`` table: :class:`~hyperfem.loading.Waypoints`."""

CONTACT_ROTATION = {
    "axis": Key("vector", length=3, required=True, example=(0.0, 0.0, 1.0),
                help="the rotation axis (any length > 0)"),
    "center": Key("vector", length=3, required=True, example=(0.5, 0.5, 1.3),
                  help="the pivot in m: a point of the axis in the obstacle's placement at profile 0"),
    "angle": Key("number", required=True, hint="angle in radians, scaled by the profile", example=1.57,
                 help="rotation angle in radians at f = 1 (right-handed about axis)"),
    "profile": Key("any", shape="profile", default="linear", help="time profile f(t) scaling angle"),
}
"""Keys of a sphere's, cylinder's or tool's ``rotation`` table: :class:`~hyperfem.loading.RigidRotation`."""

AFFINE = {
    "matrix": Key("matrix", required=True, example=((0.0, 0.0, 0.0), (0.0, 0.0, 5.0e3), (0.0, -5.0e3, 0.0)),
                  help="the square matrix A, one row per component"),
    "offset": Key("numbers", example=(0.0, 0.0, 0.0), help="the offset b; default 0"),
}
"""Keys of an affine load value ``{matrix = A, offset = b}``: :class:`~hyperfem.loading.AffineField`."""

PROFILE_TYPE = Key("string", required=True, choices=PROFILE_TYPES, example="ramp",
                   help="linear: f = t; steady: f = value; ramp: hyperfem.loading.Ramp; table: hyperfem.loading.Table "
                   "(piecewise linear)")
PROFILES = {
    "linear": {},
    "steady": {"value": Key("number", default=1.0, help="the constant value")},
    "ramp": {
        "t1": Key("number", required=True, example=0.5, help="where the ramp ends (load factor or time in s)"),
        "final": Key("number", default=1.0, help="the value from t1 on"),
        "initial": Key("number", default=0.0, help="the value up to t0"),
        "t0": Key("number", default=0.0, help="where the ramp starts, below t1"),
    },
    "table": {
        "times": Key("numbers", required=True, example=(0.0, 0.5, 1.0),
                     help="strictly increasing times (load factors or s), at least 2"),
        "values": Key("numbers", required=True, example=(0.0, 1.0, 0.5), help="the values at those times"),
    },
}
"""Keys of a profile table ``{type = ..., ...}`` besides :data:`PROFILE_TYPE`, per type."""

_STEPPING_TYPE = Key("string", choices=("quasi-static", "dynamic", "arc_length", "buckling"), default="quasi-static",
                     help="quasi-static: a load ramp (hf.LoadStepping); dynamic: a time integration (dyn.TimeStepping "
                     "and a scheme); arc_length: continuation through limit points (hf.solver.ArcLength); buckling: "
                     "linearised buckling, critical load factors and modes (hyperfem.stability.Buckling)")
QUASI_STATIC = {
    "type": _STEPPING_TYPE,
    "end": Key("number", default=1.0, help="the final load factor (LoadStepping.policy(end))"),
    "increment": Key("number", above=0.0, default=1.0, help="the first load-factor increment (initial_increment)"),
    "min_increment": Key("number", above=0.0, default=1.0 / 1024, help="the smallest increment before giving up"),
    "max_increment": Key("number", above=0.0, default=1.0, help="the largest increment"),
    "growth": Key("number", minimum=1.0, default=2.0, help="the increment's factor after an easy step"),
    "easy_iterations": Key("integer", minimum=1, default=6,
                           help="a step converging in at most this many Newton iterations is easy"),
    "max_steps": Key("integer", minimum=1, default=10000, help="limit on attempted steps"),
    "solve_initial": Key("boolean", default=False, help="solve at load factor 0 first (Simulation solve_initial)"),
}
ARC_LENGTH = {
    "type": _STEPPING_TYPE,
    "increment": Key("number", above=0.0, default=0.1,
                     help="the first load-factor increment (sets the first arc length; ArcLength increment)"),
    "min_increment": Key("number", above=0.0, example=0.001,
                         help="the smallest arc length, in load-factor units of the first step (increment/1024)"),
    "max_increment": Key("number", above=0.0, example=0.4,
                         help="the largest arc length, in load-factor units of the first step; default 4 increment"),
    "psi": Key("number", minimum=0.0, default=1.0,
               help="the load scaling of the constraint: 1 spherical, 0 cylindrical (Crisfield)"),
    "end": Key("number", example=1.0, help="stop once the load factor passes it (default: no such stop)"),
    "min_load": Key("number", example=0.0, help="stop once the load factor falls below it (the descending branch)"),
    "max_displacement": Key("number", above=0.0, example=1.5,
                            help="stop once a node has moved farther than this (length units)"),
    "max_steps": Key("integer", minimum=1, default=200, help="the number of accepted steps, at most"),
    "stop_probe": Key("vector", length=3, example=(1.0, 0.0, 0.0),
                      help="stop once the displacement component stop_component here reaches stop_value"),
    "stop_component": Key("string", choices=("x", "y", "z"), example="x", help="with stop_probe: the component"),
    "stop_value": Key("number", example=1.5, help="with stop_probe: the displacement (length units) to stop at"),
    "target_iterations": Key("integer", minimum=1, default=5,
                             help="a step of at most this many corrector iterations is easy (the arc doubles)"),
    "direction": Key("integer", minimum=-1, maximum=1, default=1, help="the sign of the first load increment: 1 or -1"),
    "inertia": Key("boolean", example=True,
                   help="count the negative pivots of every converged tangent (LDL^T, MUMPS): stability, "
                   "bifurcations; default: up to 2e5 unknowns"),
    "switch_branch": Key("boolean", default=False,
                         help="at the first bifurcation, leave the path along the critical mode (branch switching)"),
    "solve_initial": Key("boolean", default=False, help="solve at load factor 0 first (Simulation solve_initial)"),
}
BUCKLING = {
    "type": _STEPPING_TYPE,
    "n": Key("integer", minimum=1, default=2, help="critical load factors (and modes) wanted"),
    "increment": Key("number", default=1.0,
                     help="the load increment of the second tangent (t_cr = reference + mu increment)"),
    "prestress": Key("string", choices=("linear", "nonlinear"), default="linear",
                     help="the state at reference + increment: one linear solve (*BUCKLE) or a Newton solve"),
    "reference": Key("number", default=0.0, help="the load factor of the reference state (a ramp reaches it)"),
}
DYNAMIC = {
    "type": _STEPPING_TYPE,
    "scheme": Key("string", choices=SCHEMES, default="newmark",
                  help="the time integrator: dyn.Newmark, dyn.BackwardEuler, dyn.GeneralizedAlpha, dyn.QuasiStatic "
                  "(no inertia)"),
    "beta": Key("number", above=0.0, default=0.25, help="scheme newmark only: Newmark's beta"),
    "gamma": Key("number", above=0.0, default=0.5, help="scheme newmark only: Newmark's gamma"),
    "rho_inf": Key("number", minimum=0.0, maximum=1.0, default=0.8,
                   help="scheme generalized_alpha only: the high-frequency spectral radius"),
    "dt": Key("number", above=0.0, required=True, example=0.05, help="the time step in s (TimeStepping dt)"),
    "t_end": Key("number", above=0.0, required=True, example=1.0, help="the final time in s"),
    "dt_min": Key("number", above=0.0, example=0.001, help="the smallest step in s before giving up; default dt/1024"),
    "dt_max": Key("number", above=0.0, example=0.1, help="the largest step in s; default dt (adaptive: 16 dt)"),
    "adaptive": Key("boolean", default=False, help="step-doubling error control"),
    "tolerance": Key("number", above=0.0, default=1e-4,
                     help="adaptive only: allowed nodal position difference per step in m"),
    "grow_after": Key("integer", minimum=1, default=4, help="accepted steps before trying a doubled step"),
    "must_hit": Key("numbers", example=(0.5,),
                    help="times in s that steps land on (ramp ends, table times and output times are added)"),
    "max_steps": Key("integer", minimum=1, default=1000000, help="limit on attempted steps"),
    "lumped_mass": Key("boolean", default=False, help="a row-sum lumped mass (dyn.MassDensity lumped); degree 1 only"),
    "damping": Key("table", help="Rayleigh damping C = alpha M + beta K0 (dyn.RayleighDamping)"),
    "initial_acceleration": Key("boolean", default=True,
                                help="solve M a0 = f - r(u0) for the initial acceleration before the first step"),
}
DAMPING = {
    "alpha": Key("number", minimum=0.0, default=0.0, help="mass-proportional coefficient in 1/s"),
    "beta": Key("number", minimum=0.0, default=0.0, help="stiffness-proportional coefficient in s"),
}

SOLVER = {
    "rtol": Key("number", above=0.0, default=1e-9, help="relative residual tolerance (snes_rtol)"),
    "atol": Key("number", minimum=0.0, default=1e-10, help="absolute residual tolerance (snes_atol)"),
    "stol": Key("number", minimum=0.0, default=0.0, help="relative step tolerance (snes_stol)"),
    "max_iterations": Key("integer", minimum=1, default=50, help="Newton iterations per solve (snes_max_it)"),
    "line_search": Key("string", choices=("bt", "basic", "cp", "l2", "nleqerr"), example="bt",
                       help="the line search (snes_linesearch_type); default bt, cp for non-conservative loads"),
    "petsc_options": Key("table", shape="petsc_options", example={"ksp_type": "preonly", "pc_type": "lu"},
                         help="PETSc options as they are, names without the leading '-' (NewtonSolver petsc_options)"),
    "min_jacobian": Key("any", shape="min_jacobian", default="auto",
                        help="the inversion guard: the smallest admissible J at quadrature points, \"auto\" (1e-6, off "
                        "for invertible laws) or false (off)"),
    "step_filter": Key("string", choices=("auto", "exact", "bisection"), default="auto",
                       help="how the guard shortens a Newton step: exact (P1 on straight simplices), bisection, auto"),
    "predictor": Key("boolean", default=True,
                     help="carry a change of the boundary values into the interior with one tangent solve"),
}
_SUGAR = {
    "rtol": "snes_rtol",
    "atol": "snes_atol",
    "stol": "snes_stol",
    "max_iterations": "snes_max_it",
    "line_search": "snes_linesearch_type",
}

OUTPUT = {
    "directory": Key("string", example="output/bend",
                     help="output folder, relative to the working folder (run --output replaces it); default "
                     "output/NAME"),
    "fields": Key("strings", choices=FIELDS, default=("displacement",),
                  help="fields written for ParaView (FieldOutput fields); with [[contact]] also NAME_contact.bp "
                  "(contact_force, contact_traction, contact_gap: hyperfem.contact.ContactField); [] writes none"),
    "format": Key("string", choices=FORMATS, default="vtx", help="field file format: vtx (ADIOS2 .bp) or xdmf"),
    "times": Key("numbers", example=(0.5, 1.0),
                 help="write the fields at these load factors or times only; default every step"),
    "every": Key("number", above=0.0, example=0.1,
                 help="write the fields at the multiples of this load factor or time only (instead of times)"),
    "csv": Key("boolean", default=True, help="a row per step in NAME.csv (CSVLog)"),
    "summary": Key("boolean", default=True, help="the summary NAME.json (JSONSummary)"),
    "convergence": Key("boolean", default=True, help="the Newton history NAME_convergence.jsonl (ConvergenceLog)"),
    "probes": Key("matrix", length=3, example=((4.5, 1.5, 1.5),),
                  help="reference points [x, y, z] in m whose displacement is recorded (Probe)"),
    "reactions": Key("any", shape="reactions", default="all",
                     help="force in N and moment in N m on Dirichlet boundaries (Reactions): \"all\", a list of "
                     "boundaries, or false"),
    "checkpoint": Key("boolean", default=True, help="false: no checkpoints"),
    "checkpoint_every": Key("integer", minimum=1, default=10,
                            help="a checkpoint every this many steps, and at the end (Checkpoint every)"),
    "checkpoint_keep": Key("integer", minimum=1, default=2, help="checkpoints kept (Checkpoint keep)"),
    "progress": Key("boolean", default=True, help="a line per step on the terminal (Progress)"),
    "stability": Key("integer", minimum=0, default=0, example=3,
                     help="the lowest eigenvalues of the tangent at every state, this many (Stability: SLEPc; "
                     "columns lowest_eigenvalues, negative_eigenvalues, stable_state; a warning for an unstable "
                     "state); 0: off"),
    "render": Key("any", shape="render", default=False,
                  help="true, or a table of Render options (a PNG of the deformed body; needs pyvista)"),
}

RENDER = {
    "scalars": Key("string", choices=RENDER_SCALARS, default=RENDER_SCALARS[0],
                   help="what colours the surface: |u|, or a field"),
    "every": Key("integer", minimum=1, example=5, help="also draw every k steps (NAME-000010.png)"),
    "final": Key("boolean", default=True, help="draw the final state (NAME.png)"),
    "scale": Key("number", default=1.0, help="displacement magnification"),
    "view": Key("vector", length=3, default=DEFAULT_VIEW, help="direction from the body towards the camera"),
    "up": Key("vector", length=3, default=(0.0, 1.0, 0.0), help="up in the picture"),
    "undeformed": Key("string", choices=(*UNDEFORMED, "none"), default="outline",
                      help="how the reference body is drawn (none: not at all)"),
    "window_size": Key("any", shape="window_size", default=(800, 500), help="picture size in pixels [width, height]"),
    "title": Key("any", shape="title", default=True, help="true: \"NAME, t = ...\"; a string: that; false: none"),
    "scalar_bar_title": Key("string", example="von Mises stress [Pa]",
                            help="title of the colour bar; default the field's name"),
    "cmap": Key("string", default="viridis", help="matplotlib colour map"),
    "clim": Key("vector", length=2, example=(0.0, 1.0e5),
                help="fixed colour range [low, high]; default each picture's own"),
    "zoom": Key("number", above=0.0, default=1.0, help="camera zoom after fitting the body into the picture"),
    "parallel": Key("boolean", default=True, help="parallel projection (false: perspective)"),
}
"""Keys of ``[output] render = {...}``: the keyword arguments of :class:`~hyperfem.simulation.render.Render`."""


# -- sections -----------------------------------------------------------------------------------
def check_profile(value: object, where: str) -> Profile:
    """A time profile from a name (``"linear"``, ``"steady"``), a number (constant) or a table (``type = ...``)."""
    if isinstance(value, str):
        if value not in ("linear", "steady"):
            raise CaseFileError(
                f"{where}: unknown profile {value!r}{suggestion(value, PROFILE_TYPES)}; use \"linear\", \"steady\", "
                "a number, or a table {type = \"ramp\" | \"table\", ...}"
            )
        return Profile(value, {"value": 1.0} if value == "steady" else {})
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return Profile("steady", {"value": check_value(value, Key("number"), where)})
    if not isinstance(value, Mapping):
        raise CaseFileError(f"{where}: expected a profile name, a number or a table, got {describe(value)}")
    if "type" not in value:
        raise CaseFileError(f"{where}: missing required key 'type' ({', '.join(PROFILE_TYPES)})")
    kind = check_value(value["type"], PROFILE_TYPE, join(where, "type"))
    args = check_table(value, {"type": PROFILE_TYPE, **PROFILES[kind]}, where, what=f"a {kind!r} profile")
    args.pop("type")
    if kind == "steady":
        args.setdefault("value", 1.0)
    if kind == "ramp" and not args["t1"] > args.get("t0", 0.0):
        raise CaseFileError(f"{where}: a ramp needs t1 > t0, got t0 = {args.get('t0', 0.0):g}, t1 = {args['t1']:g}")
    if kind == "table":
        t, v = args["times"], args["values"]
        if len(t) != len(v) or len(t) < 2:
            raise CaseFileError(
                f"{where}: times and values need the same length (at least 2), got {len(t)} and {len(v)}"
            )
        if any(b <= a for a, b in zip(t, t[1:], strict=False)):
            raise CaseFileError(f"{where}.times: must increase strictly, got {list(t)}")
    return Profile(kind, args)


def check_mesh_table(table: Mapping, source: Path) -> MeshSpec:
    """``[mesh]``: a file (relative to the case file ``source``) or a generator with its size, order and geometry."""
    values = check_table(table, MESH, "mesh")
    if ("file" in values) == ("generator" in values):
        raise CaseFileError(
            "mesh: give either file (a gmsh .msh) or generator (\"beam\", \"fusiform\", \"spherical_shell\"), not both"
        )
    if "file" in values:
        extra = [k for k in ("size", "order", "geometry") if k in values]
        if extra:
            raise CaseFileError(f"mesh.{extra[0]}: only used with a generator, not with a mesh file")
        path = Path(values["file"]).expanduser()
        return MeshSpec(file=path if path.is_absolute() else (source.parent / path).resolve())
    geometry = {}
    if "geometry" in values:
        generator = values["generator"]
        if generator not in ("fusiform", "spherical_shell"):
            raise CaseFileError(
                "mesh.geometry: only the fusiform and spherical_shell generators have geometry parameters"
            )
        geometry = check_table(values["geometry"], GEOMETRY, "mesh.geometry")
        shell = generator == "spherical_shell"
        wrong = [k for k in geometry if (k in SHELL_GEOMETRY) != shell]
        if wrong:
            raise CaseFileError(f"mesh.geometry.{wrong[0]}: not a parameter of the {generator} generator")
        if shell and not geometry.get("inner_radius", 1.0) < geometry.get("outer_radius", 2.0):
            raise CaseFileError("mesh.geometry.outer_radius: must exceed inner_radius")
    return MeshSpec(
        generator=values["generator"], size=values.get("size"), order=values.get("order"), geometry=geometry
    )


def _elastic_pair(values: Mapping, law: str, where: str, split: bool) -> None:
    """The elastic constants as one pair; ``volumetric`` only where the law is split (``split``: mixed or viscous)."""
    given = {k for k in ("E", "nu", "mu", "lambda", "bulk_modulus") if k in values}
    pairs = [{"E", "nu"}, {"mu", "lambda"}, {"mu", "bulk_modulus"}]
    if law == "arap":
        pairs.append({"mu"})
    if given not in pairs:
        need = "E and nu, mu and lambda, or mu and bulk_modulus" + (", or mu alone" if law == "arap" else "")
        shown = ", ".join(sorted(given)) or "none"
        raise CaseFileError(f"{where}: give the elastic constants as {need} (given: {shown})")
    if "volumetric" in values and not split:
        raise CaseFileError(
            f"{where}.volumetric: only used with formulation = \"mixed\" or a [material.viscoelastic] table "
            f"(law {law!r} has its own volume term)"
        )


def _ogden_coefficients(mu: Sequence[float], convention: str, where: str) -> None:
    """FEBio's c_p = mu_p alpha_p and Abaqus's mu_p alpha_p / 2: Ogden's mu_p alpha_p > 0 is their sign."""
    for i, c in enumerate(mu):
        if not c > 0.0:
            raise CaseFileError(
                f"{where}.mu[{i}]: must be > 0 in the {convention} convention (it is mu_p alpha_p"
                f"{' / 2' if convention == 'abaqus' else ''}, > 0 by Ogden's stability condition), got {c!r}"
            )


def _material(index: int, table: Mapping, mixed: bool, has_fibres: bool, has_second: bool) -> MaterialSpec:
    where = join("material", index)
    if not isinstance(table, Mapping):
        raise CaseFileError(f"{where}: expected a table, got {describe(table)}")
    if "law" not in table:
        raise CaseFileError(f"{where}: missing required key 'law' (one of {', '.join(LAWS)})")
    law = check_value(table["law"], _COMMON_MATERIAL["law"], join(where, "law"))
    own = LAW_KEYS[law]
    nu = table.get("nu")
    if isinstance(nu, (int, float)) and not isinstance(nu, bool) and math.isfinite(nu) and not -1.0 < nu < 0.5:
        raise CaseFileError(
            f"{where}.nu: Poisson's ratio must lie in (-1, 0.5), got {nu!r}; for a nearly incompressible "
            "solid use nu < 0.5 (e.g. 0.499) or formulation = \"mixed\" with a bulk_modulus"
        )
    if "viscoelastic" in table and law not in VISCOELASTIC_LAWS:
        why = ("its isochoric part holds the active fibre stress, which a Prony series would relax too"
               if law == "muscle" else "it has no isochoric/volumetric split whose isochoric part could relax")
        raise CaseFileError(
            f"{where}.viscoelastic: law {law!r} cannot be viscoelastic: {why} "
            f"(viscoelastic laws: {', '.join(VISCOELASTIC_LAWS)})"
        )
    values = check_table(table, {**_COMMON_MATERIAL, **own}, where, what=f"a material with law {law!r}")
    viscoelastic = _viscoelastic(values["viscoelastic"], join(where, "viscoelastic")) if "viscoelastic" in values \
        else None
    if mixed and law not in MIXED_LAWS:
        raise CaseFileError(
            f"{where}.law: {law!r} has no isochoric/volumetric split for formulation = \"mixed\" "
            f"(mixed laws: {', '.join(MIXED_LAWS)}); use formulation = \"displacement\""
        )
    if law in LAME_LAWS:
        _elastic_pair(values, law, where, mixed or viscoelastic is not None)
    if law in FIBRE_LAWS and not has_fibres:
        raise CaseFileError(f"{where}: law \"{law}\" needs fibre directions: add a [fibres] table")
    if law in SECOND_FIBRE_LAWS and not has_second:
        second = "family a02" if law == "holzapfel_gasser_ogden" else "material axis a2"
        raise CaseFileError(f"{where}: law \"{law}\" needs a second direction, its {second}: add a [second_fibres] "
                            "table (the keys of [fibres])")
    if law == "ogden" and values.get("convention", "ogden") != "ogden":
        _ogden_coefficients(values["mu"], values["convention"], where)
    if law in PARAMETER_CLASSES:
        given = {k: v for k, v in values.items() if k in own}
        try:
            PARAMETER_CLASSES[law](**given)
        except ParameterError as exc:
            raise CaseFileError(f"{where}: {exc}") from None
    activation = None
    if law == "muscle":
        if "preset" not in values:
            missing = [k for k in ("c1", "c2", "K", "T_max") if k not in values]
            if missing:
                raise CaseFileError(
                    f"{where}: missing required key {missing[0]!r} (or give preset = \"muscle\" | \"tendon\")"
                )
        if "activation" in values:
            raw = values["activation"]
            if isinstance(raw, (int, float)) and not isinstance(raw, bool):
                activation = check_value(raw, Key("number", minimum=0.0), join(where, "activation"))
                if activation > 1.0:
                    raise CaseFileError(f"{where}.activation: must lie in [0, 1], got {raw!r}")
            else:
                activation = check_profile(raw, join(where, "activation"))
    skip = {"law", "region", "density", "volumetric", "preset", "activation", "viscoelastic"}
    return MaterialSpec(
        key=where,
        law=law,
        region=values.get("region"),
        parameters={k: v for k, v in values.items() if k not in skip},
        density=values.get("density"),
        volumetric=values.get("volumetric"),
        preset=values.get("preset"),
        activation=activation,
        viscoelastic=viscoelastic,
    )


def _viscoelastic(table: Mapping, where: str) -> ViscoelasticSpec:
    """``[material.viscoelastic]``: a valid :class:`~hyperfem.materials.PronySeries` and the time scale."""
    values = check_table(table, VISCOELASTIC, where, what="a viscoelastic table")
    try:
        PronySeries(g=values["g"], tau=values["tau"])
    except ParameterError as exc:
        raise CaseFileError(f"{where}: {exc}") from None
    return ViscoelasticSpec(g=values["g"], tau=values["tau"], time_scale=values.get("time_scale"))


def check_viscoelastic_use(materials: Sequence[MaterialSpec], stepping: SteppingSpec) -> None:
    """A viscoelastic material needs a clock that runs forward: a quasi-static ramp to ``end > 0`` (its load
    factor read as time) or a time integration in s whose loads are at the end of the step."""
    for m in materials:
        visco = m.viscoelastic
        if visco is None:
            continue
        where = join(m.key, "viscoelastic")
        if stepping.continuation:
            raise CaseFileError(
                f"{where}: not with stepping type = \"arc_length\" (its load factor is no time: it falls past a "
                "limit point); use a quasi-static ramp or a dynamic run"
            )
        if stepping.dynamic and stepping.scheme == "generalized_alpha":
            raise CaseFileError(
                f"{where}: not with scheme = \"generalized_alpha\" (it evaluates the loads inside the step, "
                "alpha_f > 0, which the history cannot follow); use newmark, backward_euler or quasi_static"
            )
        if stepping.dynamic and visco.time_scale not in (None, 1.0):
            raise CaseFileError(
                f"{where}.time_scale: a dynamic run's time is in s, so time_scale must be 1, got {visco.time_scale!r}"
            )
        if not stepping.dynamic and stepping.end is not None and not stepping.end > 0.0:
            raise CaseFileError(
                f"stepping.end: a viscoelastic material ({m.key}) needs time to run forward, end > 0, "
                f"got {stepping.end!r}"
            )


def check_materials(
    entries: list, mixed: bool, has_fibres: bool, has_second_fibres: bool = False
) -> tuple[MaterialSpec, ...]:
    """The ``[[material]]`` entries: one without region (the whole body), or one per distinct region.

    ``has_fibres``, ``has_second_fibres``: whether the case has ``[fibres]`` and ``[second_fibres]``
    (the laws of :data:`~hyperfem.app.spec.FIBRE_LAWS` and :data:`~hyperfem.app.spec.SECOND_FIBRE_LAWS` need them).
    """
    if not entries:
        raise CaseFileError("material: at least one [[material]] is needed")
    materials = tuple(_material(i, t, mixed, has_fibres, has_second_fibres) for i, t in enumerate(entries))
    whole = [m for m in materials if m.region is None]
    if whole and len(materials) > 1:
        raise CaseFileError(
            f"{whole[0].key}.region: with several materials each needs a region (a cell group of the mesh)"
        )
    seen: dict[str, str] = {}
    for m in materials:
        if m.region is not None and m.region in seen:
            raise CaseFileError(f"{m.key}.region: region {m.region!r} already has a material ({seen[m.region]})")
        if m.region is not None:
            seen[m.region] = m.key
    return materials


def check_fibres(table: Mapping, where: str = "fibres") -> FibreSpec:
    """``[fibres]`` (or ``[second_fibres]``, ``where``): Laplace rule, constant direction or point/cell data."""
    if "type" not in table:
        raise CaseFileError(f"{where}: missing required key 'type' ({', '.join(FIBRE_TYPES)})")
    kind = check_value(table["type"], FIBRE_COMMON["type"], f"{where}.type")
    values = check_table(table, {**FIBRE_COMMON, **FIBRES[kind]}, where, what=f"fibres of type {kind!r}")
    options = {k: v for k, v in values.items() if k not in ("type", "representation")}
    if kind == "file" and "representation" in values:
        raise CaseFileError(
            f"{where}.representation: fibres from a file are P1 (location = \"point\") or DG0 (\"cell\")"
        )
    return FibreSpec(kind, options, values.get("representation", "DG0"))


def check_fibre_use(
    materials: Sequence[MaterialSpec], fibres: FibreSpec | None, second: FibreSpec | None
) -> None:
    """``[fibres]`` and ``[second_fibres]`` must be used by some law; constant Fung axes must be orthogonal.

    (Whether a law that needs them has them is :func:`check_materials`'s check.)
    """
    laws = {m.law for m in materials}
    if fibres is not None and not laws & set(FIBRE_LAWS):
        raise CaseFileError(f"fibres: no material uses fibres (only the laws {', '.join(FIBRE_LAWS)} do)")
    if second is not None and fibres is None:
        raise CaseFileError("second_fibres: the second direction needs the first: add a [fibres] table")
    if second is not None and not laws & set(SECOND_FIBRE_LAWS):
        raise CaseFileError(
            f"second_fibres: no material uses a second direction (only the laws {', '.join(SECOND_FIBRE_LAWS)} do)"
        )
    if "fung_orthotropic" in laws and fibres is not None and second is not None:
        if fibres.type == "constant" and second.type == "constant":
            a1, a2 = fibres.options["direction"], second.options["direction"]
            n1, n2 = math.hypot(*a1), math.hypot(*a2)
            if len(a1) == len(a2) and n1 > 0.0 and n2 > 0.0:
                cosine = sum(x * y for x, y in zip(a1, a2, strict=True)) / (n1 * n2)
                if abs(cosine) > 1e-6:
                    raise CaseFileError(
                        "second_fibres.direction: the axes of law \"fung_orthotropic\" must be orthogonal, but the "
                        f"[fibres] and [second_fibres] directions make cos = {cosine:.6g}"
                    )


def _components(value: object, where: str) -> tuple[int, ...]:
    if not isinstance(value, (list, tuple)) or not value:
        raise CaseFileError(
            f"{where}: expected a non-empty array of components (0, 1, 2 or \"x\", \"y\", \"z\"), "
            f"got {describe(value)}"
        )
    out = []
    for i, c in enumerate(value):
        if isinstance(c, str) and c in AXES:
            out.append(AXES[c])
        elif isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 2:
            out.append(c)
        else:
            raise CaseFileError(f"{where}[{i}]: expected 0, 1, 2 or \"x\", \"y\", \"z\", got {describe(c)}")
    if len(set(out)) != len(out):
        raise CaseFileError(f"{where}: components repeat: {list(value)}")
    return tuple(out)


def _bc(index: int, table: Mapping) -> BCSpec:
    where = join("bc", index)
    if not isinstance(table, Mapping):
        raise CaseFileError(f"{where}: expected a table, got {describe(table)}")
    if "type" not in table:
        raise CaseFileError(f"{where}: missing required key 'type' ({', '.join(BC_TYPES)})")
    kind = check_value(table["type"], _BC_COMMON["type"], join(where, "type"))
    values = check_table(table, {**_BC_COMMON, **BCS[kind]}, where, what=f"a bc of type {kind!r}")
    components = _components(values["components"], join(where, "components")) if "components" in values else None
    if components is not None and len(values["value"]) != len(components):
        raise CaseFileError(
            f"{where}.value: {len(values['value'])} values for {len(components)} components {list(components)}"
        )
    profile = check_profile(values["profile"], join(where, "profile")) if "profile" in values else None
    return BCSpec(
        key=where,
        type=kind,
        boundary=values["boundary"],
        value=values.get("value"),
        components=components,
        axis=values.get("axis"),
        center=values.get("center"),
        angle=values.get("angle"),
        profile=profile,
    )


def check_bcs(entries: Sequence[Mapping]) -> tuple[BCSpec, ...]:
    """The ``[[bc]]`` entries; two conditions on one boundary may not prescribe the same component."""
    bcs = tuple(_bc(i, t) for i, t in enumerate(entries))
    for j, b in enumerate(bcs):
        for a in bcs[:j]:
            if a.boundary != b.boundary:
                continue
            ca, cb = a.constrained, b.constrained
            common = sorted((ca or {0, 1, 2}) & (cb or {0, 1, 2}))
            if common:
                axes = ", ".join("xyz"[c] for c in common)
                raise CaseFileError(
                    f"{b.key}: conflicts with {a.key} on boundary {b.boundary!r}: both prescribe component(s) {axes} "
                    f"({a.type} and {b.type}); give each component of a boundary one condition"
                )
    return bcs


def _load_value(value: object, kind: str, where: str) -> Any:
    if kind == "pressure":
        return value
    if isinstance(value, Mapping):
        field_ = check_table(value, AFFINE, where, what="an affine field (A x + b)")
        rows = field_["matrix"]
        if any(len(r) != len(rows) for r in rows):
            raise CaseFileError(
                f"{where}.matrix: must be square (one row per component), got {len(rows)} rows of "
                f"{[len(r) for r in rows]} entries"
            )
        if "offset" in field_ and len(field_["offset"]) != len(rows):
            raise CaseFileError(f"{where}.offset: {len(field_['offset'])} entries for a {len(rows)}x{len(rows)} matrix")
        return field_
    return check_value(value, Key("numbers"), where)


def _load(index: int, table: Mapping) -> LoadSpec:
    where = join("load", index)
    if not isinstance(table, Mapping):
        raise CaseFileError(f"{where}: expected a table, got {describe(table)}")
    if "type" not in table:
        raise CaseFileError(f"{where}: missing required key 'type' ({', '.join(LOAD_TYPES)})")
    kind = check_value(table["type"], _LOAD_COMMON["type"], join(where, "type"))
    values = check_table(table, {**_LOAD_COMMON, **LOADS[kind]}, where, what=f"a load of type {kind!r}")
    profile = check_profile(values["profile"], join(where, "profile")) if "profile" in values else None
    return LoadSpec(
        key=where,
        type=kind,
        boundary=values.get("boundary"),
        region=values.get("region"),
        value=_load_value(values["value"], kind, join(where, "value")),
        profile=profile,
    )


def check_stepping(table: Mapping) -> SteppingSpec:
    """``[stepping]``: a quasi-static ramp (default) or a time integration (``type = "dynamic"``)."""
    kind = check_value(table.get("type", "quasi-static"), QUASI_STATIC["type"], "stepping.type")
    kinds = {"quasi-static": (QUASI_STATIC, "load ramp"), "dynamic": (DYNAMIC, "time integration"),
             "arc_length": (ARC_LENGTH, "continuation"), "buckling": (BUCKLING, "buckling analysis")}
    own = kinds[kind][0]
    for key in table:
        if key in own:
            continue
        for other_kind, (other, what) in kinds.items():
            if key in other:
                raise CaseFileError(
                    f"stepping.{key}: a key of {other_kind} stepping, not of {kind} stepping "
                    f"(set type = \"{other_kind}\" for a {what})"
                )
    if kind == "buckling":
        values = check_table(table, BUCKLING, "stepping", what="a buckling analysis")
        if values.get("increment", 1.0) == 0.0:
            raise CaseFileError("stepping.increment: must not be 0")
        return SteppingSpec(type=kind, options={k: v for k, v in values.items() if k != "type"})
    if kind == "arc_length":
        values = check_table(table, ARC_LENGTH, "stepping", what="arc-length stepping")
        if "min_load" in values and "end" in values and not values["min_load"] < values["end"]:
            raise CaseFileError(
                f"stepping.min_load: must lie below stepping.end, got {values['min_load']!r} and {values['end']!r}"
            )
        if values.get("direction", 1) not in (1, -1):
            raise CaseFileError(f"stepping.direction: must be 1 or -1, got {values['direction']!r}")
        probe = [k for k in ("stop_probe", "stop_component", "stop_value") if k in values]
        if probe and len(probe) != 3:
            missing = next(k for k in ("stop_probe", "stop_component", "stop_value") if k not in values)
            raise CaseFileError(f"stepping.{missing}: give stop_probe, stop_component and stop_value together")
        options = {k: v for k, v in values.items() if k not in ("type", "solve_initial", *probe)}
        if probe:
            component = "xyz".index(values["stop_component"])
            options["probe_stop"] = (tuple(values["stop_probe"]), component, float(values["stop_value"]))
        options.setdefault("end", None)  # no default end: a continuation stops by max_steps or another limit
        return SteppingSpec(type=kind, options=options, solve_initial=values.get("solve_initial", False))
    if kind == "quasi-static":
        values = check_table(table, QUASI_STATIC, "stepping", what="quasi-static stepping")
        names = {"increment": "initial_increment"}
        options = {
            names.get(k, k): v for k, v in values.items() if k not in ("type", "end", "solve_initial")
        }
        return SteppingSpec(
            type=kind, options=options, end=values.get("end"), solve_initial=values.get("solve_initial", False)
        )
    values = check_table(table, DYNAMIC, "stepping", what="dynamic stepping")
    scheme = values.get("scheme", "newmark")
    scheme_keys: tuple[str, ...] = {"newmark": ("beta", "gamma"), "generalized_alpha": ("rho_inf",)}.get(scheme, ())
    for name in ("beta", "gamma", "rho_inf"):
        if name in values and name not in scheme_keys:
            raise CaseFileError(f"stepping.{name}: not a parameter of scheme {scheme!r}")
    if "rho_inf" in values and values["rho_inf"] > 1.0:
        raise CaseFileError(f"stepping.rho_inf: must lie in [0, 1], got {values['rho_inf']!r}")
    damping = check_table(values["damping"], DAMPING, "stepping.damping") if "damping" in values else {}
    skip = {"type", "scheme", "beta", "gamma", "rho_inf", "lumped_mass", "damping", "initial_acceleration"}
    return SteppingSpec(
        type=kind,
        options={k: v for k, v in values.items() if k not in skip},
        scheme=scheme,
        scheme_options={k: values[k] for k in scheme_keys if k in values},
        lumped_mass=values.get("lumped_mass", False),
        damping=damping,
        initial_acceleration=values.get("initial_acceleration", True),
    )


def check_solver(table: Mapping) -> SolverSpec:
    """``[solver]``: SNES tolerances (sugar for ``snes_*``), PETSc options as given, guard and predictor options."""
    values = check_table(table, SOLVER, "solver")
    petsc = {}
    for key, value in dict(values.get("petsc_options", {})).items():
        where = f"solver.petsc_options.{key}"
        if key.startswith("-"):
            raise CaseFileError(f"{where}: write PETSc option names without the leading '-' (e.g. ksp_type)")
        if not isinstance(value, (str, int, float, bool)):
            raise CaseFileError(f"{where}: expected a string, number or boolean, got {describe(value)}")
        petsc[key] = value
    for sugar, option in _SUGAR.items():
        if sugar in values:
            if option in petsc:
                raise CaseFileError(f"solver.{sugar}: also given as solver.petsc_options.{option}; give it once")
            petsc[option] = values[sugar]
    options: dict[str, object] = {k: values[k] for k in ("step_filter", "predictor") if k in values}
    if "min_jacobian" in values:
        mj = values["min_jacobian"]
        if mj is False:
            options["min_jacobian"] = None
        elif mj == "auto" or (isinstance(mj, (int, float)) and not isinstance(mj, bool)):
            options["min_jacobian"] = mj if mj == "auto" else check_value(mj, Key("number"), "solver.min_jacobian")
        else:
            raise CaseFileError(f"solver.min_jacobian: expected a number, \"auto\" or false, got {describe(mj)}")
    return SolverSpec(petsc_options=petsc, options=options)


def check_output(
    table: Mapping,
    name: str,
    directory: str | Path | None,
    stepping: SteppingSpec,
    bcs: Sequence[BCSpec] = (),
    fibres: FibreSpec | None = None,
    materials: Sequence[MaterialSpec] = (),
) -> OutputSpec:
    """``[output]``: files, fields, probes, reactions, checkpoints (``directory`` replaces its folder)."""
    values = check_table(table, OUTPUT, "output")
    if "times" in values and "every" in values:
        raise CaseFileError("output.every: give either times or every, not both")
    if stepping.type in ("arc_length", "buckling") and ("times" in values or "every" in values):
        key = "times" if "times" in values else "every"
        why = "the load factor goes up and down; every step is written" if stepping.continuation else "no steps"
        raise CaseFileError(f"output.{key}: not with {stepping.type} stepping ({why})")
    end = float(stepping.options["t_end"]) if stepping.dynamic else (stepping.end if stepping.end is not None else 1.0)
    times = values.get("times")
    if times is not None:
        _check_output_times(times, end, stepping.dynamic)
    if "every" in values:
        times = _every_times(values["every"], end, stepping.dynamic)
    fields = tuple(values.get("fields", ("displacement",)))
    if "fibre_stretch" in fields and fibres is None:
        raise CaseFileError("output.fields: fibre_stretch needs a [fibres] table")
    if "activation" in fields and not any(isinstance(m.activation, Profile) for m in materials):
        raise CaseFileError("output.fields: activation needs a material with a time-dependent activation")
    if "format" in values and not fields:
        raise CaseFileError("output.format: no fields are written (fields = [])")
    held = list(dict.fromkeys(bc.boundary for bc in bcs))
    raw = values.get("reactions", "all")
    if raw == "all":
        reactions = None
    elif raw is False:
        reactions = ()
    else:
        reactions = check_value(raw, Key("strings"), "output.reactions")
        for i, boundary in enumerate(reactions):
            if boundary not in held:
                raise CaseFileError(
                    f"output.reactions[{i}]: boundary {boundary!r} has no Dirichlet condition"
                    f"{suggestion(boundary, held)} (boundaries with one: {', '.join(held) or 'none'})"
                )
    if values.get("checkpoint", True) is False:
        if "checkpoint_every" in values or "checkpoint_keep" in values:
            key = "checkpoint_every" if "checkpoint_every" in values else "checkpoint_keep"
            raise CaseFileError(f"output.{key}: checkpoints are off (checkpoint = false)")
        every = None
    else:
        every = values.get("checkpoint_every", 10)
    folder = Path(directory) if directory is not None else Path(values.get("directory", Path("output") / name))
    render = _render(values.get("render", False), fibres, materials)
    return OutputSpec(
        directory=folder,
        fields=fields,
        format=values.get("format", "vtx"),
        times=times,
        csv=values.get("csv", True),
        summary=values.get("summary", True),
        convergence=values.get("convergence", True),
        probes=values.get("probes", ()),
        reactions=reactions,
        checkpoint_every=every,
        checkpoint_keep=values.get("checkpoint_keep"),
        progress=values.get("progress", True),
        stability=values.get("stability", 0),
        render=render,
    )


def _span_text(end: float, dynamic: bool) -> str:
    """``time span [0, 1] (stepping.t_end)`` or ``load-factor span [0, 1] (stepping.end)``."""
    low, high = min(0.0, end), max(0.0, end)
    what, key = ("time span", "stepping.t_end") if dynamic else ("load-factor span", "stepping.end")
    return f"{what} [{low:g}, {high:g}] ({key})"


def _check_output_times(times: Sequence[float], end: float, dynamic: bool) -> None:
    """Refuse ``output.times`` outside the run: no frame would ever be written there."""
    low, high = min(0.0, end), max(0.0, end)
    slack = 1e-9 * max(1.0, abs(end))
    for i, t in enumerate(times):
        if not low - slack <= t <= high + slack:
            raise CaseFileError(
                f"output.times[{i}]: {t:g} is outside the run's {_span_text(end, dynamic)}; no frame would be "
                "written there"
            )


def _every_times(every: float, end: float, dynamic: bool) -> tuple[float, ...]:
    """The output times of ``output.every``: its multiples up to ``end``, and ``end`` itself (the final state).

    An interval longer than the run leaves only the final state (with a warning).
    """
    span = abs(end)
    sign = 1.0 if end >= 0 else -1.0
    n = int(math.floor(span / every + 1e-9))
    times = [k * every * sign for k in range(1, n + 1)]
    if not times or abs(times[-1] - end) > 1e-9 * max(1.0, span):
        times.append(float(end))
    if n == 0 and span > 0:
        from hyperfem.app.report import warn  # one line on rank 0, as every warning of the command

        warn(
            f"output.every: {every:g} is longer than the run's {_span_text(end, dynamic)}; the field file gets "
            "the initial and the final state only"
        )
    return tuple(times)


def _render(raw: object, fibres: FibreSpec | None, materials: Sequence[MaterialSpec]) -> RenderSpec | None:
    """``output.render``: ``true`` (defaults), ``false`` (none) or a table of :data:`RENDER` keys."""
    where = "output.render"
    if raw is False:
        return None
    if raw is True:
        return RenderSpec()
    if not isinstance(raw, Mapping):
        raise CaseFileError(f"{where}: expected true, false or a table of render options, got {describe(raw)}")
    values = check_table(raw, RENDER, where, what="output.render")
    if "window_size" in values:
        size = values["window_size"]
        if not (
            isinstance(size, (list, tuple))
            and len(size) == 2
            and all(isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in size)
        ):
            raise CaseFileError(f"{where}.window_size: expected two positive integers [width, height], got "
                                f"{describe(size)}")
        values["window_size"] = tuple(size)
    if "title" in values and not isinstance(values["title"], (bool, str)):
        raise CaseFileError(f"{where}.title: expected a string or true/false, got {describe(values['title'])}")
    if values.get("undeformed") == "none":
        values["undeformed"] = None
    if "clim" in values and not values["clim"][0] < values["clim"][1]:
        raise CaseFileError(f"{where}.clim: needs low < high, got {list(values['clim'])}")
    scalars = values.get("scalars", "displacement")
    if scalars == "fibre_stretch" and fibres is None:
        raise CaseFileError(f"{where}.scalars: fibre_stretch needs a [fibres] table")
    if scalars == "activation" and not any(isinstance(m.activation, Profile) for m in materials):
        raise CaseFileError(f"{where}.scalars: activation needs a material with a time-dependent activation")
    try:
        check_render_options(**{k: values[k] for k in ("window_size", "undeformed", "view", "up", "scale")
                                if k in values})
    except ParameterError as exc:
        raise CaseFileError(f"{where}: {exc}") from exc
    return RenderSpec(tuple((k, values[k]) for k in RENDER if k in values))


def _surface_contact(where: str, kind: str, values: Mapping, source: Path) -> ContactSpec:
    """A ``self``, ``pair`` or ``tool`` contact: its boundaries (one or more; two for a pair, each once), the file."""
    names = values["boundaries"]
    if kind in ("pair", "tie") and len(names) != 2:
        raise CaseFileError(f"{where}.boundaries: a {kind} names exactly two facet groups, got {len(names)}")
    if not names:
        raise CaseFileError(f"{where}.boundaries: name at least one facet group")
    twice = [name for i, name in enumerate(names) if name in names[:i]]
    if twice:
        raise CaseFileError(f"{where}.boundaries: {twice[0]!r} is named twice")
    if values.get("subdivision", 1) > 8:
        raise CaseFileError(f"{where}.subdivision: must be <= 8, got {values['subdivision']!r}")
    path = None
    if kind == "tool":
        path = Path(values["file"]).expanduser()
        path = path if path.is_absolute() else (source.parent / path).resolve()
        if not path.is_file():
            raise CaseFileError(f"{where}.file: tool surface file not found: {path}")
    profile = check_profile(values["profile"], join(where, "profile")) if "profile" in values else None
    path_ = None
    if "path" in values:
        path_ = _waypoints(values, join(where, "path"))
    return ContactSpec(
        key=where,
        type=kind,
        boundaries=tuple(names),
        path=path_,
        rotation=_contact_rotation(values, join(where, "rotation")),
        file=path,
        dhat=values.get("dhat"),
        stiffness=values.get("stiffness"),
        motion=values.get("motion"),
        profile=profile,
        offset=values.get("offset"),
        scale=values.get("scale"),
        safety=values.get("safety"),
        name=values.get("name"),
        tolerance=values.get("tolerance"),
        friction=values.get("friction", 0.0),
        friction_epsilon=values.get("friction_epsilon"),
        subdivision=values.get("subdivision"),
    )


def _waypoints(values: Mapping, where: str) -> Waypoints:
    """A moving obstacle's or tool's ``path = {times, points}`` (not with ``motion`` or ``profile``)."""
    for other in ("motion", "profile"):
        if other in values:
            raise CaseFileError(f"{where}: give either path or {other}, not both")
    if not isinstance(values["path"], Mapping):
        raise CaseFileError(f"{where}: expected a table {{times, points}}, got {describe(values['path'])}")
    table = check_table(values["path"], WAYPOINTS, where, what="a path (waypoints)")
    lengths = sorted({len(row) for row in table["points"]})
    if lengths not in ([2], [3]):
        raise CaseFileError(f"{where}.points: one [x, y, z] (or [x, y] on a 2D mesh) per time, got rows of "
                            f"{[len(r) for r in table['points']]}")
    try:
        return Waypoints(table["times"], table["points"])
    except ParameterError as exc:
        raise CaseFileError(f"{where}: {str(exc).removeprefix('Waypoints: ')}") from None


def _contact_rotation(values: Mapping, where: str) -> ContactRotationSpec | None:
    """An obstacle's ``rotation = {axis, center, angle, profile}`` (``None`` where it has none)."""
    if "rotation" not in values:
        return None
    table = check_table(values["rotation"], CONTACT_ROTATION, where, what="a rotation")
    if not any(table["axis"]):
        raise CaseFileError(f"{where}.axis: must not be zero, got {list(table['axis'])}")
    profile = check_profile(table["profile"], join(where, "profile")) if "profile" in table else None
    return ContactRotationSpec(axis=table["axis"], center=table["center"], angle=table["angle"], profile=profile)


def _contact(index: int, table: Mapping, source: Path) -> ContactSpec:
    where = join("contact", index)
    if not isinstance(table, Mapping):
        raise CaseFileError(f"{where}: expected a table, got {describe(table)}")
    if "type" not in table:
        raise CaseFileError(f"{where}: missing required key 'type' ({', '.join(CONTACT_TYPES)})")
    kind = check_value(table["type"], _CONTACT_COMMON["type"], join(where, "type"))
    values = check_table(table, {**_CONTACT_COMMON, **CONTACTS[kind]}, where, what=f"a contact of type {kind!r}")
    if "name" in values and not NAME.fullmatch(values["name"]):
        raise CaseFileError(f"{where}.name: use letters, digits and _.+- only (it names output columns), got "
                            f"{values['name']!r}")
    if kind in MESH_CONTACT_TYPES:
        return _surface_contact(where, kind, values, source)
    anchor = "center" if kind == "sphere" else "point"
    if kind == "plane" and not any(values["normal"]):
        raise CaseFileError(f"{where}.normal: must not be zero, got {list(values['normal'])}")
    if kind == "cylinder" and not any(values["axis"]):
        raise CaseFileError(f"{where}.axis: must not be zero, got {list(values['axis'])}")
    for name in ("normal", "motion"):
        if name in values and len(values[name]) != len(values[anchor]):
            raise CaseFileError(
                f"{where}.{name}: {len(values[name])} components for a {anchor} of {len(values[anchor])}"
            )
    profile = check_profile(values["profile"], join(where, "profile")) if "profile" in values else None
    path = _waypoints(values, join(where, "path")) if "path" in values else None
    if path is not None and len(path.points[0]) != len(values[anchor]):
        raise CaseFileError(f"{where}.path.points: rows of {len(path.points[0])} components for a {anchor} of "
                            f"{len(values[anchor])}")
    if "rotation" in values and len(values[anchor]) != 3:
        raise CaseFileError(f"{where}.rotation: a rotation needs a 3D {kind} ({anchor} of {len(values[anchor])})")
    return ContactSpec(
        key=where,
        type=kind,
        boundary=values["boundary"],
        rotation=_contact_rotation(values, join(where, "rotation")),
        point=values.get("point"),
        normal=values.get("normal"),
        center=values.get("center"),
        radius=values.get("radius"),
        axis=values.get("axis"),
        dhat=values.get("dhat"),
        stiffness=values.get("stiffness"),
        motion=values.get("motion"),
        path=path,
        profile=profile,
        friction=values.get("friction", 0.0),
        friction_epsilon=values.get("friction_epsilon"),
    )


def check_contacts(entries: Sequence[Mapping], source: Path) -> tuple[ContactSpec, ...]:
    """The ``[[contact]]`` entries (a tool's ``file`` relative to the case file ``source``); output names unique."""
    contacts = tuple(_contact(i, t, source) for i, t in enumerate(entries))
    seen: dict[str, str] = {}
    for i, contact in enumerate(contacts):
        name = contact.name or (f"contact_{i}" if len(contacts) > 1 else "contact")
        if name in seen:
            raise CaseFileError(
                f"{contact.key}.name: {name!r} is the output name of {seen[name]} too (it prefixes the output columns)"
            )
        seen[name] = contact.key
    return contacts


def check_loads(entries: Sequence[Mapping]) -> tuple[LoadSpec, ...]:
    """The ``[[load]]`` entries."""
    return tuple(_load(i, t) for i, t in enumerate(entries))


def check_problem(table: Mapping) -> ProblemSpec:
    """``[problem]``."""
    return ProblemSpec(**check_table(table, PROBLEM, "problem"))
