"""``hyperfem convert`` of Abaqus ``.inp`` files with ``*SURFACE`` (hyperfem.mesh.abaqus).

A unit cube in five tetrahedra (C3D4, and C3D10 with straight mid-edge nodes),
with scattered element and node labels in two ``*ELEMENT`` blocks, written by
hand: ``*ELSET`` (with ``GENERATE``), ``*NSET`` and ``*SURFACE`` (by element
label, by element set, without a face identifier, ``TYPE=NODE``) become
boundaries of the converted ``.msh``, which ``hyperfem.read_mesh`` reads back
(serially and under ``mpiexec -n 2``) with the known facet counts and areas
(each cube face: two triangles, area 1). Face identifiers by hand: element
(1, 2, 4, 5) of the cube has S1 on z = 0, S2 on y = 0, S3 inside, S4 on x = 0.
Bad surfaces — an interior face, an unknown element, set or face identifier,
``*INCLUDE``, two surfaces on one face — give one-line MeshErrors naming the
file, line and token.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

import hyperfem as hf
from hyperfem.app.main import dispatch
from hyperfem.errors import MeshError
from hyperfem.mesh.convert import convert

CORNERS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
TETS = [(1, 2, 4, 5), (2, 3, 4, 7), (2, 4, 5, 7), (2, 6, 7, 5), (4, 5, 7, 8)]  # cube vertices 1..8
LABELS = [101, 7, 55, 3, 20]  # element labels, in file order
EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]  # Abaqus C3D10 mid-edge nodes 5..10

SURFACES = """** boundaries
*Elset, elset=top_els
** comment inside the data
3, 20
*ELSET, ELSET = y0, GENERATE
3, 101, 98
*Nset, nset=x1
20, 30, 60, 70
*Nset, nset=top
50, 60, 70, 80
*Nset, nset=back
30, 40, 70, 80
*Surface, name=bottom
101, S1
7, s1
*SURFACE ,NAME = lid,
 TYPE=ELEMENT
TOP_ELS, S3
*surface, name=front
y0, S2,
*Surface, type=NODE, name=right
x1
"""
EXPECTED = {"bottom": 2, "lid": 2, "front": 2, "right": 2, "back": 2}  # facets; each area 1


def _inp(surfaces: str, quadratic: bool = False) -> str:
    """The cube: node labels 10, 20, ..., 80; elements LABELS in blocks partA (2) and partB (3)."""
    nodes = {10 * (k + 1): np.array(c, float) for k, c in enumerate(CORNERS)}
    rows = []
    mids: dict[tuple[int, int], int] = {}
    for tet in TETS:
        corner_labels = [10 * v for v in tet]
        row = list(corner_labels)
        if quadratic:
            for a, b in EDGES:
                key = tuple(sorted((corner_labels[a], corner_labels[b])))
                if key not in mids:
                    mids[key] = 1000 + len(mids)
                    nodes[mids[key]] = (nodes[key[0]] + nodes[key[1]]) / 2
                row.append(mids[key])
        rows.append(row)
    kind = "C3D10" if quadratic else "C3D4"
    lines = ["*Heading", "unit cube in five tetrahedra", "*Node"]
    lines += [f"{label}, {x:g}, {y:g}, {z:g}" for label, (x, y, z) in nodes.items()]

    def element(label, row):
        if quadratic:  # a data line continued on the next one
            return f"{label}, " + ", ".join(map(str, row[:6])) + ",\n" + ", ".join(map(str, row[6:]))
        return f"{label}, " + ", ".join(map(str, row))

    lines += [f"*Element, type={kind}, elset=partA"] + [element(LABELS[k], rows[k]) for k in (0, 1)]
    lines += [f"*ELEMENT,TYPE={kind} , ELSET=partB"] + [element(LABELS[k], rows[k]) for k in (2, 3, 4)]
    return "\n".join(lines) + "\n" + surfaces


def _measure(domain, name: str | None) -> float:
    """Area of boundary ``name`` (None: the whole exterior)."""
    import ufl
    from dolfinx import fem

    measure = ufl.ds(domain=domain.mesh) if name is None else domain.ds(name)
    return domain.comm.allreduce(fem.assemble_scalar(fem.form(1.0 * measure)))


def _facets(path: Path) -> dict[str, np.ndarray]:
    """Boundary name → facet rows of the written .msh (meshio)."""
    import meshio

    mesh = meshio.read(path)
    names = {int(v[0]): k for k, v in mesh.field_data.items() if int(v[1]) == 2}
    out: dict[str, list] = {}
    for block, tags in zip(mesh.cells, mesh.cell_data["gmsh:physical"], strict=True):
        if block.type.startswith("triangle"):
            for tag in np.unique(tags):
                out.setdefault(names[int(tag)], []).append(block.data[tags == tag])
    return {k: np.concatenate(v) for k, v in out.items()}


@pytest.mark.parametrize("quadratic", [False, True], ids=["C3D4", "C3D10"])
def test_surfaces_become_boundaries(quadratic, shared_tmp):
    """Every surface and node set is a boundary with its faces: two per cube face, area 1 (any rank count)."""
    source, target = shared_tmp / "cube.inp", shared_tmp / "cube.msh"
    if MPI.COMM_WORLD.rank == 0:
        source.write_text(_inp(SURFACES, quadratic))
    MPI.COMM_WORLD.Barrier()
    dispatch(["convert", str(source), str(target)])
    domain = hf.read_mesh(target)
    assert sorted(domain.cell_groups) == ["partA", "partB"]
    assert sorted(domain.facet_groups) == sorted(EXPECTED)  # node set 'top' overlaps surface 'lid': dropped
    for name in EXPECTED:
        assert _measure(domain, name) == pytest.approx(1.0, rel=1e-12), name
    assert _measure(domain, None) == pytest.approx(6.0, rel=1e-12)  # the whole exterior still 6
    if MPI.COMM_WORLD.rank == 0:
        facets = _facets(target)
        assert {k: len(v) for k, v in facets.items()} == EXPECTED
        if quadratic:  # 6-node triangles, the mid-edge nodes at the midpoints of their edges
            import meshio

            points = meshio.read(target).points
            for rows in facets.values():
                assert rows.shape[1] == 6
                for k, (a, b) in enumerate([(0, 1), (1, 2), (2, 0)]):
                    np.testing.assert_allclose(points[rows[:, 3 + k]], (points[rows[:, a]] + points[rows[:, b]]) / 2)


@pytest.mark.serial
def test_conversion_report_and_element_order(tmp_path):
    """The report names the surfaces, the sets only used for surfaces, and the dropped node set."""
    source = tmp_path / "cube.inp"
    source.write_text(_inp(SURFACES))
    report = convert(source, tmp_path / "cube.msh")
    assert report.regions == {"partA": 2, "partB": 3}
    assert report.boundaries == {"back": 2, "bottom": 2, "lid": 2, "front": 2, "right": 2}
    assert "element sets only used to define surfaces (not regions): top_els, y0" in report.notes
    assert any(w.startswith("node set 'top' is no boundary: its faces overlap boundary 'lid'") for w in report.warnings)
    assert "node set 'x1' defines a surface: not a boundary of its own" in report.notes
    assert not any("'x1'" in w for w in report.warnings)
    # the element labels follow meshio's cells in file order: surface 'bottom' by label 101 and 7 lies on z = 0
    import meshio

    written = meshio.read(tmp_path / "cube.msh")
    assert np.all(written.points[_facets(tmp_path / "cube.msh")["bottom"]][:, :, 2] == 0.0)


@pytest.mark.serial
@pytest.mark.parametrize(
    "surface, count, area",
    [
        ("*Surface, name=skin\npartA\npartB\n", 12, 6.0),  # no face identifier: all exposed faces
        ("*Surface, name=skin\n101\n", 3, 1.5),  # element (1, 2, 4, 5): z = 0, y = 0, x = 0
        ("*Surface, name=skin\n101, S4\n20, S2\n", 2, 1.0),  # x = 0
        ("*Nset, nset=top, generate\n50, 80, 10\n*Surface, name=skin, type=node\ntop\n", 2, 1.0),
        ("*Surface, name=skin, type=node\n20\n30\n60\n70\n", 2, 1.0),  # x = 1, node labels
    ],
    ids=["elsets", "element", "labels", "nset", "nodes"],
)
def test_surface_forms(surface, count, area, tmp_path):
    source, target = tmp_path / "cube.inp", tmp_path / "cube.msh"
    source.write_text(_inp(surface))
    report = convert(source, target)
    assert report.boundaries == {"skin": count}
    assert _measure(hf.read_mesh(target, MPI.COMM_SELF), "skin") == pytest.approx(area, rel=1e-12)


BAD = {
    "interior": ("*Surface, name=clamp\n101, S3\n", "LINE: *SURFACE clamp: face S3 of element 101 is inside the mesh "
                 "(shared with element 55); a boundary must lie on the exterior"),
    "element": ("*Surface, name=clamp\n42, S1\n", "LINE: *SURFACE clamp: no element 42 in the file"),
    "elset": ("*Surface, name=clamp\nnosuch, S1\n", "LINE: *SURFACE clamp: no element set 'nosuch'"),
    "face": ("*Surface, name=clamp\n101, S5\n", "LINE: *SURFACE clamp: 'S5' is not a face of a tetrahedron "
             "(S1, S2, S3 or S4)"),
    "spos": ("*Surface, name=clamp\n101, SPOS\n", "LINE: *SURFACE clamp: 'SPOS' is not a face of a tetrahedron"),
    "set_label": ("*Elset, elset=e\n101, 9\n*Surface, name=clamp\ne, S1\n",
                  "LINE: *ELSET e: no element 9 in the file"),
    "entries": ("*Surface, name=clamp\n101, 7, S1\n",
                "LINE: *SURFACE clamp: expected 'element or element set[, face]'"),
    "type": ("*Surface, name=clamp, type=cutting surface\n0, 0, 0\n",
             "LINE: *SURFACE clamp: TYPE=CUTTING SURFACE is not supported (ELEMENT or NODE)"),
    "include": ("*Include, input=more.inp\n*Surface, name=clamp\n101, S1\n",
                "LINE: *INCLUDE is not supported in a file with *SURFACE"),
}


@pytest.mark.serial
@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_surfaces_are_refused(case, tmp_path):
    text, expected = BAD[case]
    source, target = tmp_path / "cube.inp", tmp_path / "out.msh"
    source.write_text(_inp(text))
    bad_line = next(i for i, line in enumerate(source.read_text().splitlines(), 1) if line.startswith(
        ("101, S3", "42,", "nosuch", "101, S5", "101, SPOS", "101, 9", "101, 7, S1", "*Surface, name=clamp, type",
         "*Include")))
    with pytest.raises(MeshError) as info:
        convert(source, target)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{source}:{expected.replace('LINE', str(bad_line))}"), message
    assert not target.exists()


@pytest.mark.serial
def test_surfaces_sharing_a_face_are_refused(tmp_path):
    source = tmp_path / "cube.inp"
    source.write_text(_inp("*Surface, name=a\n101, S1\n*Surface, name=b\n101\n"))
    with pytest.raises(MeshError, match=r"boundaries 'a' and 'b' share 1 face; hyperfem gives each face one boundary"):
        convert(source, tmp_path / "out.msh")


@pytest.mark.serial
def test_node_sets_without_surfaces_get_one_boundary_per_face(tmp_path):
    """Overlapping *NSET boundaries (no *SURFACE): the smaller is kept, the other dropped with a warning."""
    source, target = tmp_path / "cube.inp", tmp_path / "cube.msh"
    source.write_text(_inp("*Nset, nset=all, generate\n10, 80, 10\n*Nset, nset=top\n50, 60, 70, 80\n"))
    report = convert(source, target)
    assert report.boundaries == {"top": 2}
    assert any(w.startswith("node set 'all' is no boundary") for w in report.warnings)
    assert _measure(hf.read_mesh(target, MPI.COMM_SELF), "top") == pytest.approx(1.0, rel=1e-12)


CAE = """*End Part
**
*Assembly, name=Assembly
*Instance, name=Cube-1, part=Cube
*End Instance
*Elset, elset=_Surf-1_S3, internal, instance=Cube-1
 3, 20
*Surface, type=ELEMENT, name=Surf-1
_Surf-1_S3, S3
*Surface, type=ELEMENT, name=Surf-2
Cube-1.101, S1
Cube-1.7, S1
*End Assembly
"""


@pytest.mark.serial
def test_abaqus_cae_layout(tmp_path):
    """One part, one instance: INTERNAL sets with instance=, names qualified by the instance; several: refused."""
    source, target = tmp_path / "cube.inp", tmp_path / "cube.msh"
    source.write_text(_inp(CAE).replace("*Node", "*Part, name=Cube\n*Node", 1))
    report = convert(source, target)
    assert report.regions == {"partA": 2, "partB": 3} and report.boundaries == {"Surf-1": 2, "Surf-2": 2}
    domain = hf.read_mesh(target, MPI.COMM_SELF)
    assert _measure(domain, "Surf-1") == pytest.approx(1.0, rel=1e-12)
    assert _measure(domain, "Surf-2") == pytest.approx(1.0, rel=1e-12)
    source.write_text(source.read_text().replace("*End Instance", "*End Instance\n*Instance, name=Cube-2, part=Cube"
                                                 "\n*End Instance", 1))
    with pytest.raises(MeshError, match=r"cube.inp:\d+: \*SURFACE in a file of several parts or part instances"):
        convert(source, target)


@pytest.mark.serial
def test_quadratic_mesh_without_sets(tmp_path):
    """C3D10 without sets: region 'domain', boundary 'boundary' of 6-node triangles (the whole exterior, 6)."""
    source, target = tmp_path / "cube.inp", tmp_path / "cube.msh"
    source.write_text(_inp("", quadratic=True).replace(", elset=partA", "").replace(" , ELSET=partB", ""))
    report = convert(source, target)
    assert report.regions == {"domain": 5} and report.boundaries == {"boundary": 12}
    assert _facets(target)["boundary"].shape == (12, 6)
    assert _measure(hf.read_mesh(target, MPI.COMM_SELF), "boundary") == pytest.approx(6.0, rel=1e-12)


@pytest.mark.serial
@pytest.mark.parametrize("surfaces", [SURFACES, ""], ids=["with-surfaces", "sets-only"])
def test_hybrid_tetrahedra_are_read_as_plain_ones(surfaces, tmp_path):
    """C3D4H (Abaqus's u-p tetrahedron, common for rubber and tissue): the same nodes as C3D4, with a note."""
    source = tmp_path / "hybrid.inp"
    source.write_text(_inp(surfaces).replace("type=C3D4,", "type=C3D4H,").replace("TYPE=C3D4 ,", "TYPE=C3D4H ,"))
    assert source.read_text().count("C3D4H") == 2
    result = convert(source, tmp_path / "hybrid.msh")
    assert result.cells == len(TETS) and result.cell_type == "tetra"
    assert any("C3D4H" in note and "mixed" in note for note in result.notes)
    plain = tmp_path / "plain.inp"
    plain.write_text(_inp(surfaces))
    reference = convert(plain, tmp_path / "plain.msh")
    assert result.regions == reference.regions and result.boundaries == reference.boundaries
