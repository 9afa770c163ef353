r"""A slender column, clamped at the bottom and free at the top: Euler buckling (issue 22).

The column :math:`[0, b] \times [0, h] \times [0, L]` (:math:`b \le h`) is
clamped on ``bottom`` (:math:`z = 0`) and carries a dead compressive traction
:math:`-\sigma\,e_z` per unit reference area on ``top`` (:math:`z = L`),
linear in the load factor. For a compressible Neo-Hookean solid with the
small-strain Young's modulus :math:`E`, Euler's clamped–free load about the
weak axis, :math:`P_\text{cr} = \pi^2 E I / (4L^2)` with :math:`I = h b^3/12`,
is the traction

.. math::
    \sigma_E = \frac{P_\text{cr}}{bh} = \frac{\pi^2 E\,b^2}{48\,L^2},

so a problem loaded with :meth:`ColumnSpec.euler_traction` at :math:`t = 1`
buckles at :math:`t_\text{cr} \approx 1`; the next mode bends about the
strong axis at :math:`(h/b)^2`. The continuum column departs from the beam
formula by shear (:math:`-P_E/(\kappa G A)`, 0.15 % at :math:`L/b = 20`) and,
for :math:`\nu > 0`, by the clamp that stops the Poisson contraction at the
base: measured with P3 hexahedra and fine P2 tetrahedra (:math:`b = 1,\ h =
1.5,\ L = 20`), :math:`t_\text{cr} = 1.0034` at :math:`\nu = 0.3` and
0.99953 at :math:`\nu = 0` (``tests/test_stability.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI
from dolfinx import mesh as dmesh

from hyperfem.errors import ParameterError
from hyperfem.io.results import ensure_output_dir
from hyperfem.materials.parameters import LameParameters
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.gmsh_session import gmsh_session
from hyperfem.validation import check_count, check_positive

__all__ = ["COLUMN_GROUPS", "ColumnSpec", "column_domain", "write_column_mesh"]

COLUMN_GROUPS = ("bottom", "top")
"""The named boundaries of :func:`column_domain`."""


@dataclass(frozen=True)
class ColumnSpec:
    """Geometry and material of the column.

    Attributes:
        width: :math:`b`, the side along :math:`x` (the weak bending axis).
        depth: :math:`h \\ge b`, the side along :math:`y`.
        length: :math:`L`, along :math:`z`.
        E: Small-strain Young's modulus.
        nu: Poisson's ratio.
    """

    width: float = 1.0
    depth: float = 1.5
    length: float = 20.0
    E: float = 1.0
    nu: float = 0.3

    def __post_init__(self) -> None:
        for name in ("width", "depth", "length", "E"):
            check_positive(name, getattr(self, name), "ColumnSpec")
        if self.depth < self.width:
            raise ParameterError(f"ColumnSpec: depth must be >= width (x is the weak axis), got {self.depth!r}")
        LameParameters.from_youngs(self.E, self.nu)  # validates nu

    @property
    def lame(self) -> LameParameters:
        """Lamé parameters from (E, ν)."""
        return LameParameters.from_youngs(self.E, self.nu)

    @property
    def euler_traction(self) -> float:
        r""":math:`\sigma_E = \pi^2 E b^2 / (48 L^2)`, Euler's clamped–free load per unit area (weak axis)."""
        return math.pi**2 * self.E * self.width**2 / (48.0 * self.length**2)

    @property
    def mode_ratio(self) -> float:
        """Critical load of the first strong-axis mode over the first (weak-axis) one, :math:`(h/b)^2`."""
        return (self.depth / self.width) ** 2


def column_domain(
    spec: ColumnSpec, divisions: tuple[int, int, int], comm: MPI.Comm = MPI.COMM_WORLD, cell: str = "tetrahedron"
) -> Domain:
    """The column as a box mesh with boundaries ``bottom`` (z = 0) and ``top`` (z = L).

    Args:
        spec: The column.
        divisions: Boxes along x, y, z (6 tetrahedra or one hexahedron each).
        comm: Communicator.
        cell: ``"tetrahedron"`` or ``"hexahedron"``.

    Raises:
        ParameterError: A division below 1 or an unknown cell.
    """
    if len(divisions) != 3:
        raise ParameterError(f"column_domain: divisions must be three integers, got {divisions!r}")
    for k in divisions:
        check_count("divisions", k, "column_domain")
    cells = {"tetrahedron": dmesh.CellType.tetrahedron, "hexahedron": dmesh.CellType.hexahedron}
    if cell not in cells:
        raise ParameterError(f"column_domain: cell must be 'tetrahedron' or 'hexahedron', got {cell!r}")
    L = spec.length
    mesh = dmesh.create_box(comm, [[0.0, 0.0, 0.0], [spec.width, spec.depth, L]], list(divisions), cells[cell])
    return Domain.from_locators(
        mesh,
        {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], L)},
        source=f"column{tuple(divisions)}",
    )


def write_column_mesh(path: str | Path, spec: ColumnSpec | None = None, h: float = 1.0) -> Path:
    """Write the column as a gmsh ``.msh`` file (tetrahedra of size ``h``) for case files. Serial; call on one rank.

    Physical groups: volume ``column``; faces ``bottom`` (z = 0), ``top`` (z = L), ``sides``.

    Raises:
        ParameterError: ``h`` not a number > 0.
    """
    check_positive("h", h, "write_column_mesh")
    spec = ColumnSpec() if spec is None else spec
    path = Path(path)
    ensure_output_dir(path.parent, MPI.COMM_SELF)
    with gmsh_session() as gmsh:
        gmsh.model.add("column")
        box = gmsh.model.occ.addBox(0.0, 0.0, 0.0, spec.width, spec.depth, spec.length)
        gmsh.model.occ.synchronize()
        faces: dict[str, list[int]] = {"bottom": [], "top": [], "sides": []}
        for _, tag in gmsh.model.getBoundary([(3, box)], oriented=False):
            z = gmsh.model.occ.getCenterOfMass(2, tag)[2]
            key = "bottom" if abs(z) < 1e-9 else "top" if abs(z - spec.length) < 1e-9 else "sides"
            faces[key].append(tag)
        gmsh.model.addPhysicalGroup(3, [box], 1, name="column")
        for i, (name, tags) in enumerate(faces.items(), start=1):
            gmsh.model.addPhysicalGroup(2, tags, i, name=name)
        gmsh.model.mesh.setSize(gmsh.model.getBoundary([(3, box)], recursive=True), h)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay: deterministic
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.mesh.generate(3)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    return path
