r"""Shape-quality measures of simplex meshes (seed 003, §5.6).

Every measure is 1 for the equilateral simplex and tends to 0 as a cell
flattens. For a tetrahedron with volume :math:`V`, face areas :math:`A_k`
(the face opposite node :math:`k`), edge lengths :math:`l_{ij}`, inscribed
radius :math:`r_\text{in} = 3V / \sum_k A_k` and circumradius
:math:`r_\text{out}`:

* radius ratio :math:`Q_{rr} = 3\, r_\text{in} / r_\text{out}`. Seed 003
  (eq. 5.56) writes the factor 2, which is the triangle's normalisation: the
  equilateral tetrahedron has :math:`r_\text{in}/r_\text{out} = 1/3`, and the
  seed's own statement that it achieves the maximum quality 1 needs the
  factor 3 (Shewchuk 2002, which the seed cites, uses 3);
* inscribed radius over longest edge (eq. 5.57),
  :math:`Q_{rl} = 2\sqrt6\, r_\text{in} / \max l_{ij}`;
* minimum dihedral-angle sine (eq. 5.58),
  :math:`Q_\theta = \tfrac{9\sqrt2}{8} V \min_{i<j} l_{ij} / (A_k A_l)`, with
  :math:`k, l` the two nodes not on edge :math:`ij` (the two faces that meet
  at the edge): :math:`\sin\theta_{ij} = \tfrac32 V l_{ij} / (A_k A_l)`,
  divided by the equilateral :math:`\sin\theta = 2\sqrt2/3`;
* volume–length (mean-ratio) measure of Joe (1991) (eq. 5.59),
  :math:`Q_{vl} = 12\,(3V)^{2/3} / \sum_{i<j} l_{ij}^2`.

Triangles (2D meshes) get the same four with the triangle's normalisation:
:math:`2 r_\text{in}/r_\text{out}`, :math:`2\sqrt3\, r_\text{in}/\max l`, the
minimum angle sine over :math:`\sin 60°`, and :math:`4\sqrt3\,A/\sum l^2`.
Volumes are unsigned (DOLFINx does not orient cells); a cell of zero volume
has quality 0 in every measure. Higher-order geometry is measured by the
straight simplex through its vertices.

:func:`mesh_quality` evaluates all of them on the owned cells of a mesh and
reduces them over the ranks into a :class:`MeshQuality`; :func:`quality_report`
is the one-line summary a run prints before it solves.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.mesh.domain import Domain

__all__ = [
    "MEASURES",
    "POOR_QUALITY",
    "MeshQuality",
    "MeshQualityWarning",
    "cell_quality",
    "mesh_quality",
    "quality_report",
    "tetrahedron_quality",
    "triangle_quality",
]

MEASURES: dict[str, str] = {
    "radius_ratio": "radius ratio",
    "inradius_edge": "inradius/edge",
    "min_dihedral_sine": "min dihedral sine",
    "volume_length": "volume-length",
}
"""Measure key → label used in summaries and plots (triangles: ``min_dihedral_sine`` is the minimum angle sine)."""

POOR_QUALITY = 0.1
r"""Default threshold of :meth:`MeshQuality.warn_if_poor`.

A cell below 0.1 in these normalised measures is a sliver or needle: its
smallest dihedral angle is under about :math:`6°` (:math:`Q_\theta < 0.1`),
and the condition number of its element stiffness grows like
:math:`1/Q^2` (Shewchuk 2002), so one such cell can dominate the tangent's
conditioning and the local error. Generated meshes of this package stay well
above it (the beam meshes have minimum volume–length ratio above 0.4)."""

_PLURAL = {"tetrahedron": "tetrahedra", "triangle": "triangles"}

PERCENTILES = (1, 5, 50)
"""Percentiles reported by :class:`MeshQuality` (besides min, mean and max)."""


class MeshQualityWarning(UserWarning):
    """Some cells of the mesh are poorly shaped (a warning, not an error: the solve may still work)."""


def _norm(v: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def _safe_div(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """``num / den`` with 0 where ``den`` is 0 (a degenerate cell has quality 0)."""
    out = np.zeros(np.broadcast(num, den).shape)
    np.divide(num, den, out=out, where=den > 0)
    return out


def tetrahedron_quality(points: np.ndarray) -> dict[str, np.ndarray]:
    """The four §5.6 measures of tetrahedra.

    Args:
        points: Vertex coordinates, shape ``(n, 4, 3)``.

    Returns:
        Measure key (:data:`MEASURES`) → array of shape ``(n,)`` in [0, 1].
    """
    p = np.asarray(points, dtype=float)
    if p.ndim != 3 or p.shape[1:] != (4, 3):
        raise ParameterError(f"tetrahedron_quality: need vertex coordinates of shape (n, 4, 3), got {p.shape}")
    a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    V = np.abs(det) / 6.0
    # Face k is opposite node k.
    faces = ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))
    A = np.stack([0.5 * _norm(np.cross(p[:, j] - p[:, i], p[:, k] - p[:, i])) for i, j, k in faces], axis=1)
    edges = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
    L = np.stack([_norm(p[:, j] - p[:, i]) for i, j in edges], axis=1)
    r_in = _safe_div(3.0 * V, A.sum(axis=1))
    # Circumcentre offset from node 0: (|a|^2 b×c + |b|^2 c×a + |c|^2 a×b) / (2 det).
    offset_num = (
        np.einsum("i,ij->ij", _norm(a) ** 2, np.cross(b, c))
        + np.einsum("i,ij->ij", _norm(b) ** 2, np.cross(c, a))
        + np.einsum("i,ij->ij", _norm(c) ** 2, np.cross(a, b))
    )
    # 3 r_in / r_out = 3 r_in * 2|det| / |offset_num|
    radius_ratio = _safe_div(6.0 * r_in * np.abs(det), _norm(offset_num))
    inradius_edge = _safe_div(2.0 * math.sqrt(6.0) * r_in, L.max(axis=1))
    # The faces meeting at edge (i, j) are those opposite the other two nodes p, q.
    others = ((2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1))
    ratios = np.stack([_safe_div(L[:, e], A[:, p] * A[:, q]) for e, (p, q) in enumerate(others)], axis=1)
    dihedral = 9.0 * math.sqrt(2.0) / 8.0 * V * ratios.min(axis=1)
    volume_length = _safe_div(12.0 * np.cbrt(3.0 * V) ** 2, (L**2).sum(axis=1))
    return _clip(
        {
            "radius_ratio": radius_ratio,
            "inradius_edge": inradius_edge,
            "min_dihedral_sine": dihedral,
            "volume_length": volume_length,
        }
    )


def triangle_quality(points: np.ndarray) -> dict[str, np.ndarray]:
    """The four measures with the triangle's normalisation (see the module docstring).

    Args:
        points: Vertex coordinates, shape ``(n, 3, 2)`` or ``(n, 3, 3)``.

    Returns:
        Measure key (:data:`MEASURES`) → array of shape ``(n,)`` in [0, 1].
    """
    p = np.asarray(points, dtype=float)
    if p.ndim != 3 or p.shape[1] != 3 or p.shape[2] not in (2, 3):
        raise ParameterError(f"triangle_quality: need vertex coordinates of shape (n, 3, 2|3), got {p.shape}")
    if p.shape[2] == 2:
        p = np.concatenate([p, np.zeros(p.shape[:2] + (1,))], axis=2)
    A = 0.5 * _norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    # Edge opposite node k.
    L = np.stack([_norm(p[:, 2] - p[:, 1]), _norm(p[:, 2] - p[:, 0]), _norm(p[:, 1] - p[:, 0])], axis=1)
    r_in = _safe_div(2.0 * A, L.sum(axis=1))
    r_out = _safe_div(L.prod(axis=1), 4.0 * A)
    radius_ratio = _safe_div(2.0 * r_in, r_out)
    inradius_edge = _safe_div(2.0 * math.sqrt(3.0) * r_in, L.max(axis=1))
    # sin of the angle at node k: 2A / (product of the two edges at k).
    sines = np.stack([_safe_div(2.0 * A, L[:, (k + 1) % 3] * L[:, (k + 2) % 3]) for k in range(3)], axis=1)
    min_sine = sines.min(axis=1) / (math.sqrt(3.0) / 2.0)
    volume_length = _safe_div(4.0 * math.sqrt(3.0) * A, (L**2).sum(axis=1))
    return _clip(
        {
            "radius_ratio": radius_ratio,
            "inradius_edge": inradius_edge,
            "min_dihedral_sine": min_sine,
            "volume_length": volume_length,
        }
    )


def _clip(measures: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    # Round-off can put an equilateral cell a few ulp above 1.
    return {k: np.clip(v, 0.0, 1.0) for k, v in measures.items()}


def cell_quality(points: np.ndarray) -> dict[str, np.ndarray]:
    """The measures of triangles (``(n, 3, gdim)``) or tetrahedra (``(n, 4, 3)``), by vertex count."""
    p = np.asarray(points, dtype=float)
    if p.ndim == 3 and p.shape[1] == 4:
        return tetrahedron_quality(p)
    if p.ndim == 3 and p.shape[1] == 3:
        return triangle_quality(p)
    raise ParameterError(f"cell_quality: need (n, 3, gdim) triangles or (n, 4, 3) tetrahedra, got shape {p.shape}")


def _stats(values: np.ndarray) -> dict[str, float]:
    """Order-independent statistics of the gathered values (sorted first, so any partition gives the same)."""
    v = np.sort(values)
    if v.size == 0:
        return {name: float("nan") for name in ("min", "mean", "max", *(f"p{q}" for q in PERCENTILES))}
    out = {"min": float(v[0]), "mean": float(math.fsum(v) / v.size), "max": float(v[-1])}
    for q in PERCENTILES:
        out[f"p{q}"] = float(np.percentile(v, q))
    return out


def _gather(comm: MPI.Comm, local: np.ndarray) -> np.ndarray | None:
    """All ranks' values on rank 0 (``None`` elsewhere)."""
    local = np.ascontiguousarray(local, dtype=float)
    counts = comm.gather(local.size, root=0)
    if comm.rank == 0:
        assert counts is not None  # the root receives the list
        out = np.empty(sum(counts), dtype=float)
        comm.Gatherv(local, (out, counts), root=0)
        return out
    comm.Gatherv(local, None, root=0)
    return None


@dataclass
class MeshQuality:
    """Quality measures of a mesh's owned cells and their statistics over all ranks.

    Attributes:
        comm: The mesh communicator.
        cell_type: ``"tetrahedron"`` or ``"triangle"``.
        num_cells: Number of cells over all ranks.
        values: Measure key → per-cell values of this rank's owned cells.
        stats: Measure key → ``{"min", "mean", "max", "p1", "p5", "p50"}``
            over all cells, the same on every rank (and for any partition).
        source: Where the mesh came from (for messages).
    """

    comm: MPI.Comm
    cell_type: str
    num_cells: int
    values: dict[str, np.ndarray]
    stats: dict[str, dict[str, float]] = field(default_factory=dict)
    source: str = "<memory>"

    def summary_line(self) -> str:
        """One line: cell count, then min / mean / 5th percentile of every measure."""
        parts = [
            f"{MEASURES[k]} min {s['min']:.3f} mean {s['mean']:.3f} p5 {s['p5']:.3f}" for k, s in self.stats.items()
        ]
        cells = f"{self.num_cells} {_PLURAL.get(self.cell_type, self.cell_type)}"
        return f"mesh quality ({cells}, 1 = regular): " + "; ".join(parts)

    def poor_measures(self, threshold: float = POOR_QUALITY) -> list[str]:
        """Keys of the measures whose minimum is below ``threshold`` (the same on every rank)."""
        return [k for k, s in self.stats.items() if s["min"] < threshold]

    def warn_if_poor(self, threshold: float = POOR_QUALITY) -> list[str]:
        """Issue a :class:`MeshQualityWarning` (rank 0) if a measure's minimum is below ``threshold``.

        Args:
            threshold: Quality in (0, 1] below which a cell counts as poor;
                default :data:`POOR_QUALITY`.

        Returns:
            The keys of the poor measures (empty when the mesh is fine), on every rank.

        Raises:
            ParameterError: If ``threshold`` is not in (0, 1].
        """
        if not (isinstance(threshold, (int, float)) and 0.0 < threshold <= 1.0):
            raise ParameterError(f"MeshQuality.warn_if_poor: threshold must be in (0, 1], got {threshold!r}")
        poor = self.poor_measures(threshold)
        # `poor` is the same on every rank, so the count reductions are collective.
        counts = {k: self.comm.allreduce(int(np.count_nonzero(self.values[k] < threshold)), op=MPI.SUM) for k in poor}
        if poor and self.comm.rank == 0:
            listed = ", ".join(f"{MEASURES[k]} min {self.stats[k]['min']:.3g} ({counts[k]} cells)" for k in poor)
            warnings.warn(
                f"{self.source}: poorly shaped cells (below {threshold:g}): {listed}; expect a badly conditioned "
                "tangent and large local errors there",
                MeshQualityWarning,
                stacklevel=2,
            )
        return poor

    def histogram_png(self, path: str | Path, bins: int = 50) -> Path:
        """Write histograms of the four measures to a PNG (collective; rank 0 writes).

        Matplotlib (Agg backend) is imported here only.

        Args:
            path: Output file.
            bins: Histogram bins on [0, 1].

        Returns:
            The path written.
        """
        path = Path(path)
        gathered = {k: _gather(self.comm, v) for k, v in self.values.items()}
        if self.comm.rank == 0:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt

            fig, axes = plt.subplots(1, len(gathered), figsize=(4 * len(gathered), 3.2), sharey=True)
            for ax, (key, vals) in zip(np.atleast_1d(axes), gathered.items(), strict=True):
                ax.hist(vals, bins=bins, range=(0.0, 1.0), color="tab:blue")
                ax.set_xlabel(MEASURES[key])
                ax.set_xlim(0.0, 1.0)
            np.atleast_1d(axes)[0].set_ylabel("cells")
            fig.suptitle(f"{self.source}: {self.num_cells} {_PLURAL.get(self.cell_type, self.cell_type)}")
            fig.tight_layout()
            path.parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(path, dpi=100)
            plt.close(fig)
        self.comm.Barrier()
        return path


def _as_mesh(mesh_or_domain: object) -> tuple[dmesh.Mesh, str]:
    if isinstance(mesh_or_domain, Domain):
        return mesh_or_domain.mesh, mesh_or_domain.source
    if isinstance(mesh_or_domain, dmesh.Mesh):
        return mesh_or_domain, "<memory>"
    raise ParameterError(
        f"mesh_quality: need a dolfinx Mesh or a hyperfem Domain, got {type(mesh_or_domain).__name__}"
    )


def mesh_quality(mesh_or_domain: dmesh.Mesh | Domain) -> MeshQuality:
    """Evaluate the §5.6 measures on every owned cell (collective).

    Args:
        mesh_or_domain: A DOLFINx mesh or a hyperfem :class:`~hyperfem.mesh.Domain`
            of triangles or tetrahedra.

    Returns:
        The :class:`MeshQuality` (per-cell values local, statistics global).

    Raises:
        ParameterError: If the cells are not triangles or tetrahedra.
    """
    mesh, source = _as_mesh(mesh_or_domain)
    cell_type = mesh.topology.cell_type
    if cell_type not in (dmesh.CellType.triangle, dmesh.CellType.tetrahedron):
        raise ParameterError(f"mesh_quality ({source}): only triangles and tetrahedra, got {cell_type.name} cells")
    tdim = mesh.topology.dim
    owned = mesh.topology.index_map(tdim).size_local
    nodes = mesh.geometry.dofmaps[0][:owned, : tdim + 1]  # vertices come first in every Lagrange geometry
    points = mesh.geometry.x[nodes]
    if tdim == 2:
        points = points[:, :, : max(mesh.geometry.dim, 2)]
    values = cell_quality(points)
    comm = mesh.comm
    on_root: dict[str, dict[str, float] | None] = {}
    for key, v in values.items():
        gathered = _gather(comm, v)  # None on ranks other than 0
        on_root[key] = _stats(gathered) if gathered is not None else None
    stats: dict[str, dict[str, float]] = comm.bcast(on_root, root=0)  # rank 0's: every value set
    num_cells = mesh.topology.index_map(tdim).size_global
    return MeshQuality(comm, cell_type.name, int(num_cells), values, stats, source)


def quality_report(domain: dmesh.Mesh | Domain, *, warn: bool = True, threshold: float = POOR_QUALITY) -> str:
    """The one-line quality summary a run prints before it solves (collective).

    Args:
        domain: The mesh or domain.
        warn: Also issue a :class:`MeshQualityWarning` when a measure's
            minimum is below ``threshold``.
        threshold: See :meth:`MeshQuality.warn_if_poor`.

    Returns:
        :meth:`MeshQuality.summary_line`, the same on every rank (print it on rank 0).
    """
    quality = mesh_quality(domain)
    if warn:
        quality.warn_if_poor(threshold)
    return quality.summary_line()
