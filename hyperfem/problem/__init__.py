"""Boundary-value problems: energies, loads and Dirichlet conditions by name."""

from hyperfem.problem.base import EnergyProblem
from hyperfem.problem.boundary_conditions import Clamp, PrescribedDisplacement
from hyperfem.problem.hyperelastic import EnergyDensity, HyperelasticProblem, default_quadrature_degree
from hyperfem.problem.loads import BodyForce, DeadTraction, FollowerPressure, FollowerTraction
from hyperfem.problem.mixed import MixedHyperelasticProblem, SplitEnergy, solid_problem

__all__ = [
    "BodyForce",
    "Clamp",
    "DeadTraction",
    "EnergyDensity",
    "EnergyProblem",
    "FollowerPressure",
    "FollowerTraction",
    "HyperelasticProblem",
    "MixedHyperelasticProblem",
    "PrescribedDisplacement",
    "SplitEnergy",
    "default_quadrature_degree",
    "solid_problem",
]
