r"""Checkpoint files: the owned dof values of functions, one NumPy file per rank, and a JSON record.

No checkpoint library is available to hyperfem (``adios4dolfinx`` is not a
dependency, and DOLFINx has no restart of its own), so this is a small format
of its own. One checkpoint is a folder::

    <folder>/step-000012/
        meta.json                   everything but the arrays (rank 0, written last)
        rank-0000-of-0002.npz       per rank, for every function NAME:
                                      NAME         owned dof values (float64)
                                      NAME.global  their global dof indices (int64, block size unrolled)
                                    and "original_cells": the input indices of the owned cells
        rank-0001-of-0002.npz
    <folder>/latest.json            {"path": "step-000012", "step": 12}

The step folder is first written as ``step-000012.partial`` and renamed when
complete; ``latest.json`` is replaced atomically after that, so a run killed
while writing a checkpoint leaves the previous one intact and named.

A restart must use the same mesh on the same number of ranks: DOLFINx then
partitions and numbers it the same way, and each rank finds its own dofs
(checked: the owned cells' input indices and the global dof indices must be
those of the file; the values are placed by global index). Values are copied
bit for bit, so a restarted run repeats the arithmetic of an uninterrupted one.
Mismatches raise :class:`CheckpointError` on every rank.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from dolfinx import fem

from hyperfem.errors import CheckpointError, OutputError
from hyperfem.io.results import on_rank0, write_json

__all__ = [
    "FORMAT",
    "CheckpointError",
    "owned_values",
    "read_functions",
    "read_meta",
    "resolve_checkpoint",
    "step_folder_name",
    "write_checkpoint",
]

FORMAT = "hyperfem-checkpoint/1"
"""Format tag stored in ``meta.json``."""


def step_folder_name(step: int) -> str:
    """Name of the folder of the checkpoint after accepted step ``step``."""
    return f"step-{int(step):06d}"


def _rank_file(rank: int, size: int) -> str:
    return f"rank-{rank:04d}-of-{size:04d}.npz"


def owned_values(f: fem.Function) -> tuple[np.ndarray, np.ndarray]:
    """The owned entries of ``f`` and their global dof indices (block size unrolled)."""
    imap = f.function_space.dofmap.index_map
    bs = f.function_space.dofmap.index_map_bs
    n = imap.size_local
    blocks = imap.local_to_global(np.arange(n, dtype=np.int32)).astype(np.int64)
    indices = (blocks[:, None] * bs + np.arange(bs, dtype=np.int64)[None, :]).reshape(-1)
    return f.x.array[: n * bs].astype(np.float64, copy=True), indices


def _original_cells(mesh) -> np.ndarray:
    n = mesh.topology.index_map(mesh.topology.dim).size_local
    return np.asarray(mesh.topology.original_cell_index[:n], dtype=np.int64)


def _collective(comm, error: str) -> str:
    """The first non-empty error of any rank (every rank gets the same)."""
    return next((e for e in comm.allgather(error) if e), "")


def write_checkpoint(
    folder: str | Path,
    step: int,
    functions: Mapping[str, fem.Function],
    meta: dict,
    comm,
    *,
    keep: int | None = 2,
) -> Path:
    """Write one checkpoint (collective) and make it the latest.

    Args:
        folder: Checkpoint folder (created if needed).
        step: Accepted step the state belongs to (names the sub-folder).
        functions: Name → function; the owned values of each are stored.
        meta: JSON-serialisable record (rank 0's is written); ``format`` and
            ``ranks`` are added.
        comm: Communicator of the functions' mesh.
        keep: Checkpoints to keep (older ``step-*`` folders are removed);
            ``None`` keeps all.

    Returns:
        The step folder.

    Raises:
        OutputError: On every rank, if any rank cannot write its part.
    """
    folder = Path(folder)
    final = folder / step_folder_name(step)
    partial = folder / f"{final.name}.partial"

    def prepare() -> None:
        folder.mkdir(parents=True, exist_ok=True)
        if partial.exists():
            shutil.rmtree(partial)
        partial.mkdir()

    on_rank0(comm, prepare, f"cannot write checkpoint {final}")
    error = ""
    try:
        arrays: dict[str, np.ndarray] = {}
        mesh = None
        for name, f in functions.items():
            values, indices = owned_values(f)
            arrays[name] = values
            arrays[f"{name}.global"] = indices
            mesh = f.function_space.mesh
        if mesh is not None:
            arrays["original_cells"] = _original_cells(mesh)
        target = partial / _rank_file(comm.rank, comm.size)
        with open(target, "wb") as fh:
            np.savez(fh, **arrays)
    except OSError as exc:
        error = f"cannot write checkpoint {final} (rank {comm.rank}): {exc.strerror or exc}"
    error = _collective(comm, error)
    if error:
        raise OutputError(error)
    record = {**meta, "format": FORMAT, "ranks": comm.size, "step": int(step), "functions": list(functions)}
    write_json(partial / "meta.json", record, comm)

    def commit() -> None:
        if final.exists():
            shutil.rmtree(final)
        os.replace(partial, final)
        latest = folder / ".latest.json.partial"
        latest.write_text(json.dumps({"path": final.name, "step": int(step)}) + "\n")
        os.replace(latest, folder / "latest.json")
        if keep is not None:
            done = sorted(p for p in folder.glob("step-*") if p.is_dir() and not p.name.endswith(".partial"))
            for old in done[: max(0, len(done) - keep)]:
                if old != final:
                    shutil.rmtree(old, ignore_errors=True)

    on_rank0(comm, commit, f"cannot write checkpoint {final}")
    return final


def resolve_checkpoint(path: str | Path, comm) -> Path:
    """The step folder ``path`` names: a checkpoint folder (its latest), its latest.json, a step folder, meta.json.

    Raises:
        CheckpointError: On every rank, if there is no checkpoint there.
    """
    path = Path(path)

    def find() -> str:
        if path.is_file() and path.name == "meta.json":
            return str(path.parent)
        if path.is_file() and path.name == "latest.json":
            return find_in(path.parent)
        return find_in(path)

    def find_in(path: Path) -> str:
        if (path / "meta.json").is_file():
            return str(path)
        latest = path / "latest.json"
        if latest.is_file():
            try:
                name = json.loads(latest.read_text())["path"]
            except (ValueError, KeyError, TypeError) as exc:
                raise ValueError(f"unreadable {latest} ({type(exc).__name__})") from None
            if (path / name / "meta.json").is_file():
                return str(path / name)
            raise ValueError(f"{latest} names {name}, which holds no complete checkpoint")
        raise ValueError("no checkpoint there (no meta.json or latest.json)")

    found, error = None, ""
    if comm.rank == 0:
        try:
            found = find()
        except (OSError, ValueError) as exc:
            error = f"cannot restart from {path}: {exc}"
    found, error = comm.bcast((found, error), root=0)
    if error:
        raise CheckpointError(error)
    return Path(found)


def read_meta(path: str | Path, comm) -> dict:
    """The ``meta.json`` of the checkpoint at ``path`` (:func:`resolve_checkpoint`), read on rank 0 and broadcast.

    Raises:
        CheckpointError: On every rank, if it is missing, unreadable or of another format.
    """
    folder = resolve_checkpoint(path, comm)
    meta, error = None, ""
    if comm.rank == 0:
        try:
            meta = json.loads((folder / "meta.json").read_text())
            if not isinstance(meta, dict) or meta.get("format") != FORMAT:
                found = meta.get("format") if isinstance(meta, dict) else type(meta).__name__
                error = f"{folder}: not a {FORMAT} checkpoint (format {found!r})"
        except (OSError, ValueError) as exc:
            error = f"{folder}/meta.json cannot be read: {exc}"
    meta, error = comm.bcast((meta, error), root=0)
    if error:
        raise CheckpointError(error)
    meta["path"] = str(folder)
    return meta


def read_functions(path: str | Path, functions: Mapping[str, fem.Function], comm) -> None:
    """Load the stored values into ``functions`` (collective; ghosts updated).

    Args:
        path: The checkpoint (:func:`resolve_checkpoint`).
        functions: Name → function to fill; every name must be in the file.
        comm: Communicator of the functions' mesh.

    Raises:
        CheckpointError: On every rank, if a rank's file is missing, was
            written by another number of ranks or for another distribution
            of the mesh, or lacks a function.
    """
    folder = resolve_checkpoint(path, comm)
    error = ""
    name = _rank_file(comm.rank, comm.size)
    try:
        with np.load(folder / name) as data:
            stored = {k: data[k] for k in data.files}
    except FileNotFoundError:
        present = sorted(p.name for p in folder.glob("rank-*.npz"))
        error = (
            f"{folder}: no {name} (the checkpoint was written by another number of ranks: "
            f"{', '.join(present) or 'no rank files'})"
        )
    except (OSError, ValueError) as exc:
        error = f"{folder}/{name} cannot be read: {exc}"
    if not error and functions:
        mesh = next(iter(functions.values())).function_space.mesh
        cells = stored.get("original_cells")
        if cells is not None and not np.array_equal(cells, _original_cells(mesh)):
            error = (
                f"{folder}: rank {comm.rank} owns other cells than when the checkpoint was written "
                "(another mesh, or the mesh distributed differently)"
            )
    updates = []
    if not error:
        for key, f in functions.items():
            if key not in stored or f"{key}.global" not in stored:
                error = f"{folder}: no field {key!r} in {name} (stored: {', '.join(sorted(stored))})"
                break
            values, indices = stored[key], stored[f"{key}.global"]
            _, current = owned_values(f)
            if np.array_equal(indices, current):
                updates.append((f, values))
                continue
            order, found = np.argsort(indices), np.argsort(current)
            if indices.shape != current.shape or not np.array_equal(indices[order], current[found]):
                error = (
                    f"{folder}: field {key!r} on rank {comm.rank} has {indices.size} stored dofs for "
                    f"{current.size} owned ones, or other ones (another space or distribution)"
                )
                break
            placed = np.empty_like(values)
            placed[found] = values[order]
            updates.append((f, placed))
    error = _collective(comm, error)
    if error:
        raise CheckpointError(error)
    for f, values in updates:
        f.x.array[: values.size] = values
        f.x.scatter_forward()
