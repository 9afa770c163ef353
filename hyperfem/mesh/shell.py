r"""gmsh generator for one eighth of a thick-walled spherical shell (the inflated balloon, the aneurysm wall).

The shell :math:`A \le |X| \le B` in the octant :math:`X, Y, Z \ge 0`,
meshed with tetrahedra of size ``h`` (curved, second-order geometry with
``order=2``). Physical groups:

* volume ``wall``;
* faces ``inner`` (:math:`|X| = A`), ``outer`` (:math:`|X| = B`) and the
  symmetry planes ``x0``, ``y0``, ``z0`` (:math:`X = 0`, :math:`Y = 0`, :math:`Z = 0`).

With rollers on the three planes and a pressure on ``inner`` it models the
whole sphere. gmsh runs on rank 0 only; the mesh is distributed by DOLFINx.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.io.results import ensure_output_dir
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.gmsh_session import distribute_model, gmsh_session
from hyperfem.mesh.io import domain_from_meshdata
from hyperfem.validation import is_finite_number

__all__ = ["SHELL_GROUPS", "spherical_shell_mesh", "write_spherical_shell_mesh"]

SHELL_GROUPS = {"wall": 1, "inner": 1, "outer": 2, "x0": 3, "y0": 4, "z0": 5}


def _check(inner: float, outer: float, h: float, order: int) -> None:
    for key, value in (("inner", inner), ("outer", outer), ("h", h)):
        if not (is_finite_number(value) and value > 0):
            raise ParameterError(f"spherical shell mesh: {key} must be a finite number > 0, got {value!r}")
    if not inner < outer:
        raise ParameterError(f"spherical shell mesh: need inner < outer radius, got {inner} and {outer}")
    if order not in (1, 2):
        raise ParameterError(f"spherical shell mesh: order must be 1 or 2, got {order!r}")


def _build(gmsh: ModuleType, inner: float, outer: float, h: float, order: int) -> None:
    gmsh.model.add("spherical_shell")
    occ = gmsh.model.occ
    ball = occ.addSphere(0.0, 0.0, 0.0, outer)
    hole = occ.addSphere(0.0, 0.0, 0.0, inner)
    box = occ.addBox(0.0, 0.0, 0.0, 2 * outer, 2 * outer, 2 * outer)
    shell, _ = occ.cut([(3, ball)], [(3, hole)])
    wall, _ = occ.intersect(shell, [(3, box)])
    occ.synchronize()
    volume = wall[0][1]
    faces: dict[str, list[int]] = {name: [] for name in ("x0", "y0", "z0")}
    curved: list[tuple[float, int]] = []
    tol = 1e-9 * outer
    for _, tag in gmsh.model.getBoundary([(3, volume)], oriented=False):
        c = occ.getCenterOfMass(2, tag)
        for axis, name in enumerate(("x0", "y0", "z0")):
            if abs(c[axis]) < tol:
                faces[name].append(tag)
                break
        else:
            curved.append((sum(v * v for v in c), tag))
    curved.sort()
    faces["inner"] = [curved[0][1]]
    faces["outer"] = [curved[-1][1]]
    gmsh.model.addPhysicalGroup(3, [volume], SHELL_GROUPS["wall"], name="wall")
    for name in ("inner", "outer", "x0", "y0", "z0"):
        gmsh.model.addPhysicalGroup(2, faces[name], SHELL_GROUPS[name], name=name)
    gmsh.model.mesh.setSize(gmsh.model.getBoundary([(3, volume)], recursive=True), h)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay: deterministic
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.setOrder(order)


def spherical_shell_mesh(
    inner: float = 1.0, outer: float = 2.0, h: float = 0.35, order: int = 2, comm: MPI.Comm = MPI.COMM_WORLD
) -> Domain:
    """Generate one eighth of the shell in memory and distribute it (module docstring).

    Args:
        inner: Inner radius :math:`A`.
        outer: Outer radius :math:`B`.
        h: Element size.
        order: Geometric order of the tetrahedra (1 or 2: curved faces).
        comm: Communicator; gmsh runs on rank 0 only.

    Raises:
        ParameterError: A radius or size that is not a number > 0, ``inner >= outer``, an order other than 1 or 2.
    """
    _check(inner, outer, h, order)
    data = distribute_model(comm, lambda gmsh: _build(gmsh, inner, outer, h, order), 3, "spherical shell mesh")
    return domain_from_meshdata(data, f"spherical_shell_mesh(inner={inner}, outer={outer}, h={h}, order={order})")


def write_spherical_shell_mesh(
    path: str | Path, inner: float = 1.0, outer: float = 2.0, h: float = 0.35, order: int = 2
) -> Path:
    """Write one eighth of the shell to a gmsh ``.msh`` (format 4.1) file. Serial; call on one rank."""
    path = Path(path)
    _check(inner, outer, h, order)
    ensure_output_dir(path.parent, MPI.COMM_SELF)
    with gmsh_session() as gmsh:
        _build(gmsh, inner, outer, h, order)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    return path
