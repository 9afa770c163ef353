"""hyperfem: energy-based large-deformation solid mechanics on FEniCSx.

Write a strain-energy density :math:`\\psi(F)` in UFL, point at a gmsh mesh with
named physical groups, and solve with PETSc SNES:

>>> from mpi4py import MPI
>>> import hyperfem as hf
>>> domain = hf.mesh.beam_mesh(h=2.0)
>>> params = hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3)
>>> problem = hf.HyperelasticProblem(
...     domain, lambda F: hf.materials.neo_hookean(F, params),
...     bcs=[hf.Clamp("clamped")], loads=[hf.DeadTraction("free_end", (0, -5e3, 0))])
>>> steps = hf.solve_quasistatic(hf.NewtonSolver(problem))

Runs with output (VTX, probes, reaction forces, per-step CSV/JSON) are a
:class:`~hyperfem.simulation.Simulation`, for statics and dynamics alike.
"""

import os

# Threaded OpenBLAS under MUMPS was measured ~10x slower on small ranks: one
# thread per rank unless the user chose (must be set before numpy/PETSc load).
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from mpi4py import MPI  # noqa: E402, F401  (must precede dolfinx / petsc4py)

from hyperfem import contact, dynamics, errors, kinematics, loading, materials, mesh, simulation
from hyperfem.errors import (
    CheckpointError,
    ConvergenceError,
    HyperfemError,
    MeshError,
    MeshFileNotFoundError,
    OutputError,
    ParameterError,
    UnknownGroupError,
)
from hyperfem.mesh import Domain, beam_mesh, read_mesh
from hyperfem.problem import (
    BodyForce,
    Clamp,
    DeadTraction,
    FollowerPressure,
    FollowerTraction,
    HyperelasticProblem,
    PrescribedDisplacement,
)
from hyperfem.solver import (
    ROUNDOFF_FACTOR,
    LoadStepping,
    NewtonSolver,
    RoundoffWarning,
    SolveRecord,
    StepRecord,
    solve_quasistatic,
)
from hyperfem.simulation import Simulation
from hyperfem.solver.stepping import StepPolicy

__version__ = "0.1.0"

__all__ = [
    "CheckpointError",
    "BodyForce",
    "Clamp",
    "ConvergenceError",
    "DeadTraction",
    "Domain",
    "FollowerPressure",
    "FollowerTraction",
    "HyperelasticProblem",
    "HyperfemError",
    "LoadStepping",
    "MeshError",
    "MeshFileNotFoundError",
    "NewtonSolver",
    "ROUNDOFF_FACTOR",
    "RoundoffWarning",
    "OutputError",
    "ParameterError",
    "PrescribedDisplacement",
    "Simulation",
    "SolveRecord",
    "StepPolicy",
    "StepRecord",
    "UnknownGroupError",
    "beam_mesh",
    "contact",
    "dynamics",
    "errors",
    "kinematics",
    "loading",
    "materials",
    "mesh",
    "read_mesh",
    "simulation",
    "solve_quasistatic",
]
