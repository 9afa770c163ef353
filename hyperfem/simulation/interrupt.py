"""Stopping a run cleanly on Ctrl-C (SIGINT) or SIGTERM.

While a :class:`~hyperfem.simulation.Simulation` runs, the first SIGINT or
SIGTERM only sets a flag: the run finishes the step it is in, writes its
outputs (summary, CSV, fields, checkpoint) and raises
:class:`~hyperfem.errors.Interrupted` naming the step, the time and the
checkpoint to continue from. The ranks agree on the flag after every
accepted step (one ``allreduce``), so all of them stop after the same step
and none is left waiting in a collective call for a rank that has gone (an
interrupt that landed inside a solve used to surface as "PETSc error 101" on
one rank and could leave ``mpiexec -n 2`` hanging).

A second signal of the same kind, a second or more after the first, restores
the previous behaviour at once (``KeyboardInterrupt`` for Ctrl-C). The second
is ignored within that second because a Ctrl-C at a terminal reaches the ranks
twice under ``mpiexec``: from the terminal and forwarded by the launcher.
Signals that were ignored when the run started (a job started in the
background by a shell) stay ignored. Outside the main thread nothing is
installed.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Callable
from types import FrameType
from typing import Any

from mpi4py import MPI

__all__ = ["InterruptGuard"]

_SIGNALS = (signal.SIGINT, signal.SIGTERM)
REPEAT_GRACE = 1.0
"""Seconds after the first signal during which a second of the same kind is taken as the same request."""
_Handler = Callable[[int, FrameType | None], Any] | int | signal.Handlers
"""What ``signal.signal`` installs: a function, ``SIG_DFL`` or ``SIG_IGN``."""


class InterruptGuard:
    """Context manager that turns SIGINT/SIGTERM into a request to stop after the current step.

    Args:
        comm: The communicator whose ranks must stop together.
    """

    def __init__(self, comm: MPI.Comm):
        self.comm = comm
        self.signal: int = 0
        self._first: dict[int, float] = {}  # signal -> when its first copy was handled
        self._previous: dict[int, _Handler] = {}

    def __enter__(self) -> InterruptGuard:
        if threading.current_thread() is threading.main_thread():
            for sig in _SIGNALS:
                previous = signal.getsignal(sig)
                if previous is signal.SIG_IGN or previous is None:
                    continue
                self._previous[sig] = previous
                signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, previous in self._previous.items():
            signal.signal(sig, previous)
        self._previous.clear()

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        now = time.monotonic()
        if signum not in self._first:  # the first of its kind: a request to stop after the step
            self._first[signum] = now
            if self.signal == 0:
                self.signal = signum
                if self.comm.rank == 0:
                    name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
                    print(f"hyperfem: {name}: stopping after the current step (again to stop at once)",
                          file=sys.stderr, flush=True)
            return
        if now - self._first[signum] < REPEAT_GRACE:  # the launcher's forwarded copy of the same one
            return
        previous = self._previous.pop(signum, signal.SIG_DFL)
        signal.signal(signum, previous)
        if callable(previous):
            previous(signum, frame)
        else:
            signal.raise_signal(signum)

    def requested(self) -> int:
        """The signal some rank received since the run started (0: none). Collective."""
        return int(self.comm.allreduce(self.signal, op=MPI.MAX))
