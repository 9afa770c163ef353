"""``[stepping] type = "buckling"``: a linearised buckling analysis from a case file (cases/column.toml)."""

from __future__ import annotations

import json

import pytest
from mpi4py import MPI

from hyperfem.app import build, load_case, script
from hyperfem.app.casefile import CaseFileError
from hyperfem.errors import ParameterError
from hyperfem.stability.run import Buckling, BucklingRun

from case_texts import ROOT

CASE = ROOT / "cases" / "column.toml"


def test_column_case_gives_the_euler_load_and_writes_the_modes(shared_tmp):
    """Critical load factors over Euler's load: 1.00534 and 2.26006 on the committed mesh (beam theory 1 and
    2.25; 1.0034 converged, hyperfem/cases/column.py), the same on 1 and 2 ranks; the JSON and the modes."""
    case = load_case(CASE, output=shared_tmp)
    text = script(case)
    assert "stepping = Buckling(n=2)" in text and "BucklingRun(problem, solver, stepping, out, name='column')" in text
    assert "outputs = [" not in text
    built = build(case, MPI.COMM_WORLD)
    assert isinstance(built.simulation, BucklingRun) and built.outputs == []
    summary = built.simulation.run()
    assert summary["critical_load_factors"] == pytest.approx([1.00534, 2.26006], rel=1e-5)
    assert all(m < 0 for m in summary["buckling"]["reversed_multipliers"])
    MPI.COMM_WORLD.Barrier()
    written = json.loads((shared_tmp / "column.json").read_text())
    assert written["critical_load_factors"] == pytest.approx(summary["critical_load_factors"], rel=1e-12)
    assert (shared_tmp / "column_modes.bp").is_dir()
    with pytest.raises(ParameterError, match="no steps to continue"):
        built.simulation.run(restart=shared_tmp)


def test_a_prestressed_reference_state(shared_tmp):
    """From the equilibrium at half the load, Newton prestress: within 1 % of the linear analysis from 0."""
    case = load_case(CASE, ["stepping.reference=0.5", 'stepping.prestress="nonlinear"', "stepping.n=1"],
                     output=shared_tmp)
    summary = build(case, MPI.COMM_WORLD).simulation.run()
    assert summary["steps"] >= 1 and summary["buckling"]["reference_time"] == 0.5
    assert summary["critical_load_factors"][0] == pytest.approx(1.00534, rel=0.01)


@pytest.mark.parametrize(
    "overrides, expected",
    [
        (["stepping.n=0"], "stepping.n"),
        (["stepping.increment=0.0"], "stepping.increment: must not be 0"),
        (['stepping.prestress="exact"'], "stepping.prestress"),
        (["stepping.dt=0.1"], "stepping.dt: a key of dynamic stepping, not of buckling stepping"),
        (["output.times=[0.5]"], "output.times: not with buckling stepping"),
    ],
)
def test_bad_buckling_keys_are_one_line_errors(overrides, expected):
    with pytest.raises(CaseFileError) as info:
        load_case(CASE, overrides)
    assert expected in str(info.value) and "\n" not in str(info.value)


def test_settings_are_validated():
    with pytest.raises(ParameterError, match="increment must not be 0"):
        Buckling(increment=0.0)
    with pytest.raises(ParameterError, match="prestress"):
        Buckling(prestress="exact")
