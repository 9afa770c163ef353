r"""Arc-length continuation (issue 22): through limit points, against closed forms, with the pivots counted.

* **Inflated thick-walled sphere** (:mod:`hyperfem.cases.instability`,
  A = 1, B = 2, one eighth, three-field P2/P1, h = 0.5, K = 10³μ): the
  pressure–inner-stretch path follows the closed form through the maximum
  to :math:`\lambda_a \ge 2.5` (within 0.6 % at every step here; 0.30 % at
  h = 0.35, measured), the limit point is found once and located at
  :math:`p/\mu = 0.8175` against 0.8164 (0.016 % at h = 0.35), and the
  tangent gains exactly one negative pivot past it (unstable under pressure
  control), on 1 and 2 ranks.
* **Shallow clamped arch** under its weight: the full snap-through path,
  load maximum, descending branch, minimum; the located limit loads agree
  for arc lengths a factor 2 apart (1.67352 and 1.67342 measured) and the
  pivots go 0 → 1 → 0.
* **Prescribed displacement** as the only load: the path is the homogeneous
  uniaxial stretch, with the Dirichlet rows moved with :math:`\lambda`.
* The pivot count against dense eigenvalues; bad settings and refused set-ups.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

import hyperfem as hf
from hyperfem.cases.instability import SPHERE_PRESSURE_MAXIMUM, inflated_sphere, shallow_arch, sphere_pressure
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube
from hyperfem.errors import ParameterError
from hyperfem.materials.neo_hookean import neo_hookean
from hyperfem.materials.parameters import LameParameters
from hyperfem.problem import HyperelasticProblem
from hyperfem.solver import ArcLength, NewtonSolver, continue_arc_length, count_negative_pivots


def test_sphere_inflation_through_the_pressure_maximum():
    case = inflated_sphere(h=0.5)
    stretches: list[float] = []

    def on_step(record):
        stretches.append(case.inner_stretch())

    history = continue_arc_length(
        NewtonSolver(case.problem),
        ArcLength(increment=0.1, end=None, max_steps=40),
        on_step=on_step,
        stop=lambda record: stretches[-1] >= 2.5,
    )
    assert stretches[-1] >= 2.5
    loads = np.array([r.time for r in history])
    closed = sphere_pressure(np.array(stretches))
    assert np.max(np.abs(loads - closed) / closed) < 0.01
    assert np.all(np.diff(stretches) > 0)  # the balloon keeps growing, the pressure turns
    limits = [r for r in history if r.limit_point]
    assert len(limits) == 1
    p_max, la_max = SPHERE_PRESSURE_MAXIMUM
    assert abs(limits[0].limit_load - p_max) / p_max < 0.005
    k = history.index(limits[0])
    assert max(loads) >= limits[0].time and abs(max(loads) - limits[0].limit_load) < 2e-3
    assert all(r.dt > 0 for r in history[:k]) and all(r.dt < 0 for r in history[k + 1 :])
    # One more negative pivot past the maximum: stable before it, unstable after.
    negatives = [r.negative_pivots for r in history]
    assert all(r.stable for r in history[:k]) and not any(r.stable for r in history[k:])
    assert set(negatives[k:]) == {negatives[0] + 1}
    assert not any(r.bifurcation for r in history)


def _run_arch(increment):
    case = shallow_arch(rise=0.5, cells=16)
    deflections: list[float] = []
    history: list = []

    def on_step(record):
        history.append(record)
        deflections.append(case.crown_deflection())

    continue_arc_length(
        NewtonSolver(case.problem),
        ArcLength(increment=increment, end=None, max_steps=60),
        on_step=on_step,
        stop=lambda r: sum(h.limit_point for h in history) >= 2,
    )
    return history, np.array(deflections)


def test_arch_snaps_through_with_step_size_independent_limit_loads():
    coarse, d_coarse = _run_arch(0.2)
    fine, d_fine = _run_arch(0.1)
    for history, deflection in ((coarse, d_coarse), (fine, d_fine)):
        limits = [r for r in history if r.limit_point]
        assert len(limits) == 2
        top, bottom = limits
        assert top.limit_load > bottom.limit_load > 0
        # The descending branch lies between them; the crown moves down all along.
        i, j = history.index(top), history.index(bottom)
        assert all(r.dt < 0 for r in history[i + 1 : j]) and j - i >= 2
        assert np.all(np.diff(deflection) < 0)
        assert [r.negative_pivots for r in (history[0], top, bottom)] == [0, 1, 0]
    for a, b in zip(
        [r.limit_load for r in coarse if r.limit_point], [r.limit_load for r in fine if r.limit_point], strict=True
    ):
        assert abs(a - b) / b < 1e-3
    # Regression (this mesh and settings, a run on 1 and 2 ranks): the maximum and the minimum of the path.
    assert [r.limit_load for r in fine if r.limit_point] == pytest.approx([1.67352, 0.810462], rel=2e-4)


def test_prescribed_displacement_path_is_the_homogeneous_stretch():
    domain = unit_cube(2)
    params = LameParameters.from_youngs(10.0, 0.3)
    problem = HyperelasticProblem(domain, lambda F: neo_hookean(F, params), bcs=uniaxial_rollers(1.5))
    probe = hf.io.probes.PointProbe(domain.mesh, [[1.0, 1.0, 1.0], [0.5, 0.5, 0.5]])
    seen = []
    history = continue_arc_length(
        NewtonSolver(problem), ArcLength(increment=0.25, end=1.0), on_step=lambda r: seen.append(probe(problem.u))
    )
    assert history[-1].time >= 1.0
    for record, values in zip(history, seen, strict=True):
        # u_x = λ (stretch - 1) x, homogeneous; the corner and the centre agree.
        assert values[0, 0] == pytest.approx(0.5 * record.time, abs=1e-9)
        assert values[1, 0] == pytest.approx(0.25 * record.time, abs=1e-9)
        assert values[0, 1] == pytest.approx(2 * values[1, 1], abs=1e-9)
    assert all(r.dt > 0 for r in history) and not any(r.limit_point for r in history)


def test_negative_pivots_against_dense_eigenvalues():
    comm = MPI.COMM_WORLD
    n = 12
    rng = np.random.default_rng(3)
    M = rng.standard_normal((n, n))
    M = M + M.T + np.diag(np.linspace(-6.0, 6.0, n))
    A = PETSc.Mat().createAIJ([n, n], comm=comm)
    A.setUp()
    start, end = A.getOwnershipRange()
    for i in range(start, end):
        A.setValues(i, range(n), M[i])
    A.assemble()
    try:
        assert count_negative_pivots(A) == int(np.sum(np.linalg.eigvalsh(M) < 0))
    finally:
        A.destroy()


@pytest.mark.parametrize(
    "kwargs",
    [
        {"increment": 0.0},
        {"increment": 0.1, "min_increment": 0.2},
        {"increment": 0.1, "max_increment": 0.05},
        {"psi": -1.0},
        {"psi": math.nan},
        {"cutback": 1.0},
        {"direction": 0},
        {"max_steps": 0},
        {"end": 0.0, "min_load": 1.0},
    ],
)
def test_bad_settings_are_one_line_errors(kwargs):
    with pytest.raises(ParameterError) as info:
        ArcLength(**kwargs)
    assert "\n" not in str(info.value) and "ArcLength" in str(info.value)


def test_a_problem_without_moving_loads_is_refused():
    domain = unit_cube(1)
    params = LameParameters.from_youngs(10.0, 0.3)
    problem = HyperelasticProblem(domain, lambda F: neo_hookean(F, params), bcs=uniaxial_rollers(1.0))
    problem.bcs  # noqa: B018  (compiled)
    with pytest.raises(ParameterError, match="nothing to follow"):
        continue_arc_length(NewtonSolver(problem), ArcLength(increment=0.1))


def test_shell_mesh_bad_input():
    with pytest.raises(ParameterError, match="inner < outer"):
        hf.mesh.spherical_shell_mesh(2.0, 1.0)
    with pytest.raises(ParameterError, match="order"):
        hf.mesh.spherical_shell_mesh(order=3)


def test_inflation_demo(shared_tmp, capsys):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).parent.parent / "demos" / "inflation.py"
    spec = importlib.util.spec_from_file_location("demo_inflation", path)
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    result = demo.main(["--sizes", "0.5", "--stretch", "2.0", "--output", str(shared_tmp)])
    assert result["max_relative_errors"][0] < 0.01
    assert abs(result["located_maxima"][0] - SPHERE_PRESSURE_MAXIMUM[0]) < 0.004
    if MPI.COMM_WORLD.rank == 0:
        assert (shared_tmp / "inflation.png").stat().st_size > 0
        assert "maximum p/mu" in capsys.readouterr().out


def test_branch_switching_leaves_the_symmetric_path_of_an_arch():
    """A higher arch (H = 0.8) bifurcates into an antisymmetric mode before its symmetric limit point.

    Without switching the path stays symmetric and reaches the symmetric
    maximum (λ ≈ 3.71); with it, the bifurcation is found at λ ≈ 3.36
    (0 → 1 negative pivot, no turn of the load) and the next steps follow the
    antisymmetric branch, whose load falls: the quarter points part.
    """
    from hyperfem.cases.instability import ARCH_SPAN

    case = shallow_arch(rise=0.8, cells=16)
    quarters = hf.io.probes.PointProbe(
        case.problem.domain.mesh, [[ARCH_SPAN / 4, 0.75 * 0.8 + 0.2, 0.1], [3 * ARCH_SPAN / 4, 0.75 * 0.8 + 0.2, 0.1]]
    )
    history: list = []
    parts: list[float] = []

    def on_step(record):
        history.append(record)
        v = quarters(case.problem.u)[:, 1]
        parts.append(float(v[0] - v[1]))

    continue_arc_length(
        NewtonSolver(case.problem),
        ArcLength(increment=0.1, end=None, max_steps=40, switch_branch=True),
        on_step=on_step,
        stop=lambda r: len(history) > 12 and abs(parts[-1]) > 0.1,
    )
    k = next(i for i, r in enumerate(history) if r.bifurcation)
    assert 3.2 < history[k].time < 3.5 and history[k - 1].negative_pivots == 0 and history[k].negative_pivots == 1
    assert history[k + 1].switched and not any(r.limit_point for r in history)
    assert all(abs(p) < 2e-3 for p in parts[:k])  # symmetric before
    assert abs(parts[-1]) > 0.1  # antisymmetric after
    assert all(r.dt < 0 for r in history[k + 1 :])  # the branch's load falls


class _Killed(Exception):
    """Stands for a kill after a given step."""


def _arch_simulation(folder, stop_after=None):
    from hyperfem.simulation import Checkpoint, CSVLog, JSONSummary, Output, Simulation

    class StopAfter(Output):
        def write(self, sim, step) -> None:
            if stop_after is not None and step is not None and step.step >= stop_after:
                raise _Killed(f"killed after step {step.step}")

    case = shallow_arch(rise=0.5, cells=16)
    outputs = [
        StopAfter(),
        CSVLog(folder / "arch.csv"),
        JSONSummary(folder / "arch.json"),
        Checkpoint(folder / "ckpt", every=4),
    ]
    settings = ArcLength(increment=0.2, end=None, max_steps=12)
    return Simulation(case.problem, NewtonSolver(case.problem), settings, outputs, name="arch")


def test_simulation_continuation_rows_summary_and_restart(shared_tmp):
    """The arch in a Simulation: the load factor is the time column, every row has the step's pivots and
    events, the summary the limit point; a run killed after step 6 and continued from its checkpoint at
    step 4 ends where the uninterrupted one does."""
    import csv

    full = _arch_simulation(shared_tmp / "full")
    summary = full.run()
    assert summary["stage"] == "arc-length" and summary["completed"] and summary["steps"] == 12
    assert summary["end"] is None
    assert summary["limit_points"] == pytest.approx([1.67342], rel=1e-3)
    rows = summary["rows"]
    assert rows[0]["negative_pivots"] == 0 and rows[0]["time"] == 0.0
    assert [r["time"] for r in rows[1:]] == pytest.approx([s.time for s in full.steps], abs=0)
    assert any(r["dt"] < 0 for r in rows) and {r["negative_pivots"] for r in rows} == {0, 1}
    MPI.COMM_WORLD.Barrier()
    with (shared_tmp / "full" / "arch.csv").open() as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == 13 and "limit_point" in table[0] and "negative_pivots" in table[0]

    with pytest.raises(_Killed):
        _arch_simulation(shared_tmp / "cut", stop_after=6).run()
    resumed = _arch_simulation(shared_tmp / "cut").run(restart=shared_tmp / "cut" / "ckpt")
    assert resumed["completed"] and resumed["steps"] == 12
    assert resumed["limit_points"] == pytest.approx(summary["limit_points"], rel=1e-8)
    for a, b in zip(resumed["rows"], rows, strict=True):
        assert a["time"] == pytest.approx(b["time"], rel=1e-8, abs=1e-12)
        assert a["negative_pivots"] == b["negative_pivots"]
