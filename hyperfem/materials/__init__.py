"""Strain-energy densities :math:`\\psi(F, \\text{params})` and their parameter sets.

Each law lives in its own module as a pure function of the deformation
gradient; the matching ``*_stress`` function is the closed-form first
Piola–Kirchhoff stress used only to verify what UFL derives.
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
