"""Shared pytest configuration: single-threaded BLAS, MPI teardown, markers."""

import gc
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from mpi4py import MPI  # noqa: E402

import pytest  # noqa: E402
from dolfinx import jit  # noqa: E402

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


@pytest.fixture(autouse=True)
def _mpi_teardown():
    yield
    gc.collect()
    MPI.COMM_WORLD.Barrier()


@pytest.fixture
def comm():
    return MPI.COMM_WORLD


@pytest.fixture
def shared_tmp(tmp_path):
    """A temporary folder that every rank agrees on (rank 0's)."""
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))
