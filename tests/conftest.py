"""Shared pytest configuration: single-threaded BLAS, MPI teardown, markers."""

import gc
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from mpi4py import MPI  # noqa: E402

import dolfinx.fem  # noqa: E402
import dolfinx.mesh  # noqa: E402
import pytest  # noqa: E402
from dolfinx import jit  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from hyperfem.solver.garbage import NEEDED  # noqa: E402

# On a cold JIT cache under load, waiting 10 s for another process's compile
# of the same form can time out spuriously; allow two minutes.
jit.DOLFINX_DEFAULT_JIT_OPTIONS["timeout"] = (120, "Timeout for JIT compilation")


def pytest_collection_modifyitems(config, items):
    if MPI.COMM_WORLD.size > 1:
        skip = pytest.mark.skip(reason="serial-only test")
        for item in items:
            if "serial" in item.keywords:
                item.add_marker(skip)


def pytest_collection_finish(session):
    # Everything alive once the test modules are imported (dolfinx, ufl, basix, numpy, the
    # test modules and their parameters) lives to the end of the session. Moving it to the
    # permanent generation keeps the gc.collect() after each test from traversing it every
    # time (about 45 ms a test, some 40 s a run); what the tests create is collected as before.
    gc.collect()
    gc.freeze()


# PETSc objects on a communicator of more than one rank are not destroyed when Python
# drops them: petsc4py queues them as "garbage" of their communicator, to be destroyed by
# PETSc.garbage_cleanup(comm), collectively. Each queued solver keeps communicators alive
# (a MUMPS factorisation five on 2 ranks); once a test's mesh and spaces are gone, their
# communicators (each IndexMap has its own) can no longer be cleaned up, and MPICH has 2048
# communicators per process: a 2-rank run of the whole suite ran out of them near its end
# (MPI_Abort in an IndexMap constructor, the job killed without a message). So every mesh
# and function space a test creates on several ranks is kept until its teardown, which
# cleans up the garbage of each of their communicators. They are created collectively, so
# the list is the same on every rank, in the same order; only strong references are used
# (which objects a weak reference still finds could differ between ranks, and one rank
# would wait in a cleanup the other never enters). Only where the limit exists: on Debian's
# Open MPI a cleanup after a case-file arc-length test waited forever (hyperfem.solver.garbage).
_KEPT: list[dolfinx.mesh.Mesh | dolfinx.fem.FunctionSpace] = []


def _keeping(cls, comm_of):
    init = cls.__init__

    def recorded_init(self, *args, **kwargs):
        init(self, *args, **kwargs)
        if NEEDED and comm_of(self).size > 1:
            _KEPT.append(self)

    cls.__init__ = recorded_init


_keeping(dolfinx.mesh.Mesh, lambda mesh: mesh.comm)
_keeping(dolfinx.fem.FunctionSpace, lambda space: space.mesh.comm)


def _communicators(obj) -> list[MPI.Comm]:
    """The communicators PETSc objects made from a mesh or a space live on."""
    if isinstance(obj, dolfinx.fem.FunctionSpace):
        return [obj.dofmap.index_map.comm]
    maps = [obj.geometry.index_map()]
    for d in range(obj.topology.dim + 1):
        try:
            maps.append(obj.topology.index_map(d))
        except RuntimeError:  # entities of this dimension not created (on any rank)
            pass
    return [obj.comm] + [m.comm for m in maps]


@pytest.fixture(autouse=True)
def _mpi_teardown():
    yield
    gc.collect()
    if NEEDED and MPI.COMM_WORLD.size > 1:  # matrices a test made on the world communicator itself
        PETSc.garbage_cleanup(MPI.COMM_WORLD)
    seen = set()
    for obj in _KEPT:
        for comm in _communicators(obj):
            if comm.py2f() not in seen:
                seen.add(comm.py2f())
                PETSc.garbage_cleanup(comm)
    _KEPT.clear()
    gc.collect()
    # What survives a test (module fixtures, caches) is traversed again only at its module's end (below):
    # without this, every collection of every later test traversed it, and the two collections per test grew
    # from a few ms to about 0.12 s by the end of a run (170 s of a 2-rank run's 520 s).
    gc.freeze()
    MPI.COMM_WORLD.Barrier()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item, nextitem):
    yield
    if nextitem is None or nextitem.module is not item.module:
        # The module's fixtures are finalised: collect what the module left (in cycles), once.
        gc.unfreeze()
        gc.collect()
        if NEEDED and MPI.COMM_WORLD.size > 1:
            PETSc.garbage_cleanup(MPI.COMM_WORLD)
        gc.freeze()


@pytest.fixture
def comm():
    return MPI.COMM_WORLD


@pytest.fixture
def shared_tmp(tmp_path):
    """A temporary folder that every rank agrees on (rank 0's)."""
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))
