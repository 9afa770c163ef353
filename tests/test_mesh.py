"""gmsh beam generator, .msh round trip and named groups (serial and 2 ranks)."""

from pathlib import Path

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

import hyperfem as hf


def _area(domain, name):
    one = fem.Constant(domain.mesh, 1.0)
    return domain.comm.allreduce(fem.assemble_scalar(fem.form(one * domain.ds(name))), op=MPI.SUM)


def _volume(domain):
    one = fem.Constant(domain.mesh, 1.0)
    return domain.comm.allreduce(fem.assemble_scalar(fem.form(one * domain.dx("beam"))), op=MPI.SUM)


@pytest.mark.parametrize("order", [1, 2])
def test_beam_groups_and_measures(order):
    domain = hf.beam_mesh(h=2.5, order=order)
    assert set(domain.facet_groups) == {"clamped", "free_end", "surface"}
    assert set(domain.cell_groups) == {"beam"}
    assert domain.mesh.geometry.cmaps[0].degree == order
    assert np.isclose(_volume(domain), 160.0, rtol=1e-12)
    assert np.isclose(_area(domain, "clamped"), 16.0, rtol=1e-12)
    assert np.isclose(_area(domain, "free_end"), 16.0, rtol=1e-12)
    assert np.isclose(_area(domain, "surface"), 160.0, rtol=1e-12)
    x = ufl.SpatialCoordinate(domain.mesh)
    xc = domain.comm.allreduce(fem.assemble_scalar(fem.form(x[0] * domain.ds("free_end"))), op=MPI.SUM)
    assert np.isclose(xc / 16.0, 5.0)


def test_msh_round_trip(tmp_path):
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(str(tmp_path / "beam.msh"), root=0))
    if comm.rank == 0:
        hf.mesh.write_beam_mesh(path, h=2.5)
    comm.Barrier()
    read = hf.read_mesh(path)
    generated = hf.beam_mesh(h=2.5)
    n_read = read.mesh.topology.index_map(3).size_global
    assert n_read == generated.mesh.topology.index_map(3).size_global
    assert read.facet_groups == {"clamped": 1, "free_end": 2, "surface": 3}
    assert np.isclose(_area(read, "free_end"), 16.0)


def test_committed_meshes_are_current():
    """The committed coarse meshes carry the documented groups and sizes."""
    root = Path(__file__).resolve().parent.parent / "meshes"
    for name, cells in [("beam_h2.msh", 164), ("beam_h1.msh", 921)]:
        d = hf.read_mesh(root / name)
        assert d.mesh.topology.index_map(3).size_global == cells
        assert set(d.facet_groups) == {"clamped", "free_end", "surface"}
