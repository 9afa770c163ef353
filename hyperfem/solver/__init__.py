"""Nonlinear solution: Newton (PETSc SNES), the linear-solver layer, and the one stepper.

* :mod:`~hyperfem.solver.newton` — :class:`NewtonSolver` (the SNES wiring and
  the solve) and :class:`SolveRecord`, built from:
  :mod:`~hyperfem.solver.options` (defaults, merging, the unique prefix),
  :mod:`~hyperfem.solver.objective` (the energy line search and its round-off guard),
  :mod:`~hyperfem.solver.filters` (the step-filter protocol, the inversion
  filters and their composition; :mod:`~hyperfem.solver.step_filter` holds the
  exact filter's geometry), :mod:`~hyperfem.solver.roundoff` (the round-off stop)
  and :mod:`~hyperfem.solver.predictor` (the boundary-increment predictor);
* :mod:`~hyperfem.solver.linear` — :class:`LinearSolver` and the automatic choice
  (MUMPS LU, or CG/GMRES + GAMG with rigid-body modes, the two-level p-multigrid of
  :mod:`~hyperfem.solver.pmultigrid` from P2, a Schur field split for the mixed problem);
* :mod:`~hyperfem.solver.constraints` — do the Dirichlet conditions fix every rigid motion;
* :mod:`~hyperfem.solver.stepping` — :class:`StepPolicy` acting on a stage
  (quasi-static or dynamic), :func:`solve_quasistatic`.
"""

from hyperfem.solver.filters import (
    ComposedFilters,
    ExactInversionFilter,
    JacobianBisectionFilter,
    NewtonStepFilter,
    NoAdmissibleStep,
)
from hyperfem.solver.linear import LinearSolver, choose_linear_solver
from hyperfem.solver.newton import DEFAULT_PETSC_OPTIONS, ROUNDOFF_FACTOR, NewtonSolver, RoundoffWarning, SolveRecord
from hyperfem.solver.stepping import (
    DynamicStage,
    LoadStepping,
    QuasiStaticStage,
    Stage,
    StepPolicy,
    StepRecord,
    run_steps,
    solve_quasistatic,
)

__all__ = [
    "DEFAULT_PETSC_OPTIONS",
    "ComposedFilters",
    "DynamicStage",
    "ExactInversionFilter",
    "JacobianBisectionFilter",
    "LinearSolver",
    "LoadStepping",
    "NewtonSolver",
    "NewtonStepFilter",
    "NoAdmissibleStep",
    "QuasiStaticStage",
    "ROUNDOFF_FACTOR",
    "RoundoffWarning",
    "SolveRecord",
    "Stage",
    "StepPolicy",
    "StepRecord",
    "choose_linear_solver",
    "run_steps",
    "solve_quasistatic",
]

from hyperfem.solver.step_filter import StepFilter, exact_filter_applies  # noqa: E402

__all__ += ["StepFilter", "exact_filter_applies"]
from hyperfem.solver.projected import ProjectedTangent, projected_newton_solver  # noqa: E402

__all__ += ["ProjectedTangent", "projected_newton_solver"]
from hyperfem.solver.arc_length import ArcLength, ArcLengthRecord, ArcLengthStage, continue_arc_length  # noqa: E402
from hyperfem.solver.inertia import negative_pivots  # noqa: E402

__all__ += ["ArcLength", "ArcLengthRecord", "ArcLengthStage", "continue_arc_length", "negative_pivots"]
from hyperfem.solver.garbage import release_garbage, state_communicators  # noqa: E402

__all__ += ["release_garbage", "state_communicators"]
