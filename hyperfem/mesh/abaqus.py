"""Abaqus ``.inp`` sets and surfaces for ``hyperfem convert`` (meshio reads no ``*SURFACE``).

meshio reads the nodes, elements, ``*ELSET`` and ``*NSET`` of an input file but
drops the element labels and the ``*SURFACE`` definitions. This module reads
those keywords itself — :func:`read_inp` — and :meth:`InpModel.match` ties its
element labels to meshio's cells (meshio keeps the file order: checked, node by
node, against meshio's connectivity). Then:

* :meth:`InpModel.cell_sets` and :meth:`InpModel.point_sets` give every
  ``*ELSET`` (with ``GENERATE``, names of other sets, ``ELSET=`` of
  ``*ELEMENT``) and ``*NSET`` (with ``GENERATE``, ``NSET=`` of ``*NODE``) in
  meshio's layout;
* :meth:`InpModel.surfaces` turns each ``*SURFACE`` into boundary facets:

  - ``TYPE=ELEMENT`` (the default): each data line is an element label or an
    element-set name, and a face identifier ``S1`` … ``S4`` (Abaqus numbering of
    tetrahedron faces: S1 = nodes 1-2-3, S2 = 1-4-2, S3 = 2-4-3, S4 = 3-4-1).
    Without a face identifier the line means all exposed faces of those
    elements (Abaqus: "all exposed element faces of these elements"): here,
    their faces on the exterior of the mesh. A named face inside the mesh is
    refused: hyperfem boundaries are exterior facets;
  - ``TYPE=NODE``: node labels or node-set names; the exterior faces with all
    three corners among those nodes (as for ``*NSET`` boundaries).

Keywords and parameters are case-insensitive and may contain spaces; ``**``
lines are comments; a keyword line ending in a comma continues on the next
line; set and surface names are matched case-insensitively (as Abaqus does).
``*INCLUDE``, surfaces combined from other surfaces (``COMBINE=``), other
surface types, and assemblies of several part instances are refused with a
specific message. Every error is a :class:`~hyperfem.errors.MeshError`
``FILE:LINE: ...`` naming the offending token.
"""

from __future__ import annotations

from collections.abc import Container
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hyperfem.errors import MeshError

if TYPE_CHECKING:
    import meshio

__all__ = ["FACES", "InpModel", "faces", "has_surfaces", "read_inp"]

FACES = np.array(
    [[0, 1, 2, 4, 5, 6], [0, 3, 1, 7, 8, 4], [1, 3, 2, 8, 9, 5], [2, 3, 0, 9, 7, 6]], dtype=np.int64
)
"""Faces S1..S4 of a tetrahedron (rows), 0-based local nodes: three corners, then for 10-node tetrahedra
(meshio and Abaqus order: corners, then edges 12, 23, 31, 14, 24, 34) the mid-edge nodes of edges
corner0-corner1, corner1-corner2, corner2-corner0 (the order of a 6-node triangle)."""


def faces(cells: np.ndarray) -> np.ndarray:
    """All faces of the tetrahedra ``cells`` (n × 4 or n × 10): array (4, n, 3 or 6), faces S1..S4."""
    width = 3 if cells.shape[1] == 4 else 6
    return np.stack([cells[:, FACES[k, :width]] for k in range(4)])


@dataclass
class _Keyword:
    name: str  # upper case, single spaces: "ELSET", "END PART"
    params: dict[str, str | None]  # upper-case keys; values as written, unquoted
    line: int
    data: list[tuple[int, list[str]]] = field(default_factory=list)  # (line, non-empty tokens)


@dataclass
class _Set:
    name: str  # as first written
    line: int
    items: list[tuple[int, str]] = field(default_factory=list)  # (line, token): label or set name
    ranges: list[tuple[int, int, int, int]] = field(default_factory=list)  # (line, first, last, step)
    blocks: list[int] = field(default_factory=list)  # *ELEMENT blocks with ELSET= this set
    internal: bool = False


@dataclass
class _Block:
    line: int
    labels: np.ndarray  # element labels
    nodes: np.ndarray  # node labels (n × k)


@dataclass
class _Surface:
    name: str
    kind: str  # "ELEMENT" or "NODE"
    line: int
    items: list[tuple[int, str, str | None]]  # (line, element/node or set, face identifier)


def _split_keyword(text: str, line: int) -> _Keyword:
    parts = text.lstrip()[1:].split(",")
    name = " ".join(parts[0].split()).upper()
    params: dict[str, str | None] = {}
    for part in parts[1:]:
        if not part.strip():
            continue
        key, eq, value = part.partition("=")
        key = " ".join(key.split()).upper()
        params[key] = value.strip().strip('"').strip() if eq else None
    return _Keyword(name, params, line)


def _keywords(path: Path) -> list[_Keyword]:
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError as exc:
        raise MeshError(f"{path}: cannot read: {exc.strerror or exc}") from None
    out: list[_Keyword] = []
    pending: tuple[int, str] | None = None  # a keyword line ending in a comma
    for number, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text or text.startswith("**"):
            continue
        if pending is not None:
            start, head = pending
            head += text
            pending = (start, head) if head.endswith(",") else None
            if pending is None:
                out.append(_split_keyword(head, start))
            continue
        if text.startswith("*"):
            if text.endswith(","):
                pending = (number, text)
            else:
                out.append(_split_keyword(text, number))
        elif out:
            out[-1].data.append((number, [t.strip() for t in text.split(",") if t.strip()]))
    if pending is not None:
        out.append(_split_keyword(pending[1], pending[0]))
    return out


def has_surfaces(path: str | Path) -> bool:
    """Whether the input file has a ``*SURFACE`` keyword (not ``*SURFACE INTERACTION`` and the like)."""
    return any(k.name == "SURFACE" for k in _keywords(Path(path)))


def _int(token: str, line: int, path: Path, what: str) -> int:
    try:
        return int(token)
    except ValueError:
        try:
            value = float(token)
        except ValueError:
            value = None
        if value is None or not value.is_integer():
            raise MeshError(f"{path}:{line}: {what}: {token!r} is not an integer") from None
        return int(value)


@dataclass
class InpModel:
    """The labels, sets and surfaces of an Abaqus input file (see :func:`read_inp`).

    Attributes:
        path: The input file.
        node_labels: Node labels in file order (meshio's point order).
        blocks: One per ``*ELEMENT`` keyword, in file order (meshio's cell blocks).
        elsets: Element sets by upper-case name.
        nsets: Node sets by upper-case name.
        surface_defs: The ``*SURFACE`` definitions, in file order.
        instance: The upper-case name of the only part instance, if any.
    """

    path: Path
    node_labels: np.ndarray
    blocks: list[_Block]
    elsets: dict[str, _Set]
    nsets: dict[str, _Set]
    surface_defs: list[_Surface]
    instance: str | None = None
    _element_at: dict[int, tuple[int, int]] = field(default_factory=dict)  # label → (block, row)
    _node_at: dict[int, int] = field(default_factory=dict)  # label → point index

    # -- ties to meshio ---------------------------------------------------------------------------
    def match(self, mesh: meshio.Mesh) -> None:
        """Check that meshio read the same nodes and elements in the same order; index the labels.

        Raises:
            MeshError: meshio's points or cells differ from the file's ``*NODE`` and ``*ELEMENT`` lines.
        """
        path = self.path
        if len(self.node_labels) != len(mesh.points):
            raise MeshError(
                f"{path}: meshio read {len(mesh.points)} nodes, the *NODE lines define {len(self.node_labels)}; "
                "cannot tie the surfaces to the mesh (several *NODE blocks, or nodes outside the part?)"
            )
        self._node_at = {int(label): i for i, label in enumerate(self.node_labels)}
        if len(self._node_at) != len(self.node_labels):
            raise MeshError(f"{path}: node labels repeat; cannot tie the surfaces to the mesh")
        if len(self.blocks) != len(mesh.cells):
            raise MeshError(
                f"{path}: meshio read {len(mesh.cells)} element blocks, the file has {len(self.blocks)} *ELEMENT "
                "keywords; cannot tie the surfaces to the mesh"
            )
        order = np.argsort(self.node_labels, kind="stable")
        sorted_labels = self.node_labels[order]
        self._element_at = {}
        for b, (block, cells) in enumerate(zip(self.blocks, mesh.cells, strict=True)):
            data = np.asarray(cells.data)
            flat = block.nodes.reshape(-1)
            if flat.size % (data.shape[1] + 1) or flat.size // (data.shape[1] + 1) != len(data):
                raise MeshError(f"{path}:{block.line}: *ELEMENT: the element lines do not match meshio's cells")
            table = flat.reshape(len(data), data.shape[1] + 1)
            block.labels, block.nodes = table[:, 0].copy(), table[:, 1:].copy()
            where = np.minimum(np.searchsorted(sorted_labels, block.nodes), max(len(sorted_labels) - 1, 0))
            unknown = sorted_labels[where] != block.nodes if len(sorted_labels) else np.ones(block.nodes.shape, bool)
            if unknown.any():
                raise MeshError(f"{path}:{block.line}: *ELEMENT: no node {int(block.nodes[unknown][0])} in the file")
            indices = order[where]
            if indices.size and not np.array_equal(indices, data):
                raise MeshError(
                    f"{path}:{block.line}: *ELEMENT: meshio's cells differ from the element lines; "
                    "cannot tie the surfaces to the mesh"
                )
            for row, label in enumerate(block.labels):
                if int(label) in self._element_at:
                    raise MeshError(f"{path}:{block.line}: element label {int(label)} defined twice")
                self._element_at[int(label)] = (b, row)

    # -- sets -------------------------------------------------------------------------------------
    def _strip(self, token: str) -> str:
        head, dot, tail = token.rpartition(".")
        if dot and self.instance is not None and head.upper() == self.instance:
            return tail
        return token

    def _members(
        self, sets: dict[str, _Set], name: str, kind: str, known: Container[int], seen: tuple[str, ...] = ()
    ) -> list[int]:
        """Labels of set ``name`` (upper case), sets named in it expanded; unknown labels refused."""
        entry = sets[name]
        keyword = "*ELSET" if kind == "element" else "*NSET"
        out: list[int] = [int(label) for b in entry.blocks for label in self.blocks[b].labels]
        for line, first, last, step in entry.ranges:
            out.extend(range(first, last + 1, step))
            missing = next((n for n in range(first, last + 1, step) if n not in known), None)
            if missing is not None:
                raise MeshError(f"{self.path}:{line}: {keyword} {entry.name}: no {kind} {missing} in the file")
        for line, raw in entry.items:
            token = self._strip(raw)
            if token.lstrip("-").isdigit():
                if int(token) not in known:
                    raise MeshError(f"{self.path}:{line}: {keyword} {entry.name}: no {kind} {token} in the file")
                out.append(int(token))
            elif token.upper() in sets and token.upper() not in (*seen, name):
                out.extend(self._members(sets, token.upper(), kind, known, (*seen, name)))
            else:
                raise MeshError(f"{self.path}:{line}: {keyword} {entry.name}: no {kind} set {raw!r}")
        return out

    def cell_sets(self) -> dict[str, list[np.ndarray]]:
        """Element sets in meshio's layout: name → one array of cell indices per element block."""
        out = {}
        for key, entry in self.elsets.items():
            per_block: list[list[int]] = [[] for _ in self.blocks]
            for label in dict.fromkeys(self._members(self.elsets, key, "element", self._element_at)):
                b, row = self._element_at[label]
                per_block[b].append(row)
            out[entry.name] = [np.array(rows, dtype=np.int64) for rows in per_block]
        return out

    def point_sets(self) -> dict[str, np.ndarray]:
        """Node sets: name → point indices."""
        out = {}
        for key, entry in self.nsets.items():
            labels = dict.fromkeys(self._members(self.nsets, key, "node", self._node_at))
            out[entry.name] = np.array([self._node_at[n] for n in labels], dtype=np.int64)
        return out

    def surface_sets(self) -> set[str]:
        """Names (as written) of the element sets a surface names, and of the sets marked ``INTERNAL``."""
        out = {entry.name for entry in self.elsets.values() if entry.internal}
        for surface in self.surface_defs:
            if surface.kind == "ELEMENT":
                for _, raw, _ in surface.items:
                    entry = self.elsets.get(self._strip(raw).upper())
                    if entry is not None:
                        out.add(entry.name)
        return out

    def surface_node_sets(self) -> set[str]:
        """Names (as written) of the node sets a ``TYPE=NODE`` surface names."""
        out = set()
        for surface in self.surface_defs:
            if surface.kind == "NODE":
                for _, raw, _ in surface.items:
                    entry = self.nsets.get(self._strip(raw).upper())
                    if entry is not None:
                        out.add(entry.name)
        return out

    # -- surfaces ---------------------------------------------------------------------------------
    def surfaces(self, cells: np.ndarray, volume: list[int], cell_types: list[str]) -> dict[str, np.ndarray]:
        """The facets of every surface: name → rows of 3 (4-node) or 6 (10-node tetrahedra) point indices.

        Args:
            cells: The tetrahedra of blocks ``volume``, concatenated (as convert builds them).
            volume: Indices of the tetrahedron blocks.
            cell_types: meshio's type of every block (for messages).

        Raises:
            MeshError: An unknown element, node or set; a face identifier other than S1..S4; an element
                that is not a tetrahedron; a face inside the mesh; a surface without exterior faces.
        """
        starts = np.cumsum([0] + [len(self.blocks[b].labels) for b in volume])
        offsets = {b: int(start) for b, start in zip(volume, starts, strict=False)}  # starts has one more
        all_faces = faces(cells)  # (4, n, w)
        keys = np.sort(all_faces[:, :, :3].reshape(-1, 3), axis=1)
        _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
        inverse = inverse.reshape(4, len(cells))
        exterior = counts[inverse] == 1  # (4, n)
        out: dict[str, np.ndarray] = {}
        for surface in self.surface_defs:
            if surface.name in out:
                raise MeshError(f"{self.path}:{surface.line}: *SURFACE {surface.name} is defined twice")
            chosen = np.zeros((4, len(cells)), dtype=bool)
            if surface.kind == "NODE":
                points = np.zeros(len(self.node_labels), dtype=bool)
                for line, raw, _ in surface.items:
                    points[self._node_list(surface, line, raw)] = True
                chosen = exterior & points[all_faces[:, :, :3]].all(axis=2)
            else:
                for line, raw, face in surface.items:
                    rows = self._element_rows(surface, line, raw, offsets, cell_types)
                    if face is None:
                        chosen[:, rows] |= exterior[:, rows]
                        continue
                    k = self._face_index(surface, line, face)
                    inside = rows[~exterior[k, rows]]
                    if inside.size:
                        self._refuse_interior(surface, line, k, int(inside[0]), inverse, offsets)
                    chosen[k, rows] = True
            if not chosen.any():
                raise MeshError(
                    f"{self.path}:{surface.line}: *SURFACE {surface.name}: no face on the exterior of the mesh"
                )
            out[surface.name] = all_faces[chosen]
        return out

    def _node_list(self, surface: _Surface, line: int, raw: str) -> list[int]:
        token = self._strip(raw)
        if token.lstrip("-").isdigit():
            if int(token) not in self._node_at:
                raise MeshError(f"{self.path}:{line}: *SURFACE {surface.name}: no node {token} in the file")
            return [self._node_at[int(token)]]
        if token.upper() not in self.nsets:
            raise MeshError(f"{self.path}:{line}: *SURFACE {surface.name}: no node set {raw!r}")
        return [self._node_at[n] for n in self._members(self.nsets, token.upper(), "node", self._node_at)]

    def _element_rows(
        self, surface: _Surface, line: int, raw: str, offsets: dict[int, int], cell_types: list[str]
    ) -> np.ndarray:
        token = self._strip(raw)
        if token.lstrip("-").isdigit():
            if int(token) not in self._element_at:
                raise MeshError(f"{self.path}:{line}: *SURFACE {surface.name}: no element {token} in the file")
            labels = [int(token)]
        elif token.upper() in self.elsets:
            labels = self._members(self.elsets, token.upper(), "element", self._element_at)
        else:
            raise MeshError(f"{self.path}:{line}: *SURFACE {surface.name}: no element set {raw!r}")
        rows = []
        for label in labels:
            b, row = self._element_at[label]
            if b not in offsets:
                raise MeshError(
                    f"{self.path}:{line}: *SURFACE {surface.name}: element {label} is a {cell_types[b]} cell, "
                    "not a tetrahedron"
                )
            rows.append(offsets[b] + row)
        return np.array(rows, dtype=np.int64)

    def _face_index(self, surface: _Surface, line: int, face: str) -> int:
        label = face.upper()
        if label not in ("S1", "S2", "S3", "S4"):
            raise MeshError(
                f"{self.path}:{line}: *SURFACE {surface.name}: {face!r} is not a face of a tetrahedron "
                "(S1, S2, S3 or S4)"
            )
        return int(label[1]) - 1

    def _refuse_interior(
        self, surface: _Surface, line: int, k: int, row: int, inverse: np.ndarray, offsets: dict[int, int]
    ) -> None:
        label = self._label_of(row, offsets)
        others = np.flatnonzero((inverse == inverse[k, row]).any(axis=0))
        other = next((self._label_of(int(r), offsets) for r in others if r != row), None)
        raise MeshError(
            f"{self.path}:{line}: *SURFACE {surface.name}: face S{k + 1} of element {label} is inside the mesh "
            f"(shared with element {other}); a boundary must lie on the exterior"
        )

    def _label_of(self, row: int, offsets: dict[int, int]) -> int:
        block = max((b for b, start in offsets.items() if start <= row), key=lambda b: offsets[b])
        return int(self.blocks[block].labels[row - offsets[block]])


def _add_set(sets: dict[str, _Set], keyword: _Keyword, param: str, path: Path) -> _Set | None:
    name = keyword.params.get(param)
    if not name:
        raise MeshError(f"{path}:{keyword.line}: *{keyword.name} without {param}=")
    entry = sets.setdefault(name.upper(), _Set(name, keyword.line))
    entry.internal = entry.internal or "INTERNAL" in keyword.params
    what = f"*{keyword.name} {name}"
    for line, tokens in keyword.data:
        if "GENERATE" in keyword.params:
            if len(tokens) not in (2, 3):
                raise MeshError(f"{path}:{line}: {what}, GENERATE: expected 'first, last[, increment]'")
            first, last, *rest = (_int(t, line, path, f"{what}, GENERATE") for t in tokens)
            step = rest[0] if rest else 1
            if step < 1 or last < first:
                raise MeshError(f"{path}:{line}: {what}, GENERATE: needs first <= last and increment >= 1")
            entry.ranges.append((line, first, last, step))
        else:
            entry.items.extend((line, t) for t in tokens)
    return entry


def read_inp(path: str | Path) -> InpModel:
    """Read the labels, sets and surfaces of an Abaqus input file (call :meth:`InpModel.match` next).

    Raises:
        MeshError: ``*INCLUDE``; several parts or part instances; a ``*SURFACE`` without ``NAME``, with
            ``COMBINE``, of another ``TYPE``, or with more than two entries on a line; a set without name;
            a bad ``GENERATE`` line; a label that is not an integer.
    """
    path = Path(path)
    node_labels: list[int] = []
    blocks: list[_Block] = []
    elsets: dict[str, _Set] = {}
    nsets: dict[str, _Set] = {}
    surfaces: list[_Surface] = []
    parts, instances = [], []
    for keyword in _keywords(path):
        name = keyword.name
        if name == "INCLUDE":
            raise MeshError(
                f"{path}:{keyword.line}: *INCLUDE is not supported in a file with *SURFACE: "
                "paste the included file in its place"
            )
        if name == "PART":
            parts.append(keyword)
        elif name == "INSTANCE":
            instances.append(keyword)
        elif name == "NODE":
            labels = [_int(tokens[0], line, path, "*NODE") for line, tokens in keyword.data if tokens]
            if nset := keyword.params.get("NSET"):
                entry = nsets.setdefault(nset.upper(), _Set(nset, keyword.line))
                entry.items.extend((line, tokens[0]) for line, tokens in keyword.data if tokens)
            node_labels.extend(labels)
        elif name == "ELEMENT":
            tokens = [(line, t) for line, ts in keyword.data for t in ts]
            values = np.array([_int(t, line, path, "*ELEMENT") for line, t in tokens], dtype=np.int64)
            blocks.append(_Block(keyword.line, np.zeros(0, np.int64), values))
            if elset := keyword.params.get("ELSET"):
                entry = elsets.setdefault(elset.upper(), _Set(elset, keyword.line))
                entry.blocks.append(len(blocks) - 1)
        elif name == "ELSET":
            _add_set(elsets, keyword, "ELSET", path)
        elif name == "NSET":
            _add_set(nsets, keyword, "NSET", path)
        elif name == "SURFACE":
            surfaces.append(_surface(keyword, path))
    if len(parts) > 1 or len(instances) > 1:
        where = (parts[1] if len(parts) > 1 else instances[1]).line
        raise MeshError(
            f"{path}:{where}: *SURFACE in a file of several parts or part instances is not supported: "
            "write the input file without parts and assemblies (one flat model)"
        )
    instance = instances[0].params.get("NAME") if instances else None
    return InpModel(
        path, np.array(node_labels, dtype=np.int64), blocks, elsets, nsets, surfaces,
        instance.upper() if instance else None,
    )


def _surface(keyword: _Keyword, path: Path) -> _Surface:
    name = keyword.params.get("NAME")
    if not name:
        raise MeshError(f"{path}:{keyword.line}: *SURFACE without NAME=")
    if "COMBINE" in keyword.params:
        raise MeshError(f"{path}:{keyword.line}: *SURFACE {name}: COMBINE (surfaces from surfaces) is not supported")
    kind = " ".join((keyword.params.get("TYPE") or "ELEMENT").split()).upper()
    if kind not in ("ELEMENT", "NODE"):
        raise MeshError(f"{path}:{keyword.line}: *SURFACE {name}: TYPE={kind} is not supported (ELEMENT or NODE)")
    items = []
    for line, tokens in keyword.data:
        if kind == "ELEMENT" and len(tokens) > 2:
            raise MeshError(
                f"{path}:{line}: *SURFACE {name}: expected 'element or element set[, face]', got {len(tokens)} entries"
            )
        if tokens:
            items.append((line, tokens[0], tokens[1] if kind == "ELEMENT" and len(tokens) == 2 else None))
    return _Surface(name, kind, keyword.line, items)
