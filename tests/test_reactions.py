r"""Reaction forces and moments of every Dirichlet boundary, from the residual (:mod:`hyperfem.simulation.reactions`).

Checks against closed forms and balance laws:

* the bent cantilever is statically determinate: the clamp's force is
  :math:`-\int_\Gamma t\,dA`, and its moment balances that of the traction
  :math:`\int_\Gamma (x - c)\times t\,dA` in the deformed configuration (the
  internal forces of an objective energy carry no moment);
* uniaxial stretch between rollers is homogeneous, so the force on the pulled
  face is :math:`P_{11}` of the exact state (unit area), the opposite roller
  carries :math:`-P_{11}`, the lateral rollers nothing; components a roller
  does not hold are reported as zero;
* where two Dirichlet faces hold the same component along their common edge
  (a homogeneous triaxial stretch of the unit cube, the face x = 1 fully
  prescribed, rollers on x = 0, y = 0, z = 0, a dead traction on y = 1), the
  default ``shared="traction"`` gives each face its exact force
  :math:`P_{ii} A` and the faces add up to the total; the nodal sum gives the
  face x = 1 the strip :math:`-P_{22} h/2` of its neighbour y = 0;
* the three-field problem gives the force of :class:`~hyperfem.simulation.reactions.ReactionForce`;
* in a dynamic run the supports carry the rate of change of momentum:
  :math:`F = \int\rho\,(a + \alpha v)\,dX` when no other force acts
  (:math:`\alpha` the viscous damping), and the free rows of the balance vanish.

Every check holds on one and on two ranks.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import ufl
from mpi4py import MPI
from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem import dynamics as dyn
from hyperfem.cases import BEND_TRACTION, bend_load
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube
from hyperfem.problem import SplitEnergy, solid_problem
from hyperfem.simulation import DirichletReactions, Reaction, Reactions, Simulation
from hyperfem.simulation.reactions import ReactionForce

PARAMS = hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3)
MESH = Path(__file__).resolve().parent.parent / "meshes" / "beam_h2.msh"


def psi(F):
    return hf.materials.neo_hookean(F, PARAMS)


def _assemble(expr, measure, comm) -> float:
    return comm.allreduce(fem.assemble_scalar(fem.form(expr * measure)), op=MPI.SUM)


def test_bend_reaction_is_minus_the_load_and_balances_its_moment(comm):
    domain = hf.read_mesh(MESH, comm)
    load = bend_load()
    problem = hf.HyperelasticProblem(domain, psi, bcs=[hf.Clamp("clamped")], loads=[load])
    reactions = Reactions()
    outputs = [reactions, Reaction("clamped")]
    summary = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(increment=0.5), outputs).run()
    t = np.array(BEND_TRACTION)
    ds = domain.ds("free_end")
    area = _assemble(1.0, ds, comm)
    force = np.array(summary["reactions"]["clamped"]["force"])
    assert force == pytest.approx(-t * area, rel=1e-7, abs=1e-7 * np.abs(t).max() * area)
    # the column of the internal-energy Reaction measure is the same force (no load on the clamp)
    assert force == pytest.approx(np.array(summary["reaction_clamped"]), rel=1e-10, abs=1e-9)
    # moment balance about the clamp's centroid, in the deformed configuration
    c = np.array(summary["reactions"]["clamped"]["point"])
    assert c == pytest.approx([-5.0, 0.0, 0.0], abs=1e-12)  # the clamp is the face x = -5 of the 10 x 4 x 4 beam
    x = ufl.SpatialCoordinate(domain.mesh) + problem.u - ufl.as_vector(c.tolist())
    applied = np.array([_assemble(ufl.cross(x, ufl.as_vector(t.tolist()))[i], ds, comm) for i in range(3)])
    moment = np.array(summary["reactions"]["clamped"]["moment"])
    assert np.abs(applied).max() > 1e4  # about 5e3 Pa * 16 m^2 * 10 m
    assert np.abs(moment + applied).max() < 1e-6 * np.abs(applied).max()
    # one support: the total is the clamp's (its moment about the origin)
    row = summary["rows"][-1]
    assert [row[f"reaction_total_F{a}"] for a in "xyz"] == pytest.approx(force.tolist(), rel=1e-12, abs=1e-9)
    assert row["reaction_clamped_Fy"] == pytest.approx(force[1])
    assert summary["rows"][0]["reaction_clamped_Fy"] == 0.0  # unloaded initial state


def _uniaxial(stretch: float) -> tuple[float, float]:
    r""":math:`(P_{11}, \lambda_2)` of neo-Hookean uniaxial stress (the lateral stretch from :math:`P_{22} = 0`)."""
    mu, lm = PARAMS.mu, PARAMS.lmbda

    def p(l1, l2, k):
        lnJ = math.log(l1 * l2 * l2)
        lk = (l1, l2, l2)[k]
        return mu * lk - mu / lk + lm * lnJ / lk

    l2 = 1.0
    for _ in range(50):
        h = 1e-7
        f = p(stretch, l2, 1)
        l2 -= f / ((p(stretch, l2 + h, 1) - f) / h)
    assert abs(p(stretch, l2, 1)) < 1e-6 * mu
    return p(stretch, l2, 0), l2


def test_rollers_carry_the_homogeneous_stress(comm):
    stretch = 1.2
    domain = unit_cube(2, comm)
    problem = hf.HyperelasticProblem(domain, psi, bcs=uniaxial_rollers(stretch))
    reactions = DirichletReactions(problem)
    assert reactions.names == ["x0", "y0", "z0", "x1", "total"]
    hf.solve_quasistatic(hf.NewtonSolver(problem))
    r = reactions()
    P11, l2 = _uniaxial(stretch)
    assert r["x1"].force[0] == pytest.approx(P11, rel=1e-8)  # unit face: force = P11
    assert r["x0"].force[0] == pytest.approx(-P11, rel=1e-8)
    assert abs(r["y0"].force[1]) < 1e-8 * P11 and abs(r["z0"].force[2]) < 1e-8 * P11
    # a roller reports only the component it holds
    assert r["x1"].force[1] == 0.0 and r["x1"].force[2] == 0.0 and r["y0"].force[0] == 0.0
    # uniform stress: the force acts at the face's current centroid (stretch, l2/2, l2/2), the
    # moment about its reference centroid (1, 1/2, 1/2) is that of the lateral contraction
    assert r["x1"].point.tolist() == pytest.approx([1.0, 0.5, 0.5])
    arm = np.array([stretch, 0.5 * l2, 0.5 * l2]) - r["x1"].point
    expected = np.cross(arm, [P11, 0.0, 0.0])
    assert np.abs(expected).max() > 1e-2 * P11
    assert r["x1"].moment == pytest.approx(expected, rel=1e-7, abs=1e-8 * P11)
    assert np.abs(r["total"].force).max() < 1e-8 * P11


def _triaxial(l1: float, l2: float) -> tuple[float, float, float]:
    r""":math:`(P_{11}, P_{22}, \lambda_3)` of neo-Hookean principal stretches with :math:`P_{33} = 0`."""
    mu, lm = PARAMS.mu, PARAMS.lmbda

    def p(stretches, k):
        s = stretches
        return mu * s[k] - mu / s[k] + lm * math.log(s[0] * s[1] * s[2]) / s[k]

    l3 = 1.0
    for _ in range(50):
        h = 1e-7
        f = p((l1, l2, l3), 2)
        l3 -= f / ((p((l1, l2, l3 + h), 2) - f) / h)
    assert abs(p((l1, l2, l3), 2)) < 1e-6 * mu
    return p((l1, l2, l3), 0), p((l1, l2, l3), 1), l3


@pytest.mark.parametrize("n", [2, 3])  # n = 3 on 2 ranks: ghost copies of x1's callable values were stale
def test_faces_sharing_an_edge_get_their_own_traction(comm, n):
    l1, l2 = 1.2, 1.1
    P11, P22, l3 = _triaxial(l1, l2)
    mesh = dmesh.create_unit_cube(comm, n, n, n)
    faces = {
        f"{a}{v}": (lambda axis, at: lambda x: np.isclose(x[axis], at))(k, float(v))
        for k, a in enumerate("xyz")
        for v in (0, 1)
    }
    domain = hf.Domain.from_locators(mesh, faces)
    stretch = (l1 - 1.0, l2 - 1.0, l3 - 1.0)
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("z0", [0.0], components=[2]),
        hf.PrescribedDisplacement("x1", lambda x: np.array(stretch)[:, None] * x),  # all components
    ]
    problem = hf.HyperelasticProblem(domain, psi, bcs=bcs, loads=[hf.DeadTraction("y1", (0.0, P22, 0.0))])
    split, nodal = DirichletReactions(problem), DirichletReactions(problem, shared="nodal")
    assert split.shared == "traction"  # the default
    hf.solve_quasistatic(hf.NewtonSolver(problem))
    r, old = split(), nodal()
    scale = max(P11, P22)
    expected = {"x0": [-P11, 0, 0], "x1": [P11, 0, 0], "y0": [0, -P22, 0], "z0": [0, 0, 0], "total": [0, -P22, 0]}
    for name, force in expected.items():
        assert r[name].force == pytest.approx(force, abs=1e-8 * scale), name
    # the faces add up to the total (each shared dof is shared out, not counted twice)
    assert sum(r[k].force for k in "x0 x1 y0 z0".split()) == pytest.approx(r["total"].force, abs=1e-8 * scale)
    # x1's uniform traction acts at its current centroid (l1, l2/2, l3/2), moment about the reference one
    arm = np.array([l1, 0.5 * l2, 0.5 * l3]) - np.array([1.0, 0.5, 0.5])
    assert r["x1"].moment == pytest.approx(np.cross(arm, [P11, 0.0, 0.0]), abs=1e-8 * scale)
    assert r["x1"].about == "reference centroid of 'x1'" and r["total"].about == "origin"
    # the nodal sum: x1 also carries y0's traction on the strip of cells along their edge (area h/2)
    assert old["x1"].force[1] == pytest.approx(-P22 / (2 * n), rel=1e-8)
    assert old["y0"].force == pytest.approx(r["y0"].force, abs=1e-8 * scale)  # x1 has no y traction to give
    assert old["total"].force == pytest.approx(r["total"].force, abs=1e-8 * scale)
    with pytest.raises(hf.ParameterError, match="shared must be one of traction, nodal, got 'area'"):
        DirichletReactions(problem, shared="area")


def test_unknown_boundary_is_refused(comm):
    domain = unit_cube(1, comm)
    problem = hf.HyperelasticProblem(domain, psi, bcs=[hf.Clamp("x0")])
    with pytest.raises(hf.ParameterError, match="boundary 'x1' has no Dirichlet condition \\(held boundaries: x0\\)"):
        DirichletReactions(problem, ["x1"])
    with pytest.raises(hf.ParameterError, match="point of 'x0' must be 1 to 3 finite numbers"):
        DirichletReactions(problem, points={"x0": (0.0, float("nan"))})


def test_mixed_reaction_is_the_reaction_force(comm):
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([1.0, 0.3, 0.3])], [4, 1, 1])
    domain = hf.Domain.from_locators(
        mesh, {"left": lambda x: np.isclose(x[0], 0.0), "right": lambda x: np.isclose(x[0], 1.0)}
    )
    material = SplitEnergy(psi, 50.0 * PARAMS.mu)
    traction = (0.0, 0.0, -1e3)
    problem = solid_problem(
        domain, material, formulation="mixed", bcs=[hf.Clamp("left")], loads=[hf.DeadTraction("right", traction)]
    )
    reactions = DirichletReactions(problem, total=False)
    hf.solve_quasistatic(hf.NewtonSolver(problem))
    force = reactions()["left"].force
    assert force == pytest.approx(ReactionForce(problem, "left")(), rel=1e-10, abs=1e-8)
    assert force == pytest.approx([0.0, 0.0, 1e3 * 0.09], rel=1e-7, abs=1e-6)


def _strip(comm, damping):
    mesh = dmesh.create_rectangle(comm, [[0.0, 0.0], [4.0, 1.0]], [8, 2], dmesh.CellType.triangle)
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    base = hf.HyperelasticProblem(domain, psi, bcs=[hf.Clamp("left")])
    problem = dyn.IncrementalProblem(base, dyn.Newmark(), dyn.MassDensity(1000.0), dyn.viscous_damping(damping))
    problem.v.interpolate(lambda x: np.vstack([np.zeros(x.shape[1]), 4.0 * (x[0] / 4.0) ** 2]))
    problem.initial_acceleration()
    return problem


def test_dynamic_reaction_is_the_rate_of_momentum(comm):
    alpha = 0.5
    problem = _strip(comm, alpha)
    domain = problem.domain
    rho = 1000.0
    momentum_rate = fem.form(rho * (problem.a + alpha * problem.v)[1] * ufl.dx(domain=domain.mesh))
    checked = []

    def check() -> float:
        r = sim_reactions.reactions
        residual = r.residual()
        held = r._dofs["left"]
        dofmap = problem.u.function_space.dofmap
        owned = dofmap.index_map.size_local * dofmap.index_map_bs
        free = np.setdiff1d(np.arange(owned), held)
        scale = comm.allreduce(float(np.abs(residual[held]).max(initial=0.0)), op=MPI.MAX)
        worst = comm.allreduce(float(np.abs(residual[free]).max(initial=0.0)), op=MPI.MAX)
        checked.append((worst, scale))
        return comm.allreduce(fem.assemble_scalar(momentum_rate), op=MPI.SUM)

    sim_reactions = Reactions(total=False)
    outputs = [sim_reactions, hf.simulation.Quantity("momentum_rate_y", check), Reaction("left")]
    stepping = dyn.TimeStepping(dt=0.05, t_end=0.2)
    summary = Simulation(problem, hf.NewtonSolver(problem), stepping, outputs).run()
    rows = summary["rows"]
    assert set(rows[0]) >= {"reaction_left_Fx", "reaction_left_Fy", "reaction_left_Mz"}
    assert "reaction_left_Fz" not in rows[0]
    for row in rows:
        assert row["reaction_left_Fy"] == pytest.approx(row["momentum_rate_y"], rel=1e-6)
    # inertia at the support matters: the elastic force alone is another number
    last = rows[-1]
    assert abs(last["reaction_left_Fy"] - last["reaction_left"][1]) > 1e-3 * abs(last["reaction_left_Fy"])
    # Newmark balances exactly this residual: the free rows vanish (to the Newton tolerance)
    for worst, scale in checked[1:]:
        assert worst < 1e-6 * scale


def test_reactions_of_an_explicit_run(comm):
    """Reactions of a problem that steps itself (solver=None): the hooks of its energies (start used to fail)."""
    params = hf.materials.LameParameters.from_youngs(1.0, 0.3)
    base = hf.HyperelasticProblem(
        unit_cube(2, comm), lambda F: hf.materials.neo_hookean(F, params), bcs=uniaxial_rollers(1.1)
    )
    explicit = dyn.ExplicitDynamics(base, dyn.MassDensity(1.0, lumped=True), lame=params)
    out = Reactions()
    dt = explicit.stable_step.dt_max
    dyn.integrate_explicit(explicit, dyn.TimeStepping(dt=dt, t_end=3 * dt), outputs=[out])
    assert set(out._last) == {"x0", "x1", "y0", "z0", "total"}
    assert all(np.all(np.isfinite(r.force)) for r in out._last.values())
    assert out._last["x1"].force[0] > 0.0  # the support holds the stretched end out
