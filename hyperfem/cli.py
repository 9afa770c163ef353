"""Running hyperfem programs from the command line.

:func:`run` wraps a ``main()``: a
:class:`~hyperfem.errors.HyperfemError` is printed as one line by rank 0 with
a non-zero exit status instead of a traceback. Every rank raises the same
error (hyperfem checks are collective), so no rank is left waiting.
"""

from __future__ import annotations

import sys
from collections.abc import Callable

__all__ = ["run"]


def run(main: Callable[[], object]) -> None:
    """Call ``main()`` and turn hyperfem errors into a one-line message and exit code 1."""
    from mpi4py import MPI

    from hyperfem.errors import HyperfemError

    try:
        main()
    except HyperfemError as exc:
        if MPI.COMM_WORLD.rank == 0:
            print(f"hyperfem: error: {exc}", file=sys.stderr, flush=True)
        sys.exit(1)
