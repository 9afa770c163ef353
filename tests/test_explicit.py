"""Explicit (central-difference, lumped-mass) time integration and its stable step.

* seed 000's 1D example (Lecture 2 §2.5.6) with inertia: the bar (0, 1),
  u(0, t) = sin t, free end, E = 1000, nu = 0.3, rho = 1, against the closed-form
  modal solution of the linear bar;
* the stable-step estimate h/c: exact on the uniform 1D bar, conservative on
  tetrahedra (against the power-iteration limit 2/omega_max), stable just below
  the sharp limit and unstable just above it, ParameterError above the estimate;
* second order in dt, energy conserved to O(dt^2), mass totals, and seed 003's
  FVM node force (eq. 3.93) equal to the assembled FEM force.

Serial and under ``mpiexec -n 2``; every run is small (well under a second of
stepping each, plus form compilation).
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import ufl
from mpi4py import MPI
from dolfinx import fem, la
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem import dynamics as dyn
from hyperfem.io.probes import PointProbe

SEED_PARAMS = hf.materials.LameParameters.from_youngs(1000.0, 0.3)
C_SEED = math.sqrt(SEED_PARAMS.lmbda + 2.0 * SEED_PARAMS.mu)  # rho = 1
BEAM_PARAMS = hf.materials.LameParameters.from_youngs(1e6, 0.3)
L_BEAM = 4.0


def bar(comm, n, material=hf.materials.neo_hookean, bc=None):
    """Seed 000's 1D bar (0, 1) on n P1 intervals, E = 1000, nu = 0.3."""
    mesh = dmesh.create_interval(comm, n, [0.0, 1.0])
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    bc = hf.Clamp("left") if bc is None else bc
    return hf.HyperelasticProblem(domain, lambda F: material(F, SEED_PARAMS), bcs=[bc])


def beam(comm, material=hf.materials.neo_hookean):
    """A 4 x 1 x 1 cantilever, 8 x 2 x 2 boxes of 6 tetrahedra, E = 1e6, nu = 0.3, clamped at x = 0."""
    mesh = dmesh.create_box(comm, [[0, 0, 0], [L_BEAM, 1, 1]], [8, 2, 2], dmesh.CellType.tetrahedron)
    domain = hf.Domain.from_locators(mesh, {"clamped": lambda x: np.isclose(x[0], 0.0)})
    return hf.HyperelasticProblem(domain, lambda F: material(F, BEAM_PARAMS), bcs=[hf.Clamp("clamped")])


def launch_beam(p, V=2.0):
    """Axial first-mode velocity plus a transverse swing."""
    p.v.interpolate(
        lambda x: np.vstack([V * np.sin(np.pi * x[0] / (2 * L_BEAM)), 0.5 * V * (x[0] / L_BEAM) ** 2, 0 * x[0]])
    )


def seed000_tip(t, nmodes=400):
    r"""Closed-form tip displacement of the linear bar with u(0, t) = sin t, at rest at t = 0.

    u = sin t + w, w(0) = 0, w_X(1) = 0, w_tt = c^2 w_XX + sin t. With modes sin(k_n X),
    k_n = (n - 1/2) pi, omega_n = c k_n and 1 = sum (2/k_n) sin(k_n X):
    q_n(t) = (2/k_n) (sin t - omega_n sin(omega_n t)) / (omega_n^2 - 1) (q_n(0) = 0, q_n'(0) = -2/k_n).
    """
    u = np.sin(t)
    for n in range(1, nmodes + 1):
        k = (n - 0.5) * math.pi
        w = C_SEED * k
        u = u + (2.0 / k) * (np.sin(t) - w * np.sin(w * t)) / (w**2 - 1.0) * math.sin(k)
    return u


# -- seed 000's 1D example -------------------------------------------------------------
@pytest.mark.parametrize("material", [hf.materials.linear_elastic, hf.materials.neo_hookean])
def test_seed000_bar_explicit_matches_closed_form(comm, material):
    """The driven bar follows sin t (the seed's quasi-static answer) up to a 3 % dynamic part,
    and that part as the modal solution says: the error is a tenth of it (P1, 20 cells;
    measured 2.4e-3 linear, 2.6e-3 Neo-Hookean against a dynamic part of 2.75e-2)."""
    motion = hf.PrescribedDisplacement("left", lambda x, t: np.full((1, x.shape[1]), math.sin(t)))
    base = bar(comm, 20, material, motion)
    explicit = dyn.ExplicitDynamics(base, dyn.MassDensity(1.0, lumped=True), lame=SEED_PARAMS)
    probe = PointProbe(base.domain.mesh, [(1.0,)])
    times, tips = [0.0], [0.0]

    def record(step):
        times.append(step.time)
        tips.append(float(probe(base.u)[0, 0]))

    stepping = dyn.TimeStepping(dt=explicit.stable_step.dt_max, t_end=2.0)
    history = dyn.integrate_explicit(explicit, stepping, on_step=record)
    assert explicit.t_n == pytest.approx(2.0)
    assert all(r.iterations == 0 and r.rejected == 0 for r in history)
    t, tip = np.array(times), np.array(tips)
    exact = seed000_tip(t)
    dynamic_part = np.abs(exact - np.sin(t)).max()
    assert 0.02 < dynamic_part < 0.04
    assert np.abs(tip - np.sin(t)).max() < 1.2 * dynamic_part
    assert np.abs(tip - exact).max() < 0.15 * dynamic_part


# -- stable step -----------------------------------------------------------------------
def test_stable_step_is_sharp_on_the_uniform_bar(comm):
    """Lumped P1 bar: h/c = 2/omega_max (up to the boundary modes); consistent mass: 1/sqrt(3) of it."""
    base = bar(comm, 20, hf.materials.linear_elastic)
    lumped = dyn.ExplicitDynamics(base, dyn.MassDensity(1.0, lumped=True), lame=SEED_PARAMS)
    step = lumped.stable_step
    assert step.h_min == pytest.approx(1.0 / 20, rel=1e-12)
    assert step.wave_speed == pytest.approx(C_SEED, rel=1e-12)
    assert step.dt_crit == pytest.approx(1.0 / (20 * C_SEED), rel=1e-12)
    sharp = lumped.spectral_time_step()
    assert 1.0 <= sharp / step.dt_crit < 1.01
    consistent = dyn.ExplicitDynamics(base, dyn.MassDensity(1.0), lame=SEED_PARAMS)
    ratio = consistent.spectral_time_step() / sharp
    assert ratio == pytest.approx(1.0 / math.sqrt(3.0), rel=0.01)
    assert consistent.stable_step.dt_crit == pytest.approx(step.dt_crit / math.sqrt(3.0), rel=1e-12)


def test_inscribed_diameter_of_the_box_tetrahedra(comm):
    """create_box splits cubes of side a into 6 tetrahedra of volume a^3/6 and surface (1 + sqrt 2) a^2:
    inscribed diameter 6V/A = a/(1 + sqrt 2)."""
    domain = beam(comm).domain
    h = dyn.inscribed_diameters(domain.mesh)
    assert np.allclose(h, 0.5 / (1.0 + math.sqrt(2.0)), rtol=1e-12)
    tri = dmesh.create_rectangle(comm, [[0, 0], [1, 1]], [1, 1], dmesh.CellType.triangle)
    assert np.allclose(dyn.inscribed_diameters(tri), 4 * 0.5 / (2.0 + math.sqrt(2.0)))  # 4A/P
    quad = dmesh.create_unit_square(comm, 1, 1, dmesh.CellType.quadrilateral)
    with pytest.raises(hf.ParameterError, match="simplex"):
        dyn.inscribed_diameters(quad)
    with pytest.raises(hf.ParameterError, match="safety"):
        dyn.stable_time_step(domain, BEAM_PARAMS, 1000.0, safety=1.5)


def test_stable_step_on_tetrahedra_is_conservative_and_limits_are_sharp(comm):
    """Beam: h_min/c below the power-iteration limit 2/omega_max (measured 1.6 times);
    0.95 of that limit stays bounded, 1.05 of it blows up (linear material, no check)."""
    base = beam(comm, hf.materials.linear_elastic)
    explicit = dyn.ExplicitDynamics(base, dyn.MassDensity(1000.0, lumped=True), lame=BEAM_PARAMS, check_step=False)
    sharp = explicit.spectral_time_step()
    assert 1.2 < sharp / explicit.stable_step.dt_crit < 2.5
    launch_beam(explicit, 1e-3)
    start = explicit.save()

    def growth(dt, steps=300):
        explicit.restore(start)
        energy0 = explicit.kinetic_energy() + explicit.elastic_energy()
        worst = 1.0
        for _ in range(steps):
            explicit.step(dt)
            worst = max(worst, (explicit.kinetic_energy() + explicit.elastic_energy()) / energy0)
        return worst

    assert growth(0.95 * sharp) < 1.05
    assert growth(1.05 * sharp) > 1e3


def test_step_above_the_estimate_is_refused(comm):
    base = beam(comm)
    explicit = dyn.ExplicitDynamics(base, dyn.MassDensity(1000.0, lumped=True), lame=BEAM_PARAMS)
    step = explicit.stable_step
    assert step.dt_max == pytest.approx(dyn.stability.DEFAULT_SAFETY * step.dt_crit)
    with pytest.raises(hf.ParameterError, match=r"dt = .* exceeds the stable step .*dt_crit = h_min/c"):
        explicit.step(1.01 * step.dt_max)
    with pytest.raises(hf.ParameterError, match="integrate_explicit: dt"):
        dyn.integrate_explicit(explicit, dyn.TimeStepping(dt=2 * step.dt_crit, t_end=1.0))
    with pytest.raises(hf.ParameterError, match="lame="):
        dyn.ExplicitDynamics(base, dyn.MassDensity(1000.0, lumped=True))
    with pytest.raises(hf.ParameterError, match="stiffness-proportional"):
        dyn.ExplicitDynamics(base, dyn.MassDensity(1000.0), dyn.RayleighDamping(beta=0.01), lame=BEAM_PARAMS)


# -- accuracy and energy ----------------------------------------------------------------
def test_explicit_is_second_order(comm):
    """Linear bar in its first mode for one period: the error against dt_crit/32 drops 4x per halving."""
    omega = C_SEED * math.pi / 2
    period = 2 * math.pi / omega
    dt_crit = 1.0 / (10 * C_SEED)

    def run(dt):
        base = bar(comm, 10, hf.materials.linear_elastic)
        explicit = dyn.ExplicitDynamics(base, dyn.MassDensity(1.0, lumped=True), lame=SEED_PARAMS)
        explicit.v.interpolate(lambda x: np.atleast_2d(0.01 * np.sin(np.pi * x[0] / 2)))
        dyn.integrate_explicit(explicit, dyn.TimeStepping(dt=dt, t_end=period))
        n = explicit._owned
        return explicit.u.x.array[:n].copy()

    reference = run(dt_crit / 32)
    errors = [
        comm.allreduce(np.abs(run(f * dt_crit) - reference).max(initial=0.0), op=MPI.MAX) for f in (0.8, 0.4, 0.2)
    ]
    orders = [math.log2(errors[i] / errors[i + 1]) for i in range(2)]
    assert all(1.85 < p < 2.15 for p in orders), (errors, orders)


def test_explicit_conserves_energy_to_second_order(comm):
    """Neo-Hookean beam, free vibration: |E/E0 - 1| <= 2e-3 at 0.9 dt_crit and 4x smaller at half
    the step (measured 1.19e-3, 2.97e-4), with a large exchange of kinetic and elastic energy."""

    def run(dt):
        explicit = dyn.ExplicitDynamics(beam(comm), dyn.MassDensity(1000.0, lumped=True), lame=BEAM_PARAMS)
        launch_beam(explicit)
        diag = dyn.Diagnostics(explicit)
        diag.record()
        dyn.integrate_explicit(explicit, dyn.TimeStepping(dt=dt, t_end=0.5), on_step=diag.record)
        total = diag.column("total_energy")
        assert diag.column("elastic_energy").max() > 0.8 * total[0]
        assert diag.column("kinetic_energy").min() < 0.2 * total[0]
        return np.abs(total / total[0] - 1.0).max()

    dt = 0.9 * dyn.stable_time_step(beam(comm).domain, BEAM_PARAMS, 1000.0).dt_crit
    coarse, fine = run(dt), run(dt / 2)
    assert coarse < 2e-3
    assert 3.5 < coarse / fine < 4.5


def test_mass_proportional_damping_decays_energy(comm):
    """C = alpha M on the bar's first mode: E(t) = E0 exp(-alpha t) (alpha << omega), within 1 %."""
    alpha = 2.0
    base = bar(comm, 10, hf.materials.linear_elastic)
    explicit = dyn.ExplicitDynamics(
        base, dyn.MassDensity(1.0, lumped=True), dyn.viscous_damping(alpha), lame=SEED_PARAMS
    )
    explicit.v.interpolate(lambda x: np.atleast_2d(0.01 * np.sin(np.pi * x[0] / 2)))
    period = 4.0 / C_SEED
    energy0 = explicit.kinetic_energy()
    dyn.integrate_explicit(explicit, dyn.TimeStepping(dt=explicit.stable_step.dt_max / 2, t_end=3 * period))
    energy = explicit.kinetic_energy() + explicit.elastic_energy()
    assert energy / energy0 == pytest.approx(math.exp(-alpha * 3 * period), rel=0.01)


# -- mass -----------------------------------------------------------------------------
def test_lumped_and_consistent_mass_totals(comm):
    """Both masses carry rho |Omega| per component; a uniform translation has K = rho |Omega| v^2 / 2."""
    base = beam(comm)
    domain = base.domain
    rho = 1000.0
    density = dyn.MassDensity({"domain": rho})
    volume = L_BEAM * 1.0 * 1.0
    assert dyn.total_mass(density, domain) == pytest.approx(rho * volume, rel=1e-12)
    mass = dyn.lumped_mass(density, domain, base.V)
    n = base.V.dofmap.index_map.size_local * 3
    per_component = comm.allreduce(mass.x.array[:n].reshape(-1, 3).sum(axis=0), op=MPI.SUM)
    assert np.allclose(per_component, rho * volume, rtol=1e-12)
    assert mass.x.array.min() > 0
    # Consistent mass applied to the unit translation e_x sums to rho |Omega| too.
    one = fem.Function(base.V)
    one.interpolate(lambda x: np.vstack([np.ones(x.shape[1]), 0 * x[0], 0 * x[0]]))
    test = ufl.TestFunction(base.V)
    Mx = fem.assemble_vector(fem.form(density.integral(ufl.dot(one, test), domain, 1)))
    Mx.scatter_reverse(la.InsertMode.add)
    assert comm.allreduce(Mx.array[:n].sum(), op=MPI.SUM) == pytest.approx(rho * volume, rel=1e-12)
    v = np.array([0.3, -0.2, 0.5])
    for lumped in (True, False):
        explicit = dyn.ExplicitDynamics(base, dyn.MassDensity(rho, lumped=lumped), lame=BEAM_PARAMS)
        explicit.v.interpolate(lambda x: np.tile(v[:, None], (1, x.shape[1])))
        assert explicit.kinetic_energy() == pytest.approx(0.5 * rho * volume * v @ v, rel=1e-12)
    with pytest.raises(hf.ParameterError, match="degree-1"):
        dyn.lumped_mass(density, domain, fem.functionspace(domain.mesh, ("Lagrange", 2, (3,))))


# -- seed 003: FVM is lumped-mass FEM ------------------------------------------------------
def test_fvm_node_force_equals_fem_force(comm):
    """Seed 003 eq. 3.93 with Saint Venant-Kirchhoff (eq. 3.96): the median-dual node force
    -1/3 P^e (A N summed over the three faces at the node) equals the assembled P1 residual."""
    svk = hf.materials.saint_venant_kirchhoff
    base = beam(comm, svk)
    base.u.interpolate(lambda x: np.vstack([0.1 * x[1] * x[0], 0.05 * np.sin(x[0]) + 0.02 * x[2], -0.03 * x[0] ** 2]))
    residual = fem.assemble_vector(fem.form(base.residual))
    residual.scatter_reverse(la.InsertMode.add)
    mesh = base.domain.mesh
    V = base.V
    ncells = mesh.topology.index_map(3).size_local
    dofs = np.array([V.dofmap.cell_dofs(c) for c in range(ncells)])  # (ncells, 4) blocks
    X = V.tabulate_dof_coordinates()[dofs]  # (ncells, 4, 3)
    x = X + base.u.x.array.reshape(-1, 3)[dofs]
    Dm = np.transpose(X[:, 1:] - X[:, :1], (0, 2, 1))
    Ds = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
    F = Ds @ np.linalg.inv(Dm)
    E = 0.5 * (np.transpose(F, (0, 2, 1)) @ F - np.eye(3))
    trE = np.trace(E, axis1=1, axis2=2)[:, None, None]
    S = BEAM_PARAMS.lmbda * trE * np.eye(3) + 2 * BEAM_PARAMS.mu * E
    P = F @ S
    force = fem.Function(V)
    f = force.x.array.reshape(-1, 3)
    centroid = X.mean(axis=1)
    for i in range(4):
        total = np.zeros((ncells, 3))
        for omit in (j for j in range(4) if j != i):  # the three faces containing vertex i
            face = [k for k in range(4) if k != omit]
            AN = 0.5 * np.cross(X[:, face[1]] - X[:, face[0]], X[:, face[2]] - X[:, face[0]])
            outward = np.sign(np.einsum("ni,ni->n", AN, X[:, face[0]] - centroid))[:, None]
            total += outward * AN
        node_force = -np.einsum("nij,nj->ni", P, total) / 3.0  # force on the node (seed 3.91-3.93)
        np.add.at(f, dofs[:, i], -node_force)  # the residual is minus the force on the node
    force.x.scatter_reverse(la.InsertMode.add)
    n = V.dofmap.index_map.size_local * 3
    diff = comm.allreduce(np.abs(force.x.array[:n] - residual.array[:n]).max(initial=0.0), op=MPI.MAX)
    scale = comm.allreduce(np.abs(residual.array[:n]).max(initial=0.0), op=MPI.MAX)
    assert scale > 1e3
    assert diff < 1e-10 * scale


# -- a run of the explicit scheme is a Simulation -------------------------------------------
def explicit_strip(comm):
    """A 4 x 1 strip of 8 x 2 x 2 P1 triangles, clamped at x = 0, swinging (lumped mass, damped)."""
    mesh = dmesh.create_rectangle(comm, [[0.0, 0.0], [4.0, 1.0]], [8, 2], dmesh.CellType.triangle)
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    base = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, BEAM_PARAMS), bcs=[hf.Clamp("left")])
    density = dyn.MassDensity(1000.0, lumped=True)
    explicit = dyn.ExplicitDynamics(base, density, dyn.viscous_damping(0.1), lame=BEAM_PARAMS)
    explicit.v.interpolate(lambda x: np.vstack([np.zeros(x.shape[1]), 4.0 * (x[0] / 4.0) ** 2]))
    return explicit


class _Stop(Exception):
    """Stands for a kill after a given step."""


def test_explicit_run_has_the_outputs_and_restart_of_a_simulation(comm, tmp_path):
    """integrate_explicit is a Simulation with ExplicitStage: CSV, JSON, VTX, probes and a
    checkpoint from which the run continues to the state of the uninterrupted one."""
    from hyperfem.io import vtx_steps
    from hyperfem.simulation import VTX, Checkpoint, CSVLog, JSONSummary, Output, Probe, Recorder, Simulation

    folder = Path(comm.bcast(str(tmp_path), root=0))

    class StopAfter(Output):
        def write(self, sim, step):
            if step is not None and step.step >= 7:
                raise _Stop

    def run(where, extra=(), restart=None):
        explicit = explicit_strip(comm)
        diagnostics = dyn.Diagnostics(explicit, [(4.0, 0.5)])
        stepping = dyn.TimeStepping(dt=0.004, t_end=0.048)
        outputs = [
            Recorder(diagnostics),
            Probe([(4.0, 0.5)]),
            CSVLog(where / "strip.csv"),
            JSONSummary(where / "strip.json"),
            VTX(where / "strip.bp"),
            Checkpoint(where / "ckpt", every=5),
            *extra,
        ]
        sim = Simulation(explicit, None, stepping, outputs, stage=dyn.ExplicitStage, name="strip")
        return sim, sim.run(restart=restart)

    full, summary = run(folder / "full")
    assert summary["completed"] and summary["stage"] == "dynamic" and summary["steps"] == 12
    assert summary["linear_solver"] == "none (lumped mass)" and summary["petsc_options"] == {}
    assert all(row["newton_iterations"] == 0 and row["reason"] == "EXPLICIT" for row in summary["rows"][1:])
    assert summary["probe_displacement"][0][1] > 0.01  # the free end swings up
    comm.Barrier()
    lines = (folder / "full" / "strip.csv").read_text().splitlines()
    assert len(lines) == 14 and "kinetic_energy" in lines[0] and "p0_y" in lines[0]
    written = json.loads((folder / "full" / "strip.json").read_text())
    assert written["completed"] and len(written["rows"]) == 13 and written["final_time"] == pytest.approx(0.048)
    assert vtx_steps(folder / "full" / "strip.bp") == 13  # the initial state and every step

    with pytest.raises(_Stop):
        run(folder / "cut", extra=[StopAfter()])
    resumed, again = run(folder / "cut", restart=folder / "cut" / "ckpt")
    assert again["restarted_from"].endswith("step-000005") and again["steps"] == 12
    for name in ("u", "v", "a"):
        a, b = getattr(resumed.problem, name).x.array, getattr(full.problem, name).x.array
        assert max_difference(comm, a, b) <= 1e-12 * max_difference(comm, b, 0 * b)
    assert [row["time"] for row in again["rows"]] == pytest.approx([row["time"] for row in summary["rows"]])
    assert again["rows"][-1]["kinetic_energy"] == pytest.approx(summary["rows"][-1]["kinetic_energy"], rel=1e-12)


def max_difference(comm, a, b) -> float:
    return comm.allreduce(float(np.abs(a - b).max(initial=0.0)), op=MPI.MAX)


def test_integrate_explicit_calls_on_step_after_its_outputs(comm):
    from hyperfem.simulation import Quantity

    explicit = explicit_strip(comm)
    order = []
    outputs = [Quantity("seen", lambda: order.append("output") or len(order))]
    history = dyn.integrate_explicit(
        explicit, dyn.TimeStepping(dt=0.004, t_end=0.012), on_step=lambda r: order.append(r.step), outputs=outputs
    )
    assert [r.step for r in history] == [1, 2, 3]
    assert order == ["output", "output", 1, "output", 2, "output", 3]


def test_explicit_stage_takes_no_solver(comm):
    from hyperfem.simulation import Simulation

    explicit = explicit_strip(comm)
    with pytest.raises(hf.ParameterError, match="takes no Newton solver"):
        dyn.ExplicitStage(explicit, hf.NewtonSolver(explicit.base))
    with pytest.raises(hf.ParameterError, match="solve_initial needs a solver"):
        Simulation(explicit, None, dyn.TimeStepping(dt=0.004, t_end=0.008), stage=dyn.ExplicitStage, solve_initial=True)
    with pytest.raises(hf.ParameterError, match="no solver and no stage: .* stage=hyperfem.dynamics.ExplicitStage"):
        Simulation(explicit, None, dyn.TimeStepping(dt=0.004, t_end=0.008))
