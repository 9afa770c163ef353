r"""Contact with a rigid plane (issue 19, first slice): the IPC barrier in the Newton system.

The reference case is a unit cube pressed on a frictionless plane: rollers on
:math:`x = 0` and :math:`y = 0`, the top face pushed down by :math:`\delta`, the
bottom face resting on the plane :math:`z = -\hat d/2` (the body starts at half
the barrier width from it). The exact state is homogeneous uniaxial
compression with free lateral faces: stretch :math:`\lambda` along :math:`z`,
lateral stretch :math:`\lambda_t` from :math:`P_{xx} = 0`, and the force on the
plane is :math:`|P_{zz}|` times the reference area 1, with the Neo-Hookean

.. math::
    P = \mu F + (\lambda_L \ln J - \mu) F^{-T}, \quad F = \mathrm{diag}(\lambda_t, \lambda_t, \lambda), \quad
    J = \lambda\lambda_t^2, \qquad
    P_{xx} = \mu\lambda_t + \frac{\lambda_L \ln J - \mu}{\lambda_t} = 0, \qquad
    P_{zz} = \mu\lambda + \frac{\lambda_L \ln J - \mu}{\lambda}.

:math:`\lambda` is the current height: the top at :math:`1 - \delta`, minus the
mean height of the bottom nodes (which rest within :math:`\hat d` of the
plane). The nodal barrier gives every bottom node a force that depends only on
its distance, which is not the consistent load of a uniform pressure, so the
computed state is homogeneous up to :math:`O(\hat d)`: 0.007 % for P1 at
:math:`\hat d = 10^{-3}`, 0.13 % for P2 (whose vertices carry no share of a
uniform pressure) at :math:`10^{-3}`, 0.014 % at :math:`10^{-4}`.
"""

from __future__ import annotations

import itertools
import subprocess
import sys

import numpy as np
import pytest
from mpi4py import MPI

ipctk = pytest.importorskip("ipctk")

import hyperfem as hf  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402
from hyperfem.contact import PlaneContact, barrier, barrier_derivatives, plane_step_fraction  # noqa: E402
from hyperfem.errors import ParameterError, UnknownGroupError  # noqa: E402
from hyperfem.loading import Ramp  # noqa: E402
from hyperfem.simulation import Recorder, Simulation  # noqa: E402
from hyperfem.simulation.measures import Reaction  # noqa: E402
from hyperfem.simulation.reactions import ReactionForce, Reactions  # noqa: E402
from ranks import serial_reference  # noqa: E402  (tests/ranks.py)

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
DHAT = 1e-3
TIGHT = {"snes_rtol": 1e-12, "snes_atol": 1e-12}


def _cube(comm, n: int):
    mesh = dmesh.create_unit_cube(comm, n, n, n)
    groups = {
        "bottom": lambda x: np.isclose(x[2], 0.0),
        "top": lambda x: np.isclose(x[2], 1.0),
        "x0": lambda x: np.isclose(x[0], 0.0),
        "y0": lambda x: np.isclose(x[1], 0.0),
    }
    return hf.Domain.from_locators(mesh, groups, source=f"cube({n})")


def _supports(delta: float, top_profile=None) -> list:
    """Rollers on x0 and y0, the top pushed down by ``delta`` (ramped with t, or with ``top_profile``)."""
    top = hf.PrescribedDisplacement("top", [-delta], components=[2])
    if top_profile is not None:
        top = hf.PrescribedDisplacement("top", [-delta], components=[2], profile=top_profile)
    return [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        top,
    ]


def _block(comm=MPI.COMM_WORLD, n=3, degree=1, delta=0.2, top_profile=None):
    """The pressed Neo-Hookean block (:func:`_supports`)."""
    return hf.HyperelasticProblem(
        _cube(comm, n), lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=_supports(delta, top_profile), degree=degree
    )


def _plane(dhat=DHAT, **kwargs) -> PlaneContact:
    return PlaneContact("bottom", point=(0.0, 0.0, -dhat / 2), normal=(0.0, 0.0, 1.0), dhat=dhat, **kwargs)


def uniaxial_stress(stretch: float) -> float:
    r""":math:`P_{zz}` of Neo-Hookean uniaxial stress at stretch ``stretch`` (module docstring; scalar Newton)."""
    mu, lam = PARAMS.mu, PARAMS.lmbda
    lt = 1.0
    for _ in range(50):
        J = stretch * lt * lt
        g = mu * lt + (lam * np.log(J) - mu) / lt
        dg = mu + 2.0 * lam / lt**2 - (lam * np.log(J) - mu) / lt**2
        lt -= g / dg
        if abs(g) < 1e-15:
            break
    J = stretch * lt * lt
    return mu * stretch + (lam * np.log(J) - mu) / stretch


def _height(problem, contact, delta: float) -> float:
    """Top at ``1 - delta`` minus the mean height of the contact nodes."""
    z = contact.nodes.positions(problem.u.x.array)[:, 2]
    total = problem.domain.comm.allreduce(float(z.sum()), op=MPI.SUM)
    return 1.0 - delta - total / contact.nodes.total


def _watch(solver, contact) -> list[float]:
    """The smallest distance of every accepted Newton iterate (a SNES monitor)."""
    seen: list[float] = []
    solver.snes.setMonitor(lambda snes, it, norm: seen.append(contact.min_distance(snes.getSolution())))
    return seen


# -- the barrier and the collision filter ---------------------------------------------------------------------------


def test_barrier_is_the_ipc_log_barrier():
    """b = -(d - dhat)^2 ln(d/dhat) on (0, dhat), 0 beyond, inf at d <= 0; b', b'' against finite differences."""
    d = np.array([-1e-4, 0.0, 1e-5, 3e-4, 9.99e-4, 1e-3, 2e-3])
    b = barrier(d, DHAT)
    inside = slice(2, 5)
    assert np.all(np.isinf(b[:2])) and np.all(b[5:] == 0.0)
    assert b[inside] == pytest.approx(-((d[inside] - DHAT) ** 2) * np.log(d[inside] / DHAT), rel=1e-14)
    first, second = barrier_derivatives(d, DHAT)
    assert np.all(np.isnan(first[:2])) and np.all(first[5:] == 0.0) and np.all(second[5:] == 0.0)
    h = 1e-9
    x = d[inside]
    assert first[inside] == pytest.approx((barrier(x + h, DHAT) - barrier(x - h, DHAT)) / (2 * h), rel=1e-5)
    f1p, _ = barrier_derivatives(x + h, DHAT)
    f1m, _ = barrier_derivatives(x - h, DHAT)
    assert second[inside] == pytest.approx((f1p - f1m) / (2 * h), rel=1e-5)
    assert np.all(first[inside] < 0.0) and np.all(second[inside] > 0.0)  # decreasing, convex: PSD blocks


def test_plane_step_fraction_is_ipctk_point_plane_ccd():
    """The analytic filter equals ipctk's point_static_plane_ccd times its conservative rescaling."""
    rng = np.random.default_rng(3)
    normal = np.array([0.0, 0.6, 0.8])
    origin = np.array([0.0, 0.0, 0.1])
    for _ in range(20):
        p0 = rng.uniform(0.2, 1.0, 3)
        p1 = p0 + rng.uniform(-2.0, 0.5, 3)
        d0, approach = (p0 - origin) @ normal, -(p1 - p0) @ normal
        hit, toi = ipctk.point_static_plane_ccd(p0, p1, origin, normal, 0.9)
        expected = toi if hit else 1.0
        assert plane_step_fraction(np.array([d0]), np.array([approach]), 0.9) == pytest.approx(expected, rel=1e-12)


def test_barrier_term_taylor():
    """Gradient and Hessian of kappa*B against finite differences of its energy (errors O(eps^2), O(eps^3))."""
    problem = _block(n=2)
    contact = _plane(dhat=1e-2, stiffness=0.5).bind(problem)
    comm = problem.domain.comm
    rng = np.random.default_rng(comm.rank)
    u = 1e-3 * rng.standard_normal(problem.u.x.array.size)
    du = 1e-3 * rng.standard_normal(u.size)

    def total(values):
        return comm.allreduce(contact.energy(values), op=MPI.SUM)

    def dot(a, b):
        return comm.allreduce(float(a @ b), op=MPI.SUM)

    dofs, g = contact.gradient(u)
    hdofs, blocks = contact.hessian(u)
    assert comm.allreduce(len(dofs), op=MPI.SUM) == contact.nodes.total  # every node within dhat
    G = np.zeros(u.size)
    np.add.at(G, dofs.ravel(), g.ravel())
    Hdu = np.zeros(u.size)
    np.add.at(Hdu, hdofs.ravel(), np.einsum("mij,mj->mi", blocks, du[hdofs]).ravel())
    E0, first, second = total(u), [], []
    for eps in (1e-1, 1e-2, 1e-3):
        E1 = total(u + eps * du)
        first.append(abs(E1 - E0 - eps * dot(G, du)))
        second.append(abs(E1 - E0 - eps * dot(G, du) - 0.5 * eps**2 * dot(du, Hdu)))
    assert np.array(first[1:]) / np.array(first[:-1]) == pytest.approx([1e-2, 1e-2], rel=0.05)
    assert np.array(second[1:]) / np.array(second[:-1]) == pytest.approx([1e-3, 1e-3], rel=0.1)


def test_newton_system_taylor_and_exact_dirichlet_rows():
    """The solver's objective, residual and tangent include the barrier consistently; Dirichlet rows stay identity.

    A tilted plane couples the components of every bottom node (its block is
    kappa b'' n n^T), so the roller rows of the nodes on x0 and y0 would pick up
    entries if the blocks were added without zeroing them.
    """
    problem = _block(n=2, delta=0.0)
    tilted = PlaneContact("bottom", point=(0.0, 0.0, -5e-3), normal=(0.0, 0.1, 1.0), dhat=0.2, stiffness=0.5)
    contact = tilted.bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[contact])
    x = problem.u.x.petsc_vec.copy()
    constrained = np.zeros(x.getLocalSize())
    for bc in problem.bcs:
        dofs = bc.dof_indices()[0]
        constrained[dofs[dofs < constrained.size]] = 1.0
    rng = np.random.default_rng(problem.domain.comm.rank)
    du = x.duplicate()
    du.array[:] = 1e-3 * rng.standard_normal(du.getLocalSize()) * (1.0 - constrained)
    r0, r1, Jdu = x.duplicate(), x.duplicate(), x.duplicate()
    A = solver.snes.getJacobian()[0]
    solver.snes.computeFunction(x, r0)
    solver.snes.computeJacobian(x, A)
    A.mult(du, Jdu)
    solver._set_state(x)
    E0 = solver.energy()
    errors, tangent = [], []
    for eps in (1e-1, 1e-2):
        xe = x.copy()
        xe.axpy(eps, du)
        solver._set_state(xe)
        errors.append(abs(solver.energy() - E0 - eps * r0.dot(du)))
        solver.snes.computeFunction(xe, r1)
        r1.axpy(-1.0, r0)
        r1.axpy(-eps, Jdu)
        tangent.append(r1.norm())
    assert errors[1] / errors[0] < 0.02 and tangent[1] / tangent[0] < 0.02
    e = x.duplicate()
    e.array[:] = constrained
    Ae = x.duplicate()
    A.mult(e, Ae)
    assert np.abs(Ae.array - constrained).max() == 0.0  # identity rows, zero columns at Dirichlet dofs
    assert contact.active_count() == contact.nodes.total


# -- the pressed block ----------------------------------------------------------------------------------------------


def _pressed(comm=MPI.COMM_WORLD, n=3, degree=1, delta=0.2, dhat=DHAT, policy=None):
    problem = _block(comm, n, degree, delta)
    contact = _plane(dhat=dhat).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
    iterates = _watch(solver, contact)
    outputs = [Recorder(contact), Reaction("top")]
    summary = Simulation(problem, solver, policy or hf.StepPolicy(increment=0.25), outputs).run()
    return problem, contact, summary, iterates


@pytest.mark.parametrize("degree, n, dhat", [(1, 3, DHAT), (2, 2, 1e-4)])
def test_block_on_plane_closed_form_and_reaction(degree, n, dhat):
    """Contact force = uniaxial Neo-Hookean stress x area (0.1 %) = -reaction of the pushed face; never penetrating."""
    delta = 0.2
    problem, contact, summary, iterates = _pressed(n=n, degree=degree, delta=delta, dhat=dhat)
    force = contact.force()
    exact = -uniaxial_stress(_height(problem, contact, delta))
    assert force[2] == pytest.approx(exact, rel=1e-3)
    assert np.abs(force[:2]).max() == 0.0  # frictionless plane z = const: a normal force only
    rows = summary["rows"]
    assert [row["contact_active"] for row in rows[1:]] == [contact.nodes.total] * (len(rows) - 1)
    for row in rows[1:]:  # at every step: the plane's force balances the reaction of the pushed face
        assert row["contact_force"][2] == pytest.approx(-row["reaction_top"][2], rel=1e-9)
        assert 0.0 < row["contact_min_distance"] < dhat
    assert iterates and min(iterates) > 0.0


def test_block_pushed_half_its_height_in_one_step():
    """The hard case: 50 % compression asked in one step; cutbacks and the filters keep every iterate feasible."""
    delta = 0.5
    problem, contact, summary, iterates = _pressed(n=4, delta=delta, policy=hf.StepPolicy(increment=1.0))
    assert summary["completed"] and summary["rejected"] >= 1
    assert min(iterates) > 0.0 and all(row["contact_min_distance"] > 0.0 for row in summary["rows"])
    assert contact.force()[2] == pytest.approx(-uniaxial_stress(_height(problem, contact, delta)), rel=1e-3)


def _force_and_norm(comm) -> tuple[float, float]:
    problem, contact, _, _ = _pressed(comm, n=3, delta=0.3)
    return float(contact.force()[2]), float(problem.u.x.petsc_vec.norm())


def test_one_rank_equals_two_ranks():
    """Contact force and displacement norm on 2 ranks equal those of 1 rank to 1e-10."""
    comm = MPI.COMM_WORLD
    one = serial_reference(_force_and_norm)
    two = _force_and_norm(comm)
    assert two == pytest.approx(one, rel=1e-10)


def test_three_field_problem_on_the_plane():
    """The (u, p, theta) problem: the contact nodes are its P2 displacement nodes; force balances the reaction."""
    from hyperfem.kinematics import isochoric_invariants
    from hyperfem.problem.mixed import SplitEnergy, solid_problem

    material = SplitEnergy(lambda F: 0.5 * PARAMS.mu * (isochoric_invariants(F)[0] - 3.0), 50.0 * PARAMS.mu)
    problem = solid_problem(_cube(MPI.COMM_WORLD, 2), material, formulation="mixed", bcs=_supports(0.2))
    contact = _plane().bind(problem)
    assert contact.nodes.total == 25  # P2 nodes of the 2 x 2 bottom face
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
    iterates = _watch(solver, contact)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.25, max_increment=0.25))
    reaction = ReactionForce(problem, "top")()
    assert contact.force()[2] == pytest.approx(-reaction[2], rel=1e-8) and contact.force()[2] > 0.0
    assert min(iterates) > 0.0 and contact.active_count() == 25


MUSCLE_FORCE = -0.8908204653303  # N, the run below at activation 1 (1 rank; 2 ranks agree to 1e-15)


def test_contracting_muscle_bulges_against_a_plane():
    """Muscle with contact: a block of seed 000's muscle (4 x 1 x 1 cm, fibres along x, the (u, p, theta)
    problem, K x 50) clamped at x = 0 and activated to 1 shortens and bulges sideways onto a rigid wall 0.2 mm from
    its side: the wall's force grows with the activation, balances the clamp's reaction at every step, no node
    reaches the wall, and the wall's moment (a per-step column) balances the clamp's; the end force is the trusted
    run's."""
    from dolfinx import fem

    from hyperfem.loading import Activation
    from hyperfem.materials.muscle import MuscleParameters, muscle_isochoric
    from hyperfem.problem.mixed import SplitEnergy, solid_problem

    length, width = 0.04, 0.01
    mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([length, width, width])], [4, 2, 2])
    groups = {"origin": lambda x: np.isclose(x[0], 0.0), "side": lambda x: np.isclose(x[1], width)}
    domain = hf.Domain.from_locators(mesh, groups, source="muscle block")
    a0 = fem.Constant(mesh, np.array([1.0, 0.0, 0.0]))
    activation = Activation(mesh, value=lambda s: min(max(s, 0.0), 1.0), name="activation")
    params = MuscleParameters.muscle(K=MuscleParameters.muscle().K * 50)
    material = SplitEnergy(lambda F: muscle_isochoric(F, a0, activation.expr, params), params.K)
    problem = solid_problem(domain, material, formulation="mixed", bcs=[hf.Clamp("origin")], updaters=[activation])
    wall = PlaneContact("side", point=(0.0, width + 2e-4, 0.0), normal=(0.0, -1.0, 0.0), dhat=1e-4).bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10}, external_energies=[wall])
    iterates = _watch(solver, wall)
    outputs = [Recorder(wall), Reaction("origin"), Reactions()]
    rows = Simulation(problem, solver, hf.StepPolicy(increment=0.25), outputs).run()["rows"]
    assert [row["time"] for row in rows] == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0], abs=1e-12)
    assert min(iterates) > 0.0 and all(row["contact_min_distance"] > 0.0 for row in rows)
    forces = [row["contact_force"][1] for row in rows[1:]]
    assert forces[0] < 0.0 and all(b < a for a, b in itertools.pairwise(forces))  # grows with the activation
    for row in rows[1:]:
        assert row["contact_active"] > 0
        assert row["contact_force"] == pytest.approx(-np.array(row["reaction_origin"]), rel=1e-8, abs=1e-12)
        clamp = [row[f"reaction_total_M{c}"] for c in "xyz"]  # about the origin, as the wall's moment
        assert row["contact_moment"] == pytest.approx(-np.array(clamp), rel=1e-8, abs=1e-14)
        assert abs(row["contact_moment"][2]) > 0.05 * length * abs(row["contact_force"][1])  # an arm along x
    assert forces[-1] == pytest.approx(MUSCLE_FORCE, rel=1e-8)


def test_moving_plane_reaches_the_fixed_plane_state():
    """A plane that approaches from 0.2 below (prescribed translation) ends where the fixed plane is: same state."""
    delta, far = 0.2, 0.2
    problem = _block(n=2, delta=delta, top_profile=Ramp(t0=0.5, t1=1.0))
    moving = PlaneContact(
        "bottom", point=(0.0, 0.0, -far - DHAT / 2), normal=(0.0, 0.0, 1.0), dhat=DHAT,
        motion=(0.0, 0.0, far), profile=Ramp(t1=0.5),
    )
    contact = moving.bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
    iterates = _watch(solver, contact)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.125, max_increment=0.125))
    assert contact.time == 1.0 and min(iterates) > 0.0
    fixed, reference, _, _ = _pressed(n=2, delta=delta)
    assert contact.force()[2] == pytest.approx(reference.force()[2], rel=1e-8)


def test_plane_pushed_into_a_resting_body_without_the_predictor_is_cut_back_never_accepted():
    """Without the predictor (which carries the overrun nodes, ``test_contact_surfaces.py``), moving the plane into a
    body that rests on it is refused at the start of each attempt: the run stops with a ConvergenceError, no state
    penetrates."""
    problem = _block(n=2, delta=0.0)
    pushing = PlaneContact(
        "bottom", point=(0.0, 0.0, -DHAT / 2), normal=(0.0, 0.0, 1.0), dhat=DHAT, motion=(0.0, 0.0, 0.1)
    )
    contact = pushing.bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[contact], predictor=False)
    with pytest.raises(hf.ConvergenceError, match="behind the plane"):
        hf.solve_quasistatic(solver, stepping=hf.LoadStepping(min_increment=1.0 / 64))
    contact.update(problem.time)
    assert contact.min_distance() > 0.0


# -- dynamics -------------------------------------------------------------------------------------------------------


def _dropped(comm, scheme, n=2, speed=0.5, gap=0.02, dt=0.05, t_end=0.6):
    r"""A free cube (no supports) moving down at ``speed`` onto the plane ``gap`` below it, in a dynamic run.

    The first step's guess :math:`u_0 + \Delta t\,v_0` moves the bottom 0.025 down, through the plane 0.02
    below: the solver pulls it back along the collision filter instead of cutting the step back.
    """
    from hyperfem import dynamics as dyn

    base = hf.HyperelasticProblem(_cube(comm, n), lambda F: hf.materials.neo_hookean(F, PARAMS))
    problem = dyn.IncrementalProblem(base, scheme, dyn.MassDensity(1.0))
    problem.v.interpolate(lambda x: np.vstack([0.0 * x[0], 0.0 * x[0], np.full(x.shape[1], -speed)]))
    contact = PlaneContact("bottom", point=(0.0, 0.0, -gap), normal=(0.0, 0.0, 1.0), dhat=DHAT).bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10, "snes_atol": 1e-10}, external_energies=[contact])
    problem.initial_acceleration()
    iterates = _watch(solver, contact)

    class BarrierEnergy:
        def record(self, step=None):
            return {"barrier": comm.allreduce(contact.energy(problem.u.x.array), op=MPI.SUM)}

    outputs = [Recorder(contact), Recorder(dyn.Diagnostics(problem)), Recorder(BarrierEnergy())]
    summary = Simulation(problem, solver, dyn.TimeStepping(dt=dt, t_end=t_end), outputs).run()
    return problem, contact, summary, iterates


@pytest.mark.parametrize("scheme", ["backward_euler", "newmark"])
def test_block_dropped_on_the_plane_in_dynamics(scheme):
    """A block dropped on the plane: no iterate or step penetrates, the guess through the plane is pulled back (no
    cutback), the plane pushes it back up; backward Euler: kinetic + elastic + barrier energy never grows.

    (Newmark's trapezoidal rule is not energy-stable with a stiff barrier: here it gains energy at each impact, as
    known for the trapezoidal rule with penalty-like contact; IPC steps with implicit Euler for that reason.)
    """
    from hyperfem import dynamics as dyn

    integrator = dyn.BackwardEuler() if scheme == "backward_euler" else dyn.Newmark()
    problem, contact, summary, iterates = _dropped(MPI.COMM_WORLD, integrator)
    rows = summary["rows"]
    assert summary["completed"] and min(iterates) > 0.0
    assert all(row["contact_min_distance"] > 0.0 for row in rows)
    assert max(row["contact_force"][2] for row in rows) > 0.1 and max(row["contact_active"] for row in rows) == 9
    first = rows[1]
    assert first["rejected"] == 0 and 0.0 < first["contact_min_distance"] < DHAT  # pulled back, not cut back
    if scheme == "backward_euler":
        assert summary["rejected"] == 0
        total = [row["kinetic_energy"] + row["elastic_energy"] + row["barrier"] for row in rows]
        assert np.all(np.diff(total) <= 1e-12) and total[-1] > 0.5 * total[0]


def test_block_dropped_on_the_plane_semi_implicit_stops_without_penetrating():
    """The semi-implicit scheme (one linearization per step, ``semi_implicit_solver``) with the plane: the collision
    filter shortens the one Newton step, so no iterate or step penetrates; the impact is inelastic (the step that
    reaches the plane keeps 1 % of its gap and the filtered step leaves no velocity: the block rests within d-hat,
    the kinetic energy gone), where backward Euler with full Newton solves bounces (above)."""
    from hyperfem import dynamics as dyn
    from hyperfem.dynamics.semi_implicit import SemiImplicitStage, semi_implicit_solver

    comm = MPI.COMM_WORLD
    base = hf.HyperelasticProblem(_cube(comm, 2), lambda F: hf.materials.neo_hookean(F, PARAMS))
    problem = dyn.IncrementalProblem(base, dyn.BackwardEuler(), dyn.MassDensity(1.0))
    problem.v.interpolate(lambda x: np.vstack([0.0 * x[0], 0.0 * x[0], np.full(x.shape[1], -0.5)]))
    contact = PlaneContact("bottom", point=(0.0, 0.0, -0.02), normal=(0.0, 0.0, 1.0), dhat=DHAT).bind(problem)
    solver = semi_implicit_solver(problem, external_energies=[contact])
    problem.initial_acceleration()
    iterates = _watch(solver, contact)
    outputs = [Recorder(contact), Recorder(dyn.Diagnostics(problem))]
    summary = Simulation(problem, solver, dyn.TimeStepping(dt=0.05, t_end=0.3), outputs, stage=SemiImplicitStage).run()
    rows = summary["rows"]
    assert summary["completed"] and summary["rejected"] == 0
    assert min(iterates) > 0.0 and all(row["contact_min_distance"] > 0.0 for row in rows)
    assert rows[0]["kinetic_energy"] == pytest.approx(0.125, rel=1e-12)  # 1/2 rho |v|^2 of the unit cube
    assert max(row["contact_force"][2] for row in rows) > 0.01 and rows[-1]["contact_min_distance"] < DHAT
    assert rows[-1]["kinetic_energy"] < 1e-4 * rows[0]["kinetic_energy"]


def test_plane_on_a_path_in_dynamics_equals_its_ramped_motion():
    """A plane moved along a path (Waypoints in seconds: up 0.03 by t = 0.2, then held) under a free block at rest
    0.01 above it, backward Euler: the forces and gaps of every step equal those of the plane moved by
    ``motion`` with the same ramp as its profile (to round-off); the plane lifts the block, none penetrates."""
    from hyperfem import dynamics as dyn
    from hyperfem.loading import Waypoints

    runs = []
    for motion, profile in (((0.0, 0.0, 0.03), Ramp(t1=0.2)),
                            (Waypoints(times=(0.0, 0.2, 1.0), points=((0, 0, 0), (0, 0, 0.03), (0, 0, 0.03))), None)):
        base = hf.HyperelasticProblem(_cube(MPI.COMM_WORLD, 2), lambda F: hf.materials.neo_hookean(F, PARAMS))
        problem = dyn.IncrementalProblem(base, dyn.BackwardEuler(), dyn.MassDensity(1.0))
        extra = {} if profile is None else {"profile": profile}
        contact = PlaneContact("bottom", point=(0.0, 0.0, -0.01), normal=(0.0, 0.0, 1.0), dhat=DHAT, motion=motion,
                               **extra).bind(problem)
        solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
        problem.initial_acceleration()
        iterates = _watch(solver, contact)
        summary = Simulation(problem, solver, dyn.TimeStepping(dt=0.05, t_end=0.3), [Recorder(contact)]).run()
        assert summary["completed"] and min(iterates) > 0.0
        runs.append(summary["rows"])
    assert max(row["contact_force"][2] for row in runs[1]) > 0.1
    for ramped, on_path in zip(runs[0], runs[1], strict=True):
        assert on_path["contact_force"] == pytest.approx(ramped["contact_force"], rel=1e-9, abs=1e-12)
        assert on_path["contact_min_distance"] == pytest.approx(ramped["contact_min_distance"], rel=1e-9)


def _dropped_state(comm) -> list[float]:
    from hyperfem import dynamics as dyn

    problem, contact, summary, _ = _dropped(comm, dyn.BackwardEuler(), t_end=0.3)
    distances = [row["contact_min_distance"] for row in summary["rows"]]
    return [float(contact.force()[2]), float(problem.u.x.petsc_vec.norm()), *distances]


def test_dynamic_drop_one_rank_equals_two_ranks():
    """The dropped block: force, displacement norm and every step's min distance on 2 ranks equal 1 rank's to 1e-10."""
    comm = MPI.COMM_WORLD
    one = serial_reference(_dropped_state)
    assert _dropped_state(comm) == pytest.approx(one, rel=1e-10)


# -- the sphere -----------------------------------------------------------------------------------------------------


def test_sphere_step_fraction_is_the_first_root_of_the_inflated_ball():
    """Every node keeps (1 - s) of its distance up to the fraction, and the closest one reaches it exactly there."""
    from hyperfem.contact import CCD_SAFETY, sphere_step_fraction

    rng = np.random.default_rng(5)
    radius = 0.3
    for _ in range(200):
        direction = rng.standard_normal(3)
        offset = (radius + rng.uniform(1e-4, 0.2)) * direction / np.linalg.norm(direction)
        step = 0.5 * rng.standard_normal(3)
        alpha = sphere_step_fraction(offset[None, :], step[None, :], radius)
        d0 = np.linalg.norm(offset) - radius
        along = np.linalg.norm(offset[None, :] - np.linspace(0.0, alpha, 401)[:, None] * step[None, :], axis=1) - radius
        assert along.min() >= (1.0 - CCD_SAFETY) * d0 * (1.0 - 1e-9)
        if alpha < 1.0:
            assert along[-1] == pytest.approx((1.0 - CCD_SAFETY) * d0, rel=1e-9)
    moving_away = sphere_step_fraction(np.array([[0.0, 0.0, 0.5]]), np.array([[0.0, 0.0, -1.0]]), radius)
    passing_by = sphere_step_fraction(np.array([[0.0, 0.0, 0.5]]), np.array([[1.0, 0.0, 0.0]]), radius)
    assert moving_away == 1.0 and passing_by == 1.0


def test_sphere_barrier_taylor_and_psd_projection():
    """Gradient and exact Hessian of kappa*B for a sphere against its energy (O(eps^2), O(eps^3)); the tangent's
    blocks are the exact ones projected onto the PSD cone: b'' n n^T here, since b' (I - n n^T)/r is negative."""
    from hyperfem.contact import SphereContact

    problem = _block(n=2)
    radius = 5.0  # the nodes at 0.5 from the centre of the face are 0.03 from it: 5 active nodes
    contact = SphereContact("bottom", center=(0.5, 0.5, -radius - 4e-3), radius=radius, dhat=5e-2, stiffness=0.5)
    barrier_term = contact.bind(problem)
    comm = problem.domain.comm
    rng = np.random.default_rng(comm.rank + 7)
    u = 1e-4 * rng.standard_normal(problem.u.x.array.size)
    du = 1e-3 * rng.standard_normal(u.size)

    def total(values):
        return comm.allreduce(barrier_term.energy(values), op=MPI.SUM)

    def dot(a, b):
        return comm.allreduce(float(a @ b), op=MPI.SUM)

    dofs, g = barrier_term.gradient(u)
    hdofs, exact = barrier_term.hessian(u, project=False)
    assert comm.allreduce(len(dofs), op=MPI.SUM) >= 5  # the nodes near the centre of the face are active
    G = np.zeros(u.size)
    np.add.at(G, dofs.ravel(), g.ravel())
    Hdu = np.zeros(u.size)
    np.add.at(Hdu, hdofs.ravel(), np.einsum("mij,mj->mi", exact, du[hdofs]).ravel())
    E0, first, second = total(u), [], []
    for eps in (1e-1, 1e-2, 1e-3):
        E1 = total(u + eps * du)
        first.append(abs(E1 - E0 - eps * dot(G, du)))
        second.append(abs(E1 - E0 - eps * dot(G, du) - 0.5 * eps**2 * dot(du, Hdu)))
    assert np.array(first[1:]) / np.array(first[:-1]) == pytest.approx([1e-2, 1e-2], rel=0.05)
    assert second[1] / second[0] == pytest.approx(1e-3, rel=0.1)  # at 1e-3: round-off (1e-16 of the energy)
    _, projected = barrier_term.hessian(u, project=True)
    lowest = np.linalg.eigvalsh(projected).min() if len(projected) else 0.0
    assert lowest >= -1e-12 * (np.abs(projected).max() if len(projected) else 0.0)
    indefinite = comm.allreduce(float(np.linalg.eigvalsh(exact).min()) if len(exact) else 0.0, op=MPI.MIN)
    assert indefinite < 0.0  # the exact blocks are indefinite
    q = barrier_term.nodes.positions(u)[np.isin(barrier_term.nodes.dofs[:, 0], hdofs[:, 0])] - barrier_term._center
    n = q / np.linalg.norm(q, axis=1)[:, None]
    _, _, b2 = barrier_term._active(u)
    assert projected == pytest.approx(0.5 * b2[:, None, None] * np.einsum("mi,mj->mij", n, n), rel=1e-9, abs=1e-12)


def test_sphere_tangent_projected_while_the_nodes_move_exact_once_they_settle():
    """The tangent's choice (``hessian(u)``): projected at the first tangent, after a node moved by SETTLED_MOVE
    d-hat (0.1 d-hat) or more, after ``project_tangent()`` and after the sphere moved; exact (the indefinite blocks)
    once no node moved that far; a plane's is never marked exact (its exact Hessian is PSD already)."""
    from hyperfem.contact import SphereContact
    from hyperfem.contact.nodal import SETTLED_MOVE

    problem = _block(n=2)
    contact = SphereContact("bottom", center=(0.5, 0.5, -5.004), radius=5.0, dhat=5e-2, stiffness=0.5,
                            motion=(0.0, 0.0, -1.0))
    barrier_term = contact.bind(problem)
    comm = problem.domain.comm
    u = 1e-4 * np.random.default_rng(comm.rank + 7).standard_normal(problem.u.x.array.size)
    _, exact = barrier_term.hessian(u, project=False)
    _, projected = barrier_term.hessian(u, project=True)

    def chosen(v):
        blocks = barrier_term.hessian(v)[1]
        kind = "exact" if barrier_term.exact_tangent else "projected"
        assert blocks == pytest.approx(exact if kind == "exact" else projected, rel=1e-12, abs=1e-14)
        return kind

    assert chosen(u) == "projected"  # the first tangent
    assert chosen(u) == "exact"  # settled
    barrier_term.project_tangent()
    assert [chosen(u), chosen(u), chosen(u)] == ["projected", "projected", "exact"]  # then settles anew
    moved = u.copy()
    moved[barrier_term.nodes.dofs[:, 2]] += 0.5 * SETTLED_MOVE * barrier_term.dhat  # still settled
    _, exact = barrier_term.hessian(moved, project=False)
    _, projected = barrier_term.hessian(moved, project=True)
    assert chosen(moved) == "exact"
    moved[barrier_term.nodes.dofs[:, 2]] += 1.5 * SETTLED_MOVE * barrier_term.dhat  # moving again
    _, exact = barrier_term.hessian(moved, project=False)
    _, projected = barrier_term.hessian(moved, project=True)
    assert [chosen(moved), chosen(moved)] == ["projected", "exact"]
    barrier_term.update(0.0)  # the sphere (re)placed: projected until the nodes settle again
    assert [chosen(moved), chosen(moved)] == ["projected", "exact"]
    plane = _plane().bind(_block(n=2))
    plane.hessian(np.zeros_like(u))
    plane.hessian(np.zeros_like(u))
    assert plane.exact_tangent is False


def _ball_dragged(comm, monkeypatch, rounds: int) -> tuple[dict, list[bool], object]:
    """A ball (R = 0.2) pressed 0.11 into a 2 x 1 x 0.5 slab (12 x 6 x 3 boxes, clamped bottom) and dragged 0.4
    along x, frictionless, in 8 steps: the surgery demo's path with an analytic ball."""
    import hyperfem.solver.newton as newton
    from hyperfem.contact import SphereContact
    from hyperfem.loading import Waypoints
    from hyperfem.solver.external import ExternalTerms

    monkeypatch.setattr(newton, "CARRY_ROUNDS", rounds)
    calls: list[bool] = []
    carry_more = ExternalTerms.carry_more

    def counted(self, carried):
        more = carry_more(self, carried)
        calls.append(more is not None)
        return more

    monkeypatch.setattr(ExternalTerms, "carry_more", counted)
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([2.0, 1.0, 0.5])], [12, 6, 3])
    groups = {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], 0.5)}
    domain = hf.Domain.from_locators(mesh, groups, source="slab")
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS),
                                     bcs=[hf.PrescribedDisplacement("bottom", [0.0, 0.0, 0.0])])
    path = Waypoints(times=(0.0, 0.5, 1.0), points=((0.0, 0.0, 0.0), (0.0, 0.0, -0.11), (0.4, 0.0, -0.11)))
    ball = SphereContact("top", center=(0.6, 0.5, 0.71), radius=0.2, dhat=5e-3, motion=path).bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-9}, external_energies=[ball])
    measures = [Recorder(ball), Reaction("bottom")]
    summary = Simulation(problem, solver, hf.StepPolicy(increment=1 / 8), measures).run()
    return summary, calls, ball


def test_a_lift_that_pushes_a_node_into_the_ball_carries_it_too(monkeypatch):
    """The predictor carries the nodes the dragged ball overruns; its tangent solve pressed a node ahead of the ball
    into it, the start was refused and the step cut back (at t = 0.875 here; on 14 x 7 x 7 boxes down to 1/128 of
    the path, 842 Newton iterations instead of 146). Now the lift carries that node too and is taken again: every
    step is taken whole, none penetrates, the force equals -reaction and the end state is the cut-back run's."""
    summary, calls, ball = _ball_dragged(MPI.COMM_WORLD, monkeypatch, rounds=3)
    rows = summary["rows"]
    assert summary["completed"] and len(rows) == 9 and all(row["rejected"] == 0 for row in rows)
    assert any(calls)  # a lift was taken again with more nodes carried
    assert all(row["contact_min_distance"] > 0.0 for row in rows)
    force = np.array(rows[-1]["contact_force"])
    assert force == pytest.approx(-np.array(rows[-1]["reaction_bottom"]), rel=1e-6, abs=1e-9)
    old, old_calls, _ = _ball_dragged(MPI.COMM_WORLD, monkeypatch, rounds=0)
    assert not old_calls and sum(row["rejected"] for row in old["rows"]) >= 1  # what it was: refused, cut back
    assert force == pytest.approx(old["rows"][-1]["contact_force"], rel=1e-6)


HERTZ_RADIUS = 0.5


def _indented(comm, n=12, grading=2.5, depth=0.02, steps=2, dhat=1e-4):
    r"""A quarter of a 2 x 2 x 1 block (symmetry rollers on x = 0, y = 0) pushed up by ``depth`` against a fixed
    sphere of radius 0.5 above the corner: graded toward the contact (:math:`x \to x^p`), clamped bottom moved up."""
    from hyperfem.contact import SphereContact

    mesh = dmesh.create_unit_cube(comm, n, n, n)
    x = mesh.geometry.x
    x[:, 0], x[:, 1], x[:, 2] = x[:, 0] ** grading, x[:, 1] ** grading, 1.0 - (1.0 - x[:, 2]) ** grading
    groups = {
        "top": lambda x: np.isclose(x[2], 1.0),
        "bottom": lambda x: np.isclose(x[2], 0.0),
        "x0": lambda x: np.isclose(x[0], 0.0),
        "y0": lambda x: np.isclose(x[1], 0.0),
    }
    domain = hf.Domain.from_locators(mesh, groups, source=f"graded cube({n})")
    gap = dhat / 2
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("bottom", [0.0, 0.0, depth + gap]),
    ]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)
    tool = SphereContact("top", center=(0.0, 0.0, 1.0 + gap + HERTZ_RADIUS), radius=HERTZ_RADIUS, dhat=dhat)
    contact = tool.bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10}, external_energies=[contact])
    iterates = _watch(solver, contact)
    summary = Simulation(problem, solver, hf.StepPolicy(increment=1.0 / steps), [Recorder(contact)]).run()
    return problem, contact, summary, iterates


def hertz_force(depth: float) -> float:
    r"""Hertz: a rigid sphere pressed :math:`\delta` into a half-space, :math:`F = \tfrac43 E^* R^{1/2}\delta^{3/2}`,
    :math:`E^* = E/(1 - \nu^2)`."""
    return 4.0 / 3.0 * (1.0 / (1.0 - 0.3**2)) * np.sqrt(HERTZ_RADIUS) * depth**1.5


@pytest.mark.filterwarnings("ignore::hyperfem.mesh.quality.MeshQualityWarning")
def test_sphere_indentation_force_grows_as_hertz():
    """Indentation 0.01 and 0.02 (contact radius 0.07, 0.1 on a graded P1 mesh, cells 0.002 at the tool): the force
    grows as depth^1.5 (exponent 1.46 here, 1.52 at n = 16) and is 4 x Hertz's (a quarter model) within 25 % (+24 %,
    +20 % here; +18 %, +19 % at n = 16: P1 stiffness and the 1-thick clamped layer, decreasing under refinement);
    no iterate or step penetrates."""
    depth = 0.02
    problem, contact, summary, iterates = _indented(MPI.COMM_WORLD, depth=depth)
    rows = summary["rows"]
    assert summary["completed"] and min(iterates) > 0.0 and all(row["contact_min_distance"] > 0.0 for row in rows)
    forces = [-row["contact_force"][2] for row in rows[1:]]
    depths = [depth / 2, depth]
    exponent = np.log(forces[1] / forces[0]) / np.log(2.0)
    assert exponent == pytest.approx(1.5, abs=0.1)
    for force, d in zip(forces, depths, strict=True):
        assert 1.0 < force / (hertz_force(d) / 4.0) < 1.25
    fx, fy, _ = rows[-1]["contact_force"]
    assert fx == pytest.approx(fy, rel=1e-6) and 0.0 < fx < 0.1 * forces[-1]  # outward on the quarter, symmetric


def _indentation_state(comm) -> list[float]:
    problem, contact, _, _ = _indented(comm, n=5, grading=2.0, depth=0.02, steps=1, dhat=1e-3)
    return [*map(float, contact.force()), float(problem.u.x.petsc_vec.norm()), contact.min_distance()]


@pytest.mark.filterwarnings("ignore::hyperfem.mesh.quality.MeshQualityWarning")
def test_sphere_one_rank_equals_two_ranks():
    """A small indentation: force, displacement norm and min distance on 2 ranks equal 1 rank's to 1e-10."""
    comm = MPI.COMM_WORLD
    one = serial_reference(_indentation_state)
    assert _indentation_state(comm) == pytest.approx(one, rel=1e-10, abs=1e-14)


@pytest.mark.parametrize(
    "motion, expected",
    [
        (lambda t: (0.0, t), "a motion path must give 3 finite components, got [0.0, 0.0] (shape (2,)) at t = 0"),
        (lambda t: (0.0, 0.0, float("nan")), "a motion path must give 3 finite components"),
        (lambda t: "down", "a motion path must give 3 numbers at t = 0 (ValueError: "),
        (lambda t: [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], "got [0.0, 0.0, 0.0, 1.0, 1.0, 1.0] (shape (2, 3))"),
        (lambda t: (0.0, 0.0, 1.0 / t), "a motion path must give 3 numbers at t = 0 (ZeroDivisionError: "),
    ],
)
def test_a_bad_obstacle_path_is_one_line(motion, expected):
    """A path ``motion`` (a callable ``t -> s(t)``) is checked at t = 0, for a sphere, a plane and a cylinder."""
    from hyperfem.contact import CylinderContact, SphereContact

    for make in (lambda m: SphereContact("top", center=(0.5, 0.5, 2.0), radius=0.5, motion=m),
                 lambda m: PlaneContact("bottom", point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0), motion=m),
                 lambda m: CylinderContact("top", point=(0.5, 0.0, 2.0), axis=(0, 1, 0), radius=0.5, motion=m)):
        with pytest.raises(ParameterError) as info:
            make(motion)
        message = str(info.value)
        assert "\n" not in message and expected in message and "Contact on '" in message


def test_a_plane_moved_along_a_path_equals_the_same_motion():
    """The block pressed by the plane moved up 0.2 along a path (Waypoints, in two legs) equals the plane moved by
    ``motion`` with the same profile: the same forces to round-off at t = 0.5 and 1."""
    from hyperfem.loading import Waypoints

    forces = []
    for motion in ((0.0, 0.0, 0.2), Waypoints(times=(0.0, 0.5, 1.0), points=((0, 0, 0), (0, 0, 0.1), (0, 0, 0.2)))):
        problem = _block(delta=0.0)
        contact = _plane(motion=motion).bind(problem)
        solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10}, external_energies=[contact])
        rows = Simulation(problem, solver, hf.StepPolicy(increment=0.5), [Recorder(contact)]).run()["rows"]
        forces.append([row["contact_force"] for row in rows[1:]])
    assert forces[0][-1][2] > 0.01
    assert np.array(forces[1]) == pytest.approx(np.array(forces[0]), rel=1e-10, abs=1e-14)


def test_sphere_bad_input_is_one_line():
    from hyperfem.contact import SphereContact

    with pytest.raises(ParameterError, match="radius must be a finite number > 0"):
        SphereContact("bottom", center=(0.0, 0.0, -1.0), radius=-1.0)
    with pytest.raises(ParameterError, match="motion has 2 components, center has 3"):
        SphereContact("bottom", center=(0.0, 0.0, -1.0), radius=1.0, motion=(0.0, 1.0))
    with pytest.raises(ParameterError, match=r"wrong side of the sphere: the node at .* has distance"):
        SphereContact("bottom", center=(0.5, 0.5, 0.0), radius=0.2).bind(_block(n=2))


# -- bad input ------------------------------------------------------------------------------------------------------


def _one_line(excinfo) -> str:
    message = str(excinfo.value)
    assert "\n" not in message
    return message


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"dhat": 0.0}, "dhat must be a finite number > 0"),
        ({"dhat": -1e-3}, "dhat must be a finite number > 0"),
        ({"stiffness": 0.0}, "stiffness must be a finite number > 0"),
        ({"normal": (0.0, 0.0, 0.0)}, "normal must be a non-zero vector"),
        ({"normal": (0.0, 1.0)}, "normal has 2 components, point has 3"),
        ({"safety": 1.0}, r"safety must be a number in \(0, 1\)"),
        ({"point": (0.0, float("nan"), 0.0)}, "point component 1 \\(y\\) must be a finite number"),
    ],
)
def test_bad_parameters_are_one_line_errors(kwargs, match):
    args = {"point": (0.0, 0.0, -DHAT / 2), "normal": (0.0, 0.0, 1.0), "dhat": DHAT, **kwargs}
    with pytest.raises(ParameterError, match=match) as excinfo:
        PlaneContact("bottom", **args)
    assert _one_line(excinfo).startswith("PlaneContact on 'bottom': ")


def test_unknown_boundary_lists_the_groups():
    problem = _block(n=1)
    with pytest.raises(UnknownGroupError, match="no boundary .* named 'floor' .*available: bottom, top, x0, y0") as e:
        PlaneContact("floor", point=(0.0, 0.0, -1.0), normal=(0.0, 0.0, 1.0)).bind(problem)
    _one_line(e)


def test_body_on_the_wrong_side_names_the_node_and_its_distance():
    problem = _block(n=1)
    # A bottom corner (its coordinates may carry round-off, e.g. 4.7e-18 on Debian's DOLFINx), at -0.1.
    number = r"-?[0-9.e+-]+"
    where = rf"starts on the wrong side .* node at \({number}, {number}, {number}\) has distance -0\.1 "
    with pytest.raises(ParameterError, match=where) as e:
        PlaneContact("bottom", point=(0.0, 0.0, 0.1), normal=(0.0, 0.0, 1.0)).bind(problem)
    _one_line(e)
    with pytest.raises(ParameterError, match="the plane has 2 components, the mesh 3"):
        PlaneContact("bottom", point=(0.0, -1.0), normal=(0.0, 1.0)).bind(problem)


def test_defaults_from_the_mesh_and_the_tangent():
    """dhat = 1 % of the mean facet diameter; kappa = the mean normal tangent diagonal at the contact nodes."""
    problem = _block(n=2)
    contact = PlaneContact("bottom", point=(0.0, 0.0, -1e-3), normal=(0.0, 0.0, 1.0)).bind(problem)
    assert contact.dhat == pytest.approx(0.01 * 0.5 * np.sqrt(2.0), rel=1e-12)  # facets: right triangles, legs 1/2
    assert 0.1 * (PARAMS.lmbda + 2 * PARAMS.mu) * 0.5 < contact.stiffness < 10 * (PARAMS.lmbda + 2 * PARAMS.mu) * 0.5


@pytest.mark.serial
def test_hyperfem_imports_without_ipctk_and_contact_names_the_extra():
    """``import hyperfem`` never imports ipctk; a contact without it is a one-line error naming the extra."""
    code = (
        "import sys; sys.modules['ipctk'] = None\n"
        "import hyperfem as hf\n"
        "try:\n"
        "    hf.contact.PlaneContact('bottom', point=(0, 0, 0), normal=(0, 0, 1))\n"
        "except hf.ParameterError as e:\n"
        "    print(e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == (
        "PlaneContact on 'bottom': contact needs the IPC Toolkit bindings (ipctk), which are not installed: "
        "pip install 'hyperfem[contact]'"
    )
    plain = subprocess.run(
        [sys.executable, "-c", "import sys, hyperfem; print('ipctk' in sys.modules)"],
        capture_output=True, text=True, timeout=120,
    )
    assert plain.stdout.strip() == "False", plain.stderr


@pytest.mark.serial
def test_benchmark_smoke():
    """``benchmarks/contact.py`` runs and prints one JSON object per size, with the closed form met."""
    import json
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "benchmarks" / "contact.py"
    out = subprocess.run(
        [sys.executable, str(script), "--sizes", "3", "--repeat", "1"], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    row = json.loads(out.stdout.strip().splitlines()[-1])
    assert row["contact_nodes"] == 16 and row["closed_form_relative_error"] < 1e-3 and row["min_distance"] > 0.0
    assert row["contact_s"] > 0.0 and row["iterations_contact"] >= row["iterations_roller"]


# -- friction (smoothed Coulomb, lagged per step as in IPC) -----------------------------------------------------------

MU = 0.5


def _on_rough_plane(comm, mode: str, ratio: float = 0.0, n: int = 2, delta: float = 0.05):
    """A cube pressed on a plane with friction MU (top: z prescribed, t in [0, 1]), then pushed along x (t in [1, 2]).

    ``mode="traction"``: a dead traction on the top of total ``ratio * MU * N`` (N: the normal force at t = 1);
    ``"displacement"``: the top moved 0.2 along x. No roller: only friction holds the body tangentially.
    Returns ``(problem, contact, N, T, slips)``: ``slips`` the largest x-slip of a contact node in each step of
    the push, over all ranks.
    """
    scale = [0.0]
    bcs = [hf.PrescribedDisplacement("top", [-delta], components=[2], profile=Ramp(1.0))]
    loads = []
    if mode == "traction":
        loads = [hf.DeadTraction("top", (1.0, 0.0, 0.0), profile=lambda t: scale[0] * min(max(t - 1.0, 0.0), 1.0))]
    else:
        bcs.append(hf.PrescribedDisplacement("top", [0.2], components=[0], profile=Ramp(2.0, t0=1.0)))
    mesh = dmesh.create_unit_cube(comm, n, n, n)
    groups = {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], 1.0)}
    domain = hf.Domain.from_locators(mesh, groups, source=f"cube({n})")
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs, loads=loads)
    contact = _plane(friction=MU).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact], check_rigid_motion=False)
    iterates = _watch(solver, contact)
    stepping = hf.LoadStepping(initial_increment=0.25, max_increment=0.25)
    hf.solve_quasistatic(solver, 1.0, stepping=stepping)
    N = float(contact.force()[2])
    scale[0] = ratio * MU * N
    slips: list[float] = []
    last = [contact.nodes.positions(problem.u.x.array)[:, 0].copy()]

    def slip(_record) -> None:
        x = contact.nodes.positions(problem.u.x.array)[:, 0]
        local = float(np.abs(x - last[0]).max()) if len(x) else 0.0
        slips.append(comm.allreduce(local, op=MPI.MAX))
        last[0] = x.copy()

    hf.solve_quasistatic(solver, 2.0, stepping=stepping, on_step=slip)
    assert iterates and min(iterates) > 0.0
    return problem, contact, N, scale[0], slips


def test_friction_taylor_with_the_lag_fixed():
    """D, its gradient and Hessian (lag fixed) against finite differences: errors O(eps^2), O(eps^3); PSD blocks."""
    problem = _block(n=2)
    contact = _plane(dhat=1e-2, stiffness=0.5, friction=0.4, friction_epsilon=1e-3).bind(problem)
    comm = problem.domain.comm
    rng = np.random.default_rng(comm.rank)
    contact.lag(problem.u.x.array)
    contact.update(0.0)  # the lag taken comes into use
    for size in (1e-4, 3e-2):  # slips within epsilon (the smoothed part) and beyond it, none crossing it
        u = size * rng.standard_normal(problem.u.x.array.size)
        du = 0.1 * size * rng.standard_normal(u.size)  # steps small against the slips (|w|^3 is not smooth at 0)
        dofs, g = contact.friction_gradient(u)
        hdofs, blocks = contact.friction_hessian(u)
        assert comm.allreduce(len(dofs), op=MPI.SUM) == contact.nodes.total
        if len(blocks):
            assert np.linalg.eigvalsh(blocks).min() > -1e-10 * np.abs(blocks).max()
        G = np.zeros(u.size)
        np.add.at(G, dofs.ravel(), g.ravel())
        Hdu = np.zeros(u.size)
        np.add.at(Hdu, hdofs.ravel(), np.einsum("mij,mj->mi", blocks, du[hdofs]).ravel())

        def total(values):
            return comm.allreduce(contact.friction_energy(values), op=MPI.SUM)

        E0, first, second = total(u), [], []
        dot = comm.allreduce(float(G @ du), op=MPI.SUM)
        quad = comm.allreduce(float(du @ Hdu), op=MPI.SUM)
        for eps in (1e-1, 1e-2, 1e-3):
            E1 = total(u + eps * du)
            first.append(abs(E1 - E0 - eps * dot))
            second.append(abs(E1 - E0 - eps * dot - 0.5 * eps**2 * quad))
        assert first[2] / first[1] == pytest.approx(1e-2, rel=0.05)  # O(eps^2)
        assert second[1] / second[0] < 2e-3  # O(eps^3); the next one is at round-off


def test_friction_sticks_below_mu_n():
    """T = 0.5 mu N: the friction force balances T to 1e-8; each step slips < epsilon (the lag's elastic stick)."""
    problem, contact, N, T, slips = _on_rough_plane(MPI.COMM_WORLD, "traction", 0.5)
    friction = contact.friction_force()
    assert friction[0] == pytest.approx(-T, rel=1e-8) and abs(friction[1]) < 1e-10 * T
    assert max(slips) < contact.friction_epsilon
    assert contact.record()["contact_friction_force"] == pytest.approx(list(friction), abs=1e-14)


def test_friction_slides_at_mu_n():
    """The top dragged 0.2 along x: the nodes slide (slip >> epsilon) and the friction force is mu N (0.5 %)."""
    problem, contact, N, _, slips = _on_rough_plane(MPI.COMM_WORLD, "displacement")
    assert sum(slips) > 500 * contact.friction_epsilon
    friction = contact.friction_force()
    assert -friction[0] == pytest.approx(MU * contact.force()[2], rel=5e-3)


def test_friction_above_mu_n_has_no_stick():
    """T = 1.5 mu N: no quasi-static equilibrium; the block does not stick (it runs away or the step fails)."""
    try:
        _, contact, _, _, slips = _on_rough_plane(MPI.COMM_WORLD, "traction", 1.5)
    except hf.ConvergenceError:
        return
    assert max(slips) > 1e3 * contact.friction_epsilon


def _stick_state(comm) -> list[float]:
    problem, contact, _, _, _ = _on_rough_plane(comm, "traction", 0.5)
    return [*contact.friction_force(), *contact.force(), float(problem.u.x.petsc_vec.norm())]


def test_friction_one_rank_equals_two_ranks():
    """The stick case on 2 ranks equals 1 rank to 1e-10 (friction force, normal force, displacement norm)."""
    comm = MPI.COMM_WORLD
    one = serial_reference(_stick_state)
    two = _stick_state(comm)
    assert two == pytest.approx(one, rel=1e-10, abs=1e-14)


def test_friction_bad_input_is_one_line():
    with pytest.raises(ParameterError, match="friction must be a number >= 0"):
        _plane(friction=-0.1)
    with pytest.raises(ParameterError, match="friction_epsilon"):
        _plane(friction=0.1, friction_epsilon=0.0)
