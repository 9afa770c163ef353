"""Nonlinear solution: Newton (PETSc SNES) and quasi-static load stepping."""

from hyperfem.solver.newton import DEFAULT_PETSC_OPTIONS, ROUNDOFF_FACTOR, NewtonSolver, RoundoffWarning, SolveRecord
from hyperfem.solver.stepping import LoadStepping, StepRecord, solve_quasistatic

__all__ = [
    "DEFAULT_PETSC_OPTIONS",
    "LoadStepping",
    "NewtonSolver",
    "ROUNDOFF_FACTOR",
    "RoundoffWarning",
    "SolveRecord",
    "StepRecord",
    "solve_quasistatic",
]
