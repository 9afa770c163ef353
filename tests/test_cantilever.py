"""Cantilever bend and twist (seed 003 §5.7) on the committed coarse mesh.

Regression values come from a serial run of this code (DOLFINx 0.11, MUMPS)
on ``meshes/beam_h2.msh`` and ``meshes/beam_h1.msh``; the same values must
come out on 2 ranks. Tolerances (1e-6 relative) are far below the change any
real modification of the physics would make, and far above round-off.
"""

import warnings
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

import hyperfem as hf
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load, twist_load
from hyperfem.io import PointProbe

MESHES = Path(__file__).resolve().parent.parent / "meshes"


def _solve(mesh: str, load, degree=1, options=None):
    domain = hf.read_mesh(MESHES / mesh)
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(
        domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("clamped")], loads=[load], degree=degree
    )
    solver = hf.NewtonSolver(problem, options)
    steps = hf.solve_quasistatic(solver)
    return problem, solver, steps, PointProbe(domain.mesh, [TEST_POINT])(problem.u)[0]


REFERENCE = {
    # (mesh, case): displacement of the test point (m)
    ("beam_h2.msh", "bend"): [0.135077318161, -0.852854731738, 0.003404957717],
    ("beam_h1.msh", "bend"): [0.166200299113, -1.063124526134, 0.003653853098],
    # twist: follower traction integrated exactly (degree 2 on P1 facets); the
    # one-point rule gave [0.000665339655, 0.08590129264, -0.094105853435] (h2)
    # and [0.000864480858, 0.140974004152, -0.15864444951] (h1): 9 % / 2.7 % short.
    ("beam_h2.msh", "twist"): [0.000738777159488, 0.0943345357056, -0.104026240442],
    ("beam_h1.msh", "twist"): [0.000877624131272, 0.144740517479, -0.163307277204],
}


@pytest.mark.parametrize("mesh", ["beam_h2.msh", "beam_h1.msh"])
def test_bend_regression(mesh):
    problem, solver, steps, d = _solve(mesh, bend_load())
    assert len(steps) == 1
    assert steps[0].solve.iterations <= 6  # energy line search: full load in a few Newton steps
    np.testing.assert_allclose(d, REFERENCE[(mesh, "bend")], rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("mesh", ["beam_h2.msh", "beam_h1.msh"])
def test_twist_regression(mesh):
    problem, solver, steps, d = _solve(mesh, twist_load())
    assert not problem.conservative and not solver.energy_line_search
    assert steps[0].solve.iterations <= 10
    np.testing.assert_allclose(d, REFERENCE[(mesh, "twist")], rtol=1e-6, atol=1e-9)


def test_energy_line_search_beats_residual_line_search():
    """The measured claim of the issue: the energy merit needs far fewer Newton steps."""
    _, energy, steps_energy, d_energy = _solve("beam_h1.msh", bend_load())
    assert energy.energy_line_search  # default for a conservative problem
    domain = hf.read_mesh(MESHES / "beam_h1.msh")
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(
        domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("clamped")], loads=[bend_load()]
    )
    residual = hf.NewtonSolver(problem, energy_line_search=False)
    problem.set_time(1.0)
    rec = residual.solve(raise_on_failure=True)
    # measured: 4 vs 18; bounds with slack (iteration counts are not round-off-level here, but
    # the last iterate of each solve decides by a factor ~1e3, not 1e6)
    assert steps_energy[0].solve.iterations <= 6
    assert rec.iterations >= 2 * steps_energy[0].solve.iterations
    d_residual = PointProbe(domain.mesh, [TEST_POINT])(problem.u)[0]
    np.testing.assert_allclose(d_residual, d_energy, rtol=1e-7, atol=1e-9)


def test_line_search_reuses_the_accepted_trials_energy_and_judged_residual(monkeypatch):
    """The energy of each iterate after the first is the accepted trial's, and a step judged by its residual
    is not assembled again: the same iterates, residual norms and displacement as assembling both anew (bit
    for bit serially; on 2 ranks MUMPS's own round-off differs between runs), with one energy assembly fewer
    per Newton iteration."""
    from hyperfem.solver.objective import EnergyObjective

    runs = []
    for reuse in (True, False):
        if not reuse:
            energy = EnergyObjective._energy
            monkeypatch.setattr(EnergyObjective, "_energy", lambda self, x, current, f=energy: f(self, x, False))
            monkeypatch.setattr(EnergyObjective, "judged_residual", lambda self, x, b: False)
        problem, solver = _bend_solver("beam_h1.msh")
        assemblies: list[int] = []
        energies = solver._energies
        solver._energies = lambda calls=assemblies, f=energies: calls.append(1) or f()
        rec = solver.solve(raise_on_failure=True)
        objective = solver._objective
        counts = (len(assemblies), objective.energies_reused, objective.residuals_reused)
        runs.append((rec, counts, problem.u.x.array.copy()))
    (rec, (assembled, reused, copied), u), (rec_all, (assembled_all, reused_all, copied_all), u_all) = runs
    assert rec.iterations == rec_all.iterations >= 3 and reused == rec.iterations - 1 and reused_all == 0
    assert assembled == assembled_all - reused
    assert rec.roundoff_accepts >= 1 and copied >= 1 and copied_all == 0  # a judged step's residual copied
    exact = MPI.COMM_WORLD.size == 1
    floor = 0 if exact else 1e-12 * rec_all.residual_norms[0]  # the last norms sit at round-off
    np.testing.assert_allclose(rec.residual_norms, rec_all.residual_norms, rtol=0 if exact else 1e-10, atol=floor)
    np.testing.assert_allclose(u, u_all, rtol=0, atol=0 if exact else 1e-12 * np.abs(u_all).max())


def _bend_solver(mesh="beam_h2.msh", options=None, **kwargs):
    domain = hf.read_mesh(MESHES / mesh)
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(
        domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("clamped")], loads=[bend_load()]
    )
    problem.set_time(1.0)
    return problem, hf.NewtonSolver(problem, options, **kwargs)


TIGHT = {"snes_rtol": 1e-15, "snes_atol": 1e-15}  # far below the round-off floor of this problem


@pytest.mark.parametrize("guard", [True, False])
def test_solve_at_roundoff_floor_ends_and_says_so(guard):
    """A tolerance below the floating-point floor ends at the floor, with a warning, on any machine.

    Before: Newton reached the floor (~1e-13 of the first residual) at iteration 5 and then
    wandered in noise for up to 30 iterations until a lucky dip crossed rtol. Now the solve
    ends at the first stagnating iterate within ROUNDOFF_FACTOR of the estimate eps*||K||x||,
    with or without the energy round-off guard of the line search.
    """
    problem, default = _bend_solver()
    reference = default.solve(raise_on_failure=True)
    assert reference.reason_name == "CONVERGED_FNORM_RELATIVE"  # default tolerances sit far above the floor
    u_ref = problem.u.x.array.copy()
    problem, tight = _bend_solver(options=TIGHT, energy_roundoff_rtol=1e-9 if guard else -1.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = tight.solve()
    assert rec.converged and rec.reason_name == "CONVERGED_ROUNDOFF", rec.reason_name
    assert np.isfinite(rec.roundoff_floor) and rec.roundoff_floor > 0
    assert rec.residual_norms[-1] <= hf.ROUNDOFF_FACTOR * rec.roundoff_floor
    # Newton's quadratic phase decides when the floor is reached; the stop adds at most a few iterates.
    assert rec.iterations <= reference.iterations + 4
    if MPI.COMM_WORLD.rank == 0:
        assert any(issubclass(w.category, hf.RoundoffWarning) for w in caught)
    np.testing.assert_allclose(problem.u.x.array, u_ref, rtol=0, atol=1e-9)


def test_roundoff_stop_is_insensitive_to_noise():
    """Different round-off realisations (start perturbed by 1e-12 m) end the same way."""
    outcomes = set()
    tips = []
    for seed in range(4):
        problem, solver = _bend_solver(options=TIGHT)
        rng = np.random.default_rng(seed)
        problem.u.x.array[:] = 1e-12 * rng.standard_normal(problem.u.x.array.size)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", hf.RoundoffWarning)
            rec = solver.solve()
        outcomes.add((rec.converged, rec.reason_name in ("CONVERGED_ROUNDOFF", "CONVERGED_FNORM_RELATIVE")))
        assert rec.iterations <= 10
        tips.append(PointProbe(problem.domain.mesh, [TEST_POINT])(problem.u)[0])
    assert outcomes == {(True, True)}
    np.testing.assert_allclose(np.array(tips), np.array(tips[:1] * len(tips)), rtol=0, atol=1e-10)


def test_roundoff_stop_can_be_disabled():
    """roundoff_factor=0 restores plain SNES tolerances (which then run to snes_max_it here)."""
    _, solver = _bend_solver(options={**TIGHT, "snes_max_it": 12}, roundoff_factor=0.0)
    rec = solver.solve()
    assert rec.reason_name != "CONVERGED_ROUNDOFF"
