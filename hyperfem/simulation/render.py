r"""3D pictures of the deformed body as PNG: its boundary surface, coloured by a field, rendered offscreen.

Two layers:

* :func:`boundary_surface` — pure NumPy and MPI, always available: the
  exterior boundary of the mesh of a displacement function as triangles
  (a hexahedral mesh's quadrilateral facets split in two; a 2D mesh is its
  own surface), with the reference coordinates and the displacement at
  every vertex and optional scalars, gathered to rank 0 as a
  :class:`Surface`. Vertices shared between cells or ranks appear once (by
  the mesh file's node index), and vertices and triangles are put in a
  canonical order, so the surface is the same for any number of ranks.
  Displacements of any Lagrange degree are taken at the mesh vertices.
* :func:`render_png` (collective) and :func:`render_surface` (one process)
  draw it with `pyvista <https://pyvista.org>`_, imported only here and
  only on rank 0: offscreen, with a fixed camera (a view direction, by
  default an isometric one), the undeformed outline, a scalar bar. Without
  pyvista they raise :class:`~hyperfem.errors.OutputError` saying
  ``pip install 'hyperfem[render]'``.

:class:`Render` is the :class:`~hyperfem.simulation.outputs.Output` of a
:class:`~hyperfem.simulation.Simulation`: a picture at the end of the run
and, optionally, every k steps (``bend-000010.png``), coloured by the
displacement magnitude or by a derived cell field of
:mod:`hyperfem.simulation.fields` (``von_mises``, ``J``, ...).

Scalars from a cell-wise constant (DG0) function are per triangle (the value
of the cell the boundary facet belongs to); from any other function per
vertex (the mean over the cells around the vertex that touch the boundary;
exact for a continuous function).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh

from hyperfem.errors import HyperfemError, OutputError, ParameterError
from hyperfem.io.results import ensure_output_dir
from hyperfem.simulation.outputs import Output
from hyperfem.solver.stepping import StepRecord

if TYPE_CHECKING:
    import pyvista  # optional, untyped: Any to the checker
    from mpi4py import MPI

    from hyperfem.simulation.fields import ActivationSpec, Materials
    from hyperfem.simulation.measures import CellFunctions
    from hyperfem.simulation.runner import Simulation

__all__ = [
    "DEFAULT_VIEW",
    "DISPLACEMENT",
    "RENDER_SCALARS",
    "UNDEFORMED",
    "Render",
    "Surface",
    "boundary_surface",
    "check_render_options",
    "numbered_path",
    "render_png",
    "render_surface",
    "require_pyvista",
]

DISPLACEMENT = "displacement"
"""Name of the displacement magnitude :math:`|u|` among a :class:`Surface`'s point data."""

RENDER_SCALARS = (DISPLACEMENT, "von_mises", "J", "fibre_stretch", "activation")
"""What :class:`Render` colours the surface by: :math:`|u|`, or a scalar field of :mod:`hyperfem.simulation.fields`."""

UNDEFORMED = ("outline", "wireframe", "surface")
"""How the undeformed body is drawn: its feature edges, every triangle edge, or a translucent surface."""

INSTALL = "pip install 'hyperfem[render]'"

DEFAULT_VIEW = (1.0, 0.7, 1.6)
"""Default view direction (from the body towards the camera): an isometric-like view from +x, +y, +z."""

_TITLES = {
    DISPLACEMENT: "displacement |u|",
    "von_mises": "von Mises stress",
    "J": "J = det F",
    "fibre_stretch": "fibre stretch",
    "activation": "activation",
}

Scalars = fem.Function | Sequence[fem.Function] | Mapping[str, fem.Function] | None


# -- the surface (NumPy + MPI) ------------------------------------------------------------------
@dataclass
class Surface:
    """The boundary of a body as triangles, on one process (:func:`boundary_surface`).

    Attributes:
        points: Reference coordinates of the vertices, shape ``(n, 3)`` (2D meshes: ``z = 0``).
        displacement: Displacement at the vertices, shape ``(n, 3)``.
        triangles: Vertex indices, shape ``(m, 3)``, counter-clockwise seen from outside.
        point_data: Name → one value per vertex (:data:`DISPLACEMENT`: :math:`|u|`).
        cell_data: Name → one value per triangle (from cell-wise constant functions).
        vertex_ids: The mesh file's index of every vertex (what identifies it across partitions).
    """

    points: np.ndarray
    displacement: np.ndarray
    triangles: np.ndarray
    point_data: dict[str, np.ndarray] = field(default_factory=dict)
    cell_data: dict[str, np.ndarray] = field(default_factory=dict)
    vertex_ids: np.ndarray | None = None

    def deformed(self, scale: float = 1.0) -> np.ndarray:
        """Current coordinates ``points + scale * displacement``, shape ``(n, 3)``."""
        return self.points + scale * self.displacement

    def area(self, scale: float = 0.0) -> float:
        """Total area of the triangles at ``points + scale * displacement`` (0: reference, 1: deformed)."""
        x = self.deformed(scale)[self.triangles]
        return float(0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1).sum())

    def edges(self) -> np.ndarray:
        """The distinct edges, shape ``(e, 2)``, each as (smaller, larger) vertex index."""
        t = self.triangles
        pairs = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
        return np.unique(np.sort(pairs, axis=1), axis=0)

    @property
    def euler_characteristic(self) -> int:
        """Vertices − edges + triangles (2 for the boundary of a solid without holes)."""
        return int(len(self.points) - len(self.edges()) + len(self.triangles))

    def values(self, name: str) -> tuple[np.ndarray, str]:
        """The values of ``name`` and where they live (``"point"`` or ``"cell"``).

        Raises:
            ParameterError: No such data.
        """
        if name in self.point_data:
            return self.point_data[name], "point"
        if name in self.cell_data:
            return self.cell_data[name], "cell"
        known = ", ".join([*self.point_data, *self.cell_data]) or "none"
        raise ParameterError(f"Surface: no scalars named {name!r} (known: {known})")


def _scalar_functions(scalars: Scalars) -> dict[str, fem.Function]:
    if scalars is None:
        return {}
    if isinstance(scalars, fem.Function):
        return {scalars.name: scalars}
    if isinstance(scalars, Mapping):
        return dict(scalars)
    return {f.name: f for f in scalars}


def _facet_corners(mesh: dmesh.Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Per owned boundary facet (3D) or owned cell (2D): its cell and its vertices' geometry nodes."""
    topology, tdim = mesh.topology, mesh.topology.dim
    nodes_of_cells = mesh.geometry.dofmaps[0]
    if tdim == 2:
        cells = np.arange(topology.index_map(2).size_local, dtype=np.int32)
        nv = 3 if topology.cell_type == dmesh.CellType.triangle else 4
        return cells, nodes_of_cells[cells, :nv]
    if tdim != 3:
        raise ParameterError(f"boundary_surface: needs a 2D or 3D mesh, got topological dimension {tdim}")
    if topology.cell_type not in (dmesh.CellType.tetrahedron, dmesh.CellType.hexahedron):
        raise ParameterError(f"boundary_surface: needs tetrahedra or hexahedra, got {topology.cell_type.name} cells")
    topology.create_connectivity(tdim - 1, tdim)
    facets = np.asarray(dmesh.exterior_facet_indices(topology), dtype=np.int32)
    f2c = topology.connectivity(tdim - 1, tdim)
    cells = np.asarray(f2c.array, dtype=np.int32)[np.asarray(f2c.offsets)[facets]]  # the one cell of each
    nodes = dmesh.entities_to_geometry(mesh, tdim - 1, facets)
    nv = 3 if topology.cell_type == dmesh.CellType.tetrahedron else 4
    return cells, np.asarray(nodes)[:, :nv]  # vertices come first in every Lagrange geometry


def _cycle_quads(x: np.ndarray) -> np.ndarray:
    """Order of the 4 corners of each quadrilateral around it, shape ``(n, 4)`` (any input order)."""
    centre = x.mean(axis=1, keepdims=True)
    d = x - centre
    _, _, vt = np.linalg.svd(d)  # rows of vt: the plane's axes, then its normal
    a = np.einsum("nkd,nd->nk", d, vt[:, 0])
    b = np.einsum("nkd,nd->nk", d, vt[:, 1])
    return np.argsort(np.arctan2(b, a), axis=1)


def _local_triangles(mesh: dmesh.Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """This rank's outward boundary triangles: cells (m,), geometry nodes (m, 3), coordinates (m, 3, 3)."""
    cells, nodes = _facet_corners(mesh)
    x = mesh.geometry.x
    if nodes.shape[1] == 4 and len(nodes):
        order = _cycle_quads(x[nodes])
        quads = np.take_along_axis(nodes, order, axis=1)
        nodes = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
        cells = np.concatenate([cells, cells])
    nodes = nodes.reshape(-1, 3)
    corners = x[nodes]
    if len(nodes):
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        if mesh.topology.dim == 2:
            inward = normal[:, 2] < 0.0  # seen from +z
        else:
            nvc = {dmesh.CellType.tetrahedron: 4, dmesh.CellType.hexahedron: 8}[mesh.topology.cell_type]
            centre = x[mesh.geometry.dofmaps[0][cells, :nvc]].mean(axis=1)
            inward = np.einsum("nd,nd->n", normal, corners[:, 0] - centre) < 0.0
        nodes[inward] = nodes[inward][:, [0, 2, 1]]
        corners = x[nodes]
    return cells, nodes, corners


def _corner_values(f: fem.Function, corners: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """``f`` at every corner, evaluated in the triangle's cell: shape ``(m, 3)`` or ``(m, 3, k)``."""
    m = len(cells)
    k = int(np.prod(f.ufl_shape)) if f.ufl_shape else 1
    if m == 0:  # a rank whose cells touch no boundary
        values = np.zeros((0, 3, k))
    else:
        values = np.asarray(f.eval(corners.reshape(-1, 3), np.repeat(cells, 3).astype(np.int32)), dtype=float)
        values = values.reshape(m, 3, k)
    return values[..., 0] if k == 1 else values


def _is_piecewise_constant(f: fem.Function) -> bool:
    return f.function_space.dofmap.dof_layout.num_dofs == 1


def boundary_surface(u: fem.Function, scalars: Scalars = None, *, root: int = 0) -> Surface | None:
    """The boundary surface of ``u``'s mesh with ``u`` and ``scalars`` at its vertices, on rank ``root`` (collective).

    Args:
        u: Displacement (vector Lagrange of any degree; the values at the mesh
            vertices are used).
        scalars: Further functions on the same mesh to carry along: one, a
            sequence (named by their ``name``) or name → function. Scalar or
            vector (its magnitude); cell-wise constant ones (DG0) become
            :attr:`Surface.cell_data`, others :attr:`Surface.point_data`.
            :data:`DISPLACEMENT` (:math:`|u|`) is always in the point data.
        root: The rank that receives the surface.

    Returns:
        The :class:`Surface` on ``root``, ``None`` on the other ranks.

    Raises:
        ParameterError: A function on another mesh, a tensor-valued one, a mesh that is not
            of tetrahedra, hexahedra or 2D cells, or a failure on any rank (on every rank).
    """
    mesh = u.function_space.mesh
    comm = mesh.comm
    functions = _scalar_functions(scalars)
    for name, f in functions.items():
        if f.function_space.mesh is not mesh:
            raise ParameterError(f"boundary_surface: scalars {name!r} live on another mesh than the displacement")
        if len(f.function_space.value_shape) > 1:
            raise ParameterError(f"boundary_surface: scalars {name!r} are a tensor; give a scalar or vector function")
    local, error = None, ""
    try:
        local = _local_part(mesh, u, functions)
    except HyperfemError as exc:
        error = str(exc)
    except Exception as exc:  # noqa: BLE001 - agreed below, so that no rank waits in the gather
        error = f"boundary_surface: rank {comm.rank}: {type(exc).__name__}: {exc}"
    errors = [e for e in comm.allgather(error) if e]
    if errors:
        raise ParameterError(errors[0])
    gathered = comm.gather(local, root=root)
    surface, error = None, ""
    if comm.rank == root:
        try:
            surface = _assemble(gathered, list(functions))
        except Exception as exc:  # noqa: BLE001 - the same error on every rank
            error = f"boundary_surface: {type(exc).__name__}: {exc}"
    error = comm.bcast(error, root=root)
    if error:
        raise ParameterError(error)
    return surface


def _local_part(mesh: dmesh.Mesh, u: fem.Function, functions: dict[str, fem.Function]) -> dict:
    """This rank's triangles: vertex ids, coordinates, displacement and scalars at their corners."""
    cells, nodes, corners = _local_triangles(mesh)
    gdim = mesh.geometry.dim
    x3 = np.zeros((*corners.shape[:2], 3))
    x3[..., :gdim] = corners[..., :gdim]
    ucorner = _corner_values(u, corners, cells)
    u3 = np.zeros_like(x3)
    k = 1 if ucorner.ndim == 2 else ucorner.shape[-1]
    u3[..., :k] = ucorner.reshape(*x3.shape[:2], k)
    local = {
        "ids": np.asarray(mesh.geometry.input_global_indices, dtype=np.int64)[nodes],
        "x": x3,
        "u": u3,
        "scalars": {},
    }
    for name, f in functions.items():
        values = _corner_values(f, corners, cells)
        if values.ndim == 3:
            values = np.linalg.norm(values, axis=2)
        local["scalars"][name] = (values, _is_piecewise_constant(f))
    return local


def _assemble(parts: list[dict], names: list[str]) -> Surface:
    """One surface from every rank's triangles: shared vertices merged by id, canonical order."""
    ids = np.concatenate([p["ids"] for p in parts]).reshape(-1, 3)
    x = np.concatenate([p["x"] for p in parts]).reshape(-1, 3, 3)
    u = np.concatenate([p["u"] for p in parts]).reshape(-1, 3, 3)
    scalars = {n: np.concatenate([p["scalars"][n][0] for p in parts]).reshape(-1, 3) for n in names}
    cellwise = {n: parts[0]["scalars"][n][1] for n in names}
    # canonical triangles: smallest id first (orientation kept), each once, sorted
    shift = np.argmin(ids, axis=1)
    roll = (shift[:, None] + np.arange(3)[None, :]) % 3
    ids, x, u = (np.take_along_axis(a, roll if a.ndim == 2 else roll[..., None], axis=1) for a in (ids, x, u))
    scalars = {n: np.take_along_axis(v, roll, axis=1) for n, v in scalars.items()}
    _, keep = np.unique(ids, axis=0, return_index=True)
    keep = keep[np.lexsort(ids[keep].T[::-1])]
    ids, x, u = ids[keep], x[keep], u[keep]
    scalars = {n: v[keep] for n, v in scalars.items()}
    vertex_ids, first, inverse = np.unique(ids.ravel(), return_index=True, return_inverse=True)
    triangles = inverse.reshape(-1, 3).astype(np.int64)
    points = x.reshape(-1, 3)[first]
    displacement = u.reshape(-1, 3)[first]
    point_data = {DISPLACEMENT: np.linalg.norm(displacement, axis=1)}
    cell_data = {}
    counts = np.bincount(inverse.ravel(), minlength=len(vertex_ids)).astype(float)
    for name, values in scalars.items():
        if cellwise[name]:
            cell_data[name] = values.mean(axis=1)
        else:
            point_data[name] = np.bincount(inverse.ravel(), weights=values.ravel(), minlength=len(vertex_ids)) / counts
    return Surface(points, displacement, triangles, point_data, cell_data, vertex_ids)


# -- rendering (pyvista, one process) -------------------------------------------------------------
def _import_pyvista() -> ModuleType:
    try:
        import pyvista
    except ImportError as exc:
        raise OutputError(f"render: pyvista is not installed (3D pictures are optional: {INSTALL})") from exc
    return pyvista


def require_pyvista(comm: MPI.Comm, cmap: str | None = None) -> None:
    """Check on rank 0 that pyvista can be imported (and knows ``cmap``); the same error on every rank.

    Raises:
        OutputError: pyvista is missing (the message says ``pip install 'hyperfem[render]'``).
        ParameterError: ``cmap`` is not a colour map pyvista knows.
    """
    error = None
    if comm.rank == 0:
        try:
            _import_pyvista()
            if cmap is not None:
                from pyvista.plotting.colors import get_cmap_safe

                try:
                    get_cmap_safe(cmap)
                except (ValueError, KeyError) as exc:
                    raise ParameterError(f"render: unknown colour map {cmap!r} ({exc})") from exc
        except HyperfemError as exc:
            error = (type(exc).__name__, str(exc))
        except Exception as exc:  # noqa: BLE001 - a broken install: say so on every rank, never hang
            error = ("OutputError", f"render: pyvista cannot be used: {type(exc).__name__}: {exc}")
    error = comm.bcast(error, root=0)
    if error is not None:
        raise (ParameterError if error[0] == "ParameterError" else OutputError)(error[1])


@contextlib.contextmanager
def _quiet_vtk() -> Iterator[None]:
    """Hide VTK's warnings while rendering (on a machine without X: 'bad X server connection', then EGL)."""
    try:
        from vtkmodules.vtkCommonCore import vtkLogger
    except ImportError:  # pragma: no cover - vtk without its logger
        yield
        return
    old = vtkLogger.GetCurrentVerbosityCutoff()
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    try:
        yield
    finally:
        vtkLogger.SetStderrVerbosity(old)


def _polydata(pv: ModuleType, points: np.ndarray, triangles: np.ndarray) -> pyvista.PolyData:
    faces = np.hstack([np.full((len(triangles), 1), 3, dtype=np.int64), triangles]).ravel()
    return pv.PolyData(np.ascontiguousarray(points, dtype=float), faces)


def _unit(vector: Sequence[float], what: str) -> np.ndarray:
    v = np.asarray(vector, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0.0:
        raise ParameterError(f"render: {what} must be 3 finite numbers, not all zero, got {list(vector)}")
    return v / np.linalg.norm(v)


def check_render_options(
    window_size: Sequence[int] = (800, 500),
    undeformed: str | None = "outline",
    view: Sequence[float] = DEFAULT_VIEW,
    up: Sequence[float] = (0.0, 1.0, 0.0),
    scale: float = 1.0,
) -> tuple[tuple[int, int], np.ndarray, np.ndarray]:
    """Check the options of :func:`render_surface` that pyvista is not needed for.

    Returns:
        The window size, and the view and up directions as unit vectors.

    Raises:
        ParameterError: Not two positive integers, an unknown ``undeformed``, a zero
            direction, ``up`` along ``view``, a scale that is not finite.
    """
    size = tuple(window_size)
    if len(size) != 2 or not all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n > 0 for n in size):
        raise ParameterError(f"render: window_size must be two positive integers (width, height), got {window_size!r}")
    if undeformed is not None and undeformed not in UNDEFORMED:
        raise ParameterError(f"render: undeformed must be one of {', '.join(UNDEFORMED)} or None, got {undeformed!r}")
    if not np.isfinite(scale):
        raise ParameterError(f"render: scale must be a finite number, got {scale!r}")
    direction = _unit(view, "view")
    upward = _unit(up, "up")
    if abs(float(direction @ upward)) > 0.999:
        raise ParameterError(f"render: up {list(up)} is parallel to the view direction {list(view)}")
    return (int(size[0]), int(size[1])), direction, upward


def _with_note(title: str, note: str) -> str:
    """``title`` with the scale ``note`` (``"×1e3"``): ``"J (×1e3)"``; ``"stress (Pa)"`` → ``"stress (×1e3 Pa)"``."""
    if not note:
        return title
    if title.endswith(")") and "(" in title:
        head, _, unit = title[:-1].rpartition("(")
        return f"{head}({note} {unit})"
    return f"{title} ({note})"


def _bar_scale(values: np.ndarray, clim: tuple[float, float] | None) -> tuple[float, str]:
    """A power of 1000 to divide the scalar bar's values by, and its note for the title (``"×1e3"``)."""
    top = float(np.max(np.abs(values))) if len(values) else 0.0
    if clim is not None:
        top = max(abs(float(clim[0])), abs(float(clim[1])))
    if not np.isfinite(top) or top == 0.0 or 1e-2 <= top < 1e4:
        return 1.0, ""
    exponent = 3 * int(np.floor(np.log10(top) / 3))
    return 10.0**exponent, f"\u00d71e{exponent}"


def _colour_options(
    body: pyvista.PolyData,
    values: np.ndarray | None,
    where: str | None,
    scalars: str | None,
    scalar_bar_title: str | None,
    cmap: str,
    clim: tuple[float, float] | None,
) -> dict[str, object]:
    """The ``add_mesh`` options colouring ``body`` by ``values`` (stored on it, scaled), or one colour."""
    if values is None:
        return {"color": "#b9c7d6"}
    assert scalars is not None  # the values are those of scalars
    factor, unit = _bar_scale(values, clim)
    shown = np.asarray(values, dtype=float) / factor
    (body.point_data if where == "point" else body.cell_data)[scalars] = shown
    bar = {
        "title": _with_note(scalar_bar_title or _TITLES.get(scalars, scalars), unit),
        "vertical": True,
        "position_x": 0.85,
        "position_y": 0.12,
        "width": 0.05,
        "height": 0.72,
        "fmt": "%.3g",
        "color": "black",
        "title_font_size": 14,
        "label_font_size": 13,
        "n_labels": 5,
    }
    limits = None if clim is None else (clim[0] / factor, clim[1] / factor)
    return {"scalars": scalars, "cmap": cmap, "clim": limits, "scalar_bar_args": bar, "preference": where}


def _add_reference(plotter: pyvista.Plotter, pv: ModuleType, surface: Surface, undeformed: str) -> None:
    """Draw the reference body: its feature edges (``"outline"``), a wireframe, or translucent."""
    reference = _polydata(pv, surface.points, surface.triangles)
    if undeformed == "outline":
        edges = reference.extract_feature_edges(
            feature_angle=30.0, boundary_edges=True, non_manifold_edges=False, manifold_edges=False
        )
        plotter.add_mesh(edges, color="#505050", line_width=1.5)
    elif undeformed == "wireframe":
        plotter.add_mesh(reference, style="wireframe", color="#707070", line_width=0.5, opacity=0.6)
    else:
        plotter.add_mesh(reference, color="#c0c0c0", opacity=0.25)


def _place_camera(
    plotter: pyvista.Plotter, direction: np.ndarray, upward: np.ndarray, parallel: bool, zoom: float
) -> None:
    """Look at the centre of the bodies from ``direction``, fit them into the picture, then zoom."""
    centre = np.asarray(plotter.bounds, dtype=float).reshape(3, 2).mean(axis=1)
    plotter.camera.focal_point = tuple(centre)
    plotter.camera.position = tuple(centre + direction)
    plotter.camera.up = tuple(upward)
    if parallel:
        plotter.enable_parallel_projection()
    plotter.reset_camera()
    if zoom != 1.0:
        plotter.camera.zoom(zoom)


def render_surface(
    surface: Surface,
    path: str | Path,
    *,
    scalars: str | None = DISPLACEMENT,
    scale: float = 1.0,
    view: Sequence[float] = DEFAULT_VIEW,
    up: Sequence[float] = (0.0, 1.0, 0.0),
    undeformed: str | None = "outline",
    window_size: tuple[int, int] = (800, 500),
    title: str | None = None,
    scalar_bar_title: str | None = None,
    cmap: str = "viridis",
    clim: tuple[float, float] | None = None,
    show_edges: bool = False,
    zoom: float = 1.0,
    parallel: bool = True,
    background: str = "white",
) -> Path:
    """Draw ``surface`` deformed into a PNG, on this process only (see :func:`render_png` for MPI).

    Args:
        surface: From :func:`boundary_surface`.
        path: The ``.png`` file (its folder must exist).
        scalars: Point or cell data to colour by (``None``: one colour).
        scale: Displacement magnification (1: the true deformation; 0: the reference body).
        view: Direction from the body towards the camera.
        up: The direction that is up in the picture.
        undeformed: Draw the reference body too (:data:`UNDEFORMED`), or ``None``.
        window_size: Width and height of the picture in pixels.
        title: Text in the upper left corner.
        scalar_bar_title: Title of the scalar bar (default: a name for ``scalars``).
        cmap: Matplotlib colour map name.
        clim: Colour range (default: the range of the values).
        show_edges: Draw the triangle edges of the deformed surface.
        zoom: Camera zoom after fitting the bodies into the picture (> 1: closer).
        parallel: Parallel projection (``False``: perspective).
        background: Background colour.

    Returns:
        The path.

    Raises:
        OutputError: pyvista is missing, or the file cannot be written.
        ParameterError: Unknown scalars or invalid options.
    """
    size, direction, upward = check_render_options(window_size, undeformed, view, up, scale)
    values, where = surface.values(scalars) if scalars is not None else (None, None)
    pv = _import_pyvista()
    path = Path(path)
    with _quiet_vtk():
        plotter = pv.Plotter(off_screen=True, window_size=list(size))
        try:
            plotter.set_background(background)
            body = _polydata(pv, surface.deformed(scale), surface.triangles)
            options = _colour_options(body, values, where, scalars, scalar_bar_title, cmap, clim)
            plotter.add_mesh(body, show_edges=show_edges, edge_color="#404040", line_width=0.5,
                             smooth_shading=True, split_sharp_edges=True, feature_angle=30.0, **options)
            if undeformed is not None:
                _add_reference(plotter, pv, surface, undeformed)
            if title:
                plotter.add_text(title, position="upper_left", font_size=10, color="black")
            _place_camera(plotter, direction, upward, parallel, zoom)
            try:
                plotter.screenshot(str(path), window_size=list(size))
            except (OSError, ValueError, RuntimeError) as exc:
                raise OutputError(f"render: cannot write {path}: {exc}") from exc
        finally:
            plotter.close()
    if not path.is_file():
        raise OutputError(f"render: cannot write {path}: no file after the screenshot")
    return path


def render_png(
    u: fem.Function,
    path: str | Path,
    *,
    scalars: fem.Function | str | None = DISPLACEMENT,
    root: int = 0,
    **options: Any,
) -> Path | None:
    """Render the deformed boundary of ``u``'s mesh to a PNG (collective; rank ``root`` draws).

    Args:
        u: Displacement (vector Lagrange, any degree).
        path: The ``.png`` file (its folder is created).
        scalars: :data:`DISPLACEMENT` (:math:`|u|`, default), a scalar (or
            vector: its magnitude) function on the same mesh (e.g. the
            ``von_mises`` or ``J`` cell function of a
            :class:`~hyperfem.simulation.fields.FieldOutput`), or ``None``.
        root: The rank that draws.
        **options: Those of :func:`render_surface` (``view``, ``undeformed``, ``window_size``, ``scale``, ...).

    Returns:
        The path on ``root``, ``None`` elsewhere.

    Raises:
        OutputError: pyvista is missing, or the file cannot be written (on every rank).
        ParameterError: Invalid options (on every rank).
    """
    comm = u.function_space.mesh.comm
    path = Path(path)
    extra = {scalars.name: scalars} if isinstance(scalars, fem.Function) else None
    name = scalars.name if isinstance(scalars, fem.Function) else scalars
    surface = boundary_surface(u, extra, root=root)
    error: tuple[str, str] | None = None
    result = None
    if comm.rank == root:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            assert surface is not None  # gathered on root
            result = render_surface(surface, path, scalars=name, **options)
        except HyperfemError as exc:
            error = (type(exc).__name__, str(exc))
        except OSError as exc:
            error = ("OutputError", f"render: cannot write {path}: {exc.strerror or exc}")
        except TypeError as exc:  # an unknown option
            error = ("ParameterError", f"render: {exc}")
        except Exception as exc:  # noqa: BLE001 - whatever VTK raises: the same error on every rank, never a hang
            error = ("OutputError", f"render: cannot draw {path}: {type(exc).__name__}: {exc}")
    error = comm.bcast(error, root=root)
    if error is not None:
        kind, message = error
        raise (ParameterError if kind == "ParameterError" else OutputError)(message)
    return result


# -- the output ------------------------------------------------------------------------------------
def numbered_path(path: str | Path, step: int) -> Path:
    """Where :class:`Render` puts the picture of step ``step``: ``bend.png`` → ``bend-000010.png``."""
    path = Path(path)
    return path.with_name(f"{path.stem}-{int(step):06d}{path.suffix}")


class Render(Output):
    r"""A PNG of the deformed body at the end of the run and, optionally, every ``every`` steps.

    Rank 0 draws (pyvista, offscreen); the others wait. pyvista is checked
    when the run starts, before any solve (:func:`require_pyvista`).

    Args:
        path: The ``.png`` of the final state; every ``every`` steps also
            :func:`numbered_path` (``bend-000010.png``).
        scalars: What colours the surface (:data:`RENDER_SCALARS`): the
            displacement magnitude, or a cell field of
            :mod:`hyperfem.simulation.fields`, in discontinuous Lagrange of
            degree k − 1 for a P\ :sub:`k` displacement (P1: one colour per
            boundary triangle; P2: the mean at each vertex, drawn smooth).
        materials: The energies, for ``von_mises`` (as for
            :class:`~hyperfem.simulation.fields.FieldOutput`).
        fibres: Unit fibre field, for ``fibre_stretch``.
        activation: Activation(s), for ``activation``.
        every: Also draw after every ``every``-th step (``None``: only at the end).
        final: Draw the final state (after a failed step: the last converged one).
        scale: Displacement magnification.
        view: Direction from the body towards the camera (default :data:`DEFAULT_VIEW`).
        up: Up in the picture.
        undeformed: How to draw the reference body (:data:`UNDEFORMED`), or ``None``.
        window_size: Picture size in pixels (width, height).
        title: ``True``: ``"<run name>, t = <time>"``; a string: that; ``False``/``None``: none.
        cmap: Matplotlib colour map name.
        clim: Fixed colour range (e.g. for a series of pictures); default the range of each picture.
        zoom: Camera zoom after fitting the body into the picture.
        parallel: Parallel projection (``False``: perspective).
        scalar_bar_title: Title of the scalar bar (default: the field's name; give units here).

    Raises:
        ParameterError: Unknown scalars, invalid options, or a field without what it needs (at :meth:`start`).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        scalars: str = DISPLACEMENT,
        materials: Materials | None = None,
        fibres: fem.Function | None = None,
        activation: ActivationSpec | None = None,
        every: int | None = None,
        final: bool = True,
        scale: float = 1.0,
        view: Sequence[float] = DEFAULT_VIEW,
        up: Sequence[float] = (0.0, 1.0, 0.0),
        undeformed: str | None = "outline",
        window_size: Sequence[int] = (800, 500),
        title: bool | str | None = True,
        cmap: str = "viridis",
        clim: Sequence[float] | None = None,
        zoom: float = 1.0,
        parallel: bool = True,
        scalar_bar_title: str | None = None,
    ):
        if scalars not in RENDER_SCALARS:
            raise ParameterError(f"Render: unknown scalars {scalars!r}; known: {', '.join(RENDER_SCALARS)}")
        if every is not None and not (isinstance(every, int) and not isinstance(every, bool) and every >= 1):
            raise ParameterError(f"Render: every must be an integer >= 1 or None, got {every!r}")
        if clim is not None and (len(clim) != 2 or not float(clim[0]) < float(clim[1])):
            raise ParameterError(f"Render: clim must be (low, high) with low < high, got {clim!r}")
        size, _, _ = check_render_options(window_size, undeformed, view, up, float(scale))
        self.path = Path(path)
        self.scalars = scalars
        self.materials = materials
        self.fibres = fibres
        self.activation = activation
        self.every = every
        self.final = final
        self.title = title
        self.options: dict[str, Any] = {  # keyword arguments of render_surface
            "scale": float(scale),
            "view": tuple(float(v) for v in view),
            "up": tuple(float(v) for v in up),
            "undeformed": undeformed,
            "window_size": size,
            "cmap": cmap,
            "clim": None if clim is None else (float(clim[0]), float(clim[1])),
            "zoom": float(zoom),
            "parallel": bool(parallel),
            "scalar_bar_title": scalar_bar_title,
        }
        self.files: list[str] = []
        self._cells: CellFunctions | None = None

    def start(self, sim: Simulation) -> None:
        """Check pyvista and the folder (on every rank) and compile the cell field, before any solve."""
        require_pyvista(sim.comm, self.options["cmap"])
        ensure_output_dir(self.path.parent, sim.comm)
        if self.scalars != DISPLACEMENT:
            from hyperfem.simulation.fields import cell_field_expressions
            from hyperfem.simulation.measures import CellFunctions

            base = sim.fields.base
            expressions = cell_field_expressions(
                base, [self.scalars], self.materials, fibres=self.fibres, activation=self.activation
            )
            import ufl

            from hyperfem.simulation.measures import quadrature_degree

            # the degree of the stress of a P_k displacement (k - 1); drawn per vertex from degree 1 on. Values
            # kept at quadrature points (a material's rotation field) have cell values only (degree 0).
            parts = [e for spec in expressions.values() for e in (spec.values() if isinstance(spec, dict) else [spec])]
            on_points = any(quadrature_degree(e) is not None for e in parts if isinstance(e, ufl.core.expr.Expr))
            self._cells = CellFunctions(base.domain, expressions, 0 if on_points else max(0, base.degree - 1))
        if self.final:
            sim.files["render"] = str(self.path)

    def draw(self, sim: Simulation, path: str | Path) -> Path | None:
        """Draw the current state into ``path`` (collective; the path on rank 0)."""
        scalars: str | fem.Function = DISPLACEMENT
        if self._cells is not None:
            self._cells.refresh()
            scalars = self._cells.functions[0]
        title = self.title
        if title is True:
            title = f"{sim.name}, t = {sim.time:g}"
        return render_png(sim.fields.displacement, path, scalars=scalars, title=title or None, **self.options)

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Draw after every ``every``-th step."""
        if self.every is not None and step is not None and step.step % self.every == 0:
            path = numbered_path(self.path, step.step)
            self.draw(sim, path)
            self.files.append(str(path))

    def close(self, sim: Simulation) -> None:
        """Draw the final state (after a failure, the last converged one, and a drawing error is only a warning)."""
        if not self.final or not sim.rows or not (sim.completed or sim.state_converged):
            return
        if sim.completed:
            self.draw(sim, self.path)
            return
        try:
            self.draw(sim, self.path)
        except HyperfemError as exc:  # do not hide why the run stopped
            if sim.comm.rank == 0:
                import warnings

                warnings.warn(f"{sim.name}: no final picture: {exc}", RuntimeWarning, stacklevel=2)

    def summary(self, sim: Simulation, summary: dict) -> dict:
        """The numbered pictures drawn so far (``renders``), when drawing every k steps."""
        return {"renders": list(self.files)} if self.every is not None else {}

    def state(self, sim: Simulation) -> dict:
        """The numbered pictures drawn so far."""
        return {"files": list(self.files)}

    def restart(self, sim: Simulation, state: dict | None) -> None:
        """Keep the list of pictures of the first run."""
        if state is not None:
            self.files = [str(f) for f in state.get("files", [])]
