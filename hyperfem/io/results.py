"""Writing results: VTX (ADIOS2) files for ParaView and JSON summaries."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from dolfinx import fem, io

__all__ = ["VTXOutput", "write_json"]


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json(path: str | Path, data: dict, comm) -> Path:
    """Write ``data`` as JSON from rank 0 (all ranks must call it).

    Returns:
        The path.
    """
    path = Path(path)
    if comm.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(_jsonable(data), indent=2) + "\n")
    comm.Barrier()
    return path


class VTXOutput:
    """A VTX (``.bp``) time series of one or more functions on the same element.

    Each function is interpolated into an output space of Lagrange degree
    ``degree`` (default: the highest degree among them), so displacement, stresses
    and fields of other degrees can be written to one file.

    Args:
        comm: Communicator.
        path: Output ``.bp`` folder.
        functions: Functions to write (their names appear in ParaView).
        degree: Lagrange degree of the written fields.
    """

    def __init__(self, comm, path: str | Path, functions: Sequence[fem.Function], degree: int | None = None):
        self.path = Path(path)
        if comm.rank == 0:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        comm.Barrier()
        mesh = functions[0].function_space.mesh
        if degree is None:
            degree = max(max(1, f.function_space.ufl_element().embedded_superdegree) for f in functions)
        self._pairs = []
        out = []
        for f in functions:
            shape = f.function_space.value_shape
            V = fem.functionspace(mesh, ("Lagrange", degree, shape))
            g = fem.Function(V, name=f.name)
            self._pairs.append((f, g))
            out.append(g)
        self._writer = io.VTXWriter(comm, str(self.path), out, engine="BP4")

    def write(self, t: float) -> None:
        """Interpolate the functions and append time ``t``."""
        for f, g in self._pairs:
            g.interpolate(f)
        self._writer.write(float(t))

    def close(self) -> None:
        """Close the file."""
        self._writer.close()

    def __enter__(self) -> VTXOutput:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
