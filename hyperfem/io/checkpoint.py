r"""Checkpoint files: the owned dof values of functions, one NumPy file per rank, and a JSON record.

No checkpoint library is available to hyperfem (``adios4dolfinx`` is not
importable on either install route, and DOLFINx has no restart of its own),
so this is a small format of its own. One checkpoint is a folder::

    <folder>/step-000012/
        meta.json                   everything but the arrays (rank 0, written last)
        rank-0000-of-0002.npz       per rank, for every function NAME:
                                      NAME         owned dof values (float64)
                                      NAME.global  their global dof indices (int64, block size unrolled)
                                      NAME.keys    partition-independent keys of the owned dof blocks
                                                   (int64, 6 columns; absent where no key exists)
                                    and "original_cells": the input indices of the owned cells
        rank-0001-of-0002.npz
    <folder>/latest.json            {"path": "step-000012", "step": 12}
    <folder>/history-<run>.jsonl    the lists that grow with the run (the rows), once for all its checkpoints

**History.** What only grows during a run (the rows of every recorded state,
an output's list of rows or files) is not repeated in every ``meta.json``: a
:class:`History` appends the new items to one JSON-lines file per run and
checkpoint folder, and ``meta.json`` holds ``{"$history": file, "key": ...,
"count": n}`` in their place; :func:`read_meta` puts the first ``n`` items
back. So a checkpoint costs the size of the state plus the steps since the
previous one, and ``meta.json`` keeps its size. Items a later checkpoint
appended (or a run killed while appending) are ignored by an earlier one.
A run continued from a checkpoint writes a history file of its own, so the
checkpoints of the first run stay readable; a history file no kept
checkpoint names is removed. A list that does not just grow at its end is
stored in ``meta.json`` as before. A step folder is therefore read together
with its checkpoint folder (the history file beside it): to archive or move
one checkpoint, copy ``history-<run>.jsonl`` with it.

The step folder is first written as ``step-000012.partial`` and renamed when
complete; ``latest.json`` is replaced atomically after that, so a run killed
while writing a checkpoint leaves the previous one intact and named.

**Reading back.** On the same mesh distributed the same way (the same number
of ranks; checked through the owned cells' input indices) each rank reads its
own file and places the values by global dof index, bit for bit.

On any other number of ranks (or another distribution of the same mesh) every
rank reads all the rank files and finds its dofs by **key**: a dof lies on a
mesh entity (vertex, edge, face, or the cell interior) of its cell, and is the
``j``-th dof of the element on that entity; the key is

    (entity dimension, the entity's vertices as input node indices, sorted, padded with -1, j)

and, for dofs inside a cell, (cell dimension, input cell index, -1, -1, -1, j).
Input node and cell indices are those of the mesh file, so the key of a dof
does not depend on how the mesh was partitioned or numbered. This holds when
the place of a dof on its entity does not depend on the entity's orientation:
every element whose scalar parts have at most one dof per edge and per face
(Lagrange and serendipity of degree <= 2, DG and quadrature spaces of any
degree, and mixed and blocked elements of those) and needs no dof
transformations. Other spaces are stored without keys and restart on the
same number of ranks only.

Mismatches (another mesh, another space, a key not found) raise
:class:`CheckpointError` on every rank.
"""

from __future__ import annotations

import json
import os
import shutil
import uuid
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import basix
import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from hyperfem.errors import CheckpointError, OutputError
from hyperfem.io.results import jsonable, on_rank0, write_json

__all__ = [
    "FORMAT",
    "CheckpointError",
    "History",
    "dof_keys",
    "owned_values",
    "read_functions",
    "read_meta",
    "resolve_checkpoint",
    "step_folder_name",
    "write_checkpoint",
]

FORMAT = "hyperfem-checkpoint/3"
"""Format tag stored in ``meta.json`` (``/3``: growing lists in a :class:`History` file)."""

READABLE = ("hyperfem-checkpoint/2", FORMAT)
"""Formats :func:`read_meta` reads (``/2``: every list inline)."""

HISTORY_REF = "$history"
"""Key of a reference to a :class:`History` list in ``meta.json``."""


class History:
    """The lists of a run that only grow (its rows), written once to ``<folder>/history-<run>.jsonl``.

    :meth:`refer` gives the reference that stands for a list in ``meta.json``
    and queues its items not yet written; :func:`write_checkpoint` appends
    them before it writes ``meta.json``. One object per run and checkpoint
    folder (collective to create: rank 0 draws the file name).

    Args:
        comm: The run's communicator.
    """

    def __init__(self, comm: MPI.Comm) -> None:
        token = uuid.uuid4().hex[:12] if comm.rank == 0 else None
        self.name = f"history-{comm.bcast(token, root=0)}.jsonl"
        self._written: dict[str, list[str]] = {}  # key -> the items in the file, as the JSON lines written
        self._inline: set[str] = set()
        self._queued: list[str] = []

    def refer(self, key: str, items: Sequence) -> dict | list:
        """A reference to ``items`` in the file (new items queued), or ``items`` when they do not extend the last ones.

        Args:
            key: Name of the list (the same list under the same key every time).
            items: The whole list now; the items already written must be its start.
        """
        items = list(items)
        # Compared as the text written, not as objects: an item that holds a list the run mutates
        # later (a field writer's pending output times) would compare equal to itself and the
        # history would keep its first value (a restart then wrote frames the run never wrote).
        lines = [json.dumps({"k": key, "v": jsonable(v)}, default=str) + "\n" for v in items]
        done = self._written.get(key, [])
        if key in self._inline or lines[: len(done)] != done:  # not a continuation: kept in meta.json
            self._inline.add(key)
            return items
        self._queued.extend(lines[len(done) :])
        self._written[key] = lines
        return {HISTORY_REF: self.name, "key": key, "count": len(items)}

    def flush(self, folder: Path, comm: MPI.Comm) -> None:
        """Append the queued items to the file (rank 0; collective).

        Raises:
            OutputError: On every rank, if rank 0 cannot write.
        """
        path = Path(folder) / self.name

        def append() -> None:
            with path.open("a") as fh:
                fh.write("".join(self._queued))

        on_rank0(comm, append, f"cannot write {path}")
        self._queued = []


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


KEY_WIDTH = 6
"""Columns of a dof key: entity dimension, four vertex (or cell) indices, index on the entity."""


def _leaves(element: Any) -> Iterator[basix.finite_element.FiniteElement | None]:
    """The basix elements of a (mixed, blocked) basix.ufl element; ``None`` for a leaf without one.

    Duck-typed: the element classes of basix.ufl (some private) are told apart by what they have.
    """
    subs = getattr(element, "sub_elements", None)
    if subs and type(element).__name__ != "_BasixElement":
        for sub in subs:
            yield from _leaves(sub)
        return
    try:
        yield element.basix_element
    except (AttributeError, NotImplementedError):  # quadrature and other custom elements
        yield None


def _keyable(V: fem.FunctionSpace) -> bool:
    """Whether the dofs of ``V`` have partition-independent keys (module docstring)."""
    if V.element.needs_dof_transformations:
        return False
    tdim = V.mesh.topology.dim
    for leaf in _leaves(V.ufl_element()):
        if leaf is None:  # quadrature and other custom elements: all their dofs are inside the cell
            continue
        for dim in range(1, tdim):
            if any(len(dofs) > 1 for dofs in leaf.entity_dofs[dim]):
                return False
    return True


def dof_keys(V: fem.FunctionSpace) -> np.ndarray | None:
    """Partition-independent keys of the owned dof blocks of ``V`` (module docstring), or ``None``.

    Returns:
        ``(owned blocks, 6)`` int64 array, one row per owned dof block, or
        ``None`` when the space has no such keys.
    """
    if not _keyable(V):
        return None
    mesh = V.mesh
    tdim = mesh.topology.dim
    cmap = mesh.topology.index_map(tdim)
    ncells = cmap.size_local + cmap.num_ghosts
    reference = basix.topology(mesh.basix_cell())
    nverts = len(reference[0])
    nodes = np.asarray(mesh.geometry.input_global_indices, dtype=np.int64)
    corners = nodes[mesh.geometry.dofmaps[0][:ncells, :nverts]]  # vertices come first in every Lagrange geometry
    cells = np.asarray(mesh.topology.original_cell_index[:ncells], dtype=np.int64)
    layout = V.dofmap.dof_layout
    dofs = V.dofmap.list[:ncells]
    imap = V.dofmap.index_map
    keys = np.full((imap.size_local + imap.num_ghosts, KEY_WIDTH), -1, dtype=np.int64)
    for dim in range(tdim + 1):
        for entity, vertices in enumerate(reference[dim]):
            for j, position in enumerate(layout.entity_dofs(dim, entity)):
                block = np.full((ncells, KEY_WIDTH), -1, dtype=np.int64)
                block[:, 0] = dim
                if dim == tdim:
                    block[:, 1] = cells
                else:
                    block[:, 1 : 1 + len(vertices)] = np.sort(corners[:, vertices], axis=1)
                block[:, -1] = j
                keys[dofs[:, position]] = block  # every cell of a dof gives it the same key
    return keys[: imap.size_local]


def _original_cells(mesh: dmesh.Mesh) -> np.ndarray:
    n = mesh.topology.index_map(mesh.topology.dim).size_local
    return np.asarray(mesh.topology.original_cell_index[:n], dtype=np.int64)


def _collective(comm: MPI.Comm, error: str) -> str:
    """The first non-empty error of any rank (every rank gets the same)."""
    return next((e for e in comm.allgather(error) if e), "")


def write_checkpoint(
    folder: str | Path,
    step: int,
    functions: Mapping[str, fem.Function],
    meta: dict[str, Any],
    comm: MPI.Comm,
    *,
    keep: int | None = 2,
    history: History | None = None,
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
        history: Where the lists that ``meta`` refers to go (:meth:`History.refer`);
            its queued items are appended before ``meta.json`` is written.

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
    error = _write_arrays(functions, partial / _rank_file(comm.rank, comm.size), final, comm.rank)
    error = _collective(comm, error)
    try:
        if error:
            raise OutputError(error)
        record = {**meta, "format": FORMAT, "ranks": comm.size, "step": int(step), "functions": list(functions)}
        if history is not None:
            history.flush(folder, comm)
            record["history"] = history.name
        write_json(partial / "meta.json", record, comm)
    except OutputError as exc:
        # e.g. a full disk: leave no half-written step folder behind (the previous checkpoint stays)
        on_rank0(comm, lambda: shutil.rmtree(partial, ignore_errors=True), f"cannot remove {partial}")
        reason = str(exc).rsplit(": ", 1)[-1]
        raise OutputError(f"cannot write checkpoint {final}: {reason}") from None
    on_rank0(comm, lambda: _commit(folder, partial, final, step, keep, history), f"cannot write checkpoint {final}")
    return final


def _write_arrays(functions: Mapping[str, fem.Function], target: Path, final: Path, rank: int) -> str:
    """Write this rank's owned values (with global indices, dof keys and cells) to ``target``; the error or ``""``."""
    try:
        arrays: dict[str, np.ndarray] = {}
        mesh = None
        for name, f in functions.items():
            values, indices = owned_values(f)
            arrays[name] = values
            arrays[f"{name}.global"] = indices
            keys = dof_keys(f.function_space)
            if keys is not None:
                arrays[f"{name}.keys"] = keys
            mesh = f.function_space.mesh
        if mesh is not None:
            arrays["original_cells"] = _original_cells(mesh)
        with open(target, "wb") as fh:
            np.savez(fh, **arrays)  # type: ignore[arg-type]  # numpy stubs: the keywords are array names
    except OSError as exc:
        return f"cannot write checkpoint {final} (rank {rank}): {exc.strerror or exc}"
    return ""


def _commit(folder: Path, partial: Path, final: Path, step: int, keep: int | None, history: History | None) -> None:
    """Move the written ``partial`` folder into place as ``final``, point latest.json at it, drop old ones (rank 0)."""
    old = folder / f"{final.name}.old"
    if final.exists():  # the same step again (e.g. now completed): keep it until the new one is in place
        if old.exists():
            shutil.rmtree(old)
        os.replace(final, old)  # a kill from here to the next line leaves .old, which latest.json's reader takes
    os.replace(partial, final)
    shutil.rmtree(old, ignore_errors=True)
    latest = folder / ".latest.json.partial"
    latest.write_text(json.dumps({"path": final.name, "step": int(step)}) + "\n")
    os.replace(latest, folder / "latest.json")
    if keep is not None:
        done = sorted(p for p in folder.glob("step-*") if p.is_dir() and not p.name.endswith((".partial", ".old")))
        for old in done[: max(0, len(done) - keep)]:
            if old != final:
                shutil.rmtree(old, ignore_errors=True)
    _remove_unused_histories(folder, history)


def _remove_unused_histories(folder: Path, history: History | None) -> None:
    """Remove the history files that no checkpoint in ``folder`` names (rank 0)."""
    used = {history.name} if history is not None else set()
    for meta in folder.glob("step-*/meta.json"):
        try:
            used.add(json.loads(meta.read_text()).get("history"))
        except (OSError, ValueError, AttributeError):
            return  # an unreadable record: keep every history file
    for path in folder.glob("history-*.jsonl"):
        if path.name not in used:
            path.unlink(missing_ok=True)


def resolve_checkpoint(path: str | Path, comm: MPI.Comm, *, action: str = "restart from") -> Path:
    """The step folder ``path`` names: a checkpoint folder (its latest), its latest.json, a step folder, meta.json.

    ``action`` starts the message of a failure (``"cannot <action> <path>: ..."``).

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
            if (path / f"{name}.old" / "meta.json").is_file():  # killed while that step was written again
                return str(path / f"{name}.old")
            raise ValueError(f"{latest} names {name}, which holds no complete checkpoint")
        raise ValueError("no checkpoint there (no meta.json or latest.json)")

    found, error = None, ""
    if comm.rank == 0:
        try:
            found = find()
        except (OSError, ValueError) as exc:
            error = f"cannot {action} {path}: {exc}"
    found, error = comm.bcast((found, error), root=0)
    if error:
        raise CheckpointError(error)
    return Path(found)


def read_meta(path: str | Path, comm: MPI.Comm) -> dict[str, Any]:
    """The ``meta.json`` of the checkpoint at ``path`` (:func:`resolve_checkpoint`), read on rank 0 and broadcast.

    Raises:
        CheckpointError: On every rank, if it is missing, unreadable or of another format.
    """
    folder = resolve_checkpoint(path, comm)
    meta, error = None, ""
    if comm.rank == 0:
        try:
            meta = json.loads((folder / "meta.json").read_text())
            if not isinstance(meta, dict) or meta.get("format") not in READABLE:
                found = meta.get("format") if isinstance(meta, dict) else type(meta).__name__
                error = f"{folder}: not a {FORMAT} checkpoint (format {found!r})"
            else:
                meta = _resolve_history(meta, folder.parent, {})
        except (OSError, ValueError) as exc:
            error = f"{folder}/meta.json cannot be read: {exc}"
    meta, error = comm.bcast((meta, error), root=0)
    if error:
        raise CheckpointError(error)
    meta["path"] = str(folder)
    return meta


def _history_items(path: Path) -> dict[str, list]:
    """Key → items of a history file, in order (an incomplete last line, from a killed run, ends it)."""
    out: dict[str, list] = {}
    with path.open() as fh:
        for line in fh:
            try:
                item = json.loads(line)
            except ValueError:
                break
            out.setdefault(item["k"], []).append(item["v"])
    return out


def _resolve_history(value: Any, folder: Path, files: dict[str, dict[str, list[Any]]]) -> Any:
    """``value`` with every :data:`HISTORY_REF` reference replaced by its items (``files``: those read)."""
    if isinstance(value, list):
        return [_resolve_history(v, folder, files) for v in value]
    if not isinstance(value, dict):
        return value
    if HISTORY_REF not in value:
        return {k: _resolve_history(v, folder, files) for k, v in value.items()}
    name, key, count = value[HISTORY_REF], value["key"], int(value["count"])
    if name not in files:
        try:
            files[name] = _history_items(folder / name)
        except OSError as exc:
            raise ValueError(f"its history {folder / name} cannot be read: {exc.strerror or exc}") from None
    items = files[name].get(key, [])
    if len(items) < count:
        raise ValueError(f"its history {folder / name} holds {len(items)} of the {count} items of {key!r}")
    return items[:count]


def _rank_files(folder: Path, comm: MPI.Comm) -> tuple[list[Path], str]:
    """The complete set of rank files in ``folder`` (rank 0 looks, every rank gets the list), or an error."""
    files, error = [], ""
    if comm.rank == 0:
        found = sorted(folder.glob("rank-*-of-*.npz"))
        sizes = {p.stem.rsplit("-of-", 1)[-1] for p in found}
        if len(sizes) != 1:
            what = "rank files of several runs: " + ", ".join(sorted(sizes)) if found else "no rank files"
            error = f"{folder}: {what}"
        else:
            size = int(sizes.pop())
            files = [folder / _rank_file(r, size) for r in range(size)]
            missing = [p.name for p in files if p not in found]
            if missing:
                error = f"{folder}: incomplete checkpoint (missing {', '.join(missing)})"
    return comm.bcast((files, error), root=0)


def _load(path: Path, names: list[str] | None = None) -> dict[str, np.ndarray]:
    """The arrays ``names`` (those present; all for ``None``) of one rank file."""
    with np.load(path) as data:
        return {k: data[k] for k in (data.files if names is None else names) if k in data.files}


def _by_global_index(
    folder: Path, functions: Mapping[str, fem.Function], stored: dict[str, np.ndarray], comm: MPI.Comm
) -> tuple[list[tuple[fem.Function, np.ndarray]], str]:
    """The values of a file written on this distribution of the mesh, placed by global dof index."""
    name = _rank_file(comm.rank, comm.size)
    updates: list[tuple[fem.Function, np.ndarray]] = []
    for key, f in functions.items():
        if key not in stored or f"{key}.global" not in stored:
            return [], f"{folder}: no field {key!r} in {name} (stored: {', '.join(sorted(stored))})"
        values, indices = stored[key], stored[f"{key}.global"]
        _, current = owned_values(f)
        if np.array_equal(indices, current):
            updates.append((f, values))
            continue
        order, found = np.argsort(indices), np.argsort(current)
        if indices.shape != current.shape or not np.array_equal(indices[order], current[found]):
            return [], (
                f"{folder}: field {key!r} on rank {comm.rank} has {indices.size} stored dofs for "
                f"{current.size} owned ones, or other ones (another space or distribution)"
            )
        placed = np.empty_like(values)
        placed[found] = values[order]
        updates.append((f, placed))
    return updates, ""


def _by_key(
    folder: Path, files: list[Path], functions: Mapping[str, fem.Function], comm: MPI.Comm
) -> tuple[list[tuple[fem.Function, np.ndarray]], str]:
    """The values of a file written on another number of ranks, found by dof key (every rank reads every file)."""
    names = [n for key in functions for n in (key, f"{key}.keys")]
    try:
        parts = [_load(p, names) for p in files]
    except Exception as exc:  # noqa: BLE001 - zipfile.BadZipFile, EOFError, ...: agreed by the caller
        return [], f"{folder}: the rank files cannot be read: {type(exc).__name__}: {exc}"
    updates = []
    for key, f in functions.items():
        if any(key not in part for part in parts):
            return [], f"{folder}: no field {key!r} in the checkpoint"
        if any(f"{key}.keys" not in part for part in parts):
            return [], (
                f"{folder}: field {key!r} was stored without partition-independent dof keys (its element); "
                f"restart it on {len(files)} rank(s)"
            )
        V = f.function_space
        current = dof_keys(V)
        if current is None:
            return [], (
                f"{folder}: field {key!r}: this space has no partition-independent dof keys; "
                f"restart on {len(files)} rank(s)"
            )
        keys = np.concatenate([part[f"{key}.keys"] for part in parts])
        bs = V.dofmap.index_map_bs
        values = np.concatenate([part[key] for part in parts])
        if keys.shape[0] != V.dofmap.index_map.size_global or values.size != keys.shape[0] * bs:
            return [], (
                f"{folder}: field {key!r} has {keys.shape[0]} stored dof blocks of "
                f"{values.size // max(1, keys.shape[0])}, this run {V.dofmap.index_map.size_global} of {bs} "
                "(another space or mesh)"
            )
        _, group = np.unique(np.concatenate([keys, current]), axis=0, return_inverse=True)
        group = group.reshape(-1)
        if np.unique(group[: keys.shape[0]]).size != keys.shape[0]:
            return [], f"{folder}: field {key!r}: the stored dof keys are not unique (a space without keys)"
        row = np.full(group.max() + 1, -1, dtype=np.int64)
        row[group[: keys.shape[0]]] = np.arange(keys.shape[0])
        found = row[group[keys.shape[0] :]]
        if np.any(found < 0):
            return [], (
                f"{folder}: field {key!r}: {int(np.count_nonzero(found < 0))} dofs of rank {comm.rank} are not in the "
                "checkpoint (another mesh)"
            )
        updates.append((f, values.reshape(-1, bs)[found].reshape(-1)))
    return updates, ""


def read_functions(path: str | Path, functions: Mapping[str, fem.Function], comm: MPI.Comm) -> None:
    """Load the stored values into ``functions`` (collective; ghosts updated).

    On the distribution of the mesh that wrote the checkpoint, each rank reads
    its own file and the values are placed by global dof index; on any other
    number of ranks (or distribution), by partition-independent dof key
    (module docstring).

    Args:
        path: The checkpoint (:func:`resolve_checkpoint`).
        functions: Name → function to fill; every name must be in the file.
        comm: Communicator of the functions' mesh.

    Raises:
        CheckpointError: On every rank, if a rank file is missing or
            unreadable, a function is not stored, the stored space or mesh is
            another, or the space has no keys and the distribution differs.
    """
    folder = resolve_checkpoint(path, comm)
    files, error = _rank_files(folder, comm)
    error = _collective(comm, error)
    if error:
        raise CheckpointError(error)
    stored, same = {}, False
    if len(files) == comm.size:
        try:
            stored = _load(folder / _rank_file(comm.rank, comm.size))
        except Exception as exc:  # noqa: BLE001 - a damaged file (BadZipFile, EOFError, ...): agreed below
            error = f"{folder}/{_rank_file(comm.rank, comm.size)} cannot be read: {type(exc).__name__}: {exc}"
        if not error and functions:
            mesh = next(iter(functions.values())).function_space.mesh
            cells = stored.get("original_cells")
            same = cells is not None and np.array_equal(cells, _original_cells(mesh))
    error = _collective(comm, error)
    if error:
        raise CheckpointError(error)
    same = comm.allreduce(bool(same), op=MPI.LAND)
    if same:
        updates, error = _by_global_index(folder, functions, stored, comm)
    else:
        stored = {}
        updates, error = _by_key(folder, files, functions, comm)
    error = _collective(comm, error)
    if error:
        raise CheckpointError(error)
    for f, values in updates:
        f.x.array[: values.size] = values
        f.x.scatter_forward()
