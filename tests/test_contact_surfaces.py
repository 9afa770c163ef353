r"""Mesh contact (issue 19): two bodies, a rigid triangulated tool, obstacles pushed into a resting body.

The patch test: two unit cubes of one mesh (``lower`` below :math:`z = 0`,
``upper`` above :math:`z = g`), meshed independently (non-matching facets),
rollers on :math:`x = 0` and :math:`y = 0`, the bottom of ``lower`` held in
:math:`z`, the top of ``upper`` pushed down by :math:`\delta`. Frictionless,
the exact state is homogeneous uniaxial compression of both cubes with free
lateral faces: the force through the interface equals the reaction at the
top and :math:`|P_{zz}(\lambda)|` (``test_contact.py``) with
:math:`2\lambda = 2 + g - \delta - \bar g`, :math:`\bar g` the mean final gap.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

ipctk = pytest.importorskip("ipctk")

import hyperfem as hf  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402
from hyperfem.contact import PlaneContact, SurfaceContact, ToolContact  # noqa: E402
from hyperfem.contact.bodies import surface_defaults  # noqa: E402
from hyperfem.contact.mesh_barrier import ray_hits  # noqa: E402
from hyperfem.contact.shapes import icosphere  # noqa: E402
from hyperfem.contact.surface import contact_surface  # noqa: E402
from hyperfem.errors import MeshError, ParameterError, UnknownGroupError  # noqa: E402
from hyperfem.simulation.reactions import ReactionForce  # noqa: E402
from ranks import serial_reference  # noqa: E402  (tests/ranks.py)
from test_contact import _cube  # noqa: E402  (the cube with bottom, top, x0, y0)

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
TIGHT = {"snes_rtol": 1e-10, "snes_atol": 1e-12}
GAP, DHAT = 5e-4, 1e-3
INCREMENT = 0.25


def _uniaxial_pzz(stretch: float) -> float:
    """:math:`P_{zz}` of compressible Neo-Hookean in uniaxial stress (lateral stretch from :math:`P_{xx} = 0`)."""
    from scipy.optimize import brentq

    mu, lam = PARAMS.mu, PARAMS.lmbda
    lt = brentq(lambda s: mu * s + (lam * np.log(stretch * s * s) - mu) / s, 0.5, 2.0)
    return mu * stretch + (lam * np.log(stretch * lt * lt) - mu) / stretch


def _watch(solver, contact) -> list[float]:
    """The smallest pair distance of every accepted Newton iterate."""
    seen: list[float] = []
    solver.snes.setMonitor(lambda snes, it, norm: seen.append(contact.min_distance(snes.getSolution())))
    return seen


def _stacked(comm=MPI.COMM_WORLD, degree=1, delta=0.2, h=(0.5, 0.34), domain=None, subdivision=None):
    domain = domain or hf.mesh.stacked_blocks_mesh(h[0], h[1], GAP, comm=comm)
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("lower_bottom", [0.0], components=[2]),
        hf.PrescribedDisplacement("upper_top", [-delta], components=[2]),
    ]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs, degree=degree)
    contact = SurfaceContact(["lower_top", "upper_bottom"], dhat=DHAT, subdivision=subdivision).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
    iterates = _watch(solver, contact)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=INCREMENT, max_increment=INCREMENT))
    return problem, contact, iterates


def test_two_blocks_with_non_matching_meshes_transmit_the_uniaxial_stress():
    """The patch test (module docstring): force through the interface = top reaction to 1e-8, = |P_zz| to 0.1 %."""
    delta = 0.2
    problem, contact, iterates = _stacked(delta=delta)
    reaction = ReactionForce(problem, "upper_top")()
    force = contact.force(group=0)  # on lower_top, from the upper cube: downward
    assert force[2] == pytest.approx(reaction[2], rel=1e-8) and force[2] < 0.0
    surface = contact.surface
    x = surface.positions(problem.u.x.array)
    lower, upper = x[surface.group == 0, 2], x[surface.group == 1, 2]
    stretch = (2.0 + GAP - delta - (upper.mean() - lower.mean())) / 2.0
    assert -reaction[2] == pytest.approx(-_uniaxial_pzz(stretch), rel=1e-3)
    # Uniform pressure: both faces stay flat to a fraction of d-hat, the gap stays in (0, d-hat).
    assert lower.std() < 0.3 * DHAT and upper.std() < 0.3 * DHAT
    assert 0.0 < contact.min_distance() < DHAT and contact.active_count() > 0
    assert min(iterates) > 0.0 and not contact.intersecting()


def _stacked_state(comm) -> tuple[float, float, float]:
    problem, contact, _ = _stacked(comm)
    return float(contact.force(group=0)[2]), float(problem.u.x.petsc_vec.norm()), contact.min_distance()


def test_two_blocks_one_rank_equals_two_ranks():
    """The force transmitted by the patch test's interface on 2 ranks equals 1 rank's to 1e-4.

    Not the state to 1e-10: the frictionless barrier between non-matching facets has many equilibria (the
    edge-edge pairs lock the faces laterally where they come to rest): on 1 rank, increments of 0.125, 0.25 and
    0.5 end at forces of -0.10866105, -0.10866101 and -0.10866131, each converged to |r| < 1e-12, and round-off in
    the Newton path (one rank or two, MPICH or OpenMPI) picks one of them: the displacement norms of 1 and 2 ranks
    differed by 1.5e-4 and the forces by 1.5e-5 on Debian's route. Mesh contact whose equilibrium is unique agrees
    on 1 and 2 ranks to round-off (the two-beam demo: 1e-16; tests/test_demos.py checks its force on both), as do
    the tie, the plane, the sphere and the cylinder (1e-10, their tests).
    """
    comm = MPI.COMM_WORLD
    one = serial_reference(_stacked_state)
    two = _stacked_state(comm)
    assert two[0] == pytest.approx(one[0], rel=1e-4) and 0.0 < two[2] < DHAT and 0.0 < one[2] < DHAT


def _patch_error(problem, contact, delta: float) -> float:
    """The stacked-block patch test's relative error of the top reaction against |P_zz| of the blocks' stretch."""
    reaction = ReactionForce(problem, "upper_top")()
    assert contact.force(group=0)[2] == pytest.approx(reaction[2], rel=1e-8) and reaction[2] < 0.0
    surface = contact.surface
    x = surface.positions(problem.u.x.array)
    lower, upper = x[surface.group == 0, 2], x[surface.group == 1, 2]
    stretch = (2.0 + GAP - delta - (upper.mean() - lower.mean())) / 2.0
    return float(abs(reaction[2] / _uniaxial_pzz(stretch) - 1.0))


@pytest.mark.serial  # the 2-rank path of the proxy: test_collision_proxy_is_closed_and_the_same_on_any_ranks
@pytest.mark.parametrize(("subdivision", "low", "high"), [(1, 0.025, 0.04), (None, 0.0, 6e-3), (4, 0.0, 2e-3)])
def test_p2_surfaces_transmit_the_pressure_through_the_collision_proxy(subdivision, low, high):
    """P2 tetrahedra, h = (1, 0.6): equilibrium holds and nothing intersects. On the nodes (subdivision 1) the
    force misses |P_zz| by 3.3 % (the corner nodes carry as much as the midside ones, where a uniform pressure's
    consistent loads are 0 and a third); through the default proxy (a facet edge in 4 segments) by 0.42 %, and
    in 8 by 0.14 % (measured; hyperfem.contact.proxy)."""
    problem, contact, iterates = _stacked(degree=2, delta=0.1, h=(1.0, 0.6), subdivision=subdivision)
    assert low <= _patch_error(problem, contact, 0.1) < high
    assert min(iterates) > 0.0 and 0.0 < contact.min_distance() < DHAT and not contact.intersecting()
    dofs, gaps = contact.pair_gaps()  # per node, the closest of the pairs its collision vertices are in
    assert len(gaps) == contact.surface.size and gaps.min() == pytest.approx(contact.min_distance(), rel=1e-12)
    assert np.all(gaps <= DHAT) and np.count_nonzero(gaps < DHAT) > 0.5 * len(gaps)


@pytest.mark.parametrize(
    ("cell", "degree", "per_facet"),
    [("tetrahedron", 2, 16), ("hexahedron", 1, 8), ("hexahedron", 2, 32), ("triangle", 2, 4), ("quadrilateral", 2, 4)],
)
def test_collision_proxy_is_closed_and_the_same_on_any_ranks(cell, degree, per_facet):
    """The default proxy of a unit cube's (square's) whole boundary, 2 boxes a side: a closed surface (every edge in
    two triangles, Euler characteristic 2; in 2D a closed polyline), ``per_facet`` sub-facets a facet, its vertices
    on the facets' interpolant (exact for a field of the facets' own degree), partitions of unity, the same vertices
    and sub-facets on 1 and 2 ranks; the default stiffness scaled by nodes per vertex."""
    comm = MPI.COMM_WORLD
    dim = 3 if cell in ("tetrahedron", "hexahedron") else 2

    def build(comm):
        if dim == 3:
            mesh = dmesh.create_box(comm, [np.zeros(3), np.ones(3)], [2, 2, 2], dmesh.CellType[cell])
        else:
            mesh = dmesh.create_rectangle(comm, [np.zeros(2), np.ones(2)], [2, 2], dmesh.CellType[cell])
        domain = hf.Domain.from_locators(mesh, {"all": lambda x: np.full(x.shape[1], True)}, source="box")
        problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), degree=degree)
        return problem, contact_surface(problem, ["all"], "test")

    problem, surface = build(comm)
    W, faces = surface.proxy_map, surface.proxy_faces
    assert W is not None and faces is not None and surface.collision_faces is faces
    facets = {"tetrahedron": 48, "hexahedron": 24}.get(cell, 8)
    assert len(faces) == per_facet * facets and surface.collision_size == W.shape[0]
    if dim == 3:
        edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        assert np.all(counts == 2) and surface.collision_size - len(counts) + len(faces) == 2
    else:
        assert np.all(np.bincount(faces.ravel()) == 2) and surface.collision_size == len(faces)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-14)
    Y = surface.to_collision(surface.X)

    def field(x):  # of the facets' own degree on every face of the box: quadratic, or bilinear for Q1
        if degree == 1:
            return np.stack([x[:, 0] * x[:, 1] + x[:, 1] * x[:, 2] + x[:, 2] * x[:, 0], x[:, 0] - 2.0 * x[:, 1]], 1)
        return np.stack([x[:, 0] * x[:, 1] - x[:, -1] ** 2, 3.0 * x[:, 1] ** 2 + x[:, 0]], axis=1)

    np.testing.assert_allclose(surface.to_collision(field(surface.X)), field(Y), atol=1e-13)
    assert np.all((np.isclose(Y, 0.0) | np.isclose(Y, 1.0)).any(axis=1))  # on the boundary
    one = None
    if comm.rank == 0:
        _, alone = build(MPI.COMM_SELF)
        one = (alone.to_collision(alone.X), alone.proxy_faces)
    one = comm.bcast(one, root=0)
    np.testing.assert_allclose(Y, one[0], atol=1e-14)
    assert np.array_equal(faces, one[1])
    nodes = contact_surface(problem, ["all"], "test", subdivision=1)
    assert nodes.proxy_map is None and nodes.collision_size == nodes.size and nodes.collision_faces is nodes.faces
    plain = surface_defaults(problem, ["all"], nodes, 0.01, None)[1]
    assert surface_defaults(problem, ["all"], surface, 0.01, None)[1] == pytest.approx(
        plain * surface.size / surface.collision_size, rel=1e-12
    )


@pytest.mark.serial  # the gradient and Hessian rows are checked as one array (serially: every row is owned)
def test_barrier_derivatives_through_the_proxy_match_finite_differences():
    """The stacked P2 blocks, the upper one pressed into the barrier with a wavy, sheared bottom and its surface
    nodes jittered (some 600 pairs of the default proxy active, the closest at 2e-6): the gradient W^T g is the
    derivative of the energy and the exact Hessian W^T H W the derivative of the gradient, along a random direction
    (central differences; measured 1e-8 and 5.8e-8 relative at eps = 1e-9, asserted 1e-6; they fall as eps^2).

    Without the jitter the flat lattices of the two faces leave points exactly over the other face's edges, where
    the squared distance (point-triangle against point-edge) is only once differentiable: the central differences
    there err by O(eps) (2.7e-7 at eps = 1e-8), as IPC's barrier does anywhere on such a tie."""
    domain = hf.mesh.stacked_blocks_mesh(1.0, 0.6, GAP)
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), degree=2)
    contact = SurfaceContact(["lower_top", "upper_bottom"], dhat=DHAT).bind(problem)
    assert contact.surface.collision_size > 3 * contact.surface.size

    def pressed(x):
        v = np.zeros_like(x)
        upper = x[2] > GAP / 2  # the upper block: z in [GAP, 1 + GAP]
        v[2] = np.where(upper, -0.8 * GAP - 1e-4 * np.sin(3.0 * x[0]) * np.cos(2.0 * x[1]), 0.0)
        v[0] = np.where(upper, 0.01 * x[1], 0.0)
        return v

    problem.u.interpolate(pressed)
    u = problem.u.x.array.copy()
    surface_dofs = contact.surface.dofs.ravel()
    u[surface_dofs] += 2e-5 * np.random.default_rng(7).normal(size=surface_dofs.size)
    n = u.size
    assert contact.active_count(u) > 500 and 0.0 < contact.min_distance(u) < 0.5 * GAP

    def gradient(w):
        dofs, values = contact.gradient(w)
        g = np.zeros(n)
        g[dofs.ravel()] = values.ravel()
        return g

    contact._tangent_at = contact.vertices(u)  # settled: the exact (unprojected) Hessian
    rows, cols, values = contact.coupled_hessian(u)
    assert contact.exact_tangent
    H = np.zeros((n, n))
    np.add.at(H, (rows, cols), values)
    direction = np.zeros(n)
    direction[surface_dofs] = np.random.default_rng(1).normal(size=surface_dofs.size)
    eps = 1e-9  # the closest pair is at 2e-6
    slope = (contact.energy(u + eps * direction) - contact.energy(u - eps * direction)) / (2.0 * eps)
    g = gradient(u)
    assert slope == pytest.approx(g @ direction, rel=1e-6)
    curvature = (gradient(u + eps * direction) - gradient(u - eps * direction)) / (2.0 * eps)
    np.testing.assert_allclose(curvature, H @ direction, rtol=0, atol=1e-6 * np.abs(H @ direction).max())


def _mixed_blocks(mixed_threshold: int) -> tuple[float, float, float, bool, str]:
    """The stacked blocks as the (u, p, theta) problem: force on lower_top, reaction, gap, intersecting, PC."""
    from hyperfem.kinematics import isochoric_invariants
    from hyperfem.problem.mixed import SplitEnergy, solid_problem
    from hyperfem.solver.linear import choose_linear_solver

    domain = hf.mesh.stacked_blocks_mesh(1.0, 0.6, GAP, comm=MPI.COMM_WORLD)
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("lower_bottom", [0.0], components=[2]),
        hf.PrescribedDisplacement("upper_top", [-0.1], components=[2]),
    ]
    material = SplitEnergy(lambda F: 0.5 * PARAMS.mu * (isochoric_invariants(F)[0] - 3.0), 50.0 * PARAMS.mu)
    problem = solid_problem(domain, material, formulation="mixed", bcs=bcs)
    contact = SurfaceContact(["lower_top", "upper_bottom"], dhat=DHAT).bind(problem)
    linear = choose_linear_solver(problem, mixed_threshold=mixed_threshold)
    solver = hf.NewtonSolver(problem, TIGHT, linear_solver=linear, external_energies=[contact])
    iterates = _watch(solver, contact)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    assert min(iterates) > 0.0
    pc = str(solver.snes.getKSP().getPC().getType())
    return float(contact.force(group=0)[2]), float(ReactionForce(problem, "upper_top")()[2]), \
        contact.min_distance(), contact.intersecting(), pc


def test_mixed_blocks_on_the_field_split_equal_lu():
    """The (u, p, theta) blocks on the iterative field split (its preconditioning matrix is the tangent plus a
    shift, copied): the contact pairs grow the tangent's pattern at several Newton iterations, and each time
    the split is set up anew (before, the second growth stopped PETSc: "Cannot reuse matrix. wrong number of
    nonzeros"). The force equals LU's and the reaction."""
    split = _mixed_blocks(mixed_threshold=0)
    lu = _mixed_blocks(mixed_threshold=10**12)
    assert (split[4], lu[4]) == ("fieldsplit", "lu")
    assert split[0] == pytest.approx(split[1], rel=1e-8) and split[0] < 0.0
    assert split[0] == pytest.approx(lu[0], rel=1e-4)
    assert 0.0 < split[2] < DHAT and not split[3]


@pytest.mark.parametrize(("subdivision", "warp"), [(1, 4 * DHAT), (None, 1.2 * DHAT)])
def test_hexahedral_blocks_transmit_the_uniaxial_stress(subdivision, warp):
    """The patch test on Q1 hexahedra (``stacked_blocks_mesh(cell="hexahedron")``: 3^3 boxes below, 2^3 above,
    non-matching faces, each split into two triangles): force through the interface = top reaction to 1e-8
    (measured 2e-13), = |P_zz| to 0.1 % (measured 5.7e-5 on the nodes, 7.2e-5 through the default proxy).

    On the nodes the faces do not stay flat (measured: 2.4 d-hat, 2.4e-3 on a push of 0.2, both faces alike): a
    face's two triangles fold along a diagonal where the bilinear face does not, and the nodal barrier puts equal
    point loads where a uniform pressure's consistent ones are (1, 2, 1; 2, 4, 2; 1, 2, 1)/16: the
    node-to-surface patch-test error. Through the default collision proxy (a face edge in 2 segments on the
    bilinear face, hyperfem.contact.proxy) the warp is 0.5 d-hat (measured 4.7e-4 and 5.8e-4)."""
    delta = 0.2
    domain = hf.mesh.stacked_blocks_mesh(1 / 3, 1 / 2, GAP, cell="hexahedron")
    problem, contact, iterates = _stacked(delta=delta, domain=domain, subdivision=subdivision)
    reaction = ReactionForce(problem, "upper_top")()
    assert contact.force(group=0)[2] == pytest.approx(reaction[2], rel=1e-8) and reaction[2] < 0.0
    surface = contact.surface
    assert len(surface.faces) == 2 * (9 + 4)
    assert len(surface.collision_faces) == (1 if subdivision == 1 else 4) * 2 * (9 + 4)
    x = surface.positions(problem.u.x.array)
    lower, upper = x[surface.group == 0, 2], x[surface.group == 1, 2]
    stretch = (2.0 + GAP - delta - (upper.mean() - lower.mean())) / 2.0
    assert -reaction[2] == pytest.approx(-_uniaxial_pzz(stretch), rel=1e-3)
    assert lower.std() < warp and upper.std() < warp
    assert 0.0 < contact.min_distance() < DHAT and min(iterates) > 0.0 and not contact.intersecting()
    with pytest.raises(ParameterError, match="cell must be one of tetrahedron, hexahedron, got 'prism'"):
        hf.mesh.stacked_blocks_mesh(cell="prism")


@pytest.mark.parametrize(("subdivision", "low", "high"), [(1, 0.05, 0.07), (None, 0.0, 6e-3)])
def test_q2_hexahedral_surfaces_transmit_the_pressure_through_the_collision_proxy(subdivision, low, high):
    """Q2 hexahedra: a face is eight triangles on its nine nodes (corners, edge midpoints, centre); equilibrium
    holds and nothing intersects. On the nodes the force misses |P_zz| by 5.9 %, through the default proxy (a face
    edge in 4 segments, 32 triangles a face) by 0.39 % (measured)."""
    domain = hf.mesh.stacked_blocks_mesh(1 / 2, 1.0, GAP, cell="hexahedron")
    problem, contact, iterates = _stacked(degree=2, delta=0.2, domain=domain, subdivision=subdivision)
    assert low <= _patch_error(problem, contact, 0.2) < high
    assert len(contact.surface.faces) == 8 * (4 + 1)
    assert len(contact.surface.collision_faces) == (1 if subdivision == 1 else 4) * 8 * (4 + 1)
    assert min(iterates) > 0.0 and 0.0 < contact.min_distance() < DHAT and not contact.intersecting()


# -- a rigid triangulated tool -------------------------------------------------------------------------------------


def _pressed_cube(comm=MPI.COMM_WORLD, delta=0.2, top=None):
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("top", [-delta], components=[2]),
    ]
    return hf.HyperelasticProblem(_cube(comm, 3), lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)


PLATE = np.array([[-1.0, -1.0, -DHAT / 2], [3.0, -1.0, -DHAT / 2], [3.0, 3.0, -DHAT / 2], [-1.0, 3.0, -DHAT / 2]])
PLATE_TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])


def test_flat_tool_is_the_plane():
    """A two-triangle plate under the pressed cube: force = reaction to 1e-8, = |P_zz| of the height to 0.1 %."""
    problem = _pressed_cube()
    tool = ToolContact.from_arrays(["bottom"], PLATE, PLATE_TRIANGLES, dhat=DHAT).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[tool])
    iterates = _watch(solver, tool)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=INCREMENT, max_increment=INCREMENT))
    reaction = ReactionForce(problem, "top")()
    assert tool.force()[2] == pytest.approx(-reaction[2], rel=1e-8)
    bottom = tool.surface.positions(problem.u.x.array)[:, 2]
    assert tool.force()[2] == pytest.approx(-_uniaxial_pzz(0.8 - bottom.mean()), rel=1e-3)
    assert min(iterates) > 0.0 and not tool.intersecting()


def test_tool_from_an_stl_file_equals_the_arrays(tmp_path):
    """The same plate written as STL (meshio) and read back: the same points and triangles, placed by offset/scale."""
    import meshio

    path = tmp_path / "plate.stl"
    meshio.write_points_cells(path, PLATE * 1e3, [("triangle", PLATE_TRIANGLES)], binary=True)  # in mm
    read = ToolContact(["bottom"], file=path, scale=1e-3, offset=(0.0, 0.0, 0.0))
    given = ToolContact.from_arrays(["bottom"], PLATE, PLATE_TRIANGLES)
    order = np.lexsort(read.points.T)
    assert np.allclose(read.points[order], given.points[np.lexsort(given.points.T)], atol=1e-9)
    assert len(read.triangles) == 2


def test_bad_tool_input_is_one_line(tmp_path):
    """Missing file, a file without triangles, an unknown group, a tool inside the body, bad entries: one line."""
    import meshio

    with pytest.raises(MeshError, match="not found"):
        ToolContact(["bottom"], file=tmp_path / "missing.stl")
    lines = tmp_path / "lines.vtk"
    meshio.write_points_cells(lines, PLATE, [("line", np.array([[0, 1]]))])
    with pytest.raises(MeshError, match="must lie in the plane z = 0"):  # line cells: a 2D polyline, but at z != 0
        ToolContact(["bottom"], file=lines)
    dots = tmp_path / "dots.vtk"
    meshio.write_points_cells(dots, PLATE, [("vertex", np.array([[0], [1]]))])
    with pytest.raises(MeshError, match=r"has no triangles \(a 3D tool\) or line segments \(a 2D polyline\)"):
        ToolContact(["bottom"], file=dots)
    garbled = tmp_path / "garbled.stl"
    garbled.write_bytes(b"solid tool\n  facet normal 0 0 1\n    outer loop\n      vertex 0 0\n")
    unreadable = r"^ToolContact on \['bottom'\]: cannot read the tool surface .*garbled"
    with pytest.raises(MeshError, match=unreadable) as info:
        ToolContact(["bottom"], file=garbled)
    assert "\n" not in str(info.value)
    with pytest.raises(ParameterError, match="dhat must be"):
        ToolContact.from_arrays(["bottom"], PLATE, PLATE_TRIANGLES, dhat=-1.0)
    with pytest.raises(ParameterError, match="either file or points"):
        ToolContact(["bottom"])
    problem = _pressed_cube()
    with pytest.raises(UnknownGroupError, match="available: bottom, top, x0, y0"):
        ToolContact.from_arrays(["floor"], PLATE, PLATE_TRIANGLES).bind(problem)
    inside = PLATE + np.array([0.05, 0.13, 0.5])  # a plate through the middle of the cube
    with pytest.raises(ParameterError, match=r"intersect at the start \(.*\): the edge from \(.*\) to \(.*\) "
                       r"crosses the triangle at \(") as info:
        ToolContact.from_arrays(["bottom", "top", "x0", "y0"], inside, PLATE_TRIANGLES).bind(problem)
    assert "\n" not in str(info.value)
    touching = PLATE + np.array([0.0, 0.0, DHAT / 2])  # the plane z = 0 of the bottom face
    # (Touching, or crossing where the mesh's coordinates carry round-off: z = -5.7e-17 on Debian's DOLFINx.)
    with pytest.raises(ParameterError, match=r"start in contact: the surface point at \(.*\) is at dist|intersect"):
        ToolContact.from_arrays(["bottom"], touching, PLATE_TRIANGLES).bind(problem)
    with pytest.raises(ParameterError, match="named twice"):
        SurfaceContact(["bottom", "bottom"])
    for bad in (0, 9, 1.5, True, "2"):
        with pytest.raises(ParameterError, match=r"subdivision must be an integer from 1 to 8, got"):
            SurfaceContact(["bottom"], subdivision=bad)
    with pytest.raises(ParameterError, match=r"ToolContact on \['bottom'\]: subdivision must be"):
        ToolContact.from_arrays(["bottom"], PLATE, PLATE_TRIANGLES, subdivision=0)


def test_ray_hits():
    """A ray straight down onto the unit triangle: the distance and the triangle; a ray beside it: none."""
    triangle = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    distance, index = ray_hits(np.array([[0.2, 0.2, 0.5], [0.9, 0.9, 0.5]]), np.array([0.0, 0.0, -1.0]), triangle)
    assert distance[0] == pytest.approx(0.5) and index[0] == 0
    assert np.isinf(distance[1]) and index[1] == -1


# -- obstacles pushed into a body that rests on them -----------------------------------------------------------------


def test_plane_pushed_into_a_resting_body_equals_the_body_pushed_onto_it():
    """The plane moved 0.1 up into the cube resting on it (top held) = the top pushed 0.1 down onto the fixed plane.

    The predictor carries the bottom nodes the plane would overrun with it
    (:meth:`~hyperfem.solver.external.ExternalTerms.carry`): one step, where
    refusing the start used to cut back to the minimum increment.
    """
    moved = _pressed_cube(delta=0.0)
    plane = PlaneContact("bottom", point=(0.0, 0.0, -DHAT / 2), normal=(0.0, 0.0, 1.0), dhat=DHAT,
                         motion=(0.0, 0.0, 0.1)).bind(moved)
    solver = hf.NewtonSolver(moved, TIGHT, external_energies=[plane])
    iterates = []
    solver.snes.setMonitor(lambda snes, it, norm: iterates.append(plane.min_distance(snes.getSolution())))
    records = hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    assert sum(r.rejected for r in records) == 0
    fixed = _pressed_cube(delta=0.1)
    still = PlaneContact("bottom", point=(0.0, 0.0, -DHAT / 2), normal=(0.0, 0.0, 1.0), dhat=DHAT).bind(fixed)
    hf.solve_quasistatic(hf.NewtonSolver(fixed, TIGHT, external_energies=[still]),
                         stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    assert plane.force()[2] == pytest.approx(still.force()[2], rel=1e-6)
    assert min(iterates) > 0.0


def _indented(comm, depth=0.25, degree=1, n=(6, 6, 3)):
    """A slab 1 x 1 x 0.5 clamped at the bottom; a rigid sphere (R = 0.2, 0.01 above it) pushed ``depth`` into it."""
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([1.0, 1.0, 0.5])], list(n))
    groups = {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], 0.5)}
    domain = hf.Domain.from_locators(mesh, groups, source="slab")
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS),
                                     bcs=[hf.PrescribedDisplacement("bottom", [0.0, 0.0, 0.0])], degree=degree)
    points, faces = icosphere(2)
    sphere = points * 0.2 + np.array([0.5, 0.5, 0.71])
    tool = ToolContact.from_arrays(["top"], sphere, faces, motion=(0.0, 0.0, -(0.01 + depth)), dhat=5e-3)
    barrier = tool.bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-9, "snes_atol": 1e-12}, external_energies=[barrier])
    iterates = _watch(solver, barrier)
    steps = hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.1, max_increment=0.1))
    return problem, barrier, iterates, steps


@pytest.mark.serial  # a tool carried by the predictor on 2 ranks: the surgery demo's test (tests/test_demos.py)
def test_tool_pushed_half_into_the_tissue_never_penetrates():
    """The sphere pushed to half the slab's thickness: every iterate and step intersection-free, force = reaction."""
    problem, tool, iterates, steps = _indented(MPI.COMM_WORLD)
    assert tool.time == 1.0
    reaction = ReactionForce(problem, "bottom")()
    assert tool.force() == pytest.approx(-reaction, rel=1e-6, abs=1e-8 * abs(reaction[2]))
    assert tool.force()[2] < -0.1 and min(iterates) > 0.0 and not tool.intersecting()
    lowest = tool.surface.positions(problem.u.x.array)[:, 2].min()
    assert lowest < 0.5 - 0.2  # the top surface went down with the tool, half the thickness (0.25) less d-hat


def test_tool_pushed_into_a_p2_slab_through_the_proxy():
    """The sphere pushed half into a P2 slab (3 x 3 x 2 boxes), its top through the default collision proxy (169
    vertices for 49 nodes): the predictor carries the nodes of the overrun proxy vertices (1 and 2 ranks alike), no
    iterate or step penetrates or intersects, the force is the reaction."""
    problem, tool, iterates, steps = _indented(MPI.COMM_WORLD, degree=2, n=(3, 3, 2))
    assert (tool.surface.size, tool.surface.collision_size) == (49, 169) and tool.time == 1.0
    reaction = ReactionForce(problem, "bottom")()
    assert tool.force() == pytest.approx(-reaction, rel=1e-6, abs=1e-8 * abs(reaction[2]))
    assert tool.force()[2] < -0.1 and min(iterates) > 0.0 and not tool.intersecting()
    assert tool.surface.positions(problem.u.x.array)[:, 2].min() < 0.5 - 0.2


def test_self_contact_of_one_group_equals_the_pair():
    """One boundary group holding both facing faces (self-contact of a group) gives the pair's reaction to 1e-4.

    (The same pairs, in another order: round-off may pick another of the equilibria a few 1e-6 apart,
    ``test_two_blocks_one_rank_equals_two_ranks``.)
    """
    delta = 0.2
    pair_problem, pair, _ = _stacked(delta=delta)
    stacked = hf.mesh.stacked_blocks_mesh(0.5, 0.34, GAP)
    groups = {
        "facing": lambda x: np.isclose(x[2], 0.0) | np.isclose(x[2], GAP),
        "x0": lambda x: np.isclose(x[0], 0.0),
        "y0": lambda x: np.isclose(x[1], 0.0),
        "lower_bottom": lambda x: np.isclose(x[2], -1.0),
        "upper_top": lambda x: np.isclose(x[2], 1.0 + GAP),
    }
    domain = hf.Domain.from_locators(stacked.mesh, groups, source="stacked blocks, one facing group")
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("lower_bottom", [0.0], components=[2]),
        hf.PrescribedDisplacement("upper_top", [-delta], components=[2]),
    ]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)
    contact = SurfaceContact(["facing"], dhat=DHAT).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=INCREMENT, max_increment=INCREMENT))
    assert contact.surface.size == pair.surface.size
    assert contact.active_count() == pytest.approx(pair.active_count(), rel=0.05)
    reaction = ReactionForce(pair_problem, "upper_top")()
    assert ReactionForce(problem, "upper_top")() == pytest.approx(reaction, rel=1e-4, abs=1e-4 * abs(reaction[2]))


# -- friction on a triangulated tool --------------------------------------------------------------------------------

MU = 0.3
# A plate whose inner edge (3, -1) -> (-1, 4.5) is parallel to no edge of the cube's mesh. Parallel edges make
# mollified edge-edge pairs in IPC, whose mollifier's gradient leaves a lateral force of some % of the normal
# one: with the square PLATE's diagonal under the cube's x = y edges, 4 % of N along x and y.
ROUGH_PLATE = PLATE + np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.5, 0.0]])
ROUGH_TRIANGLES = np.array([[0, 1, 3], [1, 2, 3]])


def _on_rough_tool(comm, mode: str, ratio: float = 0.0, degree: int = 1):
    """The cube pressed 0.05 on the plate (t in [0, 1]) with friction MU, then pushed along x (t in [1, 2]):
    a dead traction ``ratio * MU * N`` on the top (``mode="traction"``) or the top moved 0.2 (``"displacement"``)."""
    from hyperfem.loading import Ramp

    scale = [0.0]
    bcs = [hf.PrescribedDisplacement("top", [-0.05], components=[2], profile=Ramp(1.0))]
    loads = []
    if mode == "traction":
        loads = [hf.DeadTraction("top", (1.0, 0.0, 0.0), profile=lambda t: scale[0] * min(max(t - 1.0, 0.0), 1.0))]
    else:
        bcs.append(hf.PrescribedDisplacement("top", [0.2], components=[0], profile=Ramp(2.0, t0=1.0)))
    material = lambda F: hf.materials.neo_hookean(F, PARAMS)  # noqa: E731
    problem = hf.HyperelasticProblem(_cube(comm, 2), material, bcs=bcs, loads=loads, degree=degree)
    tool = ToolContact.from_arrays(["bottom"], ROUGH_PLATE, ROUGH_TRIANGLES, dhat=DHAT, friction=MU).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[tool], check_rigid_motion=False)
    stepping = hf.LoadStepping(initial_increment=0.25, max_increment=0.25)
    hf.solve_quasistatic(solver, 1.0, stepping=stepping)
    scale[0] = ratio * MU * float(tool.force()[2])
    before = tool.surface.positions(problem.u.x.array)[:, 0]
    hf.solve_quasistatic(solver, 2.0, stepping=stepping)
    slip = float(np.abs(tool.surface.positions(problem.u.x.array)[:, 0] - before).max())
    return problem, tool, scale[0], slip


def test_tool_friction_sticks_below_mu_n():
    """A push of half mu N: the friction force balances it to 1e-8, the normal force stays normal, the bottom sticks.

    Sticking: the bottom moves 1.1e-3 in all (11 epsilon: the lag's elastic stick plus a partial slip of the pairs
    that carry less normal force), where the block dragged in the next test slides 0.15.
    """
    problem, tool, T, slip = _on_rough_tool(MPI.COMM_WORLD, "traction", 0.5)
    friction = tool.friction_force()
    assert friction[0] == pytest.approx(-T, rel=1e-8) and abs(friction[1]) < 1e-8 * T
    assert np.abs(tool.force()[:2]).max() < 1e-8 * tool.force()[2]
    assert slip < 20 * tool.friction_epsilon
    assert tool.record()["tool_friction_force"] == pytest.approx(list(friction), abs=1e-14)


def _rough_state(comm) -> list[float]:
    problem, tool, T, slip = _on_rough_tool(comm, "traction", 0.5)
    return [*map(float, tool.force()), *map(float, tool.friction_force()), T, slip,
            float(problem.u.x.petsc_vec.norm())]


def test_tool_friction_one_rank_equals_two_ranks():
    """The cube on the rough tool pushed by half mu N: forces, friction, slip and displacement norm on 2 ranks equal
    1 rank's to 1e-10."""
    comm = MPI.COMM_WORLD
    one = serial_reference(_rough_state)
    assert _rough_state(comm) == pytest.approx(one, rel=1e-10, abs=1e-13)


@pytest.mark.serial  # the friction's 2-rank path: the stick test above runs on 2 ranks too
def test_tool_friction_slides_at_mu_n():
    """The top dragged 0.2 along x: the bottom slides (>> epsilon) and the friction force is mu N to 0.5 %."""
    problem, tool, _, slip = _on_rough_tool(MPI.COMM_WORLD, "displacement")
    assert slip > 100 * tool.friction_epsilon
    assert -tool.friction_force()[0] == pytest.approx(MU * tool.force()[2], rel=5e-3)


def test_tool_friction_through_the_collision_proxy():
    """A P2 cube on the rough plate, its bottom through the default collision proxy (81 vertices for 25 nodes):
    a push of half mu N is held (the friction force balances it to 1e-8, the bottom moves about 12 epsilon, the
    normal force stays normal); dragged, it slides at mu N to 0.5 % (measured 0.03 %)."""
    problem, tool, T, slip = _on_rough_tool(MPI.COMM_WORLD, "traction", 0.5, degree=2)
    assert (tool.surface.size, tool.surface.collision_size) == (25, 81)
    friction = tool.friction_force()
    assert friction[0] == pytest.approx(-T, rel=1e-8) and abs(friction[1]) < 1e-8 * T
    assert np.abs(tool.force()[:2]).max() < 1e-8 * tool.force()[2]
    assert slip < 20 * tool.friction_epsilon and not tool.intersecting()
    problem, tool, _, slip = _on_rough_tool(MPI.COMM_WORLD, "displacement", degree=2)
    assert slip > 100 * tool.friction_epsilon
    assert -tool.friction_force()[0] == pytest.approx(MU * tool.force()[2], rel=5e-3)


# -- dynamics ---------------------------------------------------------------------------------------------------------


def _dropped_fast(comm):
    """The free cube moving down at 5 m/s onto the plate 0.02 below it (backward Euler, dt = 0.05, to t = 0.4)."""
    from hyperfem import dynamics as dyn
    from hyperfem.simulation import Recorder, Simulation

    base = hf.HyperelasticProblem(_cube(comm, 2), lambda F: hf.materials.neo_hookean(F, PARAMS))
    problem = dyn.IncrementalProblem(base, dyn.BackwardEuler(), dyn.MassDensity(1.0))
    problem.v.interpolate(lambda x: np.vstack([0.0 * x[0], 0.0 * x[0], np.full(x.shape[1], -5.0)]))
    plate = ROUGH_PLATE + np.array([0.0, 0.0, DHAT / 2 - 0.02])
    tool = ToolContact.from_arrays(["bottom"], plate, ROUGH_TRIANGLES, dhat=DHAT).bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10, "snes_atol": 1e-10}, external_energies=[tool])
    problem.initial_acceleration(external=solver.external.gradient_array)
    iterates = _watch(solver, tool)

    class Checks:
        def record(self, step=None):
            barrier = comm.allreduce(tool.energy(problem.u.x.array), op=MPI.SUM)
            return {"barrier": barrier, "intersecting": tool.intersecting()}

    outputs = [Recorder(tool), Recorder(dyn.Diagnostics(problem)), Recorder(Checks())]
    summary = Simulation(problem, solver, dyn.TimeStepping(dt=0.05, t_end=0.4), outputs).run()
    return problem, summary, iterates


def test_block_dropped_fast_on_a_tool_plate_never_passes_through():
    """A free cube moving down at 5 m/s onto a triangulated plate 0.02 below it, backward Euler, dt = 0.05: the
    first guess puts the bottom 0.23 below the plate, on its far side at a positive distance; the sweep check pulls
    it back. No iterate or step penetrates or intersects, the total energy (kinetic + elastic + barrier) never
    grows, and the block bounces."""
    comm = MPI.COMM_WORLD
    problem, summary, iterates = _dropped_fast(comm)
    rows = summary["rows"]
    assert summary["completed"] and min(iterates) > 0.0 and not any(row["intersecting"] for row in rows)
    assert all(row["tool_min_distance"] > 0.0 for row in rows) and max(row["tool_force"][2] for row in rows) > 10.0
    total = [row["kinetic_energy"] + row["elastic_energy"] + row["barrier"] for row in rows]
    assert all(b <= a * (1 + 1e-9) for a, b in zip(total, total[1:], strict=False))
    velocity = problem.v.x.array.reshape(-1, 3)[:, 2]
    assert comm.allreduce(float(velocity.mean()) if len(velocity) else 0.0, op=MPI.SUM) > 0.0  # moving up again


def _dropped_fast_state(comm) -> list[float]:
    problem, summary, _ = _dropped_fast(comm)
    rows = summary["rows"]
    return [*(row["tool_force"][2] for row in rows), *(row["tool_min_distance"] for row in rows),
            float(problem.u.x.petsc_vec.norm()), float(problem.v.x.petsc_vec.norm())]


def test_fast_drop_one_rank_equals_two_ranks():
    """The fast drop on the tool plate: every step's force and smallest gap and the end displacement and velocity
    on 2 ranks equal 1 rank's to 1e-10."""
    comm = MPI.COMM_WORLD
    one = serial_reference(_dropped_fast_state)
    assert _dropped_fast_state(comm) == pytest.approx(one, rel=1e-10, abs=1e-13)


# -- checkpoint and restart ----------------------------------------------------------------------------------------


def _dragged_on_rough_tool(comm, folder, stop_after=None):
    """The cube pressed on the rough plate and dragged 0.2 along x (friction MU), in a Simulation with checkpoints."""
    from hyperfem.loading import Ramp
    from hyperfem.simulation import Checkpoint, Recorder, Simulation
    from hyperfem.simulation.outputs import Output

    class StopAfter(Output):
        def write(self, sim, step) -> None:
            if stop_after is not None and step is not None and step.step >= stop_after:
                raise KeyboardInterrupt(f"interrupted after step {step.step}")

    bcs = [
        hf.PrescribedDisplacement("top", [-0.05], components=[2], profile=Ramp(0.5)),
        hf.PrescribedDisplacement("top", [0.2], components=[0], profile=Ramp(1.0, t0=0.5)),
    ]
    material = lambda F: hf.materials.neo_hookean(F, PARAMS)  # noqa: E731
    problem = hf.HyperelasticProblem(_cube(comm, 2), material, bcs=bcs)
    tool = ToolContact.from_arrays(["bottom"], ROUGH_PLATE, ROUGH_TRIANGLES, dhat=DHAT, friction=MU).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[tool], check_rigid_motion=False)
    outputs = [Recorder(tool), StopAfter(), Checkpoint(folder / "ckpt", every=1)]
    return Simulation(problem, solver, hf.StepPolicy(increment=0.125), outputs, name="drag"), tool


def test_restart_with_friction_reproduces_the_uninterrupted_drag(shared_tmp):
    """Interrupted after 5 of 8 steps (mid-drag) and restarted: the friction lag is taken again at the restart state
    (ExternalTerms.remember), so the rows and the final friction force equal the uninterrupted run's to 1e-10."""
    comm = MPI.COMM_WORLD
    full, tool = _dragged_on_rough_tool(comm, shared_tmp / "full")
    reference = full.run()
    cut, _ = _dragged_on_rough_tool(comm, shared_tmp / "cut", stop_after=5)
    with pytest.raises(KeyboardInterrupt):
        cut.run()
    resumed, again = _dragged_on_rough_tool(comm, shared_tmp / "cut")
    summary = resumed.run(restart=shared_tmp / "cut" / "ckpt")
    assert summary["completed"] and summary["steps"] == reference["steps"]
    last, expected = summary["rows"][-1], reference["rows"][-1]
    assert last["tool_friction_force"] == pytest.approx(expected["tool_friction_force"], rel=1e-10, abs=1e-14)
    assert last["tool_force"] == pytest.approx(expected["tool_force"], rel=1e-10, abs=1e-14)
    assert -expected["tool_friction_force"][0] > 0.5 * MU * expected["tool_force"][2]  # it was sliding


def test_dhat_wider_than_the_body_is_refused():
    """A barrier width not below the body's smallest side (a width in mm for a mesh in m): one line, every contact."""
    problem = _pressed_cube()
    for contact in (
        PlaneContact("bottom", point=(0.0, 0.0, -0.5), normal=(0.0, 0.0, 1.0), dhat=2.0),
        ToolContact.from_arrays(["bottom"], PLATE, PLATE_TRIANGLES, dhat=1.0),
    ):
        with pytest.raises(ParameterError, match=r"dhat = [12] is not smaller than the body \(its bounding box's "
                           r"smallest side is 1\)"):
            contact.bind(problem)
