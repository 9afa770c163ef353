"""Boundary-value problems: energies, loads and Dirichlet conditions by name."""

from hyperfem.problem.boundary_conditions import Clamp, PrescribedDisplacement, linear_profile
from hyperfem.problem.hyperelastic import EnergyDensity, HyperelasticProblem, default_quadrature_degree
from hyperfem.problem.loads import BodyForce, DeadTraction, FollowerPressure, FollowerTraction

__all__ = [
    "BodyForce",
    "Clamp",
    "DeadTraction",
    "EnergyDensity",
    "FollowerPressure",
    "FollowerTraction",
    "HyperelasticProblem",
    "PrescribedDisplacement",
    "default_quadrature_degree",
    "linear_profile",
]
from hyperfem.problem.mixed import MixedHyperelasticProblem, ReactionForce, SplitEnergy, solid_problem  # noqa: E402

__all__ += ["MixedHyperelasticProblem", "ReactionForce", "SplitEnergy", "solid_problem"]
