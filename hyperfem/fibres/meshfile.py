r"""Fibres stored as point or cell data of a mesh file, read with meshio.

The file's points (or cell centroids) are matched to the DOLFINx mesh by
coordinates, so the node numbering and the parallel partition do not matter;
the file must describe the same geometry (e.g. the ``.msh`` the mesh was read
from, or a ``.vtu``/``.xdmf`` written from it). Point data give a ``"P1"``
field, cell data a ``"DG0"`` field; both are normalised.
"""

from __future__ import annotations

from pathlib import Path

from mpi4py import MPI

import numpy as np
from dolfinx import fem

from hyperfem.errors import MeshError, MeshFileNotFoundError
from hyperfem.fibres.fields import fibre_space, normalize_fibres
from hyperfem.mesh.domain import Domain

__all__ = ["fibres_from_file"]

_VOLUME_CELLS = ("tetra", "tetra10", "hexahedron", "hexahedron27", "triangle", "triangle6", "quad", "quad9")


class _CoordinateIndex:
    """Exact-ish coordinate lookup without scipy: hash of rounded coordinates, 3^d neighbours."""

    def __init__(self, points: np.ndarray, tol: float):
        self.tol = tol
        self.points = points
        self.table: dict[tuple, int] = {}
        for i, key in enumerate(map(tuple, np.floor(points / tol).astype(np.int64))):
            self.table.setdefault(key, i)

    def find(self, x: np.ndarray) -> np.ndarray:
        d = x.shape[1]
        base = np.floor(x / self.tol).astype(np.int64)
        out = np.full(x.shape[0], -1, dtype=np.int64)
        offsets = np.array(np.meshgrid(*([[0, -1, 1]] * d), indexing="ij")).reshape(d, -1).T
        for i, b in enumerate(base):
            for off in offsets:
                j = self.table.get(tuple(b + off))
                if j is not None and np.linalg.norm(self.points[j] - x[i]) <= self.tol:
                    out[i] = j
                    break
        return out


def fibres_from_file(domain: Domain, path: str | Path, name: str, location: str = "point") -> fem.Function:
    """Read a fibre field from a mesh file's point or cell data (via meshio).

    Args:
        domain: The mesh the field lives on.
        path: Any file meshio reads (``.msh``, ``.vtu``, ``.xdmf``...).
        name: Name of the point/cell data array (3 components per entry).
        location: ``"point"`` (gives a P1 field) or ``"cell"`` (a DG0 field).

    Returns:
        The unit fibre :class:`~dolfinx.fem.Function`.

    Raises:
        MeshFileNotFoundError: If the file is missing.
        MeshError: If the array is missing or a point/cell cannot be matched.
    """
    import meshio

    path = Path(path)
    comm = domain.comm
    if not comm.allreduce(int(path.is_file()), op=MPI.MIN):
        raise MeshFileNotFoundError(f"fibre file not found: {path}")
    if location not in ("point", "cell"):
        raise MeshError(f"fibres_from_file: location must be 'point' or 'cell', got {location!r}")
    try:  # every rank reads the file, so every rank fails alike
        data = meshio.read(path)
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - meshio raises many types, and calls sys.exit(1)
        reason = (str(exc).splitlines() or [type(exc).__name__])[0]
        if isinstance(exc, SystemExit):
            reason = f"not a {path.suffix or 'known'} mesh file meshio can read"
        raise MeshError(f"{path}: meshio cannot read the file: {reason}") from None
    gdim = domain.gdim
    mesh = domain.mesh
    if location == "point":
        if name not in data.point_data:
            raise MeshError(f"{path}: no point data named {name!r} (available: {sorted(data.point_data)})")
        ref = np.asarray(data.points, dtype=float)[:, :gdim]
        values = np.asarray(data.point_data[name], dtype=float)
        V = fibre_space(mesh, "P1")
    else:
        if name not in data.cell_data:
            raise MeshError(f"{path}: no cell data named {name!r} (available: {sorted(data.cell_data)})")
        pts = np.asarray(data.points, dtype=float)[:, :gdim]
        centroids, vals = [], []
        for block, block_data in zip(data.cells, data.cell_data[name], strict=True):
            if block.type in _VOLUME_CELLS and block.data.shape[1] > gdim:
                nv = {"tetra10": 4, "hexahedron27": 8, "triangle6": 3, "quad9": 4}.get(block.type, block.data.shape[1])
                centroids.append(pts[block.data[:, :nv]].mean(axis=1))
                vals.append(np.asarray(block_data, dtype=float))
        if not centroids:
            raise MeshError(f"{path}: cell data {name!r} has no volume cells")
        ref, values = np.concatenate(centroids), np.concatenate(vals)
        V = fibre_space(mesh, "DG0")
    values = values.reshape(values.shape[0], -1)[:, :gdim]
    a0 = fem.Function(V, name=name)
    X = V.tabulate_dof_coordinates()[:, :gdim]
    scale = float(np.ptp(ref, axis=0).max()) or 1.0
    index = _CoordinateIndex(ref, 1e-8 * scale)
    match = index.find(X)
    missing = comm.allreduce(int(np.count_nonzero(match < 0)), op=MPI.SUM)
    if missing:
        raise MeshError(f"{path}: {missing} {location}(s) of the mesh not found in the file (different geometry?)")
    a0.x.array[:] = values[match].reshape(-1)
    return normalize_fibres(a0)
