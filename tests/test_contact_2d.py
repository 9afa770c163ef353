r"""Mesh contact in 2D (plane strain): the boundary edges of triangles and quadrilaterals as segments.

The patch test of ``test_contact_surfaces.py`` in the plane: two unit squares
of one mesh (``lower`` below :math:`y = 0`, ``upper`` above :math:`y = g`,
meshed independently: non-matching edges where they meet), a roller on
:math:`x = 0`, the bottom of ``lower`` held in :math:`y`, the top of
``upper`` pushed down by :math:`\delta`. Frictionless, the exact state is
homogeneous plane-strain uniaxial stress of both squares (free lateral edge
:math:`x = 1`): with :math:`F = \mathrm{diag}(\lambda_x, \lambda_y)` and the
Neo-Hookean :math:`P = \mu F + (\lambda \ln J - \mu) F^{-T}`,
:math:`J = \lambda_x\lambda_y`, the lateral stretch solves

.. math::
    P_{xx} = \mu\lambda_x + \frac{\lambda\ln(\lambda_x\lambda_y) - \mu}{\lambda_x} = 0,

and the force through the interface (per unit thickness, the edge of length 1)
equals the top reaction and :math:`P_{yy} = \mu\lambda_y + (\lambda\ln J - \mu)/\lambda_y`,
with :math:`2\lambda_y = 2 + g - \delta - \bar g`, :math:`\bar g` the mean final gap.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

ipctk = pytest.importorskip("ipctk")

import hyperfem as hf  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402
from hyperfem.contact import SurfaceContact, TieContact, ToolContact  # noqa: E402
from hyperfem.contact.mesh_barrier import ray_hits  # noqa: E402
from hyperfem.contact.surface import global_dofs  # noqa: E402
from hyperfem.errors import ParameterError  # noqa: E402
from hyperfem.simulation.reactions import ReactionForce  # noqa: E402

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
TIGHT = {"snes_rtol": 1e-10, "snes_atol": 1e-12}
GAP, DHAT = 5e-4, 1e-3


def _plane_strain_pyy(stretch: float) -> float:
    """:math:`P_{yy}` of the plane-strain Neo-Hookean in uniaxial stress (lateral stretch from :math:`P_{xx} = 0`)."""
    from scipy.optimize import brentq

    mu, lam = PARAMS.mu, PARAMS.lmbda
    lx = brentq(lambda s: mu * s + (lam * np.log(stretch * s) - mu) / s, 0.5, 2.0)
    return mu * stretch + (lam * np.log(stretch * lx) - mu) / stretch


def _watch(solver, contact) -> list[float]:
    """The smallest pair distance of every accepted Newton iterate."""
    seen: list[float] = []
    solver.snes.setMonitor(lambda snes, it, norm: seen.append(contact.min_distance(snes.getSolution())))
    return seen


def _squares(comm, n_lower: int, n_upper: int, cell: str = "triangle", degree: int = 1, gap: float = GAP) -> hf.Domain:
    """Two unit squares, ``n^2`` boxes each, one mesh (all cells read on rank 0); ``degree`` 2: curved-capable
    geometry is not needed, the P2/Q2 displacement lives on the affine mesh."""
    import basix.ufl
    import ufl

    cell_type = dmesh.CellType.triangle if cell == "triangle" else dmesh.CellType.quadrilateral
    parts = []
    for y0, n in ((-1.0, n_lower), (gap, n_upper)):
        corners = [np.array([0.0, y0]), np.array([1.0, y0 + 1.0])]
        block = dmesh.create_rectangle(MPI.COMM_SELF, corners, [n, n], cell_type=cell_type)
        parts.append((block.geometry.x[:, :2].copy(), np.asarray(block.geometry.dofmaps[0]).copy()))
    k = parts[0][1].shape[1]
    if comm.rank == 0:
        x = np.vstack([parts[0][0], parts[1][0]])
        cells = np.vstack([parts[0][1], parts[1][1] + len(parts[0][0])]).astype(np.int64)
    else:
        x, cells = np.zeros((0, 2)), np.zeros((0, k), dtype=np.int64)
    element = ufl.Mesh(basix.ufl.element("Lagrange", cell, 1, shape=(2,)))
    mesh = dmesh.create_mesh(comm, cells, element, x)
    at = {"lower_bottom": (1, -1.0), "lower_top": (1, 0.0), "upper_bottom": (1, gap), "upper_top": (1, 1.0 + gap),
          "x0": (0, 0.0)}
    groups = {name: (lambda x, k=k, v=v: np.isclose(x[k], v)) for name, (k, v) in at.items()}
    return hf.Domain.from_locators(mesh, groups, source=f"two {cell} squares")


def _stacked(
    comm=MPI.COMM_WORLD, cell="triangle", n=(4, 3), degree=1, delta=0.2, boundaries=None, domain=None, subdivision=None
):
    domain = domain or _squares(comm, *n, cell=cell)
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("lower_bottom", [0.0], components=[1]),
        hf.PrescribedDisplacement("upper_top", [-delta], components=[1]),
    ]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs, degree=degree)
    contact = SurfaceContact(boundaries or ["lower_top", "upper_bottom"], dhat=DHAT, subdivision=subdivision)
    contact = contact.bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
    iterates = _watch(solver, contact)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.25, max_increment=0.25))
    return problem, contact, iterates


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_two_squares_transmit_the_plane_strain_uniaxial_stress(cell):
    """The patch test (module docstring): interface force = top reaction to 1e-8, = |P_yy| to 0.1 %; every accepted
    iterate intersection-free."""
    delta = 0.2
    problem, contact, iterates = _stacked(cell=cell, delta=delta)
    reaction = ReactionForce(problem, "upper_top")()
    force = contact.force(group=0)  # on lower_top, from the upper square: downward
    assert force.shape == (2,) and force[1] < 0.0
    assert force[1] == pytest.approx(reaction[1], rel=1e-8)
    surface = contact.surface
    assert surface.dim == 2 and surface.faces.shape == (4 + 3, 2)
    x = surface.positions(problem.u.x.array)
    lower, upper = x[surface.group == 0, 1], x[surface.group == 1, 1]
    stretch = (2.0 + GAP - delta - (upper.mean() - lower.mean())) / 2.0
    assert -reaction[1] == pytest.approx(-_plane_strain_pyy(stretch), rel=1e-3)
    # A lateral force of ~1e-3 |f_y| (measured 9.7e-4 triangles, 8.1e-4 quadrilaterals), balanced by the roller:
    # the end vertices at x = 1 of the two non-matching edges, whose edge-vertex pairs act at the edge's end.
    assert abs(force[0]) < 2e-3 * abs(force[1])
    # Uniform pressure: both edges stay straight to a fraction of d-hat (measured 0.07-0.1 d-hat).
    assert lower.std() < 0.3 * DHAT and upper.std() < 0.3 * DHAT
    assert 0.0 < contact.min_distance() < DHAT and contact.active_count() > 0
    assert min(iterates) > 0.0 and not contact.intersecting()


def _stacked_state(comm) -> tuple[float, float]:
    _, contact, _ = _stacked(comm)
    return float(contact.force(group=0)[1]), contact.min_distance()


def test_two_squares_one_rank_equals_two_ranks():
    """The interface force on 2 ranks equals 1 rank's to 1e-4 (not tighter: the frictionless barrier between
    non-matching facets has many equilibria, ``test_contact_surfaces.test_two_blocks_one_rank_equals_two_ranks``)."""
    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")
    one = _stacked_state(MPI.COMM_SELF) if comm.rank == 0 else None
    one = comm.bcast(one, root=0)
    two = _stacked_state(comm)
    assert two[0] == pytest.approx(one[0], rel=1e-4) and 0.0 < two[1] < DHAT and 0.0 < one[1] < DHAT


def test_a_body_driven_onto_another_from_afar_closes_in_the_steps_asked_for():
    """The upper square 0.05 above the lower one (50 barrier widths), its top pushed down 0.25 in 4 steps: the step
    that closes the gap starts from the collision-free part of the predictor's move (the rest of it crossed the
    lower square), not from a refused start cut back (before: 9 refused attempts, 13 steps). The force through the
    contact = the top reaction (1e-8) and the plane-strain P_yy (0.1 %) as when the squares start within reach."""
    gap = 0.05
    domain = _squares(MPI.COMM_WORLD, 4, 3, gap=gap)
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("lower_bottom", [0.0], components=[1]),
        hf.PrescribedDisplacement("upper_top", [-0.2 - gap], components=[1]),
    ]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)
    contact = SurfaceContact(["lower_top", "upper_bottom"], dhat=DHAT).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
    iterates = _watch(solver, contact)
    steps = hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.25, max_increment=0.25))
    assert [s.time for s in steps] == [0.25, 0.5, 0.75, 1.0]
    reaction = ReactionForce(problem, "upper_top")()
    assert contact.force(group=0)[1] == pytest.approx(reaction[1], rel=1e-8)
    x = contact.surface.positions(problem.u.x.array)
    lower, upper = x[contact.surface.group == 0, 1], x[contact.surface.group == 1, 1]
    stretch = (2.0 + gap - 0.2 - gap - (upper.mean() - lower.mean())) / 2.0
    assert -reaction[1] == pytest.approx(-_plane_strain_pyy(stretch), rel=1e-3)
    assert min(iterates) > 0.0 and not contact.intersecting()


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
@pytest.mark.parametrize(("subdivision", "low", "high"), [(1, 0.015, 0.04), (None, 0.0, 4e-3)])
def test_degree_two_edges_balance_the_reaction(cell, subdivision, low, high):
    """Degree 2: a boundary edge is two segments through its midpoint node; equilibrium holds to 1e-8 and nothing
    intersects. On the nodes the force is 2.2 % (P2 triangles) and 3.0 % (Q2) below |P_yy| (measured, 2 x 2 below,
    1 x 1 above): the nodal barrier on quadratic edges does not carry a uniform pressure. Through the default
    collision proxy (an edge in 4 segments, hyperfem.contact.proxy) 0.15 % and 0.14 %."""
    delta = 0.2
    problem, contact, iterates = _stacked(cell=cell, n=(2, 1), degree=2, delta=delta, subdivision=subdivision)
    reaction = ReactionForce(problem, "upper_top")()
    assert contact.force(group=0)[1] == pytest.approx(reaction[1], rel=1e-8) and reaction[1] < 0.0
    surface = contact.surface
    assert surface.faces.shape == (2 * (2 + 1), 2) and surface.size == 5 + 3  # every edge node a vertex
    x = surface.positions(problem.u.x.array)
    lower, upper = x[surface.group == 0, 1], x[surface.group == 1, 1]
    stretch = (2.0 + GAP - delta - (upper.mean() - lower.mean())) / 2.0
    assert low <= abs(reaction[1] / _plane_strain_pyy(stretch) - 1.0) < high
    assert min(iterates) > 0.0 and 0.0 < contact.min_distance() < DHAT and not contact.intersecting()


def test_self_contact_of_one_group_equals_the_pair():
    """One boundary group holding both facing edges (self-contact of a group) gives the pair's reaction to 1e-4."""
    pair_problem, pair, _ = _stacked()
    stacked = _squares(MPI.COMM_WORLD, 4, 3)
    groups = {
        "facing": lambda x: np.isclose(x[1], 0.0) | np.isclose(x[1], GAP),
        "x0": lambda x: np.isclose(x[0], 0.0),
        "lower_bottom": lambda x: np.isclose(x[1], -1.0),
        "upper_top": lambda x: np.isclose(x[1], 1.0 + GAP),
    }
    domain = hf.Domain.from_locators(stacked.mesh, groups, source="two squares, one facing group")
    problem, contact, iterates = _stacked(domain=domain, boundaries=["facing"])
    assert contact.surface.size == pair.surface.size and min(iterates) > 0.0
    reaction = ReactionForce(pair_problem, "upper_top")()
    assert ReactionForce(problem, "upper_top")() == pytest.approx(reaction, rel=1e-4, abs=1e-4 * abs(reaction[1]))


def test_barrier_taylor():
    """The 2D barrier's gradient and (exact) Hessian against its energy: Taylor remainders of order 2 and 3, with
    the squares 0.4 d-hat apart (edge-vertex pairs active) and a random perturbation of the surface nodes."""
    comm = MPI.COMM_WORLD
    domain = _squares(comm, 4, 3)
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS))
    barrier = SurfaceContact(["lower_top", "upper_bottom"], dhat=DHAT, stiffness=1.0).bind(problem)
    surface = barrier.surface
    u = problem.u.x.array.copy()
    # The upper edge moved down to 0.3-0.4 d-hat above the lower one (tilted) and 0.01 along x: every vertex in reach
    # projects inside an edge of the other side (the vertex-vertex pairs of the aligned corners at x = 0 and 1 would
    # switch type under the perturbation, where the barrier is not twice differentiable).
    upper = surface.group[surface.rows] == 1
    x = surface.X[surface.rows, 0]
    u[surface.dofs[upper, 1]] = -(GAP - 0.3 * DHAT + 1e-4 * x[upper])
    u[surface.dofs[upper, 0]] = 0.01
    assert barrier.active_count(u) == 7 and 0.0 < barrier.min_distance(u) < DHAT

    def total(v):
        return comm.allreduce(barrier.energy(v), op=MPI.SUM)

    rng = np.random.default_rng(7)
    du = np.zeros_like(u)
    du[surface.dofs.ravel()] = rng.standard_normal(surface.dofs.size) * 1e-5
    problem.u.x.array[:] = du
    problem.u.x.scatter_forward()  # the owners' values on the ghosts too
    du = problem.u.x.array.copy()
    problem.u.x.array[:] = 0.0
    dofs, g = barrier.gradient(u)
    slope = comm.allreduce(float((g * du[dofs]).sum()), op=MPI.SUM)
    rows, cols, values = barrier.coupled_hessian(u)
    assert barrier.exact_tangent is False  # first tangent: projected; exact once the iterates settle
    rows, cols, values = barrier.coupled_hessian(u)
    assert barrier.exact_tangent is True
    owned = problem.u.function_space.dofmap.index_map.size_local * 2
    full = np.zeros(2 * problem.u.function_space.dofmap.index_map.size_global)
    full[global_dofs(problem)[:owned]] = du[:owned]
    full = comm.allreduce(full, op=MPI.SUM)  # du by global dof, from its owner
    curvature = comm.allreduce(float((values * full[rows] * full[cols]).sum()), op=MPI.SUM)
    e0 = total(u)
    r1, r2 = [], []
    for h in (1.0, 0.5, 0.25):
        e = total(u + h * du)
        r1.append(abs(e - e0 - h * slope))
        r2.append(abs(e - e0 - h * slope - 0.5 * h * h * curvature))
    assert r1[1] / r1[0] == pytest.approx(0.25, rel=0.1) and r1[2] / r1[1] == pytest.approx(0.25, rel=0.1)
    assert r2[1] / r2[0] == pytest.approx(0.125, rel=0.2) and r2[2] / r2[1] == pytest.approx(0.125, rel=0.2)


# -- a rigid polyline tool ------------------------------------------------------------------------------------------


def _pressed_square(comm=MPI.COMM_WORLD, delta=0.2, cell="triangle"):
    cell_type = dmesh.CellType.triangle if cell == "triangle" else dmesh.CellType.quadrilateral
    mesh = dmesh.create_unit_square(comm, 3, 3, cell_type=cell_type)
    groups = {"bottom": lambda x: np.isclose(x[1], 0.0), "top": lambda x: np.isclose(x[1], 1.0),
              "x0": lambda x: np.isclose(x[0], 0.0)}
    domain = hf.Domain.from_locators(mesh, groups, source="unit square")
    bcs = [hf.PrescribedDisplacement("x0", [0.0], components=[0]),
           hf.PrescribedDisplacement("top", [-delta], components=[1])]
    return hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)


PLATE = np.array([[-1.0, -DHAT / 2], [0.7, -DHAT / 2], [3.0, -DHAT / 2]])  # two segments, a kink-free polyline
PLATE_SEGMENTS = np.array([[0, 1], [1, 2]])


@pytest.mark.parametrize("cell", ["triangle", "quadrilateral"])
def test_flat_polyline_tool_is_the_plane(cell):
    """A straight two-segment polyline under the pressed square: force = reaction to 1e-8, = |P_yy| to 0.1 %."""
    problem = _pressed_square(cell=cell)
    tool = ToolContact.from_arrays(["bottom"], PLATE, PLATE_SEGMENTS, dhat=DHAT).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[tool])
    iterates = _watch(solver, tool)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.25, max_increment=0.25))
    reaction = ReactionForce(problem, "top")()
    assert tool.force().shape == (2,) and tool.force()[1] == pytest.approx(-reaction[1], rel=1e-8)
    bottom = tool.surface.positions(problem.u.x.array)[:, 1]
    assert tool.force()[1] == pytest.approx(-_plane_strain_pyy(0.8 - bottom.mean()), rel=1e-3)
    assert min(iterates) > 0.0 and not tool.intersecting()


def test_polyline_tool_read_from_a_file_is_the_arrays_tool(shared_tmp):
    """A polyline in a gmsh or VTU file (line cells, z = 0; an unused point dropped) gives the arrays' tool: the same
    points and segments, and pressed under the square the same force as the reaction (to 1e-8)."""
    import meshio

    padded = np.vstack([np.hstack([PLATE, np.zeros((3, 1))]), [[9.0, 9.0, 0.0]]])
    files = [shared_tmp / "plate.msh", shared_tmp / "plate.vtu"]
    if MPI.COMM_WORLD.rank == 0:
        for path in files:
            kwargs = {"file_format": "gmsh22", "binary": False} if path.suffix == ".msh" else {}
            meshio.write_points_cells(path, padded, [("line", PLATE_SEGMENTS)], **kwargs)
    MPI.COMM_WORLD.barrier()
    for path in files:
        tool = ToolContact(["bottom"], file=path, dhat=DHAT)
        np.testing.assert_array_equal(tool.points, PLATE)
        np.testing.assert_array_equal(tool.triangles, PLATE_SEGMENTS)
    problem = _pressed_square()
    bound = tool.bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[bound])
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.25, max_increment=0.25))
    assert bound.force()[1] == pytest.approx(-ReactionForce(problem, "top")()[1], rel=1e-8)


def test_polyline_tool_pushed_into_a_resting_square_equals_the_square_pushed_onto_it():
    """The tool moved 0.1 up into the square resting on it (top held) = the top pushed 0.1 down onto the fixed tool:
    the predictor carries the bottom nodes the tool would overrun (2D ray casting against the segments)."""
    moved = _pressed_square(delta=0.0)
    tool = ToolContact.from_arrays(["bottom"], PLATE, PLATE_SEGMENTS, dhat=DHAT, motion=(0.0, 0.1)).bind(moved)
    solver = hf.NewtonSolver(moved, TIGHT, external_energies=[tool])
    iterates = _watch(solver, tool)
    records = hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    assert sum(r.rejected for r in records) == 0
    fixed = _pressed_square(delta=0.1)
    still = ToolContact.from_arrays(["bottom"], PLATE, PLATE_SEGMENTS, dhat=DHAT).bind(fixed)
    hf.solve_quasistatic(hf.NewtonSolver(fixed, TIGHT, external_energies=[still]),
                         stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    assert tool.force()[1] == pytest.approx(still.force()[1], rel=1e-6)
    assert min(iterates) > 0.0 and not tool.intersecting()


def test_square_dragged_on_a_rough_polyline_slides_at_mu_n():
    """Friction in 2D (ipctk's tangential collisions of edge-vertex pairs): the square pressed 0.05 on the polyline
    (mu = 0.3), then its top dragged 0.2 along x in steps of 0.125: the bottom slides (>> epsilon) and the friction
    force is mu N to 0.5 % (measured 8e-6; 1.6 % with steps of 0.25, where the first drag step still sticks)."""
    from hyperfem.loading import Ramp

    mesh = dmesh.create_unit_square(MPI.COMM_WORLD, 3, 3)
    groups = {"bottom": lambda x: np.isclose(x[1], 0.0), "top": lambda x: np.isclose(x[1], 1.0)}
    domain = hf.Domain.from_locators(mesh, groups, source="unit square")
    bcs = [hf.PrescribedDisplacement("top", [-0.05], components=[1], profile=Ramp(1.0)),
           hf.PrescribedDisplacement("top", [0.2], components=[0], profile=Ramp(2.0, t0=1.0))]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)
    tool = ToolContact.from_arrays(["bottom"], PLATE, PLATE_SEGMENTS, dhat=DHAT, friction=0.3).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[tool], check_rigid_motion=False)
    stepping = hf.LoadStepping(initial_increment=0.125, max_increment=0.125)
    hf.solve_quasistatic(solver, 1.0, stepping=stepping)
    before = tool.surface.positions(problem.u.x.array)[:, 0]
    hf.solve_quasistatic(solver, 2.0, stepping=stepping)
    slip = float(np.abs(tool.surface.positions(problem.u.x.array)[:, 0] - before).max())
    assert slip > 100 * tool.friction_epsilon
    assert -tool.friction_force()[0] == pytest.approx(0.3 * tool.force()[1], rel=5e-3)
    assert tool.moment().shape == (3,) and tool.moment()[:2].tolist() == [0.0, 0.0]


def _tied_squares(comm=MPI.COMM_WORLD, delta=0.2, cell="triangle", degree=1):
    """The two squares (non-matching: 4 x 4 below, 3 x 3 above, 5e-4 apart) glued and pulled apart by ``delta``."""
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("lower_bottom", [0.0], components=[1]),
        hf.PrescribedDisplacement("upper_top", [delta], components=[1]),
    ]
    domain = _squares(comm, 4, 3, cell=cell)
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs, degree=degree)
    tie = TieContact("upper_bottom", "lower_top").bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10, "snes_atol": 1e-7}, external_energies=[tie])
    assert all(step.solve.converged for step in hf.solve_quasistatic(solver))
    return problem, tie


@pytest.mark.parametrize(
    ("cell", "degree"), [("triangle", 1), ("quadrilateral", 1), ("triangle", 2), ("quadrilateral", 2)]
)
def test_tie_glues_non_matching_squares_in_plane_strain_uniaxial_stress(cell, degree):
    """A 2D tie (nodes on the other group's segments) holds the homogeneous state: with the reference gap kept,
    each square stretches by 1 + delta/2, and the pull is the closed-form plane-strain P_yy (P1, Q1: measured
    4e-9 off). Degree 2 through the collision proxy: 2e-10 and 3e-10 (on the nodes alone it was 2.3e-4 and
    2.5e-4 off: the tie's forces lived on the linear sub-segments and could not reproduce the (1, 4, 1)/6
    consistent loads of a uniform traction on non-matching P2 edges)."""
    delta = 0.2
    problem, tie = _tied_squares(delta=delta, cell=cell, degree=degree)
    reaction = ReactionForce(problem, "upper_top")()
    assert reaction[1] == pytest.approx(_plane_strain_pyy(1.0 + delta / 2), rel=1e-6)
    # The pull balances the tie (y; the x reaction of upper_top includes its corner's on the x0 roller)
    assert tie.force()[1] == pytest.approx(-reaction[1], rel=1e-6)
    assert tie.max_gap() < 1e-6 * delta and np.allclose(tie.gaps, GAP)
    assert tie.dim == 2 and len(tie.record()["tie_force"]) == 2


def test_tie_2d_one_rank_equals_two_ranks():
    """The glued squares on 2 ranks equal 1 rank to 1e-10 in the reaction."""
    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")

    def pull(c):
        problem, _ = _tied_squares(c)
        return float(ReactionForce(problem, "upper_top")()[1])

    one = comm.bcast(pull(MPI.COMM_SELF) if comm.rank == 0 else None, root=0)
    assert pull(comm) == pytest.approx(one, rel=1e-10)


def test_closest_on_segments():
    """The closest point of a point on a set of segments: inside one, at an end, the nearer of two."""
    from hyperfem.contact.tie import closest_on_segments

    segments = np.array([[[0.0, 0.0], [1.0, 0.0]], [[1.0, 0.0], [1.0, 1.0]]])
    points = np.array([[0.25, 0.5], [2.0, 2.0], [0.9, 0.3], [-1.0, 0.0]])
    index, weights, distance = closest_on_segments(points, segments)
    np.testing.assert_array_equal(index, [0, 1, 1, 0])
    np.testing.assert_allclose(weights, [[0.75, 0.25], [0.0, 1.0], [0.7, 0.3], [1.0, 0.0]])
    np.testing.assert_allclose(distance, [0.5, np.sqrt(2.0), 0.1, 1.0])


def test_ray_hits_segments():
    """A ray straight down onto a segment: the distance and the segment; a ray beside it: none."""
    segment = np.array([[[0.0, 0.0], [1.0, 0.0]]])
    distance, index = ray_hits(np.array([[0.2, 0.5], [1.5, 0.5]]), np.array([0.0, -1.0]), segment)
    assert distance[0] == pytest.approx(0.5) and index[0] == 0
    assert np.isinf(distance[1]) and index[1] == -1


# -- refusals ---------------------------------------------------------------------------------------------------------


def test_unsupported_input_is_refused_in_one_line():
    """A 1D mesh, a 3D tool on a 2D mesh, a 2D tool's bad entries: one-line ParameterErrors."""
    from types import SimpleNamespace

    from hyperfem.contact.surface import contact_surface

    comm = MPI.COMM_WORLD
    line = hf.Domain.from_locators(dmesh.create_unit_interval(comm, 4), {"end": lambda x: np.isclose(x[0], 1.0)})
    with pytest.raises(ParameterError, match=r"^SurfaceContact: mesh contact needs a 3D mesh of tetrahedra or "
                       r"hexahedra or a 2D mesh of triangles or quadrilaterals, got 1D interval cells$"):
        contact_surface(SimpleNamespace(domain=line), ["end"], "SurfaceContact")
    problem = _pressed_square(delta=0.0)
    triangle = np.array([[-1.0, -1.0, -0.1], [3.0, -1.0, -0.1], [0.0, 3.0, -0.1]])
    with pytest.raises(ParameterError, match=r"^ToolContact on \['bottom'\]: a 3D tool on a 2D mesh; give a "
                       r"polyline, points \(k, 2\) and segments \(s, 2\) \(ToolContact.from_arrays\) or a file "
                       r"of line segments at z = 0$"):
        ToolContact.from_arrays(["bottom"], triangle, np.array([[0, 1, 2]])).bind(problem)
    with pytest.raises(ParameterError, match=r"segments of a 2D tool must be \(s, 2\) indices into points$"):
        ToolContact.from_arrays(["bottom"], PLATE, np.array([[0, 1, 2]]))
    with pytest.raises(ParameterError, match=r"motion must have 2 components, got 3$"):
        ToolContact.from_arrays(["bottom"], PLATE, PLATE_SEGMENTS, motion=(0.0, 0.0, 1.0))
    from hyperfem.loading import RigidRotation

    with pytest.raises(ParameterError, match=r"a rotation needs a 3D obstacle, got 2 components$"):
        ToolContact.from_arrays(["bottom"], PLATE, PLATE_SEGMENTS,
                                rotation=RigidRotation((0.0, 0.0, 1.0), lambda t: t, (0.0, 0.0, 0.0)))
    touching = PLATE + np.array([0.0, DHAT / 2])
    with pytest.raises(ParameterError, match=r"start in contact|intersect at"):
        ToolContact.from_arrays(["bottom"], touching, PLATE_SEGMENTS, dhat=DHAT).bind(problem)
    through = np.array([[0.45, -1.0], [0.45, 0.5], [0.45, 2.0]])  # a vertical polyline through bottom and top
    with pytest.raises(ParameterError, match=r"intersect at the start \(.*\): the segment from \(.*\) to \(.*\) "
                       r"crosses the one from \("):
        ToolContact.from_arrays(["bottom", "top"], through, PLATE_SEGMENTS, dhat=DHAT).bind(problem)


# -- the case file --------------------------------------------------------------------------------------------------

PAIR_2D = """name = "two_squares"
[mesh]
file = "squares.msh"                 # lower below y = 0, upper above y = 5e-4 (non-matching edges)
[[material]]
law = "neo_hookean"
E = 1.0
nu = 0.3
[[bc]]
type = "displacement"
boundary = "x0"
value = [0.0]
components = ["x"]
[[bc]]
type = "displacement"
boundary = "lower_bottom"
value = [0.0]
components = ["y"]
[[bc]]
type = "displacement"
boundary = "upper_top"
value = [-0.2]
components = ["y"]
[[contact]]
type = "pair"
boundaries = ["lower_top", "upper_bottom"]
dhat = 1e-3
[stepping]
increment = 0.25
max_increment = 0.25
[solver]
rtol = 1e-10
atol = 1e-12
[output]
reactions = ["upper_top"]
fields = []
checkpoint = false
progress = false
"""


def test_tie_case_on_a_2d_mesh(shared_tmp):
    """``type = "tie"`` on the 2D gmsh squares (5e-4 apart, non-matching): pulled apart, the force on the first
    group = -the top reaction (1e-6) at every step and the plane-strain P_yy of a stretch 1 + 0.2/2 (1e-6)."""
    from hyperfem.app import build, load_case

    path = shared_tmp / "tied_squares.toml"
    tie = PAIR_2D.replace('type = "pair"', 'type = "tie"').replace("dhat = 1e-3\n", "")
    tie = tie.replace("value = [-0.2]", "value = [0.2]").replace("atol = 1e-12", "atol = 1e-7")
    if MPI.COMM_WORLD.rank == 0:
        _write_squares_msh(shared_tmp / "squares.msh")
        path.write_text(tie)
    MPI.COMM_WORLD.Barrier()
    summary = build(load_case(path, output=shared_tmp / "out")).simulation.run()
    rows = summary["rows"]
    assert summary["completed"] and summary["steps"] == 4
    for row in rows[1:]:
        assert row["contact_force"][1] == pytest.approx(row["reaction_upper_top_Fy"], rel=1e-6)
    assert rows[-1]["reaction_upper_top_Fy"] == pytest.approx(_plane_strain_pyy(1.1), rel=1e-6)
    assert rows[-1]["contact_max_gap"] < 1e-6


def _write_squares_msh(path) -> None:
    """Two unit squares (gmsh, triangles of sizes 0.25 and 0.34): the groups of :func:`_squares` plus the surfaces."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("squares")
        lower = gmsh.model.occ.addRectangle(0.0, -1.0, 0.0, 1.0, 1.0)
        upper = gmsh.model.occ.addRectangle(0.0, GAP, 0.0, 1.0, 1.0)
        gmsh.model.occ.synchronize()
        edges: dict[str, list[int]] = {k: [] for k in ("lower_bottom", "lower_top", "upper_bottom", "upper_top", "x0")}
        bodies = ((lower, "lower", (-1.0, 0.0), 0.25), (upper, "upper", (GAP, 1 + GAP), 0.34))
        for surface, prefix, (y0, y1), h in bodies:
            for _, tag in gmsh.model.getBoundary([(2, surface)], oriented=False):
                x, y, _ = gmsh.model.occ.getCenterOfMass(1, tag)
                if abs(y - y1) < 1e-9:
                    edges[f"{prefix}_top"].append(tag)
                elif abs(y - y0) < 1e-9:
                    edges[f"{prefix}_bottom"].append(tag)
                elif abs(x) < 1e-9:
                    edges["x0"].append(tag)
            gmsh.model.mesh.setSize(gmsh.model.getBoundary([(2, surface)], recursive=True), h)
        gmsh.model.addPhysicalGroup(2, [lower], 1, name="lower")
        gmsh.model.addPhysicalGroup(2, [upper], 2, name="upper")
        for k, (name, tags) in enumerate(edges.items()):
            gmsh.model.addPhysicalGroup(1, tags, 10 + k, name=name)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def _run_squares_case(folder, name: str, text: str, extra=None):
    """Write the two squares' mesh, ``extra(folder)``'s files and the case ``text`` (rank 0); build and run the case
    (4 steps): the built objects, the case file and the summary's rows."""
    from hyperfem.app import build, load_case

    path = folder / name
    if MPI.COMM_WORLD.rank == 0:
        _write_squares_msh(folder / "squares.msh")
        if extra is not None:
            extra(folder)
        path.write_text(text)
    MPI.COMM_WORLD.Barrier()
    built = build(load_case(path, output=folder / "out"))
    summary = built.simulation.run()
    assert summary["completed"] and summary["steps"] == 4
    return built, path, summary["rows"]


def test_pair_contact_case_on_a_2d_mesh(shared_tmp):
    """``type = "pair"`` on a 2D gmsh mesh of triangles: the force on lower_top = the top reaction (1e-8) at every
    step and the plane-strain P_yy to 0.1 %; a tool contact on a 2D mesh is refused in one line."""
    from hyperfem.app import build, load_case
    from hyperfem.app.casefile import CaseFileError

    built, path, rows = _run_squares_case(shared_tmp, "two_squares.toml", PAIR_2D)
    for row in rows[1:]:
        assert row["contact_force"][1] == pytest.approx(row["reaction_upper_top_Fy"], rel=1e-8)
    barrier = built.variables["contact"]
    surface = barrier.surface
    x = surface.positions(built.variables["problem"].u.x.array)
    stretch = (2.0 + GAP - 0.2 - (x[surface.group == 1, 1].mean() - x[surface.group == 0, 1].mean())) / 2.0
    assert -rows[-1]["reaction_upper_top_Fy"] == pytest.approx(-_plane_strain_pyy(stretch), rel=1e-3)
    tool = PAIR_2D.replace('type = "pair"', 'type = "tool"\nfile = "plate.stl"')
    if MPI.COMM_WORLD.rank == 0:
        import meshio

        plate = np.array([[-1.0, -2.0, -1.0], [3.0, -2.0, -1.0], [0.0, -2.0, 3.0]])
        meshio.write_points_cells(shared_tmp / "plate.stl", plate, [("triangle", np.array([[0, 1, 2]]))])
        path.write_text(tool)
    MPI.COMM_WORLD.Barrier()
    with pytest.raises(CaseFileError, match=r"contact\[0\]: .*a 3D tool on a 2D mesh; give a polyline"):
        build(load_case(path, output=shared_tmp / "out"))


TOOL_2D = PAIR_2D.replace(
    'boundary = "lower_bottom"\nvalue = [0.0]', 'boundary = "lower_top"\nvalue = [0.0]'
).replace('value = [-0.2]', 'value = [0.0]').replace(
    'type = "pair"\nboundaries = ["lower_top", "upper_bottom"]',
    'type = "tool"\nboundaries = ["lower_bottom"]\nfile = "plate.msh"\nmotion = [0.0, 0.1]',
).replace('reactions = ["upper_top"]', 'reactions = ["lower_top"]')


def test_polyline_tool_case_on_a_2d_mesh(shared_tmp):
    """``type = "tool"`` on a 2D gmsh mesh with a polyline file (gmsh line cells): a flat plate 2e-3 below the lower
    square (its top held in y) moves up 0.1. The tool's force = the reaction at the held top (1e-8) at every step and
    the plane-strain P_yy of the compressed square to 0.1 %; every step ends apart (min distance > 0);
    a motion of 3 components on the 2D mesh is refused in one line."""
    from hyperfem.app import build, load_case
    from hyperfem.app.casefile import CaseFileError

    below = -1.0 - 2e-3
    built, path, rows = _run_squares_case(shared_tmp, "tool_square.toml", TOOL_2D, _write_plate_polyline)
    for row in rows[1:]:
        assert row["contact_force"][1] == pytest.approx(-row["reaction_lower_top_Fy"], rel=1e-8)
        assert row["contact_min_distance"] > 0.0
    barrier = built.variables["contact"]
    x = barrier.surface.positions(built.variables["problem"].u.x.array)
    stretch = -(x[:, 1].mean() if len(x) else 0.0)  # the bottom's height; the top stays at y = 0
    assert barrier.force()[1] == pytest.approx(-_plane_strain_pyy(stretch), rel=1e-3)
    assert 0.0 < x[:, 1].mean() - (below + 0.1) < 1e-3  # the bottom rests on the plate, within dhat
    if MPI.COMM_WORLD.rank == 0:
        path.write_text(TOOL_2D.replace("motion = [0.0, 0.1]", "motion = [0.0, 0.1, 0.0]"))
    MPI.COMM_WORLD.Barrier()
    with pytest.raises(CaseFileError, match=r"contact\[0\]\.motion: 3 components \(the mesh .* has 2 displacement"):
        build(load_case(path, output=shared_tmp / "out"))


def _write_plate_polyline(folder):
    """A flat gmsh polyline 2e-3 below the lower square (the tool of :data:`TOOL_2D`)."""
    import meshio

    below = -1.0 - 2e-3
    meshio.write_points_cells(folder / "plate.msh", np.array([[-1.0, below, 0.0], [3.0, below, 0.0]]),
                              [("line", np.array([[0, 1]]))], file_format="gmsh22", binary=False)


@pytest.mark.parametrize("kind", ["pair", "tool"])
def test_2d_contact_cases_one_rank_equal_two_ranks(shared_tmp, kind):
    """The pair and polyline-tool cases on the ranks of ``mpiexec -n 2``: every step's contact force, smallest
    distance and reaction equal a 1-rank run's to 1e-10."""
    from hyperfem.app import build, load_case

    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")
    text, extra, reaction = {"pair": (PAIR_2D, None, "reaction_upper_top_Fy"),
                             "tool": (TOOL_2D, _write_plate_polyline, "reaction_lower_top_Fy")}[kind]
    _, path, rows = _run_squares_case(shared_tmp, f"{kind}_ranks.toml", text, extra)
    one = None
    if comm.rank == 0:
        summary = build(load_case(path, output=shared_tmp / "out_one"), MPI.COMM_SELF).simulation.run()
        one = summary["rows"]
    one = comm.bcast(one, root=0)
    assert len(one) == len(rows) == 5
    for a, b in zip(rows[1:], one[1:], strict=True):
        assert a["contact_force"] == pytest.approx(b["contact_force"], rel=1e-10, abs=1e-14)
        assert a[reaction] == pytest.approx(b[reaction], rel=1e-10)
        assert a["contact_min_distance"] == pytest.approx(b["contact_min_distance"], rel=1e-8)
