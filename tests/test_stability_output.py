"""The Stability output: the lowest eigenvalues of the tangent at every state of a run, and its warning."""

from __future__ import annotations

import math
import warnings

import pytest
from mpi4py import MPI

import hyperfem as hf
from hyperfem.app import load_case, script
from hyperfem.cases.column import ColumnSpec, column_domain
from hyperfem.errors import ParameterError
from hyperfem.materials.neo_hookean import neo_hookean
from hyperfem.simulation import JSONSummary, Simulation, Stability, UnstableStateWarning

from case_texts import ROOT

COLUMN = ColumnSpec()


def test_a_column_shortened_past_its_critical_strain_turns_unstable(shared_tmp):
    """Clamped at both ends, the top pushed down to 1.5 x the critical shortening in four steps (displacement
    control keeps it straight): stable at 0.375 and 0.75 of the critical shortening, one negative eigenvalue
    at 1.125 and 1.5; the warning once; the summary names the first unstable load factor (0.75)."""
    strain = 4 * math.pi**2 * (COLUMN.width**2 / 12) / COLUMN.length**2  # P = 4 pi^2 EI / L^2
    bcs = [hf.Clamp("bottom"), hf.PrescribedDisplacement("top", (0.0, 0.0, -1.5 * strain * COLUMN.length))]
    problem = hf.HyperelasticProblem(
        column_domain(COLUMN, (1, 1, 10)), lambda F: neo_hookean(F, COLUMN.lame), bcs=bcs, degree=2
    )
    policy = hf.StepPolicy(increment=0.25, growth=1.0)
    outputs = [Stability(2), JSONSummary(shared_tmp / "column.json")]
    sim = Simulation(problem, hf.NewtonSolver(problem), policy, outputs, name="column")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        summary = sim.run()
    rows = summary["rows"]
    assert [r["negative_eigenvalues"] for r in rows] == [0, 0, 0, 1, 1]
    assert [r["stable_state"] for r in rows] == [True, True, True, False, False]
    assert all(len(r["lowest_eigenvalues"]) == 2 for r in rows)
    assert rows[0]["lowest_eigenvalues"][0] > rows[2]["lowest_eigenvalues"][0] > 0 > rows[4]["lowest_eigenvalues"][0]
    assert summary["stability"]["first_unstable_time"] == pytest.approx(0.75)
    mine = [w for w in caught if issubclass(w.category, UnstableStateWarning)]
    assert len(mine) == (1 if MPI.COMM_WORLD.rank == 0 else 0)
    assert "negative eigenvalue" in str(mine[0].message) if mine else True


def test_bad_count_and_the_case_file_key():
    with pytest.raises(ParameterError, match="n"):
        Stability(0)
    text = script(load_case(ROOT / "cases" / "inflation.toml", ["output.stability=2"]))
    assert "Stability(2)" in text
    assert "Stability(" not in script(load_case(ROOT / "cases" / "inflation.toml"))
