r"""Rigid obstacles that turn (issue 19: "translation/rotation profiles, as for Dirichlet values"): a ball, a
cylinder, a plane and a triangulated tool with a :class:`~hyperfem.loading.RigidRotation` composed with the translation.

The placement at time :math:`t` is :math:`x = R(\theta(t))(X - c_r) + c_r + f(t)\,m`. Checked: the composition
against the formula; a roller along :math:`x` turned to :math:`y` while the cube is pressed on it ends where the
static roller along :math:`y` does, and a plane tilted while the cube is pressed on it where the tilted plane
does; a plate spun in its own plane under the cube equals the static plate; a rough
ball turned about its own centre drags the node it holds (the friction's slip is relative to the ball's
surface); bad rotations are refused in one line. 1 rank = 2 ranks.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI

ipctk = pytest.importorskip("ipctk")

import hyperfem as hf  # noqa: E402
from hyperfem.contact import Ball, Cylinder, CylinderContact, PlaneContact, SphereContact, ToolContact  # noqa: E402
from hyperfem.contact.mesh_barrier import RigidSurface  # noqa: E402
from hyperfem.errors import ParameterError  # noqa: E402
from hyperfem.loading import Ramp, RigidRotation, Steady, rotation_matrix  # noqa: E402
from hyperfem.simulation.reactions import ReactionForce  # noqa: E402
from test_contact import _block  # noqa: E402
from test_contact_cylinder import RADIUS  # noqa: E402
from test_contact_surfaces import DHAT, PLATE, PLATE_TRIANGLES, TIGHT, _pressed_cube  # noqa: E402


def test_rotation_composes_with_translation():
    """Turned about the pivot, then translated: the centre, the axis and the tool's vertices against the formula;
    transfer() maps the placement at one time onto the placement at another."""
    rotation = RigidRotation((1.0, 2.0, 2.0), Ramp(2.0, final=1.2), center=(0.3, -0.1, 0.5))
    motion = np.array([0.2, -0.4, 0.1])
    t0, t1 = 0.5, 1.5
    R = rotation_matrix((1.0, 2.0, 2.0), 1.2 * t1 / 2.0)
    pivot = np.array([0.3, -0.1, 0.5])
    c0 = np.array([1.0, 0.5, -0.2])
    ball = Ball(c0, 0.4, motion, rotation=rotation)
    np.testing.assert_allclose(ball.origin(t1), R @ (c0 - pivot) + pivot + t1 * motion, rtol=0, atol=1e-14)
    cylinder = Cylinder(c0, (0.0, 0.0, 2.0), 0.4, motion, rotation=rotation)
    np.testing.assert_allclose(cylinder.axis_at(t1), R @ np.array([0.0, 0.0, 1.0]), rtol=0, atol=1e-15)
    x = np.array([[2.0, 0.0, 0.0], [0.0, 0.0, 3.0]])  # the distance of points is the turned cylinder's
    q = (x - cylinder.origin(t1)) @ (np.eye(3) - np.outer(R[:, 2], R[:, 2]))
    np.testing.assert_allclose(cylinder.signed_distance(x, t1), np.linalg.norm(q, axis=1) - 0.4, atol=1e-14)
    tool = RigidSurface(PLATE, PLATE_TRIANGLES, motion, lambda t: t, rotation)
    np.testing.assert_allclose(tool.vertices(t1), (PLATE - pivot) @ R.T + pivot + t1 * motion, atol=1e-14)
    np.testing.assert_allclose(tool.transfer(tool.vertices(t0), t0, t1), tool.vertices(t1), atol=1e-14)
    np.testing.assert_allclose(ball.transfer(ball.origin(t0), t0, t1), ball.origin(t1), atol=1e-14)
    # A ball turned about its own centre stays where it is.
    spun = Ball(c0, 0.4, rotation=RigidRotation((0.0, 1.0, 0.0), Ramp(1.0, final=2.0), center=tuple(c0)))
    np.testing.assert_allclose(spun.origin(0.7), c0, atol=1e-15)


def _on_roller(comm, contact: CylinderContact | PlaneContact) -> tuple:
    problem = _block(comm, n=3, delta=0.05)
    barrier = contact.bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[barrier])
    seen: list[float] = []
    solver.snes.setMonitor(lambda snes, it, norm: seen.append(barrier.min_distance(snes.getSolution())))
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    return problem, barrier, seen


TURN = math.pi / 3


def _turned_roller() -> CylinderContact:
    """A roller along x under the middle of the bottom face, turned by TURN t about the vertical through it."""
    rotation = RigidRotation((0.0, 0.0, 1.0), Ramp(1.0, final=TURN), center=(0.5, 0.5, 0.0))
    return CylinderContact("bottom", point=(0.5, 0.5, -RADIUS - 2e-3), axis=(1.0, 0.0, 0.0), radius=RADIUS,
                           dhat=1e-3, rotation=rotation)


def _placed_roller(angle: float) -> CylinderContact:
    """The same roller placed at ``angle`` from x, not turning."""
    return CylinderContact("bottom", point=(0.5, 0.5, -RADIUS - 2e-3), axis=(math.cos(angle), math.sin(angle), 0.0),
                           radius=RADIUS, dhat=1e-3)


def _roller_state(comm, contact) -> list[float]:
    problem, barrier, seen = _on_roller(comm, contact)
    assert min(seen) > 0.0 and barrier.active_count() > 0
    force = barrier.force()
    assert force[2] == pytest.approx(-ReactionForce(problem, "top")()[2], rel=1e-8)
    return [*force, barrier.min_distance(), float(problem.u.x.petsc_vec.norm())]


def test_turned_roller_ends_where_the_placed_roller_is():
    """Turned from x by pi/3 while the cube is pressed 0.05 on it: the force, gap and displacement of the roller
    placed at pi/3 from the start (frictionless: the end state does not depend on the path), to 1e-8; the roller
    that stays along x ends elsewhere."""
    turned = _roller_state(MPI.COMM_WORLD, _turned_roller())
    placed = _roller_state(MPI.COMM_WORLD, _placed_roller(TURN))
    assert turned == pytest.approx(placed, rel=1e-8, abs=1e-12)
    axis = np.array([math.cos(TURN), math.sin(TURN), 0.0])
    assert abs(np.dot(turned[:3], axis)) < 1e-10 * turned[2]  # no force along the turned axis
    assert _roller_state(MPI.COMM_WORLD, _placed_roller(0.0)) != pytest.approx(turned, rel=1e-4)


def test_turned_roller_one_rank_equals_two_ranks():
    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")
    one = _roller_state(MPI.COMM_SELF, _turned_roller()) if comm.rank == 0 else None
    one = comm.bcast(one, root=0)
    assert _roller_state(comm, _turned_roller()) == pytest.approx(one, rel=1e-10, abs=1e-14)


TILT = 0.02


def _tilted_plane(turning: bool) -> PlaneContact:
    """A plane 0.012 below the bottom, tilted by TILT about y through the middle below it (its edge below x = 0 up
    by 0.01): turned there with the load (``turning``), or placed there from the start."""
    pivot = (0.5, 0.5, -0.012)
    if turning:
        rotation = RigidRotation((0.0, 1.0, 0.0), Ramp(1.0, final=TILT), center=pivot)
        return PlaneContact("bottom", point=pivot, normal=(0.0, 0.0, 1.0), dhat=1e-3, rotation=rotation)
    return PlaneContact("bottom", point=pivot, normal=(math.sin(TILT), 0.0, math.cos(TILT)), dhat=1e-3)


@pytest.mark.serial  # three solves (4 s on 2 ranks); 1 rank = 2 ranks: test_turned_plane_one_rank_equals_two_ranks
def test_plane_turned_to_a_tilt_ends_where_the_tilted_plane_is():
    """The plane tilted by 0.02 about y while the cube is pushed 0.05 down onto it: the force, gap
    and displacement of the plane placed at that tilt from the start (frictionless: the end state does not depend
    on the path), to 1e-8; its normal and point follow the rotation; the flat plane ends elsewhere."""
    turned_plane = _tilted_plane(True)
    normal = turned_plane.obstacle.normal_at(1.0)
    np.testing.assert_allclose(normal, [math.sin(TILT), 0.0, math.cos(TILT)], rtol=0, atol=1e-15)
    np.testing.assert_allclose(turned_plane.obstacle.origin(0.5), (0.5, 0.5, -0.012), rtol=0, atol=1e-15)
    turned = _roller_state(MPI.COMM_WORLD, turned_plane)
    placed = _roller_state(MPI.COMM_WORLD, _tilted_plane(False))
    assert turned == pytest.approx(placed, rel=1e-8, abs=1e-12)
    assert turned[0] > 1e-3 * turned[2]  # the tilted plane pushes the cube along x too, against its rollers
    flat = PlaneContact("bottom", point=(0.5, 0.5, -0.012), normal=(0.0, 0.0, 1.0), dhat=1e-3)
    assert _roller_state(MPI.COMM_WORLD, flat) != pytest.approx(turned, rel=1e-4)


def test_turned_plane_one_rank_equals_two_ranks():
    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")
    one = _roller_state(MPI.COMM_SELF, _tilted_plane(True)) if comm.rank == 0 else None
    one = comm.bcast(one, root=0)
    assert _roller_state(comm, _tilted_plane(True)) == pytest.approx(one, rel=1e-10, abs=1e-14)


def _plate_state(points, rotation) -> list[float]:
    problem = _pressed_cube(delta=0.1)
    tool = ToolContact.from_arrays(["bottom"], points, PLATE_TRIANGLES, dhat=DHAT, rotation=rotation).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[tool])
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    assert tool.min_distance() > 0.0 and not tool.intersecting()
    return [*tool.force(), tool.min_distance(), float(problem.u.x.petsc_vec.norm())]


def test_tool_spun_in_its_plane_ends_where_the_turned_tool_is():
    """The plate (4 x 4, around the cube) spun by pi/4 t about the vertical through its middle while the cube is
    pressed on it: frictionless, the end state of the plate given turned by pi/4 from the start, to 1e-8 (its
    diagonal edge, which pushes sideways, is where the turned plate's is)."""
    rotation = RigidRotation((0.0, 0.0, 1.0), Ramp(1.0, final=math.pi / 4), center=(1.0, 1.0, 0.0))
    spun = _plate_state(PLATE, rotation)
    assert spun == pytest.approx(_plate_state(rotation.rotate(PLATE, 1.0), None), rel=1e-8, abs=1e-12)


def test_tool_turned_by_a_steady_rotation_is_the_turned_tool():
    """A steady tilt of the plate is the plate given with tilted points (the same numbers, to round-off)."""
    tilt = RigidRotation((1.0, 1.0, 0.0), Steady(0.05), center=(0.5, 0.5, -DHAT / 2))
    turned = ToolContact.from_arrays(["bottom"], PLATE, PLATE_TRIANGLES, rotation=tilt).surface.vertices(0.3)
    given = ToolContact.from_arrays(["bottom"], tilt.rotate(PLATE, 0.0), PLATE_TRIANGLES).surface.vertices(0.3)
    np.testing.assert_allclose(turned, given, rtol=0, atol=1e-15)


def test_rough_ball_turned_about_its_centre_drags_the_node_it_holds():
    """A ball under the bottom face, one node within dhat; the ball turned by 0.02 about y through its centre:
    its surface slides along x under the node, so friction pulls the node along +x with mu N (sliding); not
    turned, no friction force."""
    problem = _block(n=2)
    dhat, mu, R = 1e-2, 0.5, 0.5
    center = (0.5, 0.5, -R - dhat / 2)
    forces = []
    for angle in (0.0, 0.02):
        turn = RigidRotation((0.0, 1.0, 0.0), lambda t, a=angle: a * t, center=center)
        contact = SphereContact("bottom", center=center, radius=R, dhat=dhat, stiffness=1.0, friction=mu,
                                friction_epsilon=1e-4, rotation=turn).bind(problem)
        u = problem.u.x.array
        contact.lag(u)
        contact.update(1.0)  # the lag comes into use; the ball has turned (its centre stays)
        forces.append((contact.friction_force(), contact.force()))
    (still, _), (dragged, normal) = forces
    assert np.abs(still).max() <= 1e-12 * np.abs(dragged).max()  # nothing, up to round-off (6e-32 on Debian)
    assert normal[2] > 0.0  # the ball below pushes the bottom up
    assert dragged[0] == pytest.approx(mu * abs(normal[2]), rel=1e-6)
    assert abs(dragged[1]) < 1e-12 * dragged[0] and abs(dragged[2]) < 1e-12 * dragged[0]


def test_bad_rotations_are_one_line():
    with pytest.raises(ParameterError, match="axis must be a non-zero finite 3-vector"):
        RigidRotation((0.0, 0.0, 0.0), Steady(0.1))
    nan = RigidRotation((0.0, 0.0, 1.0), lambda t: float("nan"))
    with pytest.raises(ParameterError, match=r"SphereContact on 'bottom': rotation angle\(0\) must be a finite"):
        SphereContact("bottom", center=(0.5, 0.5, -1.0), radius=0.5, rotation=nan)
    with pytest.raises(ParameterError, match=r"CylinderContact on 'bottom': rotation angle\(0\) must be a finite"):
        CylinderContact("bottom", point=(0.5, 0.5, -1.0), axis=(1.0, 0.0, 0.0), radius=0.5, rotation=nan)
    with pytest.raises(ParameterError, match=r"ToolContact on \['bottom'\]: rotation angle\(0\) must be a finite"):
        ToolContact.from_arrays(["bottom"], PLATE, PLATE_TRIANGLES, rotation=nan)
    with pytest.raises(ParameterError, match="rotation must be a hyperfem.loading.RigidRotation"):
        SphereContact("bottom", center=(0.5, 0.5, -1.0), radius=0.5, rotation=(0.0, 0.0, 1.0))  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="a rotation needs a 3D obstacle"):
        SphereContact("bottom", center=(0.5, -1.0), radius=0.5, rotation=RigidRotation((0.0, 0.0, 1.0), Steady(0.1)))
    late = RigidRotation((0.0, 0.0, 1.0), lambda t: 0.0 if t < 1 else float("inf"))
    ball = Ball((0.0, 0.0, 0.0), 1.0, rotation=late)
    with pytest.raises(ParameterError, match=r"RigidRotation: angle\(2\) must be a finite number, got inf"):
        ball.origin(2.0)
