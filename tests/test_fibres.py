"""Fibre fields: constant, callable, Laplace rule, and mesh-file data (meshio); always unit length."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.errors import MeshError, ParameterError
from hyperfem.fibres import (
    REPRESENTATIONS,
    constant_fibres,
    fibres_from_callable,
    fibres_from_file,
    laplace_fibres,
)
from hyperfem.mesh.fusiform import FusiformGeometry, fusiform_mesh, write_fusiform_mesh


def _values(a0):
    return a0.x.array.reshape(-1, 3)


def _assert_unit(a0):
    v = _values(a0)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-12)


@pytest.fixture(scope="module")
def box():
    mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([2.0, 1.0, 1.0])], [4, 2, 2])
    return hf.Domain.from_locators(
        mesh, {"left": lambda x: np.isclose(x[0], 0.0), "right": lambda x: np.isclose(x[0], 2.0)}
    )


@pytest.mark.parametrize("representation", REPRESENTATIONS)
def test_constant_and_callable(box, representation):
    a0 = constant_fibres(box.mesh, [0.0, 3.0, 4.0], representation, quadrature_degree=2)
    _assert_unit(a0)
    np.testing.assert_allclose(_values(a0), np.tile([0.0, 0.6, 0.8], (_values(a0).shape[0], 1)), atol=1e-14)
    b0 = fibres_from_callable(box.mesh, lambda x: np.vstack([1.0 + x[0], x[1], x[2]]), representation, 2)
    _assert_unit(b0)
    X = b0.function_space.tabulate_dof_coordinates() if representation != "quadrature" else None
    if X is not None:
        expected = np.column_stack([1.0 + X[:, 0], X[:, 1], X[:, 2]])
        np.testing.assert_allclose(_values(b0), expected / np.linalg.norm(expected, axis=1)[:, None], atol=1e-12)


def test_invalid_fibres(box):
    with pytest.raises(ParameterError, match="representation"):
        constant_fibres(box.mesh, [1.0, 0.0, 0.0], "P3")
    with pytest.raises(ParameterError, match="nonzero"):
        constant_fibres(box.mesh, [0.0, 0.0, 0.0])
    with pytest.raises(ParameterError, match="zero-length"):
        fibres_from_callable(box.mesh, lambda x: np.vstack([x[0] - x[0], 0 * x[1], 0 * x[2]]), "DG0")


@pytest.mark.parametrize("representation", REPRESENTATIONS)
def test_laplace_box_is_axial(box, representation):
    """Between the two end faces of a box phi = x/L, so the fibres are exactly e_x."""
    a0 = laplace_fibres(box, "left", "right", representation, quadrature_degree=2, degree=1)
    _assert_unit(a0)
    np.testing.assert_allclose(_values(a0), np.tile([1.0, 0.0, 0.0], (_values(a0).shape[0], 1)), atol=1e-8)


def test_laplace_fusiform():
    """Fibres run from origin to insertion (positive axial component) and follow the spindle."""
    geo = FusiformGeometry()
    domain = fusiform_mesh(h=0.006, geometry=geo)
    assert set(domain.cell_groups) == {"muscle", "tendon_proximal", "tendon_distal"}
    assert set(domain.facet_groups) == {"origin", "insertion", "lateral"}
    a0 = laplace_fibres(domain, "origin", "insertion", "DG0")
    _assert_unit(a0)
    v = _values(a0)
    X = a0.function_space.tabulate_dof_coordinates()
    assert v[:, 2].min() > 0.5
    # in the distal half of the belly the fibres splay inwards towards the axis (x·a0 < 0 radially)
    belly = (X[:, 2] > 0.01) & (X[:, 2] < 0.025) & (np.hypot(X[:, 0], X[:, 1]) > 0.004)
    radial = (X[belly, 0] * v[belly, 0] + X[belly, 1] * v[belly, 1]) / np.hypot(X[belly, 0], X[belly, 1])
    total = domain.comm.allreduce(float(radial.sum()))
    assert total < 0


def _field(x):
    v = np.column_stack([-x[:, 1], x[:, 0], 0.01 + 0.0 * x[:, 2]])
    return v / np.linalg.norm(v, axis=1)[:, None]


def test_fibres_from_meshio_file(tmp_path):
    """Point and cell data written with meshio next to a .msh are matched by coordinates, on any partition."""
    import meshio

    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(str(tmp_path), root=0))
    msh, vtu = folder / "spindle.msh", folder / "spindle.vtu"
    if comm.rank == 0:
        write_fusiform_mesh(msh, h=0.008)
        m = meshio.read(msh)
        tets = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
        centroids = m.points[tets].mean(axis=1)
        meshio.write(
            vtu,
            meshio.Mesh(
                m.points,
                [("tetra", tets)],
                point_data={"fibres": 5.0 * _field(m.points)},
                cell_data={"fibres": [2.0 * _field(centroids)]},
            ),
        )
    comm.Barrier()
    domain = hf.read_mesh(msh, comm)
    for location in ("point", "cell"):
        a0 = fibres_from_file(domain, vtu, "fibres", location)
        _assert_unit(a0)
        X = a0.function_space.tabulate_dof_coordinates()
        np.testing.assert_allclose(_values(a0), _field(X), atol=1e-6)
    with pytest.raises(MeshError, match="no point data"):
        fibres_from_file(domain, vtu, "missing")
    with pytest.raises(MeshError, match="not found"):
        fibres_from_file(domain, folder / "nope.vtu", "fibres")
