r"""gmsh generator for a fusiform (spindle) muscle with a tendon at each end.

The muscle belly is a body of revolution about the :math:`z` axis,
:math:`z \in [-L/2, L/2]`, with radius

.. math::
    r(z) = r_t + (R - r_t)\cos^2\!\left(\frac{\pi z}{L}\right),

lofted through circles; each end carries a cylindrical tendon of radius
:math:`r_t` and length :math:`L_t`. Physical groups:

* volumes ``muscle``, ``tendon_proximal`` (:math:`z < 0`), ``tendon_distal``;
* surfaces ``origin`` (:math:`z = -L/2 - L_t`), ``insertion``
  (:math:`z = L/2 + L_t`) and ``lateral`` (all other outer faces).

gmsh runs on rank 0 only; the mesh is distributed by DOLFINx.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from mpi4py import MPI

from hyperfem.errors import MeshError, ParameterError
from hyperfem.io.results import ensure_output_dir
from hyperfem.mesh.budget import check_mesh_size
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.gmsh_session import distribute_model, gmsh_session
from hyperfem.mesh.io import domain_from_meshdata
from hyperfem.validation import is_finite_number

__all__ = ["FUSIFORM_GROUPS", "FusiformGeometry", "fusiform_mesh", "write_fusiform_mesh"]

FUSIFORM_GROUPS = {
    "muscle": 1,
    "tendon_proximal": 2,
    "tendon_distal": 3,
    "origin": 1,
    "insertion": 2,
    "lateral": 3,
}


@dataclass(frozen=True)
class FusiformGeometry:
    """Dimensions of the spindle (metres).

    Attributes:
        belly_length: Length :math:`L` of the muscle belly.
        belly_radius: Largest radius :math:`R` (at :math:`z = 0`).
        tendon_radius: Tendon radius :math:`r_t < R`.
        tendon_length: Length :math:`L_t` of each tendon.
        sections: Number of lofted cross-sections of the belly.
    """

    belly_length: float = 0.06
    belly_radius: float = 0.012
    tendon_radius: float = 0.004
    tendon_length: float = 0.015
    sections: int = 9

    def __post_init__(self) -> None:
        for name in ("belly_length", "belly_radius", "tendon_radius", "tendon_length"):
            value = getattr(self, name)
            if not (is_finite_number(value) and value > 0):
                raise ParameterError(f"FusiformGeometry: {name} must be > 0, got {value!r}")
        if self.tendon_radius >= self.belly_radius:
            raise ParameterError(
                f"FusiformGeometry: tendon_radius {self.tendon_radius} must be below belly_radius {self.belly_radius}"
            )
        sections = self.sections
        if not isinstance(sections, int) or isinstance(sections, bool) or sections < 3 or sections % 2 == 0:
            raise ParameterError(f"FusiformGeometry: sections must be odd and >= 3, got {self.sections}")

    def radius(self, z: float) -> float:
        """Belly radius :math:`r(z)`."""
        return (
            self.tendon_radius
            + (self.belly_radius - self.tendon_radius) * math.cos(math.pi * z / self.belly_length) ** 2
        )

    @property
    def volume(self) -> float:
        r"""Volume of belly and tendons, :math:`\pi L (r_t^2 + r_t b + \tfrac38 b^2) + 2\pi r_t^2 L_t`.

        Here :math:`b = R - r_t`: the mean of :math:`\cos^2` over the belly is :math:`\tfrac12`, of
        :math:`\cos^4` :math:`\tfrac38`.
        """
        rt, b = self.tendon_radius, self.belly_radius - self.tendon_radius
        belly = math.pi * self.belly_length * (rt**2 + rt * b + 0.375 * b**2)
        return belly + 2 * math.pi * rt**2 * self.tendon_length

    @property
    def total_length(self) -> float:
        """Origin-to-insertion length :math:`L + 2L_t`."""
        return self.belly_length + 2 * self.tendon_length


def _build(gmsh: ModuleType, geo: FusiformGeometry, h: float, order: int) -> None:
    occ = gmsh.model.occ
    gmsh.model.add("fusiform")
    half = geo.belly_length / 2
    wires = []
    for k in range(geo.sections):
        z = -half + k * geo.belly_length / (geo.sections - 1)
        c = occ.addCircle(0, 0, z, geo.radius(z))
        wires.append(occ.addCurveLoop([c]))
    belly = occ.addThruSections(wires, makeSolid=True, makeRuled=False)
    prox = occ.addCylinder(0, 0, -half - geo.tendon_length, 0, 0, geo.tendon_length, geo.tendon_radius)
    dist = occ.addCylinder(0, 0, half, 0, 0, geo.tendon_length, geo.tendon_radius)
    occ.fragment([(3, belly[0][1])], [(3, prox), (3, dist)])
    occ.synchronize()

    vols: dict[str, list[int]] = {"muscle": [], "tendon_proximal": [], "tendon_distal": []}
    for _, tag in gmsh.model.getEntities(3):
        z = occ.getCenterOfMass(3, tag)[2]
        key = "muscle" if abs(z) < half else ("tendon_proximal" if z < 0 else "tendon_distal")
        vols[key].append(tag)
    if any(len(v) != 1 for v in vols.values()):
        raise MeshError(f"fusiform mesh: unexpected volumes {vols}")
    z0, z1 = -half - geo.tendon_length, half + geo.tendon_length
    surfs: dict[str, list[int]] = {"origin": [], "insertion": [], "lateral": []}
    boundary = gmsh.model.getBoundary([(3, v[0]) for v in vols.values()], combined=True, oriented=False)
    for _, tag in boundary:
        z = occ.getCenterOfMass(2, abs(tag))[2]
        xmin, ymin, zmin, xmax, ymax, zmax = occ.getBoundingBox(2, abs(tag))
        if abs(zmax - zmin) < 1e-4 * geo.total_length and abs(z - z0) < 1e-6 * geo.total_length:
            surfs["origin"].append(abs(tag))
        elif abs(zmax - zmin) < 1e-4 * geo.total_length and abs(z - z1) < 1e-6 * geo.total_length:
            surfs["insertion"].append(abs(tag))
        else:
            surfs["lateral"].append(abs(tag))
    for name, tags in vols.items():
        gmsh.model.addPhysicalGroup(3, tags, FUSIFORM_GROUPS[name], name=name)
    for name, tags in surfs.items():
        if not tags:
            raise MeshError(f"fusiform mesh: no surface found for {name!r}")
        gmsh.model.addPhysicalGroup(2, tags, FUSIFORM_GROUPS[name], name=name)
    gmsh.option.setNumber("Mesh.MeshSizeMin", h)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay: deterministic
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.setOrder(order)


def _check(h: float, order: int) -> None:
    if not (is_finite_number(h) and h > 0):
        raise ParameterError(f"fusiform mesh: element size h must be > 0, got {h!r}")
    if order not in (1, 2):
        raise ParameterError(f"fusiform mesh: order must be 1 or 2, got {order!r}")


def fusiform_mesh(
    h: float = 0.004,
    geometry: FusiformGeometry | None = None,
    order: int = 1,
    comm: MPI.Comm = MPI.COMM_WORLD,
    *,
    allow_large: bool | None = None,
) -> Domain:
    """Generate the fusiform muscle in memory (gmsh on rank 0) and distribute it.

    Args:
        h: Target element size (metres).
        geometry: Dimensions (default :class:`FusiformGeometry()`).
        order: Geometric order of the tetrahedra (1 or 2).
        comm: Communicator.
        allow_large: Mesh even if the estimate exceeds the available memory
            (:mod:`hyperfem.mesh.budget`); ``None``: the ``HYPERFEM_ALLOW_LARGE`` environment variable.

    Returns:
        The distributed :class:`~hyperfem.mesh.Domain`.

    Raises:
        ProblemSizeError: Meshing at ``h`` would not fit in memory (on every rank).
    """
    _check(h, order)
    geometry = geometry or FusiformGeometry()
    check_mesh_size("fusiform mesh", geometry.volume, h, comm, allow_large)
    data = distribute_model(comm, lambda gmsh: _build(gmsh, geometry, h, order), 3, "fusiform mesh")
    return domain_from_meshdata(data, f"fusiform_mesh(h={h}, order={order})")


def write_fusiform_mesh(
    path: str | Path,
    h: float = 0.004,
    geometry: FusiformGeometry | None = None,
    order: int = 1,
    *,
    allow_large: bool | None = None,
) -> Path:
    """Write the fusiform mesh to a gmsh ``.msh`` (4.1, ASCII) file. Serial; call on one rank.

    Raises:
        ProblemSizeError: Meshing at ``h`` would not fit in memory (``allow_large`` as for :func:`fusiform_mesh`).
    """
    path = Path(path)
    _check(h, order)
    geometry = geometry or FusiformGeometry()
    check_mesh_size("fusiform mesh", geometry.volume, h, MPI.COMM_SELF, allow_large)
    ensure_output_dir(path.parent, MPI.COMM_SELF)  # OutputError if the folder cannot be written

    with gmsh_session() as gmsh:
        _build(gmsh, geometry, h, order)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    return path
