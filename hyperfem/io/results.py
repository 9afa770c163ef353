"""Writing results: VTX (ADIOS2) and XDMF files for ParaView, and JSON files.

JSON files and folder checks are written by rank 0 (:func:`on_rank0`); its
outcome is broadcast so that a folder that cannot be created or written
raises the same :class:`~hyperfem.errors.OutputError` on every rank instead
of leaving the other ranks waiting in a collective call. VTX files are
written collectively by ADIOS2 (BP4 engine: every frame is indexed as it is
written, so a killed run leaves every complete frame readable;
:func:`vtx_steps` counts them). XDMF files (:class:`XDMFWriter`) are written
collectively through HDF5. What a run writes, and when, is decided by the
outputs of :class:`~hyperfem.simulation.Simulation`.
"""

from __future__ import annotations

import json
import os
import re
import uuid
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from mpi4py import MPI
from dolfinx import fem, io

from hyperfem.errors import OutputError

__all__ = [
    "VTXWriter",
    "XDMFWriter",
    "abandon",
    "abandoned",
    "ensure_output_dir",
    "flatten_row",
    "jsonable",
    "note_overwrite",
    "on_rank0",
    "previous_summaries",
    "vtx_steps",
    "write_json",
]


_ABANDONED: list[object] = []
_T = TypeVar("_T")


def abandon(writer: object) -> None:
    """Keep a writer that failed (e.g. an ADIOS2 engine on a full disk) alive until the process ends.

    Closing or destroying an ADIOS2 engine whose transport failed throws from a
    C++ destructor, which terminates the process (SIGABRT, exit 134, after the
    one-line error). The command line (:func:`hyperfem.app.program.run`) ends such a
    process with ``os._exit`` once its error line is out (:func:`abandoned`).
    """
    _ABANDONED.append(writer)


def abandoned() -> bool:
    """Whether a writer was abandoned in this process (then exit without destructors)."""
    return bool(_ABANDONED)


def _adios_reason(exc: BaseException) -> str:
    """The part of an ADIOS2 exception that says what went wrong (``No space left on device``)."""
    text = re.sub(r"\x1b\[[0-9;]*m", "", str(exc)).strip()
    match = re.search(r"errno = \d+: ([^\n]+)", text)
    if match:
        return match.group(1).strip()
    return text.splitlines()[-1].strip() if text else type(exc).__name__


def _reason(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    text = str(exc).splitlines()[0] if str(exc) else ""
    return text or type(exc).__name__


def on_rank0(comm: MPI.Comm, action: Callable[[], _T], what: str) -> _T | None:
    """Run ``action()`` on rank 0 and raise the same :class:`OutputError` on every rank if it fails.

    Args:
        comm: Communicator (every rank must call).
        action: File-system work done by rank 0 only.
        what: Start of the error message, e.g. ``"cannot write /tmp/x.json"``.

    Returns:
        ``action()``'s result on rank 0, ``None`` elsewhere.
    """
    result: _T | None = None
    error = ""
    if comm.rank == 0:
        try:
            result = action()
        except (OSError, ValueError, TypeError) as exc:
            error = f"{what}: {_reason(exc)}"
    error = comm.bcast(error, root=0)
    if error:
        raise OutputError(error)
    return result


def ensure_output_dir(path: str | Path, comm: MPI.Comm) -> Path:
    """Create the output folder ``path`` (rank 0) and check that it is writable, on every rank.

    Rank 0 makes the folder (with parents) and writes and removes a probe
    file; success or the reason for failure is broadcast, so every rank
    returns or raises the same error. Call it before any long computation.

    Returns:
        The path.

    Raises:
        OutputError: If the folder cannot be created or written (same message on every rank).
    """
    path = Path(path)

    def probe() -> None:
        path.mkdir(parents=True, exist_ok=True)
        test = path / f".hyperfem-write-test-{uuid.uuid4().hex}"
        with open(test, "w") as fh:
            fh.write("ok\n")
        os.remove(test)

    on_rank0(comm, probe, f"output folder {path} cannot be created or written")
    return path


def _is_summary(path: Path) -> bool:
    """Whether ``path`` is the JSON summary of a run (a dict with ``name``, ``steps`` and ``completed``)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return False
    return isinstance(data, dict) and {"name", "steps", "completed"} <= data.keys()


def previous_summaries(path: str | Path, comm: MPI.Comm) -> list[Path]:
    """The JSON summaries of earlier runs in the folder ``path`` (rank 0 looks; every rank gets the list).

    A folder that does not exist, or holds no summary, gives ``[]``.
    """
    path = Path(path)

    def look() -> list[str]:
        if not path.is_dir():
            return []
        return [str(p) for p in sorted(path.glob("*.json")) if _is_summary(p)]

    found = on_rank0(comm, look, f"cannot read the output folder {path}")
    return [Path(p) for p in comm.bcast(found, root=0)]


def note_overwrite(paths: Sequence[str | Path], comm: MPI.Comm) -> list[Path]:
    """Say (rank 0) which of ``paths`` exist and are about to be overwritten; every rank gets that list.

    For scripts that write to a fixed default folder (the demos): a second run replaces the
    first one's files, and says so in one line (``overwriting output/bend.json, output/bend.bp``).
    """

    def look() -> list[str]:
        return [str(p) for p in paths if Path(p).exists()]

    found = comm.bcast(on_rank0(comm, look, "cannot look at the output files"), root=0)
    if found and comm.rank == 0:
        print(f"overwriting {', '.join(found)} (the output of a previous run)", flush=True)
    return [Path(p) for p in found]


def jsonable(obj: object) -> Any:
    """``obj`` with NumPy arrays and scalars, tuples and paths turned into JSON types (recursively)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def flatten_row(row: dict[str, Any]) -> dict[str, Any]:
    """A row of a run's summary as CSV columns: scalars as they are, lists of numbers spread out.

    A list (tuple, array) ``name`` becomes the columns ``name_0, name_1, ...``;
    nested ones ``name_0_1`` (row-major), so ``{"u": [[1, 2]]}`` gives
    ``{"u_0_0": 1.0, "u_0_1": 2.0}``. This is how
    :class:`~hyperfem.simulation.outputs.CSVLog` writes a row, and how
    :func:`~hyperfem.simulation.plots.read_rows` reads the rows of a JSON
    summary as columns of the CSV.

    Args:
        row: Column name → scalar or (nested) list of numbers.

    Returns:
        Column name → scalar.
    """
    flat: dict[str, Any] = {}
    for key, value in row.items():
        if isinstance(value, (list, tuple, np.ndarray)):
            array = np.asarray(value, dtype=float)
            for index in np.ndindex(array.shape):
                flat["_".join([key, *map(str, index)])] = float(array[index])
        else:
            flat[key] = value
    return flat


def write_json(path: str | Path, data: dict[str, Any], comm: MPI.Comm) -> Path:
    """Write ``data`` as JSON from rank 0 (all ranks must call it).

    The text goes to a temporary file that then replaces ``path``, so a run
    killed while writing leaves the previous version, never a truncated one.

    Returns:
        The path.

    Raises:
        OutputError: On every rank, if rank 0 cannot write the file.
    """
    path = Path(path)

    def write() -> None:
        text = json.dumps(jsonable(data), indent=2, default=str) + "\n"
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f".{path.name}.partial")
        try:
            partial.write_text(text)
            os.replace(partial, path)
        except OSError:
            partial.unlink(missing_ok=True)  # a full disk leaves the previous version and no stray file
            raise

    on_rank0(comm, write, f"cannot write {path}")
    return path


class VTXWriter:
    """A VTX (``.bp``) time series of one or more functions, for ParaView.

    VTX stores one element for all its functions, so each function is
    interpolated into a common Lagrange space of degree ``degree`` (default:
    the highest degree among them): continuous unless one of the functions
    is discontinuous, then discontinuous (a DG0 cell field stays cell-wise,
    a P2 displacement next to it is represented exactly). Functions already on
    that element are copied unchanged.

    Args:
        comm: Communicator.
        path: Output ``.bp`` folder (its parent is created and checked on every rank).
        functions: Functions on one mesh (their names appear in ParaView).
        degree: Lagrange degree of the written fields.
    """

    def __init__(
        self, comm: MPI.Comm, path: str | Path, functions: Sequence[fem.Function], degree: int | None = None
    ) -> None:
        self.path = Path(path)
        ensure_output_dir(self.path.parent, comm)
        mesh = functions[0].function_space.mesh
        elements = [f.function_space.ufl_element() for f in functions]
        discontinuous = any(e.discontinuous for e in elements)
        if degree is None:
            degree = max(e.embedded_superdegree for e in elements)
        family = "DG" if discontinuous else "Lagrange"
        degree = degree if discontinuous else max(1, degree)
        self._pairs: list[tuple[fem.Function, fem.Function]] = []
        out = []
        for f in functions:
            shape = f.function_space.value_shape
            V = fem.functionspace(mesh, (family, degree, shape) if shape else (family, degree))
            g = fem.Function(V, name=f.name)
            self._pairs.append((f, g))
            out.append(g)
        self._comm = comm
        self._writer: io.VTXWriter | None = io.VTXWriter(comm, str(self.path), out, engine="BP4")

    def write(self, t: float) -> None:
        """Interpolate the functions into the output space and append a frame at time ``t``.

        Raises:
            OutputError: On every rank, if ADIOS2 could not write the frame (e.g. a full disk).
        """
        if self._writer is None:
            raise OutputError(f"cannot write {self.path}: the file failed before and was abandoned")
        for f, g in self._pairs:
            g.interpolate(f)
        error = ""
        try:
            self._writer.write(float(t))
        except RuntimeError as exc:
            error = _adios_reason(exc)
        errors = [e for e in self._comm.allgather(error) if e]
        if errors:
            self._abandon()
            raise OutputError(f"cannot write {self.path}: {errors[0]}")

    def _abandon(self) -> None:
        """Give up the writer without closing it (see :func:`abandon`)."""
        if self._writer is not None:
            abandon(self._writer)
            self._writer = None

    def close(self) -> None:
        """Close the file (nothing to do after a failed write).

        Raises:
            OutputError: On every rank, if ADIOS2 could not close the file (e.g. a full disk).
        """
        if self._writer is None:
            return
        error = ""
        try:
            self._writer.close()
        except RuntimeError as exc:
            error = _adios_reason(exc)
        # ADIOS2 closes collectively, but its files (profiling.json) are written by rank 0 alone:
        # where any rank failed, every rank keeps its writer (its destructor would throw again).
        errors = [e for e in self._comm.allgather(error) if e]
        if errors:
            self._abandon()
            raise OutputError(f"cannot close {self.path}: {errors[0]}")
        self._writer = None

    def __enter__(self) -> VTXWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


BP4_INDEX_HEADER = 64
"""Bytes of the header of a BP4 ``md.idx`` file; one record of the same size follows per step."""


def vtx_steps(path: str | Path) -> int:
    """Number of complete frames (steps) in a VTX/BP4 folder, from its index ``md.idx``.

    ADIOS2's BP4 engine appends one 64-byte record to ``md.idx`` at the end of
    every step, after the step's data and metadata, so the count is that of
    the frames a reader (ParaView) finds, also in a file whose writer was killed.
    0 when the folder or its index does not exist.
    """
    index = Path(path) / "md.idx"
    if not index.is_file():
        return 0
    return max(0, (index.stat().st_size - BP4_INDEX_HEADER) // BP4_INDEX_HEADER)


class XDMFWriter:
    """An XDMF (``.xdmf`` + ``.h5``) time series of functions, for ParaView.

    XDMF holds one mesh and, per time, nodal values on the mesh's geometry
    nodes or one value per cell. So every function is interpolated into the
    Lagrange space of the geometry's degree (P1 on straight cells; a P2
    displacement loses its edge values) unless it is cell-wise constant
    (DG0), which is written as cell data. Use :class:`VTXWriter` for
    higher-degree fields.

    Args:
        comm: Communicator.
        path: Output ``.xdmf`` file (its parent is created and checked on every rank).
        functions: Functions on one mesh (their names appear in ParaView).
    """

    def __init__(self, comm: MPI.Comm, path: str | Path, functions: Sequence[fem.Function]) -> None:
        self.path = Path(path)
        ensure_output_dir(self.path.parent, comm)
        mesh = functions[0].function_space.mesh
        degree = mesh.geometry.cmaps[0].degree
        self._pairs = []
        for f in functions:
            element = f.function_space.ufl_element()
            shape = f.function_space.value_shape
            if element.discontinuous and element.embedded_superdegree == 0:
                family, k = "DG", 0
            else:
                family, k = "Lagrange", degree
            V = fem.functionspace(mesh, (family, k, shape) if shape else (family, k))
            self._pairs.append((f, fem.Function(V, name=f.name)))
        self._file = io.XDMFFile(comm, str(self.path), "w")
        self._file.write_mesh(mesh)

    def write(self, t: float) -> None:
        """Interpolate the functions and append them at time ``t``."""
        for f, g in self._pairs:
            g.interpolate(f)
            self._file.write_function(g, float(t))

    def close(self) -> None:
        """Close the file."""
        self._file.close()

    def __enter__(self) -> XDMFWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
