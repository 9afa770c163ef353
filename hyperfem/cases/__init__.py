"""Reference set-ups from the seed documents, shared by demos, tests and benchmarks.

* :mod:`~hyperfem.cases.cantilever` — Erleben's static cantilever (bend, twist)
  and its mesh-convergence table;
* :mod:`~hyperfem.cases.cantilever_dynamics` — the eight dynamic cantilever
  experiments of seed 003, §5.7;
* :mod:`~hyperfem.cases.beam_theory` — analytic beam frequencies that verify
  the dynamics;
* :mod:`~hyperfem.cases.muscle` — the fusiform muscle of seed 000 (materials,
  isometric and free experiments).
"""

from hyperfem.cases.beam_theory import cowper_shear_coefficient, euler_bernoulli_cantilever, timoshenko_cantilever
from hyperfem.cases.cantilever import (
    BEND_TRACTION,
    MESH_CONVERGENCE,
    REFERENCE,
    TEST_POINT,
    TWIST_MAGNITUDE,
    CantileverSpec,
    bend_load,
    convergence_note,
    mesh_size_of,
    twist_load,
)
from hyperfem.cases.cantilever_dynamics import CASES, CantileverDynamics, cantilever_problem
from hyperfem.cases.muscle import EXPERIMENTS, MUSCLE_DENSITY, muscle_materials, muscle_problem

__all__ = [
    "BEND_TRACTION",
    "CASES",
    "EXPERIMENTS",
    "MESH_CONVERGENCE",
    "MUSCLE_DENSITY",
    "REFERENCE",
    "TEST_POINT",
    "TWIST_MAGNITUDE",
    "CantileverDynamics",
    "CantileverSpec",
    "bend_load",
    "cantilever_problem",
    "convergence_note",
    "cowper_shear_coefficient",
    "euler_bernoulli_cantilever",
    "mesh_size_of",
    "muscle_materials",
    "muscle_problem",
    "timoshenko_cantilever",
    "twist_load",
]
