"""Strain-energy densities :math:`\\psi(F, \\text{params})` and their parameter sets.

Each law lives in its own module as a pure function of the deformation
gradient; the matching ``*_stress`` function is the closed-form first
Piola–Kirchhoff stress used only to verify what UFL derives.

Laws that need the polar rotation of :math:`F` (fixed-corotated, ARAP,
corotational linear) are callable objects holding it in quadrature fields
(:mod:`~hyperfem.materials.polar`); :mod:`~hyperfem.materials.invertibility`
says which energies tolerate inverted elements.
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
