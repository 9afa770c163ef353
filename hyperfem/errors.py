"""Exceptions raised by hyperfem.

Every error hyperfem raises on bad input or failed solves derives from
:class:`HyperfemError` and carries a one-line message that says *what* went
wrong and *where*, so that command-line drivers can print it and exit
non-zero without a traceback.
"""

from __future__ import annotations

__all__ = [
    "CheckpointError",
    "ConvergenceError",
    "HyperfemError",
    "Interrupted",
    "MeshError",
    "MeshFileNotFoundError",
    "OutputError",
    "ParameterError",
    "ProblemSizeError",
    "SolverError",
    "UnknownGroupError",
]


class HyperfemError(Exception):
    """Base class of all hyperfem errors."""


class ParameterError(HyperfemError, ValueError):
    """Invalid material, load, solver or stepping parameter."""


class ProblemSizeError(ParameterError):
    """A mesh size or a degree whose estimated memory exceeds what the machine has (:mod:`hyperfem.mesh.budget`).

    The message gives the estimate, the limit and the override (``allow_large=True``,
    ``--allow-large``, ``HYPERFEM_ALLOW_LARGE=1``).
    """


class MeshError(HyperfemError):
    """A mesh could not be read, generated or interpreted."""


class MeshFileNotFoundError(MeshError, FileNotFoundError):
    """The mesh file does not exist."""


class CheckpointError(HyperfemError, ValueError):
    """A checkpoint cannot be read, or does not belong to the run that tries to restart from it."""


class OutputError(HyperfemError, OSError):
    """An output folder or file cannot be created or written.

    Raised on every rank (the check is collective), before any result is computed
    where possible.
    """

    def __str__(self) -> str:  # OSError would format (errno, strerror)
        return str(self.args[0]) if self.args else ""


class UnknownGroupError(MeshError, LookupError):
    """A physical-group name is not defined on the mesh.

    The message lists the names that do exist for that entity dimension.
    """

    def __str__(self) -> str:  # LookupError would quote the message
        return str(self.args[0]) if self.args else ""


class ConvergenceError(HyperfemError, RuntimeError):
    """A nonlinear solve failed after all cutbacks.

    Attributes:
        time: The last time (load factor of a quasi-static ramp) that converged.
        history: Records of the steps that did converge.
    """

    def __init__(self, message: str, time: float = 0.0, history: list | None = None):
        super().__init__(message)
        self.time = float(time)
        self.history = [] if history is None else history


class SolverError(HyperfemError, RuntimeError):
    """PETSc failed inside a solve for a reason that is not a hard step (a bug or a broken install).

    A step that is merely hard (line search, inversion, a diverged linear
    solve) is a failed :class:`~hyperfem.solver.SolveRecord`, cut back by the
    stepper; this is raised instead, with PETSc's error code.
    """


class Interrupted(HyperfemError):
    """The user interrupted a run (Ctrl-C, SIGTERM); the last completed step was kept.

    Attributes:
        time: The time (load factor) of the last completed step.
    """

    exit_code = 130
    """Exit status of the command (128 + SIGINT, as shells report an interrupted program)."""

    def __init__(self, message: str, time: float = 0.0):
        super().__init__(message)
        self.time = float(time)
