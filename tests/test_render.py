"""3D pictures: the boundary surface (always; serial and MPI) and the pyvista rendering (where pyvista is installed).

The surface tests use box meshes whose answers are known exactly (area,
Euler characteristic, enclosed volume, affine displacements at the vertices)
and check that 1 and 2 ranks give the same surface. The rendering tests
write small PNGs and look at their size and pixels; the case-file test runs
one load step on the coarse committed beam.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from dolfinx import fem, mesh
from mpi4py import MPI

from hyperfem.app import load_case, plan
from hyperfem.app.build import build
from hyperfem.app.calls import source as node_source
from hyperfem.app.schema import CaseFileError
from hyperfem.errors import OutputError, ParameterError
from hyperfem.simulation.render import DISPLACEMENT, Render, Surface, boundary_surface, render_png

from case_texts import BASE

CELLS = {"tetrahedron": mesh.CellType.tetrahedron, "hexahedron": mesh.CellType.hexahedron}


def _box(comm, cell: str = "tetrahedron", n=(3, 4, 5)):
    return mesh.create_box(comm, [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]], list(n), cell_type=CELLS[cell])


def _affine(x):
    return np.vstack([0.1 * x[1] + 0.02, 0.05 * x[0] - 0.03 * x[2], 0.04 * x[2] + 0.01 * x[0]])


def _affine_at(points: np.ndarray) -> np.ndarray:
    return _affine(points.T).T


def _displacement(domain, degree: int) -> fem.Function:
    u = fem.Function(fem.functionspace(domain, ("Lagrange", degree, (3,))), name="u")
    u.interpolate(_affine)
    return u


def _shared_path(tmp_path: Path) -> Path:
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))


def _canonical(surface: Surface, digits: int = 9) -> list:
    """Triangles as sorted coordinate triples with their data: the surface up to vertex and triangle order."""
    key = [tuple(np.round(p, digits)) for p in surface.points]
    out = []
    for t, tri in enumerate(surface.triangles):
        corners = sorted((key[i], round(float(surface.point_data[DISPLACEMENT][i]), digits)) for i in tri)
        cells = tuple(round(float(v[t]), digits) for v in surface.cell_data.values())
        out.append((tuple(corners), cells))
    return sorted(out)


# -- the surface -----------------------------------------------------------------------------------
@pytest.mark.parametrize("cell", ["tetrahedron", "hexahedron"])
@pytest.mark.parametrize("degree", [1, 2])
def test_box_surface_is_closed_with_the_right_area(comm, cell, degree):
    """The boundary of a 1 x 2 x 3 box: area 22, Euler characteristic 2, every edge in two triangles, volume 6."""
    u = _displacement(_box(comm, cell), degree)
    surface = boundary_surface(u)
    if comm.rank != 0:
        assert surface is None
        return
    assert surface.area() == pytest.approx(22.0, rel=1e-10)
    assert surface.euler_characteristic == 2
    t = surface.triangles
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)  # closed and manifold
    p = surface.points[t]  # outward triangles: the divergence theorem gives the volume with a + sign
    volume = np.einsum("nd,nd->n", p[:, 0], np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])).sum() / 6.0
    assert volume == pytest.approx(6.0, rel=1e-10)
    on_box = np.isclose(surface.points, 0.0) | np.isclose(surface.points, [1.0, 2.0, 3.0])
    assert np.all(on_box.any(axis=1))  # every vertex is on a face of the box
    assert len(np.unique(surface.vertex_ids)) == len(surface.points)


@pytest.mark.parametrize("degree", [1, 2])
def test_deformed_coordinates_are_reference_plus_displacement(comm, degree):
    """An affine displacement (exact in P1 and P2): the vertices move by u(X), |u| is the point data."""
    u = _displacement(_box(comm), degree)
    surface = boundary_surface(u)
    if comm.rank == 0:
        expected = _affine_at(surface.points)
        assert np.allclose(surface.displacement, expected, rtol=0.0, atol=1e-12)
        assert np.allclose(surface.deformed(), surface.points + expected, rtol=0.0, atol=1e-12)
        assert np.allclose(surface.deformed(2.0), surface.points + 2.0 * expected, rtol=0.0, atol=1e-12)
        assert np.allclose(surface.point_data[DISPLACEMENT], np.linalg.norm(expected, axis=1), atol=1e-12)
        assert surface.area(1.0) > surface.area()  # this u stretches the box


def test_scalars_per_vertex_and_per_triangle(comm):
    """A P1 scalar is exact at the vertices; a DG0 one is the value of the facet's cell; a vector: its magnitude."""
    domain = _box(comm)
    u = _displacement(domain, 2)
    f = fem.Function(fem.functionspace(domain, ("Lagrange", 1)), name="f")
    f.interpolate(lambda x: 1.0 + x[0] + 2.0 * x[1] + 3.0 * x[2])
    g = fem.Function(fem.functionspace(domain, ("DG", 0)), name="g")
    g.interpolate(lambda x: x[0])  # at the cell midpoints
    w = fem.Function(fem.functionspace(domain, ("DG", 1, (3,))), name="w")
    w.interpolate(lambda x: np.vstack([3.0 + 0.0 * x[0], 4.0 + 0.0 * x[0], 0.0 * x[0]]))
    surface = boundary_surface(u, [f, g, w])
    if comm.rank != 0:
        return
    assert set(surface.point_data) == {DISPLACEMENT, "f", "w"} and set(surface.cell_data) == {"g"}
    x = surface.points
    assert np.allclose(surface.point_data["f"], 1.0 + x[:, 0] + 2.0 * x[:, 1] + 3.0 * x[:, 2], atol=1e-12)
    assert np.allclose(surface.point_data["w"], 5.0, atol=1e-12)
    xt = x[surface.triangles][:, :, 0]  # x of each corner
    values = surface.cell_data["g"]
    h = 1.0 / 3.0
    right, left = np.all(np.isclose(xt, 1.0), axis=1), np.all(np.isclose(xt, 0.0), axis=1)
    assert right.any() and left.any()
    assert np.all((values[right] > 1.0 - h) & (values[right] < 1.0))
    assert np.all((values[left] > 0.0) & (values[left] < h))
    assert np.all((values >= 0.0) & (values <= 1.0))


def test_same_surface_on_any_number_of_ranks(comm):
    """The gathered surface on COMM_WORLD equals that of the whole mesh on one rank (up to ordering)."""
    def surface_on(c):
        domain = _box(c, n=(2, 3, 4))
        u = _displacement(domain, 2)
        g = fem.Function(fem.functionspace(domain, ("DG", 0)), name="g")
        g.interpolate(lambda x: x[0] + 10.0 * x[1] + 100.0 * x[2])
        return boundary_surface(u, {"g": g})

    everywhere = surface_on(comm)
    if comm.rank == 0:
        alone = surface_on(MPI.COMM_SELF)
        assert len(everywhere.points) == len(alone.points) and len(everywhere.triangles) == len(alone.triangles)
        assert _canonical(everywhere) == _canonical(alone)
        assert np.array_equal(everywhere.vertex_ids, alone.vertex_ids)  # the same canonical order, too
        assert np.allclose(everywhere.points, alone.points, atol=1e-14)
        assert np.array_equal(everywhere.triangles, alone.triangles)


def test_two_dimensional_mesh_is_its_own_surface(comm):
    """A 2D mesh: its cells, at z = 0, counter-clockwise from +z (a disc: Euler characteristic 1)."""
    domain = mesh.create_rectangle(comm, [[0.0, 0.0], [2.0, 1.0]], [4, 2])
    u = fem.Function(fem.functionspace(domain, ("Lagrange", 2, (2,))), name="u")
    u.interpolate(lambda x: np.vstack([0.1 * x[1], 0.0 * x[0]]))
    surface = boundary_surface(u)
    if comm.rank == 0:
        assert surface.area() == pytest.approx(2.0, rel=1e-12)
        assert surface.euler_characteristic == 1
        assert np.allclose(surface.points[:, 2], 0.0) and np.allclose(surface.displacement[:, 2], 0.0)
        assert np.allclose(surface.displacement[:, 0], 0.1 * surface.points[:, 1], atol=1e-12)
        p = surface.points[surface.triangles]
        assert np.all(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2] > 0.0)


def test_bad_scalars_are_refused_on_every_rank(comm):
    domain = _box(comm, n=(1, 1, 1))
    u = _displacement(domain, 1)
    tensor = fem.Function(fem.functionspace(domain, ("DG", 0, (3, 3))), name="T")
    with pytest.raises(ParameterError, match="'T' are a tensor"):
        boundary_surface(u, tensor)
    other = fem.Function(fem.functionspace(_box(comm, n=(1, 1, 1)), ("DG", 0)), name="q")
    with pytest.raises(ParameterError, match="'q' live on another mesh"):
        boundary_surface(u, other)


# -- rendering -------------------------------------------------------------------------------------
def test_missing_pyvista_says_how_to_install(comm, tmp_path, monkeypatch):
    """Without pyvista: an OutputError on every rank that names the extra (no rank hangs)."""
    monkeypatch.setitem(sys.modules, "pyvista", None)  # import pyvista raises ImportError
    u = _displacement(_box(comm, n=(1, 1, 1)), 1)
    with pytest.raises(OutputError, match=r"pip install 'hyperfem\[render\]'"):
        render_png(u, _shared_path(tmp_path) / "x.png")
    with pytest.raises(OutputError, match=r"pyvista is not installed"):
        Render(tmp_path / "x.png").start(type("Sim", (), {"comm": comm})())


def test_render_options_are_checked_before_drawing():
    with pytest.raises(ParameterError, match="window_size"):
        Render("x.png", window_size=(800,))
    with pytest.raises(ParameterError, match="parallel to the view"):
        Render("x.png", view=(0, 1, 0), up=(0, 2, 0))
    with pytest.raises(ParameterError, match="unknown scalars 'stress'"):
        Render("x.png", scalars="stress")
    with pytest.raises(ParameterError, match="undeformed"):
        Render("x.png", undeformed="ghost")


def _png(path: Path):
    image = pytest.importorskip("PIL.Image")
    with image.open(path) as picture:
        picture.load()
        return picture.format, picture.size, np.asarray(picture.convert("RGB"))


def test_render_png_writes_the_picture(comm, tmp_path):
    """A PNG of the requested size, with the body (non-white pixels of several colours) on a white background."""
    pytest.importorskip("pyvista")
    domain = _box(comm)
    u = _displacement(domain, 2)
    g = fem.Function(fem.functionspace(domain, ("DG", 0)), name="g")
    g.interpolate(lambda x: x[2])
    folder = _shared_path(tmp_path)
    for name, scalars in (("u.png", DISPLACEMENT), ("g.png", g)):
        path = render_png(u, folder / "sub" / name, scalars=scalars, window_size=(240, 160), title="box", scale=2.0)
        assert (path == folder / "sub" / name) if comm.rank == 0 else path is None
        if comm.rank == 0:
            kind, size, pixels = _png(path)
            assert kind == "PNG" and size == (240, 160)
            body = np.any(pixels < 235, axis=2)
            assert 0.05 < body.mean() < 0.95
            assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20  # a colour map, shading, text
            assert np.all(pixels[0, -1] > 245)  # the corner is background
    with pytest.raises(ParameterError, match="no scalars named 'nope'"):
        render_png(u, folder / "n.png", scalars="nope")
    blocker = folder / "file"
    if comm.rank == 0:
        blocker.write_text("not a folder")
    comm.Barrier()
    with pytest.raises(OutputError, match="cannot write"):
        render_png(u, blocker / "x.png")


CASE = 'name = "rendered"\n' + BASE + """
[stepping]
increment = 0.5
[output]
fields = []
csv = false
convergence = false
checkpoint = false
progress = false
"""
RENDER_LINE = (
    'render = { scalars = "von_mises", every = 1, window_size = [200, 120], undeformed = "wireframe", title = false }'
)
CASE += RENDER_LINE + "\n"


def test_case_file_render_key(comm, tmp_path):
    """``[output] render``: checked, printed as ``Render(...)`` (the 1:1 script), and run: final and numbered PNGs."""
    folder = _shared_path(tmp_path)
    source = folder / f"case-{comm.rank}.toml"
    source.write_text(CASE)
    case = load_case(source, output=folder / "out")
    render = dict(case.output.render.options)
    assert render == {"scalars": "von_mises", "every": 1, "undeformed": "wireframe", "window_size": (200, 120),
                      "title": False}
    (outputs,) = [s for s in plan(case) if s.target == "outputs"]
    assert node_source(dict(outputs.items)["output.render"]) == (
        "Render(\n    out / 'rendered.png',\n    scalars='von_mises',\n    materials=material,\n    every=1,\n"
        "    undeformed='wireframe',\n    window_size=(200, 120),\n    title=False,\n)"
    )
    assert load_case(source, ["output.render=true"], output=folder / "out").output.render.options == ()
    assert load_case(source, ["output.render=false"], output=folder / "out").output.render is None
    pytest.importorskip("pyvista")
    summary = build(case, comm).simulation.run()
    out = folder / "out"
    assert summary["files"]["render"] == str(out / "rendered.png")
    assert summary["renders"] == [str(out / "rendered-000001.png"), str(out / "rendered-000002.png")]
    if comm.rank == 0:
        for name in ("rendered.png", "rendered-000001.png", "rendered-000002.png"):
            kind, size, pixels = _png(out / name)
            assert kind == "PNG" and size == (200, 120) and np.any(pixels < 200)


@pytest.mark.parametrize(
    "render, message",
    [
        ('"yes"', "output.render: expected true, false or a table"),
        ("{ scalar = \"J\" }", "output.render.scalar: unknown key (did you mean 'scalars'?)"),
        ("{ scalars = \"stress\" }", "output.render.scalars: unknown value 'stress'"),
        ("{ window_size = [800.0, 500] }", "output.render.window_size: expected two positive integers"),
        ("{ view = [0, 0, 0] }", "output.render: render: view must be 3 finite numbers, not all zero"),
        ("{ scalars = \"fibre_stretch\" }", "output.render.scalars: fibre_stretch needs a [fibres] table"),
        ("{ clim = [2, 1] }", "output.render.clim: needs low < high"),
        ("{ every = 0 }", "output.render.every: must be >= 1"),
    ],
)
def test_case_file_render_errors(comm, tmp_path, render, message):
    source = tmp_path / "case.toml"
    source.write_text(CASE.replace(RENDER_LINE, f"render = {render}"))
    with pytest.raises(CaseFileError) as info:
        load_case(source)
    assert message in str(info.value)


def test_render_command_draws_a_checkpoint(comm, tmp_path, capsys):
    """``hyperfem render CASE --checkpoint OUT``: the state of the run's last checkpoint, drawn as during the run.

    Without a checkpoint it is one CheckpointError (no pyvista needed to get there).
    """
    from hyperfem.app.main import dispatch
    from hyperfem.io import CheckpointError

    folder = _shared_path(tmp_path)
    source = folder / "case.toml"
    if comm.rank == 0:
        source.write_text(CASE.replace(RENDER_LINE, "").replace("checkpoint = false", "checkpoint_every = 1"))
    comm.Barrier()
    with pytest.raises(CheckpointError, match=r"cannot draw the state of .*nothing: no checkpoint there"):
        dispatch(["render", str(source), "--checkpoint", str(folder / "nothing")])
    pytest.importorskip("pyvista")
    dispatch(["run", str(source), "--output", str(folder / "out")])
    picture = folder / "picture.png"
    dispatch(["render", str(source), "--checkpoint", str(folder / "out"), "--scalars", "J", "-o", str(picture),
              "--set", "output.render={window_size = [160, 100]}"])
    if comm.rank == 0:
        assert "rendered at t = 1, step 2 (completed run" in capsys.readouterr().out
        kind, size, pixels = _png(picture)
        assert kind == "PNG" and size == (160, 100) and np.any(pixels < 200)
