"""Mesh quality measures (seed 003, §5.6): closed forms, limits, invariances, MPI consistency.

Closed forms used below:

* equilateral simplex: every measure is 1 (the normalisation);
* the Kuhn ("path") tetrahedron 0 → e1 → e1+e2 → e1+e2+e3, of which
  ``create_box`` cubes are made: V = 1/6, face areas 1/2, 1/2, √2/2, √2/2,
  so r_in = 3V/ΣA = 1/(2(1+√2)); its circumsphere is the cube's, r_out = √3/2;
  longest edge √3; dihedral angles 45°, 60°, 90°; Σl² = 10. Hence
  Q_rr = 3 r_in/r_out = √3/(1+√2), Q_rl = 2√6 r_in/√3 = 2 − √2,
  Q_θ = sin 45° / (2√2/3) = 3/4, Q_vl = 12 (1/2)^{2/3} / 10;
* the right isosceles triangle of ``create_unit_square``: r_in = 1/(2+√2),
  r_out = √2/2, so 2 r_in/r_out = 2(√2 − 1), 2√3 r_in/√2 = √6/(2+√2),
  min sine (√2/2)/(√3/2) = √(2/3), 4√3 A/Σl² = √3/2.
"""

import math
import warnings
from pathlib import Path

import basix.ufl
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

import hyperfem as hf
from hyperfem.errors import ParameterError
from hyperfem.mesh.quality import (
    MEASURES,
    MeshQualityWarning,
    cell_quality,
    mesh_quality,
    quality_report,
    tetrahedron_quality,
    triangle_quality,
)

MESH = Path(__file__).resolve().parent.parent / "meshes" / "beam_h2.msh"

REGULAR_TET = np.array(
    [[0.0, 0.0, 1.0], [math.sqrt(8 / 9), 0.0, -1 / 3], [-math.sqrt(2 / 9), math.sqrt(2 / 3), -1 / 3],
     [-math.sqrt(2 / 9), -math.sqrt(2 / 3), -1 / 3]]
)
KUHN = {
    "radius_ratio": math.sqrt(3.0) / (1.0 + math.sqrt(2.0)),
    "inradius_edge": 2.0 - math.sqrt(2.0),
    "min_dihedral_sine": 0.75,
    "volume_length": 1.2 * 2.0 ** (-2.0 / 3.0),
}
RIGHT_TRIANGLE = {
    "radius_ratio": 2.0 * (math.sqrt(2.0) - 1.0),
    "inradius_edge": math.sqrt(6.0) / (2.0 + math.sqrt(2.0)),
    "min_dihedral_sine": math.sqrt(2.0 / 3.0),
    "volume_length": math.sqrt(3.0) / 2.0,
}


def _one_tet(comm, points):
    """A one-cell mesh (the cell on rank 0)."""
    element = basix.ufl.element("Lagrange", "tetrahedron", 1, shape=(3,))
    if comm.rank == 0:
        cells, x = np.array([[0, 1, 2, 3]], dtype=np.int64), np.asarray(points, dtype=float)
    else:
        cells, x = np.zeros((0, 4), dtype=np.int64), np.zeros((0, 3))
    return dmesh.create_mesh(comm, cells, element, x)


def _perturbed_box(comm):
    """A box whose nodes are moved by a smooth field of the coordinates (the same on any partition)."""
    m = dmesh.create_box(comm, [[0.0, 0.0, 0.0], [2.0, 1.0, 1.0]], [4, 3, 3])
    x = m.geometry.x
    shift = 0.08 * np.stack(
        [np.sin(3 * x[:, 1] + 2 * x[:, 2]), np.cos(2 * x[:, 0] + x[:, 2]), np.sin(x[:, 0] * x[:, 1] * 5)]
    )
    x[:, :3] += shift.T
    return m


def test_regular_tetrahedron_mesh_has_quality_one(comm):
    q = mesh_quality(_one_tet(comm, REGULAR_TET))
    assert q.num_cells == 1
    for key in MEASURES:
        assert q.stats[key]["min"] == pytest.approx(1.0, abs=1e-12)
        assert q.stats[key]["max"] == pytest.approx(1.0, abs=1e-12)
    assert q.poor_measures() == []


def test_equilateral_triangle_has_quality_one():
    tri = np.array([[[0.0, 0.0], [1.0, 0.0], [0.5, math.sqrt(3.0) / 2.0]]])
    for key, v in triangle_quality(tri).items():
        assert v[0] == pytest.approx(1.0, abs=1e-12), key


@pytest.mark.parametrize("eps", [1e-2, 1e-4, 1e-6])
def test_nearly_flat_tetrahedron_tends_to_zero(eps):
    base = REGULAR_TET[1:]
    centre = base.mean(axis=0)
    flat = np.vstack([centre + np.array([0.0, 0.0, eps]), base])[None]
    q = tetrahedron_quality(flat)
    # Q_rr, Q_rl, Q_theta are linear in the height, Q_vl goes like height^(2/3).
    for key in ("radius_ratio", "inradius_edge", "min_dihedral_sine"):
        assert 0.0 < q[key][0] < 5.0 * eps, key
    assert 0.0 < q["volume_length"][0] < 5.0 * eps ** (2.0 / 3.0)


def test_degenerate_cells_have_quality_zero_not_nan():
    flat_tet = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]], dtype=float)
    collapsed = np.zeros((1, 4, 3))
    for q in (tetrahedron_quality(flat_tet), tetrahedron_quality(collapsed)):
        for key, v in q.items():
            assert v[0] == 0.0, key
    needle = np.array([[[0, 0], [1, 0], [2, 0]]], dtype=float)
    assert all(v[0] == 0.0 for v in triangle_quality(needle).values())


def test_invariant_under_rotation_scaling_translation_and_vertex_order():
    rng = np.random.default_rng(3)
    points = rng.standard_normal((50, 4, 3))
    ref = cell_quality(points)
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    for scale in (1e-3, 7.0, 1e3):
        moved = scale * points @ Q.T + np.array([5.0, -2.0, 1.0])
        moved = moved[:, [2, 0, 3, 1]]  # renumbered vertices, reflected orientation
        for key, v in cell_quality(moved).items():
            np.testing.assert_allclose(v, ref[key], rtol=1e-9, atol=1e-12, err_msg=key)
    tri = rng.standard_normal((50, 3, 2))
    ref2 = cell_quality(tri)
    R2 = np.array([[math.cos(0.7), -math.sin(0.7)], [math.sin(0.7), math.cos(0.7)]])
    for key, v in cell_quality(3.0 * tri[:, [1, 2, 0]] @ R2.T).items():
        np.testing.assert_allclose(v, ref2[key], rtol=1e-9, atol=1e-12, err_msg=key)


def test_box_cells_are_kuhn_tetrahedra(comm):
    q = mesh_quality(dmesh.create_box(comm, [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], [2, 2, 2]))
    assert q.num_cells == 48 and q.cell_type == "tetrahedron"
    for key, value in KUHN.items():
        assert q.stats[key]["min"] == pytest.approx(value, rel=1e-12), key
        assert q.stats[key]["max"] == pytest.approx(value, rel=1e-12), key


def test_unit_square_cells_are_right_isosceles_triangles(comm):
    q = mesh_quality(dmesh.create_unit_square(comm, 3, 3))
    assert q.cell_type == "triangle"
    for key, value in RIGHT_TRIANGLE.items():
        assert q.stats[key]["min"] == pytest.approx(value, rel=1e-12), key
        assert q.stats[key]["max"] == pytest.approx(value, rel=1e-12), key


def test_values_on_stretched_box_in_unit_interval(comm):
    m = dmesh.create_box(comm, [[0.0, 0.0, 0.0], [3.0, 1.0, 0.5]], [2, 3, 4])
    q = mesh_quality(m)
    for key in MEASURES:
        v = q.values[key]
        assert np.all((v > 0.0) & (v <= 1.0)), key
        s = q.stats[key]
        assert 0.0 < s["min"] <= s["p1"] <= s["p5"] <= s["p50"] <= s["max"] <= 1.0
        assert s["min"] <= s["mean"] <= s["max"]


def test_statistics_and_summary_are_partition_independent(comm):
    """The distributed mesh gives the same statistics as the same mesh on one rank."""
    distributed = mesh_quality(_perturbed_box(comm))
    local = mesh_quality(_perturbed_box(MPI.COMM_SELF))
    assert distributed.num_cells == local.num_cells == 4 * 3 * 3 * 6
    for key in MEASURES:
        for name, value in local.stats[key].items():
            assert distributed.stats[key][name] == pytest.approx(value, rel=1e-12, abs=1e-14), (key, name)
    assert distributed.summary_line() == local.summary_line()
    assert comm.allgather(distributed.summary_line()) == [local.summary_line()] * comm.size
    # the perturbation makes the cells differ
    assert local.stats["volume_length"]["min"] < local.stats["volume_length"]["max"] - 0.05


def test_warn_if_poor(comm):
    base = REGULAR_TET[1:]
    sliver = np.vstack([base.mean(axis=0) + np.array([0.0, 0.0, 1e-3]), base])
    q = mesh_quality(_one_tet(comm, sliver))
    if comm.rank == 0:
        with pytest.warns(MeshQualityWarning, match="poorly shaped"):
            poor = q.warn_if_poor()
    else:
        poor = q.warn_if_poor()
    assert set(poor) == set(MEASURES)  # every measure of a sliver is below 0.1
    assert issubclass(MeshQualityWarning, UserWarning)
    good = mesh_quality(dmesh.create_box(comm, [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], [2, 2, 2]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert good.warn_if_poor() == []
    # Kuhn tetrahedra: radius ratio 0.717, inradius/edge 0.586 are below 0.74; the others are not.
    if comm.rank == 0:
        with pytest.warns(MeshQualityWarning, match="inradius/edge min 0.586"):
            assert good.warn_if_poor(0.74) == ["radius_ratio", "inradius_edge"]
    else:
        assert good.warn_if_poor(0.74) == ["radius_ratio", "inradius_edge"]
    with pytest.raises(ParameterError, match="threshold"):
        good.warn_if_poor(0.0)


def test_quality_report_on_domain_and_errors(comm):
    domain = hf.read_mesh(MESH, comm=comm)
    line = quality_report(domain)
    assert line.startswith(f"mesh quality ({domain.mesh.topology.index_map(3).size_global} tetrahedra")
    assert all(label in line for label in MEASURES.values())
    assert comm.allgather(line) == [line] * comm.size
    assert mesh_quality(domain.mesh).summary_line() == line
    with pytest.raises(ParameterError, match="Mesh or a hyperfem Domain"):
        mesh_quality("beam.msh")
    with pytest.raises(ParameterError, match="hexahedron"):
        mesh_quality(dmesh.create_unit_cube(comm, 1, 1, 1, dmesh.CellType.hexahedron))


def test_histogram_png(comm, tmp_path):
    path = Path(comm.bcast(str(tmp_path), root=0)) / "quality.png"
    q = mesh_quality(dmesh.create_box(comm, [[0.0, 0.0, 0.0], [3.0, 1.0, 0.5]], [2, 3, 4]))
    assert q.histogram_png(path) == path
    if comm.rank == 0:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
