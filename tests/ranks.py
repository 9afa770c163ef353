"""The 1 rank = 2 ranks comparisons of the tests: the serial reference run beside the run on every rank."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import pytest
from mpi4py import MPI

T = TypeVar("T")


def serial_reference(state: Callable[[MPI.Comm], T]) -> T:
    """``state(MPI.COMM_SELF)`` run on rank 0 and given to every rank; skips the test on 1 rank.

    The caller compares it with ``state(MPI.COMM_WORLD)``, run on the ranks of ``mpiexec -n 2``.
    """
    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")
    one = state(MPI.COMM_SELF) if comm.rank == 0 else None
    return comm.bcast(one, root=0)
