"""PETSc options of :class:`~hyperfem.solver.NewtonSolver`: defaults, merging, the prefix, rejected options.

The options of a solver are, from lowest to highest priority: the SNES
defaults (:data:`SNES_DEFAULTS`, with the ``cp`` line search for
non-conservative problems), the KSP/PC options of its
:class:`~hyperfem.solver.linear.LinearSolver`, and the user's
``petsc_options``. They live under a unique prefix ending in ``_``; nothing
stays in the global options database, also when PETSc rejects them.
"""

from __future__ import annotations

from collections.abc import Mapping

from mpi4py import MPI  # noqa: F401  (before petsc4py)
from petsc4py import PETSc

from hyperfem.errors import ParameterError
from hyperfem.solver.linear import DIRECT, unique_prefix

__all__ = [
    "DEFAULT_PETSC_OPTIONS",
    "SNES_DEFAULTS",
    "clean_options",
    "describe_option_error",
    "merge_options",
    "solver_prefix",
]

SNES_DEFAULTS: dict[str, object] = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "bt",
    "snes_rtol": 1e-9,
    "snes_atol": 1e-10,
    "snes_stol": 0.0,
    "snes_max_it": 50,
}
"""SNES defaults of :class:`~hyperfem.solver.NewtonSolver`; the KSP/PC part comes from its linear solver."""

DEFAULT_PETSC_OPTIONS: dict[str, object] = {**SNES_DEFAULTS, **DIRECT}
"""SNES defaults plus the direct solver small problems get (:func:`~hyperfem.solver.linear.choose_linear_solver`)."""


def solver_prefix(prefix: str | None, kind: str = "newton") -> str:
    """The options prefix of a solver: ``prefix`` checked, or a fresh unique one.

    Args:
        prefix: A user prefix (must end with ``_``), or ``None``.
        kind: The middle part of a generated prefix ``hyperfem_<kind>_<n>_``.

    Raises:
        ParameterError: ``prefix`` does not end with ``_``.
    """
    if prefix is None:
        return unique_prefix(kind)
    if not prefix.endswith("_"):
        raise ParameterError(f"NewtonSolver: options prefix must end with '_', got {prefix!r}")
    return prefix


def merge_options(
    conservative: bool, linear: Mapping[str, object], petsc_options: Mapping[str, object] | None
) -> dict[str, object]:
    """SNES defaults, then the linear solver's options, then the user's (keys without the prefix).

    Args:
        conservative: Whether the problem has an energy (else the ``cp`` line search).
        linear: The KSP/PC options of the linear solver.
        petsc_options: The user's options, or ``None``.
    """
    defaults = dict(SNES_DEFAULTS)
    if not conservative:
        # No energy to judge steps by. Measured on the twist case (P2,
        # h = 1): residual-norm 'bt' 13 iterations, 'cp' 6, 'basic' 5
        # (unsafeguarded); 'cp' is the safeguarded choice.
        defaults["snes_linesearch_type"] = "cp"
        # 'cp' ends the whole solve (CONVERGED_FNORM_ABS) once |F.Y| falls
        # below snes_linesearch_atol (1e-15) times a step norm: an absolute
        # test in the problem's units, outside the round-off stop. The mixed
        # viscoelastic hold steps (mu = 1, K = 1e4) stopped at |F| = 1.2e-7
        # with snes_atol 1e-13 (F.Y = 1.1e-19: F in the u and theta blocks,
        # the step almost all pressure). With 0 only hyperfem's test ends a
        # solve: that run then matches the NumPy Simo recursion to 2e-12
        # (was 2.2e-7), one Newton iteration more in 4 of 6 steps. Solves
        # whose floor lies above snes_atol (K/mu = 1e8: K times round-off)
        # end at the round-off stop, which counts the identity of theta
        # (roundoff.VOLUME_REFERENCE) for that.
        defaults["snes_linesearch_atol"] = 0.0
    user = dict(petsc_options or {})
    for key in [k for k in user if k.endswith("pc_type") and user[k] != linear.get(k)]:
        # Another preconditioner, of the whole system or of one split ("fieldsplit_u_pc_type"): the linear
        # solver's options of its own one (a factorisation's solver package, GAMG's, the p-multigrid's and the
        # field split's settings) would be left unused (PETSc's "unused database options") or, worse, read
        # by the new one (GAMG refuses the p-multigrid's "mg_levels").
        scope = key[: -len("pc_type")]
        linear = {k: v for k, v in linear.items() if k == key or not k.startswith(_pc_specific(scope))}
        if user[key] in ("lu", "cholesky"):  # PETSc's own factorisations are serial only
            linear[f"{scope}pc_factor_mat_solver_type"] = "mumps"
            if not scope:
                # The AMG paths lag their hierarchy (snes_lag_preconditioner 3-10). A lagged factorisation
                # is a chord method: measured (benchmarks/linear_degree.py, bend, full load), P2 at
                # 30.8k unknowns took 16 Newton iterations with LU lagged by 5 and 4 without. The
                # user's own lag, if any, is kept below.
                linear.pop("snes_lag_preconditioner", None)
    if user.get("ksp_type") == "preonly" and linear.get("ksp_type") != "preonly":
        # One preconditioner application: the Krylov method's tolerances and restart would be unused.
        linear = {k: v for k, v in linear.items() if not k.startswith("ksp_")}
    return {**defaults, **linear, **user}


_PC_SPECIFIC = ("pc_", "mg_", "fieldsplit_")
"""Prefixes of options that belong to one preconditioner (dropped from the linear solver's when the user names
another ``pc_type``)."""


def _pc_specific(scope: str) -> tuple[str, ...]:
    """The prefixes of the options of the preconditioner whose type is ``<scope>pc_type``."""
    return tuple(scope + prefix for prefix in _PC_SPECIFIC)


def clean_options(prefix: str, options: Mapping[str, object]) -> None:
    """Undo what a failed ``NonlinearProblem`` construction left in PETSc's options database."""
    opts = PETSc.Options()
    try:
        opts.prefixPop()
    except PETSc.Error:
        pass
    for key in options:
        opts.delValue(f"-{prefix}{key}")


def describe_option_error(exc: PETSc.Error, user: Mapping[str, object]) -> str:
    """What PETSc rejected, naming the user's options (the ``*_type`` ones for an unknown type)."""
    ierr = getattr(exc, "ierr", None)
    typed = {k: v for k, v in user.items() if str(k).endswith("_type")}
    if ierr == 86 and typed:  # PETSC_ERR_UNKNOWN_TYPE
        listed = ", ".join(f"{k} = {v!r}" for k, v in typed.items())
        return f"PETSc rejected an unknown type among the options {listed} (error {ierr})"
    listed = ", ".join(f"{k} = {v!r}" for k, v in user.items()) or "(defaults only)"
    return f"PETSc rejected the options {listed} (error {ierr})"
