r"""The size guard: cells, unknowns and memory estimated before meshing or building spaces.

A mesh size or a degree that cannot fit would otherwise run until the machine
is out of memory (gmsh grows for minutes and prints nothing; a degree-40 space
ends in ``std::bad_alloc``). The estimates here are cheap, deterministic
functions of their arguments, so every rank computes the same number; the
limit (the memory available on the nodes) is agreed collectively.

Cells of a gmsh mesh of size :math:`h` filling a volume :math:`V`:

.. math::
    N_c \approx \frac{V}{c\,h^3}, \qquad c = 0.2

(calibrated on the beam: :math:`c = 0.122, 0.174, 0.203, 0.198, 0.214` at
:math:`h = 2, 1, 0.5, 0.35, 0.25`, i.e. 164, 921, 6308, 18806, 47958
tetrahedra; the fusiform muscle gives 0.195 and 0.209 at :math:`h = 2, 1.5`
mm; coarse meshes have fewer cells than the estimate). Meshing takes
:data:`MESH_BYTES_PER_CELL` (gmsh's model plus the distributed DOLFINx mesh:
0.72–0.81 kB per tetrahedron measured at 0.2–0.7 million cells).

Unknowns of a Lagrange space of degree :math:`k` from the entity counts
(Euler's relation on a tetrahedral mesh: :math:`N_e \approx N_v + N_c`,
:math:`N_f \approx 2 N_c`), per component

.. math::
    N = N_v + (k-1) N_e + \tfrac{(k-1)(k-2)}{2} N_f + \tfrac{(k-1)(k-2)(k-3)}{6} N_c,

and the tangent has :math:`n_k + 11 k` couplings per row and component
(:math:`n_k` the dofs of one cell; measured 41, 81, 124, 187 nonzeros per row
of the vector P1–P4 tangent against 45, 96, 159, 237 estimated). Solving
takes :data:`BYTES_PER_NONZERO` per nonzero plus :data:`BYTES_PER_UNKNOWN`
(process RSS of a Newton solve of the bend with CG + GAMG: 24–26 B per
nonzero at P2/P3, 48 at P1, where the per-unknown part is larger), plus what
one cell needs at once (its dense element tensor, the basis tabulated at the
quadrature points, the element's own matrices) — which is what a degree-40
space exhausts on any mesh.

Where the guard refuses, :class:`~hyperfem.errors.ProblemSizeError` says the
estimate and the limit in one line; ``allow_large=True`` (``--allow-large``
on the command line, or ``HYPERFEM_ALLOW_LARGE=1`` in the environment) tries
anyway.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mpi4py import MPI

from hyperfem.errors import ParameterError, ProblemSizeError

if TYPE_CHECKING:
    from hyperfem.mesh.domain import Domain

__all__ = [
    "ALLOW_LARGE_ENV",
    "BYTES_PER_NONZERO",
    "BYTES_PER_UNKNOWN",
    "CELL_VOLUME_FACTOR",
    "MESH_BYTES_PER_CELL",
    "SizeEstimate",
    "allow_large_problems",
    "available_memory",
    "check_mesh_size",
    "check_problem_size",
    "estimate_cells",
    "estimate_mesh",
    "estimate_space",
    "large_allowed",
]

CELL_VOLUME_FACTOR = 0.2
r"""Average tetrahedron volume of a gmsh mesh of size :math:`h`, in units of :math:`h^3`."""

MESH_BYTES_PER_CELL = 1024
"""Peak memory of meshing one tetrahedron with gmsh and distributing it with DOLFINx."""

BYTES_PER_NONZERO = 26
"""Memory of one nonzero of the tangent during a solve (matrix, preconditioner, work)."""

BYTES_PER_UNKNOWN = 800
"""Memory of one unknown during a solve (dofmaps, vectors, solver work)."""

ALLOW_LARGE_ENV = "HYPERFEM_ALLOW_LARGE"
"""Environment variable: ``1`` lets the guard pass estimates beyond the available memory."""

MESH_HINT = f"pass --allow-large (API: allow_large=True) or set {ALLOW_LARGE_ENV}=1 to try anyway"
PROBLEM_HINT = f"set {ALLOW_LARGE_ENV}=1 (or build it in hyperfem.mesh.budget.allow_large_problems()) to try anyway"
GIB = 2.0**30

# Topological dimension of the simplex and of the tensor-product cells.
_SIMPLEX = {"interval": 1, "triangle": 2, "tetrahedron": 3}
_TENSOR = {"quadrilateral": 2, "hexahedron": 3}


@dataclass(frozen=True)
class SizeEstimate:
    """What a mesh or a space is estimated to need.

    Attributes:
        cells: Cells.
        unknowns: Unknowns of the space (0 for a mesh alone).
        bytes: Peak memory in bytes of the step it guards (meshing, or building and solving).
    """

    cells: float
    unknowns: float
    bytes: float


def _num(value: float) -> str:
    """``6.2e11`` for large numbers, ``23`` or ``0.52`` for small ones."""
    if value >= 1e4:
        mantissa, exponent = f"{value:.1e}".split("e")
        return f"{mantissa}e{int(exponent)}"
    return f"{value:.2g}" if value < 10 else f"{value:.0f}"


def estimate_cells(volume: float, h: float) -> float:
    r"""Tetrahedra of a gmsh mesh of size ``h`` filling ``volume``: :math:`V / (c h^3)`."""
    return volume / (CELL_VOLUME_FACTOR * h**3)


def _dofs_per_cell(cell: str, degree: int) -> int:
    r"""Dofs of one cell of a scalar Lagrange element: :math:`\binom{k+d}{d}` or :math:`(k+1)^d`."""
    if cell in _TENSOR:
        return (degree + 1) ** _TENSOR[cell]
    return math.comb(degree + _SIMPLEX.get(cell, 3), _SIMPLEX.get(cell, 3))


def _scalar_dofs(cell: str, vertices: float, cells: float, degree: int) -> float:
    """Global dofs of a scalar Lagrange space of ``degree`` from the vertex and cell counts (see module)."""
    k = degree
    if cell in _TENSOR:
        d = _TENSOR[cell]
        edges, faces = (2 * cells, 0.0) if d == 2 else (3 * cells, 3 * cells)
        interior = (k - 1) ** d
        return vertices + (k - 1) * edges + (k - 1) ** 2 * faces * (d == 3) + interior * cells
    d = _SIMPLEX.get(cell, 3)
    if d == 1:
        return vertices + (k - 1) * cells
    edges = vertices + cells
    if d == 2:
        return vertices + (k - 1) * edges + (k - 1) * (k - 2) / 2 * cells
    faces = 2 * cells
    return vertices + (k - 1) * edges + (k - 1) * (k - 2) / 2 * faces + (k - 1) * (k - 2) * (k - 3) / 6 * cells


def _quadrature_points(cell: str, quadrature_degree: int) -> int:
    """Points of the collapsed Gauss–Jacobi rule of degree :math:`q`: :math:`(\\lfloor q/2 \\rfloor + 1)^d`."""
    d = _TENSOR.get(cell, _SIMPLEX.get(cell, 3))
    return (quadrature_degree // 2 + 1) ** d


def estimate_space(
    cell: str, vertices: float, cells: float, fields: Sequence[tuple[int, int]], quadrature_degree: int
) -> SizeEstimate:
    """Unknowns and peak memory of building and solving on a (mixed) Lagrange space.

    Args:
        cell: Cell type name (``"tetrahedron"``, ``"hexahedron"``, ...).
        vertices: Global number of mesh vertices.
        cells: Global number of cells.
        fields: ``(components, degree)`` of each field (``[(3, 2)]``: vector P2).
        quadrature_degree: Degree of the volume rule.

    Returns:
        The estimate; ``bytes`` = tangent and unknowns (global) + what one cell needs (every rank).
    """
    unknowns = sum(c * _scalar_dofs(cell, vertices, cells, k) for c, k in fields)
    couplings = sum(c * (_dofs_per_cell(cell, k) + 11 * k) for c, k in fields)
    cell_dofs = sum(c * _dofs_per_cell(cell, k) for c, k in fields)
    basis = sum(_dofs_per_cell(cell, k) for _, k in fields)
    points = _quadrature_points(cell, quadrature_degree)
    per_cell = 8.0 * (2 * cell_dofs**2 + 4 * points * basis + 3 * basis**2)  # element tensor, tables, element
    total = BYTES_PER_NONZERO * unknowns * couplings + BYTES_PER_UNKNOWN * unknowns + per_cell
    return SizeEstimate(cells, unknowns, total)


def estimate_mesh(volume: float, h: float) -> tuple[SizeEstimate, SizeEstimate]:
    """Meshing ``volume`` at size ``h`` with tetrahedra, and solving on it with vector P1.

    Returns:
        ``(meshing, solving)``.
    """
    cells = estimate_cells(volume, h)
    mesh = SizeEstimate(cells, 0.0, MESH_BYTES_PER_CELL * cells)
    solve = estimate_space("tetrahedron", cells / 5.5, cells, [(3, 1)], 1)
    return mesh, solve


def _mem_available() -> int:
    """Bytes available on this node: ``MemAvailable`` of ``/proc/meminfo``, else the free physical pages."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (OSError, ValueError, AttributeError):  # pragma: no cover - no way to tell
        return 2**62


def available_memory(comm: MPI.Comm) -> tuple[int, int]:
    """Memory available to the ranks of ``comm``: summed over the nodes they run on (collective).

    Returns:
        ``(bytes, nodes)``, the same on every rank.
    """
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        leader = node.rank == 0
    finally:
        node.Free()
    local = _mem_available() if leader else 0
    return int(comm.allreduce(local, op=MPI.SUM)), int(comm.allreduce(int(leader), op=MPI.SUM))


_OVERRIDE: list[bool] = []  # the innermost allow_large_problems() block, if any


@contextmanager
def allow_large_problems(allowed: bool = True) -> Iterator[None]:
    """Within the block, the guard lets (``allowed``) or does not let estimates beyond the memory pass.

    For constructors without an ``allow_large`` argument
    (:class:`~hyperfem.HyperelasticProblem`, the mixed problem)::

        with allow_large_problems():
            problem = hf.HyperelasticProblem(domain, psi, degree=6)

    Call it on every rank (rank 0's setting decides).
    """
    _OVERRIDE.append(bool(allowed))
    try:
        yield
    finally:
        _OVERRIDE.pop()


def large_allowed(allow_large: bool | None = None) -> bool:
    """Whether the guard lets large estimates pass.

    ``allow_large`` if given, else the innermost :func:`allow_large_problems`,
    else the environment variable ``HYPERFEM_ALLOW_LARGE``.

    Raises:
        ParameterError: ``allow_large`` is not a bool or None, or ``HYPERFEM_ALLOW_LARGE`` is not 0/1.
    """
    if allow_large is not None:
        if not isinstance(allow_large, bool):
            raise ParameterError(f"allow_large must be True, False or None, got {allow_large!r}")
        return allow_large
    if _OVERRIDE:
        return _OVERRIDE[-1]
    value = os.environ.get(ALLOW_LARGE_ENV, "").strip().lower()
    if value in ("", "0", "false", "no", "off"):
        return False
    if value in ("1", "true", "yes", "on"):
        return True
    raise ParameterError(f"{ALLOW_LARGE_ENV} must be 1 or 0, got {os.environ[ALLOW_LARGE_ENV]!r}")


def _refuse_if_too_large(
    need: float, what: str, comm: MPI.Comm, allow_large: bool | None, hint: str, on_rank0: bool = False
) -> None:
    """Raise on every rank if ``need`` bytes exceed the available memory and the user has not allowed it.

    ``on_rank0``: the work runs on rank 0 alone (gmsh), so the limit is the memory of rank 0's node.
    """
    error = ""
    if comm.rank == 0:  # one rank reads the environment and decides; the others follow
        try:
            allowed = large_allowed(allow_large)
        except ParameterError as exc:
            error, allowed = str(exc), True
    else:
        allowed = False
    error, allowed = comm.bcast((error, allowed) if comm.rank == 0 else None, root=0)
    if error:
        raise ParameterError(error)
    if on_rank0:
        limit, nodes = int(comm.bcast(_mem_available() if comm.rank == 0 else None, root=0)), 1
    else:
        limit, nodes = available_memory(comm)
    if need <= limit or allowed:
        return
    where = "this machine has" if nodes == 1 else f"the {nodes} nodes have"
    raise ProblemSizeError(f"{what}; {where} {_num(limit / GIB)} GiB available; {hint}")


def check_mesh_size(
    what: str, volume: float, h: float, comm: MPI.Comm = MPI.COMM_SELF, allow_large: bool | None = None
) -> SizeEstimate:
    """Refuse to mesh ``volume`` at size ``h`` when meshing would not fit in memory (collective over ``comm``).

    Args:
        what: The generator, for the message (``"beam mesh"``).
        volume: Volume of the domain.
        h: Element size.
        comm: Ranks that take part (the memory of their nodes is the limit).
        allow_large: Pass anyway; ``None``: ``HYPERFEM_ALLOW_LARGE``.

    Returns:
        The estimate of meshing.

    Raises:
        ProblemSizeError: ``beam mesh: h = 0.001 gives ~8.0e11 tetrahedra (~7.5e5 GiB to mesh, ~1.3e6 GiB
            to solve at P1); this machine has 23 GiB available; pass allow_large=True ...``.
    """
    mesh, solve = estimate_mesh(volume, h)
    summary = (
        f"{what}: h = {h:g} gives ~{_num(mesh.cells)} tetrahedra (~{_num(mesh.bytes / GIB)} GiB to mesh, "
        f"~{_num(solve.bytes / GIB)} GiB to solve at P1)"
    )
    _refuse_if_too_large(mesh.bytes, summary, comm, allow_large, MESH_HINT, on_rank0=True)  # gmsh: rank 0
    return mesh


def check_problem_size(
    domain: Domain,
    fields: Sequence[tuple[int, int]],
    quadrature_degree: int,
    where: str,
    allow_large: bool | None = None,
) -> SizeEstimate:
    """Refuse to build a space of ``fields`` on ``domain`` that would not fit in memory (collective).

    Args:
        domain: The :class:`~hyperfem.mesh.Domain`.
        fields: ``(components, degree)`` of each field (``[(3, 2), (1, 1), (1, 1)]``: P2/P1/P1).
        quadrature_degree: Degree of the volume rule.
        where: The problem, for the message.
        allow_large: Pass anyway; ``None``: ``HYPERFEM_ALLOW_LARGE``.

    Returns:
        The estimate.

    Raises:
        ProblemSizeError: ``HyperelasticProblem: P40 on 921 cells gives ~2.9e7 unknowns (~2.7e4 GiB to build
            and solve); this machine has 23 GiB available; set HYPERFEM_ALLOW_LARGE=1 ...``.
    """
    topology = domain.mesh.topology
    cells = topology.index_map(topology.dim).size_global
    vertices = topology.index_map(0).size_global
    estimate = estimate_space(topology.cell_type.name, vertices, cells, fields, quadrature_degree)
    family = "Q" if topology.cell_type.name in _TENSOR else "P"
    space = "/".join(f"{family}{k}" for _, k in fields)
    summary = (
        f"{where}: {space} on {cells} cells gives ~{_num(estimate.unknowns)} unknowns "
        f"(~{_num(estimate.bytes / GIB)} GiB to build and solve)"
    )
    _refuse_if_too_large(estimate.bytes, summary, domain.comm, allow_large, PROBLEM_HINT)
    return estimate
