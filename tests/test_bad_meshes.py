"""Bad meshes get one-line :class:`~hyperfem.errors.MeshError` naming the file and the cause (issue 17, item 7).

Each mesh is built with the gmsh API (a discrete volume with a few nodes and
cells, a physical volume ``body`` and a physical surface ``clamped``) and
written to a folder every rank sees. Before the fix: duplicate nodes were read
(or failed in the DOLFINx reader), a NaN coordinate surfaced as
"rigid-body motion unconstrained" (or ``LinAlgError``), mixed cell types as
DOLFINx's "Multiple cell types of this dimension. Call cell_types instead.",
a surface mesh as a missing boundary group, and a flat mesh built into a
problem as "rigid-body motion unconstrained" at the solver.
"""

import math
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

import hyperfem as hf
from hyperfem.errors import MeshError

CUBE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
TETS = [[1, 2, 3, 4], [2, 3, 4, 5]]


@pytest.fixture
def shared_dir():
    """A temporary folder every rank sees (made by rank 0; one machine)."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="hyperfem-bad-") if comm.rank == 0 else None, root=0))
    yield path
    comm.Barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def _write(path: Path, nodes, blocks, tdim: int = 3, clamp=(1, 2, 3)) -> Path:
    """Write a discrete mesh on rank 0: ``blocks`` are ``(gmsh element type, 1-based connectivity)``."""
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        import gmsh

        gmsh.initialize(interruptible=False)
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            gmsh.model.add("bad")
            body = gmsh.model.addDiscreteEntity(tdim)
            nodes = np.asarray(nodes, dtype=float)
            gmsh.model.mesh.addNodes(tdim, body, list(range(1, len(nodes) + 1)), nodes.ravel().tolist())
            tag = 1
            for etype, conn in blocks:
                conn = np.asarray(conn)
                gmsh.model.mesh.addElementsByType(body, etype, list(range(tag, tag + len(conn))), conn.ravel().tolist())
                tag += len(conn)
            gmsh.model.addPhysicalGroup(tdim, [body], 1, name="body")
            if tdim == 3:
                face = gmsh.model.addDiscreteEntity(2)
                gmsh.model.mesh.addElementsByType(face, 2, [tag], list(clamp))
                gmsh.model.addPhysicalGroup(2, [face], 2, name="clamped")
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.write(str(path))
        finally:
            gmsh.finalize()
    comm.Barrier()
    return path


def _psi(F):
    return hf.materials.neo_hookean(F, hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3))


def _raises_on_every_rank(path: Path, pattern: str) -> None:
    with pytest.raises(MeshError, match=pattern) as info:
        hf.read_mesh(path)
    assert str(path) in str(info.value)


def test_good_two_tetrahedra_are_read(shared_dir):
    domain = hf.read_mesh(_write(shared_dir / "good.msh", CUBE, [(4, TETS)]))
    assert domain.mesh.topology.index_map(3).size_global == 2
    hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("clamped")])


def test_duplicate_nodes_are_named(shared_dir):
    nodes = np.vstack([CUBE, CUBE[1:2]])  # node 6 repeats node 2: the two cells do not share a face
    path = _write(shared_dir / "dup.msh", nodes, [(4, [[1, 2, 3, 4], [6, 3, 4, 5]])])
    _raises_on_every_rank(path, r"2 nodes share coordinates \(node 2 and node 6 at \(1, 0, 0\)\); remove duplicates")


def test_touching_volumes_without_fragment_have_duplicate_nodes(shared_dir):
    """Two boxes meshed side by side without fragment(): gmsh writes each interface node twice."""
    path = shared_dir / "twobox.msh"
    if MPI.COMM_WORLD.rank == 0:
        import gmsh

        gmsh.initialize(interruptible=False)
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            a = gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
            b = gmsh.model.occ.addBox(1, 0, 0, 1, 1, 1)
            gmsh.model.occ.synchronize()
            gmsh.model.addPhysicalGroup(3, [a, b], 1, name="body")
            gmsh.model.addPhysicalGroup(2, [t for _, t in gmsh.model.getEntities(2)], 1, name="skin")
            gmsh.option.setNumber("Mesh.MeshSizeMax", 1.0)
            gmsh.model.mesh.generate(3)
            gmsh.write(str(path))
        finally:
            gmsh.finalize()
    MPI.COMM_WORLD.Barrier()
    _raises_on_every_rank(path, r"\d+ nodes share coordinates \(node \d+ and node \d+ at \(1, ")


def test_nan_coordinate_is_named(shared_dir):
    nodes = CUBE.copy()
    nodes[4, 2] = math.nan
    path = _write(shared_dir / "nan.msh", nodes, [(4, TETS)])
    _raises_on_every_rank(path, r"1 node\(s\) have coordinates that are not finite numbers \(node 5 at \(1, 1, nan\)\)")


def test_mixed_cell_types_are_named(shared_dir):
    nodes = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1], [0.5, 0.5, 2]]
    path = _write(shared_dir / "mixed.msh", nodes, [(5, [[1, 2, 3, 4, 5, 6, 7, 8]]), (4, [[5, 6, 7, 9]])])
    _raises_on_every_rank(path, r"the 3D cells mix 2 types \(1 tetrahedron, 1 hexahedron\); hyperfem needs one")


def test_surface_mesh_in_space_has_no_volume_cells(shared_dir):
    faces = [[1, 2, 3], [1, 2, 4], [1, 3, 4], [2, 3, 4]]
    path = _write(shared_dir / "surface.msh", CUBE, [(2, faces)], tdim=2)
    _raises_on_every_rank(path, r"no volume cells: the mesh has only 2D cells \(4 triangles\) with coordinates in 3D")


def test_volume_cells_outside_every_group_are_named(shared_dir):
    """Tetrahedra in the file but only surface groups: DOLFINx would read the triangles as the mesh."""
    path = shared_dir / "ungrouped.msh"
    if MPI.COMM_WORLD.rank == 0:
        import gmsh

        gmsh.initialize(interruptible=False)
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
            gmsh.model.occ.synchronize()
            gmsh.model.addPhysicalGroup(2, [t for _, t in gmsh.model.getEntities(2)], 1, name="skin")
            gmsh.option.setNumber("Mesh.MeshSizeMax", 1.0)
            gmsh.option.setNumber("Mesh.SaveAll", 1)
            gmsh.model.mesh.generate(3)
            gmsh.write(str(path))
        finally:
            gmsh.finalize()
    MPI.COMM_WORLD.Barrier()
    _raises_on_every_rank(path, r"\d+ tetrahedra are in no physical group .*gmsh: Physical Volume")


def test_flat_mesh_is_refused_by_the_problem_as_in_the_cli(shared_dir):
    """All nodes in z = 0: the API says what ``hyperfem run`` says (cells without volume), not 'rigid-body motion'."""
    nodes = CUBE.copy()
    nodes[:, 2] = 0.0
    nodes[3] = [0.3, 0.3, 0.0]
    path = _write(shared_dir / "flat.msh", nodes, [(4, TETS)])
    domain = hf.read_mesh(path)  # readable: hyperfem mesh-quality reports such meshes
    message = rf"{path}: 2 of 2 cells have no volume \(degenerate\); fix the mesh"
    with pytest.raises(MeshError, match=message):
        hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("clamped")])
    split = hf.problem.SplitEnergy(lambda F: hf.materials.neo_hookean(F, hf.materials.LameParameters(1.0, 0.0)), 10.0)
    with pytest.raises(MeshError, match=message):
        hf.problem.MixedHyperelasticProblem(domain, split, bcs=[hf.Clamp("clamped")])
