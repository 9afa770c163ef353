"""Strain-energy densities :math:`\\psi(F, \\text{params})` and their parameter sets.

Each law lives in its own module as a pure function of the deformation
gradient; the matching ``*_stress`` function is the closed-form first
Piola–Kirchhoff stress used only to verify what UFL derives.

Laws that need the polar rotation of :math:`F` (fixed-corotated, ARAP,
corotational linear) are callable objects holding it in quadrature fields
(:mod:`~hyperfem.materials.polar`); :mod:`~hyperfem.materials.invertibility`
says which energies tolerate inverted elements.

The fibre-reinforced laws (muscle, Holzapfel–Gasser–Ogden, Weiss, Fung orthotropic)
take their reference directions after the deformation gradient: ``psi(F, a0, ..., params)``.

The principal-stretch laws (Ogden, Hencky, Saint Venant–Kirchhoff in stretches) are built on
:func:`eigenvalue_sum` of :mod:`~hyperfem.materials.principal_stretches`, exact where stretches coincide.
"""

from hyperfem.materials.linear_elastic import linear_elastic, linear_elastic_stress
from hyperfem.materials.neo_hookean import neo_hookean, neo_hookean_stress
from hyperfem.materials.parameters import LameParameters
from hyperfem.materials.robust_neo_hookean import (
    log_taylor3,
    robust_neo_hookean,
    robust_neo_hookean_stress,
)
from hyperfem.materials.saint_venant_kirchhoff import (
    saint_venant_kirchhoff,
    saint_venant_kirchhoff_stress,
)

__all__ = [
    "LameParameters",
    "linear_elastic",
    "linear_elastic_stress",
    "log_taylor3",
    "neo_hookean",
    "neo_hookean_stress",
    "robust_neo_hookean",
    "robust_neo_hookean_stress",
    "saint_venant_kirchhoff",
    "saint_venant_kirchhoff_stress",
]

from hyperfem.materials.mooney_rivlin import (  # noqa: E402
    MooneyRivlinParameters,
    mooney_rivlin,
    mooney_rivlin_stress,
)
from hyperfem.materials.muscle import (  # noqa: E402
    MuscleParameters,
    muscle,
    muscle_isochoric,
    muscle_stress,
    transversely_isotropic,
)
from hyperfem.materials.volumetric import VOLUMETRIC_LAWS, volumetric_energy  # noqa: E402

__all__ += [
    "MooneyRivlinParameters",
    "MuscleParameters",
    "VOLUMETRIC_LAWS",
    "mooney_rivlin",
    "mooney_rivlin_stress",
    "muscle",
    "muscle_isochoric",
    "muscle_stress",
    "transversely_isotropic",
    "volumetric_energy",
]

from hyperfem.materials.fixed_corotated import (  # noqa: E402
    ARAP,
    FixedCorotated,
    PolarRotationEnergy,
    arap,
    arap_stress,
    fixed_corotated,
    fixed_corotated_stress,
)
from hyperfem.materials.corotational_linear import (  # noqa: E402
    CorotationalLinear,
    StepRotation,
    corotational_linear,
    corotational_linear_energy,
    corotational_linear_stress,
)
from hyperfem.materials.invertibility import invertible, is_invertible, with_parameters  # noqa: E402
from hyperfem.materials.polar import (  # noqa: E402
    QuadratureField,
    RotationField,
    polar_decomposition,
    polar_rotation,
    polar_svd,
    rotation_derivative,
)
from hyperfem.materials.stable_neo_hookean import (  # noqa: E402
    StableNeoHookeanParameters,
    stable_neo_hookean,
    stable_neo_hookean_stress,
)

__all__ += [
    "ARAP",
    "CorotationalLinear",
    "FixedCorotated",
    "PolarRotationEnergy",
    "QuadratureField",
    "RotationField",
    "StableNeoHookeanParameters",
    "StepRotation",
    "arap",
    "arap_stress",
    "corotational_linear",
    "corotational_linear_energy",
    "corotational_linear_stress",
    "fixed_corotated",
    "fixed_corotated_stress",
    "invertible",
    "is_invertible",
    "polar_decomposition",
    "polar_rotation",
    "polar_svd",
    "rotation_derivative",
    "stable_neo_hookean",
    "stable_neo_hookean_stress",
    "with_parameters",
]

from hyperfem.materials.arruda_boyce import (  # noqa: E402
    ArrudaBoyceParameters,
    arruda_boyce,
    arruda_boyce_isochoric,
    arruda_boyce_stress,
)
from hyperfem.materials.fung import (  # noqa: E402
    FungOrthotropicParameters,
    fung_orthotropic,
    fung_orthotropic_isochoric,
    fung_orthotropic_stress,
)
from hyperfem.materials.gent import GentParameters, gent, gent_isochoric, gent_stress  # noqa: E402
from hyperfem.materials.holzapfel_gasser_ogden import (  # noqa: E402
    HolzapfelGasserOgdenParameters,
    holzapfel_gasser_ogden,
    holzapfel_gasser_ogden_isochoric,
    holzapfel_gasser_ogden_stress,
)
from hyperfem.materials.veronda_westmann import (  # noqa: E402
    VerondaWestmannParameters,
    veronda_westmann,
    veronda_westmann_isochoric,
    veronda_westmann_stress,
)
from hyperfem.materials.weiss import WeissParameters, weiss, weiss_isochoric, weiss_stress  # noqa: E402
from hyperfem.materials.yeoh import (  # noqa: E402
    ReducedPolynomialParameters,
    YeohParameters,
    reduced_polynomial,
    reduced_polynomial_isochoric,
    reduced_polynomial_stress,
    yeoh,
    yeoh_isochoric,
    yeoh_stress,
)

__all__ += [
    "ArrudaBoyceParameters",
    "FungOrthotropicParameters",
    "GentParameters",
    "HolzapfelGasserOgdenParameters",
    "ReducedPolynomialParameters",
    "VerondaWestmannParameters",
    "WeissParameters",
    "YeohParameters",
    "arruda_boyce",
    "arruda_boyce_isochoric",
    "arruda_boyce_stress",
    "fung_orthotropic",
    "fung_orthotropic_isochoric",
    "fung_orthotropic_stress",
    "gent",
    "gent_isochoric",
    "gent_stress",
    "holzapfel_gasser_ogden",
    "holzapfel_gasser_ogden_isochoric",
    "holzapfel_gasser_ogden_stress",
    "reduced_polynomial",
    "reduced_polynomial_isochoric",
    "reduced_polynomial_stress",
    "veronda_westmann",
    "veronda_westmann_isochoric",
    "veronda_westmann_stress",
    "weiss",
    "weiss_isochoric",
    "weiss_stress",
    "yeoh",
    "yeoh_isochoric",
    "yeoh_stress",
]

from hyperfem.materials.ogden import (  # noqa: E402
    CONVENTIONS,
    OgdenParameters,
    ogden,
    ogden_equibiaxial_stress,
    ogden_isochoric,
    ogden_pure_shear_stress,
    ogden_uniaxial_stress,
)
from hyperfem.materials.principal_stretches import (  # noqa: E402
    SpectralInvariants,
    eigenvalue_power_sum,
    eigenvalue_sum,
    hencky,
    saint_venant_kirchhoff_principal,
    spectral_invariants,
    volume_preservation,
)

__all__ += [
    "CONVENTIONS",
    "OgdenParameters",
    "SpectralInvariants",
    "eigenvalue_power_sum",
    "eigenvalue_sum",
    "hencky",
    "ogden",
    "ogden_equibiaxial_stress",
    "ogden_isochoric",
    "ogden_pure_shear_stress",
    "ogden_uniaxial_stress",
    "saint_venant_kirchhoff_principal",
    "spectral_invariants",
    "volume_preservation",
]

from hyperfem.materials.fitting import (  # noqa: E402
    FIT_LAWS,
    TRELOAR,
    Curve,
    FitResult,
    ModeError,
    StabilityLoss,
    fit,
    plot_fits,
    read_curves,
    treloar_data,
)
from hyperfem.materials.homogeneous import MODES, HomogeneousResponse, mode_stretches  # noqa: E402

__all__ += [
    "FIT_LAWS",
    "MODES",
    "TRELOAR",
    "Curve",
    "FitResult",
    "HomogeneousResponse",
    "ModeError",
    "StabilityLoss",
    "fit",
    "mode_stretches",
    "plot_fits",
    "read_curves",
    "treloar_data",
]

from hyperfem.materials.prony import PronySeries  # noqa: E402
from hyperfem.materials.prony_fit import (  # noqa: E402
    PronyFit,
    RelaxationCurve,
    fit_prony,
    plot_relaxation,
    read_relaxation,
)
from hyperfem.materials.viscoelastic import Viscoelastic, ViscousHistory  # noqa: E402

__all__ += ["PronySeries", "Viscoelastic", "ViscousHistory"]
__all__ += ["PronyFit", "RelaxationCurve", "fit_prony", "plot_relaxation", "read_relaxation"]
