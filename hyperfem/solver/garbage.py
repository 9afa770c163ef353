"""PETSc objects that Python dropped on several ranks: destroyed at points every rank reaches.

On a communicator of more than one rank, petsc4py does not destroy a PETSc object
when Python drops it (a collective destruction at a moment the garbage collector
chooses would deadlock): it queues it as *garbage* of its communicator, until
``PETSc.garbage_cleanup(comm)`` destroys the queue collectively. A queued Krylov
solver keeps its communicators (MUMPS duplicates five on 2 ranks), and MPICH has
2048 per process: a long run that drops solvers, factorisations or vectors on
every step (continuation, cut-backs, restarts) would end in an ``MPI_Abort`` from
deep inside DOLFINx. :func:`release_garbage` is called where every rank is
anyway (the start of each Newton solve), on the communicators a problem's PETSc
objects live on: the mesh's and that of the state's dof map (DOLFINx gives each
index map its own).

What the last solve on a mesh left queued stays there when the mesh is dropped
(a few communicators per mesh): a script that makes hundreds of meshes in one
process on several ranks (a parameter sweep) calls
``release_garbage(state_communicators(problem.u))`` once it is done with each,
on every rank. The test suite does the same after every test
(``tests/conftest.py``).
"""

from __future__ import annotations

from collections.abc import Iterable

from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

__all__ = ["NEEDED", "release_garbage", "state_communicators"]


def state_communicators(u: fem.Function) -> list[MPI.Comm]:
    """The communicators of the PETSc objects made for the state ``u``: its mesh's and its dof map's."""
    space = u.function_space
    return [space.mesh.comm, space.dofmap.index_map.comm]


NEEDED = MPI.get_vendor()[0] != "Open MPI"
"""Whether :func:`release_garbage` acts. Open MPI has no small limit of communicators, and on Debian's Open
MPI (PETSc 3.24) a 2-rank ``PETSc.garbage_cleanup`` after a case-file arc-length run waited forever (rank 0
held a queued KSP and Mat; not understood): there the garbage waits as it did before, costing memory only."""


def release_garbage(comms: Iterable[MPI.Comm]) -> None:
    """Destroy the PETSc objects Python dropped on each of ``comms`` (collective on each; a no-op on one rank
    and under Open MPI, :data:`NEEDED`)."""
    if not NEEDED:
        return
    for comm in comms:
        if comm.size > 1:
            PETSc.garbage_cleanup(comm)  # type: ignore[arg-type]  # petsc4py accepts an mpi4py communicator
