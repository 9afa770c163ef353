r"""A fusiform muscle contracting with inertia: the quasi-static limit, and the demo (serial and 2 ranks).

The three-field muscle of :mod:`hyperfem.cases.muscle` on the committed mesh
(268 cells, 2180 unknowns), free experiment (origin clamped, 2 kPa dead
traction on the insertion), activation :math:`\alpha = \min(t/T_a, 1)`,
backward Euler from the passive equilibrium.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

import hyperfem as hf
from hyperfem import dynamics as dyn
from hyperfem.cases.muscle import MUSCLE_DENSITY, muscle_problem
from hyperfem.fibres import laplace_fibres
from hyperfem.loading import Activation

ROOT = Path(__file__).resolve().parent.parent
MESH = ROOT / "meshes" / "fusiform_h8mm.msh"  # committed: a gmsh of another version meshes differently
RAMP, DT = 0.02, 0.005


@pytest.fixture(scope="module")
def muscle():
    domain = hf.read_mesh(MESH, MPI.COMM_WORLD)
    return domain, laplace_fibres(domain, "origin", "insertion")


def _problem(domain, a0):
    activation = Activation(domain.mesh, value=lambda t: min(t / RAMP, 1.0), name="muscle activation")
    base = muscle_problem(domain, a0, activation, "free")
    hf.NewtonSolver(base).solve(raise_on_failure=True)  # passive equilibrium at t = 0
    return base


def _max_nodal(block, comm, array) -> float:
    """Largest nodal displacement length of a state array (owned nodes, all ranks)."""
    owned = block.space.dofmap.index_map.size_local * block.gdim
    d = array[block.dofs[:owned]].reshape(-1, block.gdim)
    return comm.allreduce(float(np.sqrt((d**2).sum(axis=1)).max(initial=0.0)), op=MPI.MAX)


# Serial only: under mpiexec -n 2 the same muscle problem, integrated by backward Euler from its passive
# equilibrium, is checked against the serial numbers by test_demo_short_window (and the static
# solution of demos/muscle.py by tests/test_muscle_demo.py).
@pytest.mark.serial
def test_quasistatic_limit(muscle):
    r"""As :math:`\rho \to 0` the backward-Euler trajectory tends to the static equilibria, linearly in :math:`\rho`.

    Reference: :func:`~hyperfem.solve_quasistatic` on the base problem at the same
    activations (the static solver, not the time loop). A step differs from equilibrium
    by the inertia force :math:`\rho(u - u_n - \Delta t v_n)/\Delta t^2`, linear in
    :math:`\rho`; relative to the stiffness it is about :math:`(\omega_1\Delta t)^{-2}`
    with :math:`\omega_1 \propto \rho^{-1/2}` the lowest frequency (about 210 rad/s at
    the physical density, see ``demos/muscle_dynamics.py``), so the deviation
    :math:`\varepsilon(\rho)` (largest nodal distance over the steps, relative to the
    largest quasi-static displacement) is proportional to :math:`\rho` once
    :math:`(\omega_1\Delta t)^2 \gg 1`. Measured (serial):
    :math:`\varepsilon = 2.0\cdot 10^{-2}, 2.5\cdot 10^{-3}, 3.3\cdot 10^{-4}, 3.4\cdot 10^{-5}` at
    :math:`\rho/\rho_\text{muscle} = 10^{-1}, \dots, 10^{-4}` (ratios 8.0, 7.7, 9.5 per
    decade, tending to 10). Checked: :math:`\varepsilon < 5\cdot 10^{-4}` at :math:`10^{-3}`, and a ratio
    between 6 and 13 from :math:`10^{-2}` to :math:`10^{-3}`.
    """
    domain, a0 = muscle
    comm = domain.comm
    base = _problem(domain, a0)
    reference = [base.u.x.array.copy()]
    stepping = hf.LoadStepping(initial_increment=DT, max_increment=DT, min_increment=DT / 64)
    steps = hf.solve_quasistatic(
        hf.NewtonSolver(base), RAMP, stepping, on_step=lambda _: reference.append(base.u.x.array.copy())
    )
    assert len(steps) == round(RAMP / DT)
    block = dyn.DisplacementBlock(base)
    scale = _max_nodal(block, comm, reference[-1] - reference[0])
    assert 0.01 < scale < 0.02  # the insertion moves by 13 mm

    def deviation(factor: float) -> float:
        density = dyn.MassDensity(factor * MUSCLE_DENSITY)
        problem = dyn.IncrementalProblem(_problem(domain, a0), dyn.BackwardEuler(), density)
        problem.initial_acceleration()
        errors = []

        def compare(record):
            errors.append(_max_nodal(block, comm, problem.u.x.array - reference[record.step]) / scale)

        stepping = dyn.TimeStepping(dt=DT, t_end=RAMP)
        history = dyn.integrate(problem, hf.NewtonSolver(problem), stepping, on_step=compare)
        assert len(history) == len(steps) and sum(r.rejected for r in history) == 0
        return max(errors)

    deviation = {factor: deviation(factor) for factor in (1e-2, 1e-3)}
    assert deviation[1e-3] < 5e-4, deviation
    assert 6.0 < deviation[1e-2] / deviation[1e-3] < 13.0, deviation


# Serial run of `demos/muscle_dynamics.py --dt 0.004 --t-end 0.024` (backward Euler, rho = 1060 kg/m^3,
# T_a = 20 ms): shortening of the insertion (m) at t = 0, 4, ..., 24 ms; 2 ranks must agree.
EXPECTED_SHORTENING = [
    0.0,
    0.0023133788253077523,
    0.00550403753542843,
    0.008774624688921002,
    0.011644242042294977,
    0.013786174619033543,
    0.014281645263792095,
]


@pytest.fixture(scope="module")
def demo_summary(tmp_path_factory):
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("muscle_dynamics")), root=0))
    spec = importlib.util.spec_from_file_location("demo_muscle_dynamics", ROOT / "demos" / "muscle_dynamics.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    summary = module.main(["--dt", "0.004", "--t-end", "0.024", "--quiet", "--output", str(folder)])
    summary["folder"] = folder
    return summary


def test_demo_short_window(demo_summary):
    s = demo_summary
    assert s["ranks"] == MPI.COMM_WORLD.size
    assert s["times"] == pytest.approx([0.004 * k for k in range(7)])
    assert s["activation"] == pytest.approx([min(t / 0.02, 1.0) for t in s["times"]])
    shortening, static = np.array(s["shortening"]), np.array(s["shortening_quasistatic"])
    # Inertia: the muscle lags behind the quasi-static shortening early in the ramp and overshoots it after.
    assert shortening[1] < 0.7 * static[1]
    assert shortening.max() > 1.05 * s["quasistatic_shortening"]
    # At full activation the quasi-static run is the free experiment of demos/muscle.py
    # (tests/test_muscle_demo.py: 13.068609 mm), reached through other steps: equal to
    # the Newton tolerance (5.7e-8 relative measured).
    assert s["quasistatic_shortening"] == pytest.approx(0.013068608770634121, rel=1e-6)
    assert s["overshoot"] == pytest.approx(shortening.max() / s["quasistatic_shortening"] - 1.0)
    np.testing.assert_allclose(shortening, EXPECTED_SHORTENING, rtol=1e-6, atol=1e-10)
    assert s["min_J"] > 0.5
    MPI.COMM_WORLD.Barrier()
    written = json.loads((s["folder"] / "muscle_dynamics.json").read_text())
    assert written["shortening"] == pytest.approx(s["shortening"])
    assert (s["folder"] / "diagnostics.csv").exists() and (s["folder"] / "displacement.bp").is_dir()
