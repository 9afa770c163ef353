r"""A rigid triangulated tool (a surgical instrument, an indenter, a jaw) read from a file, moving by a prescribed path.

:class:`ToolContact` names the boundary groups of the body that the tool may
touch and the tool's surface: triangles read from an STL, OBJ, PLY, VTK/VTU
or gmsh file (meshio; every triangle block of the file), or given as arrays
(:meth:`ToolContact.from_arrays`), translated by ``profile(t)·motion`` or along
a path ``motion(t)`` (as the plane, the sphere and the cylinder) and optionally turned by a ``rotation``
(a :class:`~hyperfem.loading.RigidRotation` about a pivot, composed with the
translation). :meth:`~ToolContact.bind` gives a
:class:`~hyperfem.contact.mesh_barrier.MeshBarrier` whose collision mesh is
the body's surface plus the tool's triangles, the tool's vertices static
within a solve (no dofs; no tool–tool pairs): point–triangle and edge–edge
pairs between tool and body, both ways, so a sharp tool edge cannot cut
through a body face between its nodes, nor a body node pass through a tool
face. The tool's output force (``<name>_force``) is the force the tool
exerts on the body.

In 2D (plane strain) the tool is a polyline: points ``(k, 2)`` and segments
``(s, 2)`` given as arrays (:meth:`ToolContact.from_arrays`; the
``triangles`` entry holds the segments) or read from a file whose cells are
line segments in the plane z = 0 and which has no triangles (gmsh, VTK/VTU,
...: :func:`read_tool_surface`); its motion and offset have 2 components, no
rotation; the pairs are edge–vertex pairs between the body's boundary
segments and the tool's. A file with triangles gives a 3D tool.

Example::

    tool = hf.contact.ToolContact(["top"], file="meshes/spatula.stl", motion=(0, 0, -0.3)).bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[tool])
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hyperfem.contact.bodies import surface_defaults
from hyperfem.contact.ccd import CCD_SAFETY
from hyperfem.contact.mesh_barrier import MeshBarrier, RigidSurface
from hyperfem.contact.obstacles import check_motion, check_rotation
from hyperfem.contact.settings import check_boundaries, check_contact_settings, check_subdivision
from hyperfem.contact.surface import contact_surface
from hyperfem.errors import MeshError, ParameterError
from hyperfem.loading.motion import RigidRotation
from hyperfem.loading.profiles import linear_profile
from hyperfem.problem.protocol import SolidProblem
from hyperfem.validation import check_finite_vector

__all__ = ["ToolContact", "read_tool_surface"]


def read_tool_surface(path: str | Path, where: str) -> tuple[np.ndarray, np.ndarray]:
    """The points and facets of a tool file: a surface, or in 2D a polyline (unused points dropped).

    A file with triangles gives a 3D tool: points ``(k, 3)`` and every triangle block's triangles ``(f, 3)``. A
    file with line segments and no triangles gives a 2D polyline: points ``(k, 2)`` (the file's z, if any, must be
    0) and every line block's segments ``(s, 2)``.

    Raises:
        MeshError: The file is missing, cannot be read, has neither triangles nor line segments, or holds a
            polyline off the plane z = 0 (one line).
    """
    import meshio

    path = Path(path)
    if not path.is_file():
        raise MeshError(f"{where}: tool surface file {str(path)!r} not found")
    try:
        mesh = meshio.read(path)
    except Exception as exc:  # meshio raises many kinds
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise MeshError(f"{where}: cannot read the tool surface {str(path)!r}: {first}") from None
    points = np.asarray(mesh.points, dtype=float)
    triangles = [np.asarray(block.data) for block in mesh.cells if block.type == "triangle"]
    lines = [np.asarray(block.data) for block in mesh.cells if block.type == "line"]
    blocks, dim = (triangles, 3) if triangles else (lines, 2)
    if not blocks:
        kinds = ", ".join(sorted({block.type for block in mesh.cells})) or "none"
        raise MeshError(
            f"{where}: the tool surface {str(path)!r} has no triangles (a 3D tool) or line segments (a 2D "
            f"polyline) (cell types: {kinds})"
        )
    facets = np.concatenate(blocks).astype(np.int64)
    used, inverse = np.unique(facets, return_inverse=True)
    points = points[used]
    if dim == 2:
        if points.shape[1] > 2 and np.abs(points[:, 2:]).max(initial=0.0) > 0.0:
            raise MeshError(f"{where}: the polyline {str(path)!r} must lie in the plane z = 0 (a 2D tool)")
        return points[:, :2], inverse.reshape(-1, 2).astype(np.int32)
    if points.shape[1] == 2:
        points = np.hstack([points, np.zeros((len(points), 1))])
    return points[:, :3], inverse.reshape(-1, 3).astype(np.int32)


@dataclass(frozen=True, eq=False)
class ToolContact:
    r"""Intersection-free contact of boundary surfaces with a rigid triangulated tool (module docstring).

    Attributes:
        boundaries: The body's boundary groups the tool may touch.
        file: The tool's surface file (``None`` with :meth:`from_arrays`).
        motion: The tool's translation, scaled by ``profile(t)`` (``None``: it stays), or a path: a callable
            giving the translation at ``t`` (indent, then drag: any piecewise path; ``profile`` is then unused).
        profile: :math:`f(t)` of the translation (default: the load factor).
        offset: A translation applied to the file's points once (placing the tool).
        scale: A factor applied to the file's points once (units: a file in mm for a mesh in m: 1e-3).
        dhat: Barrier width :math:`\hat d > 0` (``None``: 1 % of the smallest mean facet size of the groups).
        stiffness: ``ipctk``'s barrier stiffness (``None``: :func:`~hyperfem.contact.bodies.surface_defaults`).
        safety: The collision filter's :math:`s \in (0, 1)`.
        friction: Coulomb coefficient :math:`\mu \ge 0` (0: frictionless), smoothed and lagged per step
            as in IPC (``ipctk``'s tangential collisions and friction potential; :mod:`~hyperfem.contact.mesh_barrier`).
        friction_epsilon: The slip length :math:`\epsilon > 0` below which a pair sticks elastically
            (``None``: :math:`0.1\,\hat d`).
        name: Prefix of the output columns.
        points: The tool's points (instead of ``file``): ``(k, 3)``, or ``(k, 2)`` for a 2D polyline tool.
        triangles: The tool's triangles ``(f, 3)`` (instead of ``file``), or its segments ``(s, 2)`` in 2D.
        rotation: A :class:`~hyperfem.loading.RigidRotation` of the tool about a pivot of its placed points
            (after ``offset`` and ``scale``), composed with the translation: :math:`x(t) = R(\theta(t))(X - c_r)
            + c_r + s(t)` (``None``: it does not turn; :mod:`~hyperfem.contact.obstacles`).
        subdivision: The body's collision proxy (as for :class:`~hyperfem.contact.SurfaceContact`; 1: none).

    Raises:
        ParameterError: A bad entry (one line), or ``ipctk`` not installed.
        MeshError: The file is missing, unreadable or has no triangles.
    """

    boundaries: Sequence[str]
    file: str | Path | None = None
    motion: Sequence[float] | Callable[[float], Sequence[float]] | None = None
    profile: Callable[[float], float] = linear_profile
    offset: Sequence[float] | None = None
    scale: float = 1.0
    dhat: float | None = None
    stiffness: float | None = None
    safety: float = CCD_SAFETY
    name: str = "tool"
    friction: float = 0.0
    friction_epsilon: float | None = None
    points: np.ndarray | None = None
    triangles: np.ndarray | None = None
    rotation: RigidRotation | None = None
    subdivision: int | None = None

    def __post_init__(self) -> None:
        names, where = check_boundaries(self.boundaries, "ToolContact")
        object.__setattr__(self, "boundaries", tuple(names))
        check_subdivision(self.subdivision, where)
        if (self.file is None) == (self.points is None):
            raise ParameterError(f"{where}: give either file or points and triangles")
        read = None if self.file is None else read_tool_surface(self.file, where)
        given = np.asarray(self.points) if read is None else read[0]
        dim = 2 if given.ndim == 2 and given.shape[1] == 2 else 3
        check_rotation(self.rotation, dim, where)
        object.__setattr__(self, "motion", check_motion(self.motion, dim, where))
        if self.offset is not None:
            offset = check_finite_vector(self.offset, where, "offset")
            if len(offset) != dim:
                raise ParameterError(f"{where}: offset must have {dim} components, got {len(offset)}")
            object.__setattr__(self, "offset", offset)
        if not (isinstance(self.scale, (int, float)) and np.isfinite(self.scale) and self.scale > 0):
            raise ParameterError(f"{where}: scale must be a number > 0, got {self.scale!r}")
        check_contact_settings(
            where, dhat=self.dhat, stiffness=self.stiffness, safety=self.safety, friction=self.friction,
            friction_epsilon=self.friction_epsilon, profile=self.profile, name=self.name,
        )
        if read is not None:
            points, faces = read
        else:
            if self.triangles is None:
                raise ParameterError(f"{where}: points need triangles")
            points = np.asarray(self.points, dtype=float)
            faces = np.asarray(self.triangles, dtype=np.int64)
            if points.ndim != 2 or points.shape[1] != dim or not np.all(np.isfinite(points)):
                raise ParameterError(
                    f"{where}: points must be finite, shape (k, 3) (or (k, 2) in 2D), got shape {points.shape}"
                )
            if faces.ndim != 2 or faces.shape[1] != dim or faces.min() < 0 or faces.max() >= len(points):
                kind = "triangles must be (f, 3)" if dim == 3 else "the segments of a 2D tool must be (s, 2)"
                raise ParameterError(f"{where}: {kind} indices into points")
        points = points * float(self.scale) + (np.zeros(dim) if self.offset is None else np.asarray(self.offset))
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "triangles", np.asarray(faces, dtype=np.int32))

    @classmethod
    def from_arrays(
        cls, boundaries: Sequence[str], points: np.ndarray, triangles: np.ndarray, **kwargs: object
    ) -> ToolContact:
        """A tool given as ``points`` ``(k, 3)`` and ``triangles`` ``(f, 3)``, or in 2D a polyline: ``points``
        ``(k, 2)`` and segments ``(s, 2)`` (the other entries as for the class)."""
        return cls(boundaries, points=points, triangles=triangles, **kwargs)  # type: ignore[arg-type]

    @property
    def where(self) -> str:
        """The contact, for messages."""
        return f"ToolContact on {list(self.boundaries)!r}"

    @property
    def surface(self) -> RigidSurface:
        """The tool as a :class:`~hyperfem.contact.mesh_barrier.RigidSurface`."""
        assert self.points is not None and self.triangles is not None
        motion = self.motion if self.motion is None or callable(self.motion) else np.asarray(self.motion, dtype=float)
        return RigidSurface(self.points, self.triangles, motion, self.profile, self.rotation)

    def bind(self, problem: SolidProblem) -> MeshBarrier:
        """The barrier of this contact on ``problem`` (collective).

        Raises:
            UnknownGroupError: A boundary group does not exist (the message lists them).
            ParameterError: Not a degree-1/2 problem on tetrahedra or hexahedra (3D) or triangles or quadrilaterals
                (2D), a tool of another dimension than the mesh, or the tool starts touching or inside the body.
        """
        surface = contact_surface(problem, self.boundaries, self.where, self.subdivision)
        tool = self.surface
        if tool.dim != surface.dim:
            wanted = (
                "a polyline, points (k, 2) and segments (s, 2) (ToolContact.from_arrays) or a file of line segments "
                "at z = 0" if surface.dim == 2 else "triangles in 3D (ToolContact.from_arrays or a file)"
            )
            raise ParameterError(f"{self.where}: a {tool.dim}D tool on a {surface.dim}D mesh; give {wanted}")
        dhat, stiffness = surface_defaults(problem, self.boundaries, surface, self.dhat, self.stiffness)
        return MeshBarrier(
            self, problem, surface, where=self.where, dhat=dhat, stiffness=stiffness, safety=self.safety,
            friction=self.friction, friction_epsilon=self.friction_epsilon,
            tool=tool,
        )
