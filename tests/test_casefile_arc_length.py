"""``[stepping] type = "arc_length"`` in case files: the keys, their errors, the example case run end to end."""

from __future__ import annotations

from pathlib import Path

import pytest
from mpi4py import MPI

from hyperfem.app import build, check_groups, load_case, script
from hyperfem.app.build import build_domain
from hyperfem.app.casefile import CaseFileError
from hyperfem.cases.instability import SPHERE_PRESSURE_MAXIMUM
from hyperfem.solver import ArcLength

from case_texts import ROOT

CASE = ROOT / "cases" / "inflation.toml"


def _error(overrides) -> str:
    with pytest.raises(CaseFileError) as info:
        load_case(CASE, overrides)
    return str(info.value)


def test_the_example_case_maps_onto_arc_length(shared_tmp):
    case = load_case(CASE, [f"output.directory={str(shared_tmp)!r}"])
    assert case.stepping.continuation and not case.stepping.dynamic
    text = script(case)
    compile(text, "inflation.py", "exec")
    assert "ArcLength(increment=0.1, max_displacement=1.5, max_steps=60, end=None)" in text
    assert "spherical_shell_mesh(h=0.5, order=2" in text
    check_groups(case, build_domain(case, MPI.COMM_WORLD))


def test_the_example_case_passes_the_pressure_maximum(shared_tmp):
    """The case as ``hyperfem run`` builds it, stopped at an inner stretch of 2.1: the limit point in the
    summary and the rows (within 0.2 % of the closed-form maximum on this mesh), the pivots in every row."""
    case = load_case(CASE, [f"output.directory={str(shared_tmp)!r}", "stepping.max_displacement=1.1",
                            "output.checkpoint=false"])
    built = build(case)
    assert isinstance(built.simulation.continuation, ArcLength)
    summary = built.simulation.run()
    assert summary["completed"] and summary["stage"] == "arc-length" and summary["end"] is None
    assert summary["limit_points"] == pytest.approx([SPHERE_PRESSURE_MAXIMUM[0]], rel=2e-3)
    rows = summary["rows"]
    assert rows[-1]["probe_displacement"][0][0] > 1.1  # stopped by max_displacement
    assert {r["negative_pivots"] for r in rows} == {rows[0]["negative_pivots"], rows[0]["negative_pivots"] + 1}
    assert sum(r["limit_point"] for r in rows) == 1
    # hyperfem plot: the path in the load factor (not a dynamic run), the limit point starred
    from hyperfem.simulation.plots import load_displacement, plot_run, read_rows

    made = plot_run(shared_tmp, comm=MPI.COMM_WORLD)
    if MPI.COMM_WORLD.rank == 0:
        assert sorted(p.name for p in made) == ["inflation_convergence_newton.png", "inflation_load_displacement.png"]
        table = read_rows(shared_tmp / "inflation.csv")
        assert sum(r["limit_point"] for r in table) == 1.0 and {r["stable"] for r in table} == {0.0, 1.0}
        assert load_displacement(shared_tmp / "inflation.csv", output=shared_tmp / "p.png").stat().st_size > 0


@pytest.mark.parametrize(
    "overrides, expected",
    [
        (["stepping.dt=0.1"], 'stepping.dt: a key of dynamic stepping, not of arc_length stepping'),
        (["stepping.growth=2.0"], 'stepping.growth: a key of quasi-static stepping'),
        (["stepping.psi=-1.0"], "stepping.psi"),
        (["stepping.direction=2"], "stepping.direction"),
        (["stepping.end=1.0", "stepping.min_load=2.0"], "stepping.min_load: must lie below stepping.end"),
        (["output.times=[0.5]"], "output.times: not with arc_length stepping"),
        (["stepping.max_steps=0"], "stepping.max_steps"),
        (["mesh.geometry={inner_radius = 2.0, outer_radius = 1.0}"], "mesh.geometry.outer_radius: must exceed"),
        (["mesh.geometry={belly_length = 0.05}"], "mesh.geometry.belly_length: not a parameter of the spherical"),
        (["stepping.type=\"quasi-static\""], "stepping.max_displacement: a key of arc_length stepping"),
    ],
)
def test_bad_arc_length_keys_are_one_line_errors(overrides, expected):
    message = _error(overrides)
    assert expected in message and "\n" not in message


def test_geometry_of_the_shell_reaches_the_generator():
    case = load_case(CASE, ["mesh.geometry={inner_radius = 0.5, outer_radius = 0.8}", "mesh.size=0.3"])
    assert "spherical_shell_mesh(h=0.3, inner=0.5, outer=0.8, order=2" in script(case)


def test_quasi_static_cases_are_unchanged():
    assert "LoadStepping(initial_increment=0.5)" in script(load_case(Path(ROOT / "cases" / "block_mixed.toml")))


def test_a_probe_stops_the_continuation(shared_tmp):
    """stop_probe/stop_component/stop_value: the run ends at the first step whose inner-face probe has moved
    0.1 outward (on the rising branch), although max_displacement would allow more."""
    overrides = ["stepping.stop_probe=[1.0, 0.0, 0.0]", 'stepping.stop_component="x"', "stepping.stop_value=0.1",
                 "output.checkpoint=false"]
    case = load_case(CASE, overrides, output=shared_tmp)
    assert "probe_stop=((1.0, 0.0, 0.0), 0, 0.1)" in script(case)
    summary = build(case).simulation.run()
    probes = [r["probe_displacement"][0][0] for r in summary["rows"]]
    assert probes[-1] >= 0.1 > probes[-2]
    with pytest.raises(CaseFileError, match="stepping.stop_value: give stop_probe, stop_component and stop_value"):
        load_case(CASE, ["stepping.stop_probe=[1.0, 0.0, 0.0]", 'stepping.stop_component="x"'])


def test_probe_stop_settings_are_checked(shared_tmp):
    from hyperfem.errors import ParameterError

    with pytest.raises(ParameterError, match="probe_stop component"):
        ArcLength(probe_stop=((0.0, 0.0, 0.0), 3, 1.0))
    with pytest.raises(ParameterError, match="probe_stop must be"):
        ArcLength(probe_stop=(0.0, 1.0))
    from hyperfem.solver import NewtonSolver, continue_arc_length

    problem = build(load_case(CASE, ["mesh.size=1.0"], output=shared_tmp)).problem
    with pytest.raises(ParameterError, match="probe_stop is evaluated by a Simulation"):
        continue_arc_length(NewtonSolver(problem), ArcLength(probe_stop=((1.0, 0.0, 0.0), 0, 0.1)))
