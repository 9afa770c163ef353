"""``hyperfem convert``: tetrahedral meshes of other formats (via meshio) to the gmsh file hyperfem reads.

Any format meshio reads (``.vtu``, ``.inp``, ``.mesh``, ``.msh``, ``.xdmf``, ...)
goes in; a gmsh 2.2 ASCII ``.msh`` comes out, with one physical group per
region (tetrahedra, dimension 3) and per boundary (triangles, dimension 2),
which :func:`hyperfem.read_mesh` reads back (checked before returning).

Where the groups come from, in this order:

1. an integer cell-data array — ``--tags NAME``, else ``gmsh:physical``,
   ``medit:ref`` or ``CellEntityIds`` — on the tetrahedra (regions) and the
   triangles (boundaries); names from ``names`` (``--names 1=beam,2=clamped``),
   else from the file's field data (gmsh), else ``region_<tag>`` /
   ``boundary_<tag>`` (the notes list the tags left without a name);
2. else the file's cell sets (Abaqus ``*ELSET``; sets of tetrahedra become
   regions, sets of triangles boundaries) and point sets (``*NSET``: the
   exterior faces whose three corners are all in the set become a boundary);
3. else the whole volume is region ``domain`` and its exterior faces boundary ``boundary``.

Abaqus ``*SURFACE`` definitions (which meshio drops) are read by
:mod:`hyperfem.mesh.abaqus` and become boundaries of their name (6-node
triangles for C3D10): ``TYPE=ELEMENT`` by element label or element set and
face ``S1`` … ``S4`` (without a face: the element's exterior faces),
``TYPE=NODE`` by nodes or node sets. In a file with surfaces the sets are read
by that module too (element labels matched to meshio's cells), an element set
that defines a surface (or is marked ``INTERNAL``) is a region only where it
overlaps no other region (regions first, then such sets from the largest
down), and a surface face inside the mesh, an unknown element, set or face
identifier, and ``*INCLUDE`` are refused (``FILE:LINE: ...``).

Each face has one boundary (hyperfem tags a facet once): surfaces that share
faces are refused; a node-set boundary that shares faces with another boundary
is dropped with a warning (smaller node sets kept first).

Tetrahedra in no region go to region ``unassigned`` (with a warning). Tags are
renumbered 1, 2, ... per dimension (gmsh physical tags must be positive).
Refused with a specific message: a file without tetrahedra (a surface mesh),
mixed volume cells (tetrahedra with hexahedra, wedges, pyramids), other
volume cells, linear and quadratic cells together, overlapping cell sets,
degenerate tetrahedra, and inverted (negatively oriented) tetrahedra unless
``reorient=True`` (:mod:`hyperfem.mesh.orientation`).
"""

from __future__ import annotations

import re
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hyperfem.mesh.abaqus import InpModel, faces, has_surfaces, read_inp
from hyperfem.mesh.orientation import orientation
from hyperfem.errors import MeshError, MeshFileNotFoundError, ParameterError

if TYPE_CHECKING:
    import meshio

__all__ = ["NAMED_DIMS", "TAG_ARRAYS", "Conversion", "convert", "describe_msh", "parse_names"]

TAG_ARRAYS = ("gmsh:physical", "medit:ref", "CellEntityIds")
"""Cell-data arrays read as group tags when ``--tags`` is not given."""

VOLUME = {"tetra": 4, "tetra10": 10}
FACET = {"tetra": "triangle", "tetra10": "triangle6"}
IGNORED = ("vertex", "line", "line3")
OTHER_VOLUME = ("hexahedron", "hexahedron20", "hexahedron27", "wedge", "wedge15", "pyramid", "pyramid13")
# tetra10 in meshio (VTK) order: vertices 0-3, then edges 01, 12, 02, 03, 13, 23; swapping 0 and 1 swaps 12/02, 03/13.
_SWAP = {4: [1, 0, 2, 3], 10: [1, 0, 2, 3, 4, 6, 5, 8, 7, 9]}


@dataclass
class Conversion:
    """What :func:`convert` wrote.

    Attributes:
        path: The ``.msh`` file.
        cell_type: ``"tetra"`` or ``"tetra10"``.
        cells: Number of tetrahedra.
        nodes: Number of nodes.
        regions: Region name → number of cells.
        boundaries: Boundary name → number of facets.
        reoriented: Inverted tetrahedra whose vertex order was fixed.
        notes: Where the groups came from.
        warnings: Ignored cells, tetrahedra in no region, reoriented cells.
    """

    path: Path
    cell_type: str
    cells: int
    nodes: int
    regions: dict[str, int] = field(default_factory=dict)
    boundaries: dict[str, int] = field(default_factory=dict)
    reoriented: int = 0
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def summary(self) -> str:
        """One line: counts and groups."""
        regions = ", ".join(f"{k} ({v})" for k, v in self.regions.items())
        boundaries = ", ".join(f"{k} ({v})" for k, v in self.boundaries.items()) or "none"
        return (
            f"wrote {self.path}: {self.cells} {self.cell_type} cells, {self.nodes} nodes; "
            f"regions: {regions}; boundaries: {boundaries}"
        )


_HYBRID_TET = re.compile(r"(?im)^\s*\*\s*ELEMENT\b[^\n]*?\bTYPE\s*=\s*C3D4H\b")


def _read(path: Path, notes: list[str] | None = None) -> meshio.Mesh:
    """The meshio mesh of ``path``; Abaqus C3D4H (hybrid) tetrahedra are read as C3D4, with a note."""
    import meshio

    try:
        if path.suffix.lower() == ".inp" and _HYBRID_TET.search(path.read_text(errors="replace")):
            # meshio 5.3 maps C3D4H to a cell type it does not know ("tetra4"). The nodes are those of C3D4;
            # "hybrid" is Abaqus's u-p formulation, a solver choice (formulation = "mixed" here), not geometry.
            from meshio.abaqus import _abaqus

            table = _abaqus.abaqus_to_meshio_type
            saved = table.get("C3D4H")
            table["C3D4H"] = "tetra"
            try:
                mesh = meshio.read(path)
            finally:
                if saved is None:
                    table.pop("C3D4H", None)
                else:
                    table["C3D4H"] = saved
            if notes is not None:
                notes.append('C3D4H (hybrid) tetrahedra read as C3D4; use formulation = "mixed" for near '
                             "incompressibility")
            return mesh
        return meshio.read(path)
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - meshio raises many types, and may call sys.exit
        reason = (str(exc).splitlines() or [type(exc).__name__])[0] if str(exc) else type(exc).__name__
        raise MeshError(f"{path}: meshio cannot read it: {reason}") from None


def _blocks(mesh: meshio.Mesh, path: Path) -> tuple[str, list[int], list[int], list[str]]:
    """The tetrahedron type, indices of volume and facet blocks, and notes on ignored cells."""
    types = [block.type for block in mesh.cells]
    counts: dict[str, int] = {}
    for block in mesh.cells:
        counts[block.type] = counts.get(block.type, 0) + len(block.data)
    tets = [t for t in VOLUME if t in counts]
    others = [t for t in counts if t in OTHER_VOLUME or (t not in VOLUME and t not in IGNORED and _dim(t) == 3)]
    listing = ", ".join(f"{counts[t]} {t}" for t in counts)
    if not tets:
        if others:
            raise MeshError(
                f"{path}: unsupported cell type {others[0]} ({listing}); hyperfem solves on tetrahedra: "
                "remesh with tetrahedra (e.g. gmsh -3)"
            )
        raise MeshError(f"{path}: no tetrahedra ({listing or 'no cells'}); convert imports volume meshes of tetrahedra")
    if others:
        raise MeshError(
            f"{path}: mixed cell types ({listing}); hyperfem needs a purely tetrahedral mesh: "
            "split the other cells into tetrahedra or remesh with tetrahedra"
        )
    if len(tets) > 1:
        raise MeshError(f"{path}: linear and quadratic tetrahedra together ({listing}); use one order")
    tet = tets[0]
    facet = FACET[tet]
    cautions = []
    wrong_facets = [t for t in counts if _dim(t) == 2 and t != facet]
    if wrong_facets:
        ignored = ", ".join(f"{counts[t]} {t}" for t in wrong_facets)
        cautions.append(f"ignored {ignored} cells (not faces of {tet} cells)")
    volume = [i for i, t in enumerate(types) if t == tet]
    facets = [i for i, t in enumerate(types) if t == facet]
    return tet, volume, facets, cautions


def _dim(cell_type: str) -> int:
    if cell_type.startswith(("vertex",)):
        return 0
    if cell_type.startswith("line"):
        return 1
    if cell_type.startswith(("triangle", "quad", "polygon")):
        return 2
    return 3


def _tag_array(mesh: meshio.Mesh, tags: str | None, path: Path) -> str | None:
    if tags is not None:
        if tags not in mesh.cell_data:
            available = ", ".join(mesh.cell_data) or "none"
            raise MeshError(f"{path}: no cell-data array {tags!r} (available: {available})")
        return tags
    return next((name for name in TAG_ARRAYS if name in mesh.cell_data), None)


def _names_from_field_data(mesh: meshio.Mesh) -> dict[tuple[int, int], str]:
    """(dim, tag) → name from gmsh field data."""
    out: dict[tuple[int, int], str] = {}
    for name, value in mesh.field_data.items():
        value = np.asarray(value).reshape(-1)
        if value.size >= 2:
            out[(int(value[1]), int(value[0]))] = name
    return out


def _exterior_facets(cells: np.ndarray) -> np.ndarray:
    """Faces that belong to one tetrahedron only: rows of 3 (tetra) or 6 (tetra10: with mid-edge) nodes."""
    every = faces(cells).reshape(-1, 3 if cells.shape[1] == 4 else 6)
    keys = np.sort(every[:, :3], axis=1)
    _, index, counts = np.unique(keys, axis=0, return_index=True, return_counts=True)
    return every[index[counts == 1]]


NAMED_DIMS = {"region": 3, "boundary": 2}
"""Prefixes of ``--names`` entries that name one dimension (``region:1=muscle``)."""


def parse_names(text: str | None) -> dict[tuple[int | None, int], str]:
    """``"1=beam,boundary:2=clamped"`` → ``{(None, 1): "beam", (2, 2): "clamped"}`` (dimension ``None``: any).

    Raises:
        ParameterError: An entry is not ``TAG=NAME`` / ``region:TAG=NAME`` / ``boundary:TAG=NAME``.
    """
    out: dict[tuple[int | None, int], str] = {}
    if not text:
        return out
    for entry in (e.strip() for e in text.split(",")):
        key, sep, value = entry.partition("=")
        kind, colon, tag = key.strip().rpartition(":")
        dim = NAMED_DIMS.get(kind.strip()) if colon else None
        if not sep or not value.strip() or not re.fullmatch(r"-?\d+", tag.strip()) or (colon and dim is None):
            raise ParameterError(
                f"convert --names: {entry!r} is not TAG=NAME (or region:TAG=NAME, boundary:TAG=NAME), e.g. "
                "--names 1=beam,2=clamped"
            )
        out[(dim, int(tag))] = value.strip()
    return out


def _group_name(kind: str, dim: int, tag: int, file_names: Mapping, given: Mapping, unnamed: list[str]) -> str:
    """The name of tag ``tag`` of dimension ``dim``: ``--names``, else the file's field data, else ``kind_tag``."""
    for key in ((dim, tag), (None, tag)):
        if key in given:
            return given[key]
    if (dim, tag) in file_names:
        return file_names[(dim, tag)]
    unnamed.append(f"{kind} {tag}")
    return f"{kind}_{tag}"


def _groups_from_array(
    mesh: meshio.Mesh,
    name: str,
    volume: list[int],
    facets: list[int],
    tet: str,
    path: Path,
    names: Mapping[tuple[int | None, int], str] | None = None,
    unnamed: list[str] | None = None,
) -> tuple[dict[str, np.ndarray], np.ndarray, dict[str, np.ndarray]]:
    field_names = _names_from_field_data(mesh)
    given = names or {}
    unnamed = [] if unnamed is None else unnamed
    data = mesh.cell_data[name]
    for i in (*volume, *facets):
        if not np.issubdtype(np.asarray(data[i]).dtype, np.integer):
            raise MeshError(f"{path}: cell-data array {name!r} is not integer (got {np.asarray(data[i]).dtype})")
    cell_tags = np.concatenate([np.asarray(data[i]).reshape(-1) for i in volume])
    facet_cells = [mesh.cells[i].data for i in facets]
    facet_tags = np.concatenate([np.asarray(data[i]).reshape(-1) for i in facets]) if facets else np.zeros(0, int)
    facet_data = np.concatenate(facet_cells) if facet_cells else np.zeros((0, 3 if tet == "tetra" else 6), int)
    unassigned = cell_tags <= 0 if name == "gmsh:physical" else np.zeros(len(cell_tags), dtype=bool)
    region_tags = [int(v) for v in np.unique(cell_tags[~unassigned])]
    keep = facet_tags > 0 if name == "gmsh:physical" else np.ones(len(facet_tags), dtype=bool)
    boundary_tags = [int(v) for v in np.unique(facet_tags[keep])]
    _check_named_tags(given, region_tags, boundary_tags, path)
    regions: dict[str, np.ndarray] = {}
    boundaries: dict[str, np.ndarray] = {}
    for groups, kind, dim, found in ((regions, "region", 3, region_tags), (boundaries, "boundary", 2, boundary_tags)):
        for value in found:
            group = _group_name(kind, dim, value, field_names, given, unnamed)
            if group in groups:
                raise ParameterError(f"convert --names: two {kind} tags are named {group!r}; give each its own name")
            groups[group] = (cell_tags if dim == 3 else facet_tags) == value
    boundaries = {k: facet_data[v] for k, v in boundaries.items()}
    return regions, unassigned, boundaries


def _check_named_tags(given: Mapping, region_tags: list[int], boundary_tags: list[int], path: Path) -> None:
    """Refuse ``--names`` entries for tags the file does not have."""
    present = {3: set(region_tags), 2: set(boundary_tags)}
    for dim, tag in given:
        found = tag in present[dim] if dim is not None else tag in present[3] | present[2]
        if not found:
            where = {None: "no region or boundary", 3: "no region", 2: "no boundary"}[dim]
            raise ParameterError(
                f"convert --names: {path} has {where} with tag {tag} (region tags: "
                f"{', '.join(map(str, region_tags)) or 'none'}; boundary tags: "
                f"{', '.join(map(str, boundary_tags)) or 'none'})"
            )


def _groups_from_sets(
    mesh: meshio.Mesh,
    volume: list[int],
    facets: list[int],
    cells: np.ndarray,
    path: Path,
    helpers: Collection[str] = frozenset(),
) -> tuple[dict[str, np.ndarray], np.ndarray, dict[str, np.ndarray], list[str], list[str]]:
    """Regions, unassigned cells, boundaries, the ``helpers`` left out of the regions, the node-set boundaries.

    ``helpers`` (sets that define Abaqus surfaces) are regions only where they overlap no other region: the
    other sets first, then the helpers from the largest down (instead of the overlap error).
    """
    offsets = np.cumsum([0] + [len(mesh.cells[i].data) for i in volume])
    regions: dict[str, np.ndarray] = {}
    boundaries: dict[str, np.ndarray] = {}
    for name, per_block in mesh.cell_sets.items():
        if name.startswith("gmsh:"):
            continue
        mask = np.zeros(len(cells), dtype=bool)
        chosen = []
        for k, i in enumerate(volume):
            if i < len(per_block) and per_block[i] is not None and len(per_block[i]):
                mask[offsets[k] + np.asarray(per_block[i], dtype=int)] = True
        for i in facets:
            if i < len(per_block) and per_block[i] is not None and len(per_block[i]):
                chosen.append(mesh.cells[i].data[np.asarray(per_block[i], dtype=int)])
        if mask.any():
            regions[name] = mask
        if chosen:
            boundaries[name] = np.concatenate(chosen)
    kept = [name for name in regions if name not in helpers]
    dropped = []
    for name in sorted((h for h in regions if h in helpers), key=lambda h: -int(regions[h].sum())):
        if any(np.any(regions[name] & regions[k]) for k in kept):
            dropped.append(name)
        else:
            kept.append(name)
    regions = {name: mask for name, mask in regions.items() if name not in dropped}
    names = list(regions)
    for a in range(len(names)):
        for b in range(a):
            if np.any(regions[names[a]] & regions[names[b]]):
                raise MeshError(
                    f"{path}: cell sets {names[b]!r} and {names[a]!r} overlap; each tetrahedron needs one region "
                    "(remove one of the sets, or pass --tags with a cell-data array)"
                )
    from_nodes = []
    if mesh.point_sets:
        exterior = _exterior_facets(cells)
        for name, points in mesh.point_sets.items():
            inside = np.zeros(len(mesh.points), dtype=bool)
            inside[np.asarray(points, dtype=int)] = True
            chosen = exterior[inside[exterior[:, :3]].all(axis=1)]
            if len(chosen) and name not in boundaries:
                boundaries[name] = chosen
                from_nodes.append(name)
    covered = np.zeros(len(cells), dtype=bool)
    for mask in regions.values():
        covered |= mask
    return regions, ~covered, boundaries, dropped, from_nodes


def _face_keys(facets: np.ndarray) -> np.ndarray:
    """One comparable value per facet: its sorted corners."""
    keys = np.ascontiguousarray(np.sort(np.asarray(facets, dtype=np.int64)[:, :3], axis=1))
    return keys.view(np.dtype((np.void, 24))).reshape(-1)


def _one_boundary_per_face(
    boundaries: dict[str, np.ndarray],
    from_nodes: list[str],
    strict: bool,
    path: Path,
    cautions: list[str],
    notes: list[str],
    helpers: Collection[str] = frozenset(),
) -> dict[str, np.ndarray]:
    """Give every face one boundary: hyperfem tags each facet once.

    Boundaries from node sets that share faces with another boundary are dropped (with a warning, a note for
    ``helpers``: node sets that define surfaces; the smaller sets kept first); with ``strict`` (Abaqus surfaces
    present) the other boundaries sharing faces are refused.
    """
    if not strict and not from_nodes:
        return boundaries
    keys = {name: _face_keys(f) for name, f in boundaries.items()}
    kept = [name for name in boundaries if name not in from_nodes]
    if strict:
        for a in range(len(kept)):
            for b in range(a):
                shared = len(np.intersect1d(keys[kept[a]], keys[kept[b]]))
                if shared:
                    faces = f"{shared} face{'s' if shared > 1 else ''}"
                    raise MeshError(
                        f"{path}: boundaries {kept[b]!r} and {kept[a]!r} share {faces}; hyperfem gives each face "
                        "one boundary: remove or split one of the surfaces"
                    )
    for name in sorted(from_nodes, key=lambda n: len(keys[n])):
        other = next((k for k in kept if len(np.intersect1d(keys[name], keys[k]))), None)
        if other is None:
            kept.append(name)
        elif name in helpers:
            notes.append(f"node set {name!r} defines a surface: not a boundary of its own")
        else:
            cautions.append(
                f"node set {name!r} is no boundary: its faces overlap boundary {other!r} (hyperfem gives each face "
                "one boundary)"
            )
    return {name: f for name, f in boundaries.items() if name in kept}


def convert(
    source: str | Path,
    target: str | Path,
    *,
    reorient: bool = False,
    tags: str | None = None,
    names: str | Mapping[tuple[int | None, int], str] | None = None,
) -> Conversion:
    """Convert a tetrahedral mesh with its groups to a gmsh 2.2 ``.msh`` file (serial; call on one rank).

    Args:
        source: Any mesh file meshio reads.
        target: The ``.msh`` file to write.
        reorient: Fix inverted tetrahedra (swap two vertices) instead of refusing them.
        tags: Name of the integer cell-data array holding the group tags.
        names: Names of tagged groups: ``"1=beam,2=clamped"`` (``region:1=...`` or
            ``boundary:1=...`` where a tag is both), or :func:`parse_names`' mapping.
            They replace the file's own names; tags named by neither become
            ``region_<tag>`` / ``boundary_<tag>`` (listed in the notes).

    Raises:
        MeshFileNotFoundError: ``source`` does not exist.
        MeshError: Unreadable file, no/mixed/unsupported cells, overlapping sets, degenerate
            or (without ``reorient``) inverted tetrahedra, or a result hyperfem cannot read back.
    """
    source, target = Path(source), Path(target)
    notes: list[str] = []
    mesh, abaqus = _load(source, target, notes)
    tet, volume, facets, cautions = _blocks(mesh, source)
    cells = np.concatenate([np.asarray(mesh.cells[i].data, dtype=np.int64) for i in volume])
    points = np.asarray(mesh.points, dtype=float)
    if points.shape[1] == 2:
        raise MeshError(f"{source}: planar points (2 coordinates) cannot carry tetrahedra")

    given = parse_names(names) if names is None or isinstance(names, str) else dict(names)
    regions, unassigned, boundaries, from_nodes = _groups(
        mesh, tags, given, (tet, volume, facets, cells), source, abaqus, notes
    )
    if abaqus is not None:
        _add_surfaces(abaqus, mesh, cells, volume, boundaries, from_nodes, cautions, notes)
    boundaries = _one_boundary_per_face(
        boundaries, from_nodes, abaqus is not None, source, cautions, notes,
        abaqus.surface_node_sets() if abaqus is not None else set(),
    )
    if unassigned.any():
        cautions.append(f"{int(unassigned.sum())} of {len(cells)} tetrahedra belong to no region: region 'unassigned'")
        regions["unassigned"] = unassigned

    inverted = _orient(points, cells, tet, reorient, source, cautions)
    _write(target, points, cells, tet, regions, boundaries, source)
    _check_readable(target)
    return Conversion(
        path=target,
        cell_type=tet,
        cells=len(cells),
        nodes=len(points),
        regions={r: int(regions[r].sum()) for r in regions},
        boundaries={b: len(f) for b, f in boundaries.items()},
        reoriented=inverted if reorient else 0,
        notes=notes,
        warnings=cautions,
    )


def _load(source: Path, target: Path, notes: list[str]) -> tuple[Any, InpModel | None]:
    """Check the paths and read ``source`` (with its Abaqus surfaces, where it has any)."""
    if not source.is_file():
        raise MeshFileNotFoundError(f"mesh file not found: {source}")
    if target.suffix != ".msh":
        raise MeshError(f"{target}: convert writes gmsh files: the output must end in .msh")
    abaqus = read_inp(source) if source.suffix.lower() == ".inp" and has_surfaces(source) else None
    mesh = _read(source, notes)
    if abaqus is not None:
        abaqus.match(mesh)
        mesh.cell_sets, mesh.point_sets = abaqus.cell_sets(), abaqus.point_sets()
    return mesh, abaqus


def _groups(
    mesh: Any,
    tags: str | None,
    given: Mapping[tuple[int | None, int], str],
    blocks: tuple[str, list[int], list[int], np.ndarray],
    source: Path,
    abaqus: InpModel | None,
    notes: list[str],
) -> tuple[dict[str, np.ndarray], np.ndarray, dict[str, np.ndarray], list[str]]:
    """Regions, unassigned cells, boundaries and node-set boundaries: from a tag array, sets, or neither."""
    tet, volume, facets, cells = blocks
    name = _tag_array(mesh, tags, source)
    from_nodes: list[str] = []
    if name is None and given:
        raise ParameterError(f"convert --names: {source} has no tag array (its groups are named sets, or none)")
    if name is not None:
        unnamed: list[str] = []
        regions, unassigned, boundaries = _groups_from_array(mesh, name, volume, facets, tet, source, given, unnamed)
        notes.append(f"groups from the cell-data array {name!r}")
        if unnamed:
            notes.append(
                f"no names for {', '.join(unnamed)} (kept as {', '.join(u.replace(' ', '_') for u in unnamed)}); "
                "name them with --names TAG=NAME,..."
            )
    elif any(not k.startswith("gmsh:") for k in mesh.cell_sets) or mesh.point_sets:
        helpers = abaqus.surface_sets() if abaqus is not None else set()
        regions, unassigned, boundaries, dropped, from_nodes = _groups_from_sets(
            mesh, volume, facets, cells, source, helpers
        )
        notes.append("groups from the cell and point sets")
        if dropped:
            notes.append(f"element sets only used to define surfaces (not regions): {', '.join(dropped)}")
    else:
        regions, unassigned = {"domain": np.ones(len(cells), dtype=bool)}, np.zeros(len(cells), dtype=bool)
        boundaries = {"boundary": _exterior_facets(cells)}
        notes.append("no tags or sets: one region 'domain', the exterior faces are boundary 'boundary'")
    return regions, unassigned, boundaries, from_nodes


def _add_surfaces(
    abaqus: InpModel,
    mesh: Any,
    cells: np.ndarray,
    volume: list[int],
    boundaries: dict[str, np.ndarray],
    from_nodes: list[str],
    cautions: list[str],
    notes: list[str],
) -> None:
    """Add the Abaqus ``*SURFACE`` boundaries, which replace sets of the same name (in place)."""
    surfaces = abaqus.surfaces(cells, volume, [block.type for block in mesh.cells])
    for surface in surfaces:
        if surface in boundaries:
            cautions.append(f"boundary {surface!r} is the *SURFACE of that name (the set of that name is ignored)")
            if surface in from_nodes:
                from_nodes.remove(surface)
    boundaries.update(surfaces)
    notes.append(f"boundaries from *SURFACE: {', '.join(f'{k} ({len(v)})' for k, v in surfaces.items())}")


def _orient(
    points: np.ndarray, cells: np.ndarray, tet: str, reorient: bool, source: Path, cautions: list[str]
) -> int:
    """Refuse degenerate tetrahedra and inverted ones (or, with ``reorient``, fix those in place); their count."""
    counts, inverted, degenerate = orientation(points[cells[:, :4]])
    if counts.degenerate:
        first = int(np.flatnonzero(degenerate)[0])
        raise MeshError(
            f"{source}: {counts.degenerate} of {counts.cells} tetrahedra have no volume (degenerate; the first is "
            f"cell {first}); fix the mesh"
        )
    if counts.inverted:
        if not reorient:
            raise MeshError(
                f"{source}: {counts.inverted} of {counts.cells} tetrahedra are inverted (negative orientation: "
                "vertices in mirrored order); rerun with --reorient to fix their vertex order"
            )
        cells[inverted] = cells[inverted][:, _SWAP[VOLUME[tet]]]  # facets keep their order: hyperfem ignores it
        cautions.append(f"reoriented {counts.inverted} inverted tetrahedra (swapped two vertices)")
    return counts.inverted


def _write(
    target: Path,
    points: np.ndarray,
    cells: np.ndarray,
    tet: str,
    regions: Mapping[str, np.ndarray],
    boundaries: Mapping[str, np.ndarray],
    source: Path,
) -> None:
    """Write the gmsh 2.2 file: one physical group per region (dimension 3) and boundary (dimension 2)."""
    import meshio

    region_names = list(regions)
    cell_tag = np.zeros(len(cells), dtype=np.int64)
    for k, region in enumerate(region_names, start=1):
        cell_tag[regions[region]] = k
    facet_blocks = [np.asarray(f, dtype=np.int64) for f in boundaries.values()]
    facet_tag = [np.full(len(f), k, dtype=np.int64) for k, f in enumerate(facet_blocks, start=1)]
    blocks = [(tet, cells)] + [(FACET[tet], f) for f in facet_blocks]
    tags_out = [cell_tag] + facet_tag
    field_data = {r: np.array([k, 3]) for k, r in enumerate(region_names, start=1)}
    for k, b in enumerate(boundaries, start=1):
        if b in field_data:
            raise MeshError(f"{source}: the name {b!r} is both a region and a boundary; rename one")
        field_data[b] = np.array([k, 2])
    out = meshio.Mesh(
        points, blocks, cell_data={"gmsh:physical": tags_out, "gmsh:geometrical": tags_out}, field_data=field_data
    )
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        meshio.write(target, out, file_format="gmsh22", binary=False)
    except OSError as exc:
        raise MeshError(f"{target}: cannot write: {exc.strerror or exc}") from None


def _check_readable(path: Path) -> None:
    """Read the written file back with hyperfem (one rank)."""
    from mpi4py import MPI

    from hyperfem.mesh.io import read_mesh

    try:
        read_mesh(path, MPI.COMM_SELF)
    except MeshError as exc:
        raise MeshError(f"{path}: written, but hyperfem cannot read it back: {exc}") from None


def describe_msh(path: str | Path) -> str:
    """One line on a gmsh file: cell counts and physical groups (via meshio)."""
    mesh = _read(Path(path))
    counts: dict[str, int] = {}
    for block in mesh.cells:
        counts[block.type] = counts.get(block.type, 0) + len(block.data)
    by_dim: dict[int, list[str]] = {}
    for name, value in mesh.field_data.items():
        by_dim.setdefault(int(np.asarray(value).reshape(-1)[1]), []).append(name)
    cells = ", ".join(f"{v} {k}" for k, v in counts.items() if _dim(k) == 3)
    regions = ", ".join(by_dim.get(3, [])) or "none"
    boundaries = ", ".join(by_dim.get(2, [])) or "none"
    return f"{path}: {cells}, {len(mesh.points)} nodes; regions: {regions}; boundaries: {boundaries}"
