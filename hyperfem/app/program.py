"""Running hyperfem programs from the command line.

:func:`run` wraps a ``main()``: a
:class:`~hyperfem.errors.HyperfemError` is printed as one line by rank 0 with
a non-zero exit status instead of a traceback. Every rank raises the same
error (hyperfem checks are collective), so no rank is left waiting. Any other
exception under MPI prints its traceback and aborts the whole job, so a rank
that fails alone cannot leave the others hanging in a collective call.

:class:`ArgumentParser` prints usage and errors on rank 0 only; the argument
types (:func:`positive_float`, :func:`positive_int`, :func:`fraction`, ...) reject
bad values before anything is computed (every rank exits with status 2, as
argparse does).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import traceback
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from _typeshed import SupportsWrite

__all__ = [
    "ArgumentParser",
    "fraction",
    "nonnegative_float",
    "positive_float",
    "positive_int",
    "run",
    "unit_interval",
]


def _rank() -> int:
    from mpi4py import MPI

    return MPI.COMM_WORLD.rank


class ArgumentParser(argparse.ArgumentParser):
    """:class:`argparse.ArgumentParser` that prints help, usage and errors on rank 0 only.

    Every rank parses the same arguments, so every rank exits together.
    """

    def _print_message(self, message: str, file: SupportsWrite[str] | None = None) -> None:  # noqa: D401 - hook
        if _rank() == 0:
            super()._print_message(message, file)


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value


def nonnegative_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}")
    return value


def fraction(text: str) -> float:
    """argparse type: a number in (0, 1] (e.g. a load increment)."""
    value = _number(text)
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"must lie in (0, 1], got {text!r}")
    return value


def unit_interval(text: str) -> float:
    """argparse type: a number in [0, 1] (e.g. a spectral radius)."""
    value = _number(text)
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError(f"must lie in [0, 1], got {text!r}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}")
    return value


def _exit_if_abandoned(code: int) -> None:
    """Leave with ``code`` and no destructors if a failed file writer was abandoned.

    A writer that failed (an ADIOS2 engine on a full disk) would abort the process in its
    C++ destructor at exit: everything that could be written is written, so the process
    ends without running destructors (``os._exit``, after flushing stdout and stderr).
    """
    from hyperfem.io.results import abandoned

    if abandoned():
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def run(main: Callable[[], object]) -> None:
    """Call ``main()``; hyperfem errors become a one-line message and exit code 1.

    Under MPI (more than one rank) any other exception prints its traceback
    and calls ``MPI.COMM_WORLD.Abort(1)``: the other ranks may be waiting in a
    collective call for the rank that failed.
    """
    from mpi4py import MPI

    from hyperfem.errors import HyperfemError

    comm = MPI.COMM_WORLD
    try:
        main()
        _exit_if_abandoned(0)
    except HyperfemError as exc:
        if comm.rank == 0:
            print(f"hyperfem: error: {exc}", file=sys.stderr, flush=True)
        code = getattr(exc, "exit_code", 1)
        _exit_if_abandoned(code)
        sys.exit(code)
    except KeyboardInterrupt:
        # A second Ctrl-C (or one outside a run): stop now. Abort, so that no rank waits in a
        # collective call for this one.
        if comm.rank == 0:
            print("hyperfem: interrupted", file=sys.stderr, flush=True)
        if comm.size > 1:
            comm.Abort(130)
        sys.exit(130)
    except Exception:
        if comm.size == 1:
            raise
        print(f"hyperfem: rank {comm.rank}: unexpected error, aborting all ranks", file=sys.stderr, flush=True)
        traceback.print_exc()
        sys.stderr.flush()
        comm.Abort(1)
