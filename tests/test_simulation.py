"""The run layer: one Simulation for statics and dynamics, outputs written after every accepted step."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from dolfinx import mesh as dmesh

import hyperfem as hf
import hyperfem.simulation.outputs as outputs_module
from hyperfem import dynamics as dyn
from hyperfem.problem import SplitEnergy, solid_problem
from hyperfem.simulation import (
    Progress,
    VTX,
    BoundaryAverage,
    CellVTX,
    CSVLog,
    JSONSummary,
    Probe,
    RadialBulge,
    Reaction,
    Recorder,
    Simulation,
    cauchy_stress,
)

PARAMS = hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3)
TRACTION = (0.0, 0.0, -1e3)
AREA = 0.3 * 0.3


@pytest.fixture
def folder(tmp_path):
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))


def _box(n=(4, 1, 1)) -> hf.Domain:
    mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([1.0, 0.3, 0.3])], list(n))
    return hf.Domain.from_locators(
        mesh,
        {"left": lambda x: np.isclose(x[0], 0.0), "right": lambda x: np.isclose(x[0], 1.0)},
        source="test-box",
    )


def _pulled(degree=2, profile=None) -> hf.HyperelasticProblem:
    load = hf.DeadTraction("right", TRACTION, **({} if profile is None else {"profile": profile}))
    return hf.HyperelasticProblem(
        _box(), lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=[hf.Clamp("left")], loads=[load], degree=degree
    )


def _node_counts(domain) -> tuple[int, int]:
    mesh = domain.mesh
    mesh.topology.create_entities(1)
    return mesh.topology.index_map(0).size_global, mesh.topology.index_map(1).size_global


def _csv_rows(path: Path) -> list[dict]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_static_run_writes_every_step(folder, monkeypatch):
    problem = _pulled()
    writes = []
    original = outputs_module.write_json
    monkeypatch.setattr(outputs_module, "write_json", lambda *a: writes.append(a[0]) or original(*a))
    outputs = [
        Probe([(1.0, 0.15, 0.15)]),
        Reaction("left"),
        CSVLog(folder / "box.csv"),
        JSONSummary(folder / "box.json"),
        VTX(folder / "box.bp"),
    ]
    policy = hf.StepPolicy(increment=0.25, grow_after=99)
    summary = Simulation(problem, hf.NewtonSolver(problem), policy, outputs, name="box").run()
    assert summary["completed"] and summary["error"] is None and summary["stage"] == "quasi-static"
    assert summary["steps"] == summary["load_steps"] == 4 and len(summary["rows"]) == 5
    assert [row["time"] for row in summary["rows"]] == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0])
    vertices, edges = _node_counts(problem.domain)
    assert summary["dofs"] == 3 * (vertices + edges)  # P2: a node per vertex and per edge
    # the support carries the applied load (global balance, up to the Newton tolerance)
    assert summary["reaction_left"] == pytest.approx([0.0, 0.0, -TRACTION[2] * AREA], rel=1e-6, abs=1e-6)
    assert summary["probe_displacement"][0][2] < 0
    assert len(writes) == 1 + 4 + 1  # once per recorded state, once at the end
    comm = MPI.COMM_WORLD
    comm.Barrier()
    written = json.loads((folder / "box.json").read_text())
    assert written["completed"] and written["steps"] == 4 and written["files"]["csv"] == str(folder / "box.csv")
    rows = _csv_rows(folder / "box.csv")
    assert [float(r["time"]) for r in rows] == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0])
    assert float(rows[-1]["reaction_left_2"]) == pytest.approx(summary["reaction_left"][2])
    assert (folder / "box.bp").is_dir()

    # Unloading with the same run layer: back to the reference configuration.
    unload = hf.StepPolicy(end=0.0, increment=0.5)
    result = Simulation(problem, hf.NewtonSolver(problem), unload, [Probe([(1.0, 0.15, 0.15)])]).run()
    assert result["time"] == 0.0 and [r["dt"] for r in result["rows"][1:]] == pytest.approx([-0.5, -0.5])
    assert np.abs(result["probe_displacement"]).max() < 1e-8


def _late_huge_load(s: float) -> float:
    """Nothing up to s = 1/2, then an impossible traction."""
    return 0.0 if s <= 0.5 + 1e-12 else 1e12 * (s - 0.5)


def test_failure_writes_the_completed_steps_and_reraises(folder):
    problem = _pulled(degree=1, profile=_late_huge_load)
    solver = hf.NewtonSolver(problem, {"snes_max_it": 2})
    policy = hf.StepPolicy(increment=0.25, min_increment=0.25, max_increment=0.25)
    outputs = [CSVLog(folder / "fail.csv"), JSONSummary(folder / "fail.json")]
    sim = Simulation(problem, solver, policy, outputs, name="fail")
    with pytest.raises(hf.ConvergenceError, match="fail: stepping failed: reached t = 0.5") as info:
        sim.run()
    assert f"completed steps written to {folder / 'fail.json'}" in str(info.value)
    assert info.value.time == pytest.approx(0.5) and len(info.value.history) == 2
    MPI.COMM_WORLD.Barrier()
    written = json.loads((folder / "fail.json").read_text())
    assert written["completed"] is False and "reached t = 0.5" in written["error"]
    assert written["steps"] == 2 and [row["time"] for row in written["rows"]] == pytest.approx([0.0, 0.25, 0.5])
    assert len(_csv_rows(folder / "fail.csv")) == 3


def test_mixed_problem_outputs(folder):
    """Probes, measures, VTX and cell fields work on the three-field problem (collapsed fields)."""
    domain = _box()
    material = SplitEnergy(lambda F: hf.materials.neo_hookean(F, PARAMS), 50.0 * PARAMS.mu)
    problem = solid_problem(
        domain, material, formulation="mixed", bcs=[hf.Clamp("left")], loads=[hf.DeadTraction("right", TRACTION)]
    )
    average = BoundaryAverage("right", 2)
    outputs = [
        Probe([(1.0, 0.15, 0.15)]),
        average,
        RadialBulge(axis=(1.0, 0.0, 0.0), origin=(0.0, 0.15, 0.15)),
        VTX(folder / "mixed.bp"),
        CellVTX(folder / "mixed_cells.bp", {"cauchy_stress": cauchy_stress(problem, {None: material})}),
    ]
    summary = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(), outputs, name="mixed").run()
    vertices, edges = _node_counts(domain)
    assert summary["dofs"] == 3 * (vertices + edges) + 2 * vertices  # P2 displacement, P1 pressure and volume
    assert average.area == pytest.approx(AREA)
    tip = summary["probe_displacement"][0][2]
    assert tip < 0 and summary["u2_right"] == pytest.approx(tip, rel=0.05)
    assert np.isfinite(summary["max_radial_bulge"])
    assert "volume_consistency" in summary["rows"][-1]
    MPI.COMM_WORLD.Barrier()
    assert (folder / "mixed.bp").is_dir() and (folder / "mixed_cells.bp").is_dir()


def _strip(comm):
    mesh = dmesh.create_rectangle(comm, [[0.0, 0.0], [4.0, 1.0]], [8, 2], dmesh.CellType.triangle)
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    base = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=[hf.Clamp("left")])
    problem = dyn.IncrementalProblem(base, dyn.Newmark(), dyn.MassDensity(1000.0))
    problem.v.interpolate(lambda x: np.vstack([np.zeros(x.shape[1]), 4.0 * (x[0] / 4.0) ** 2]))
    problem.initial_acceleration()
    return problem


def test_dynamic_run_is_integrate_with_outputs(folder, comm):
    stepping = dyn.TimeStepping(dt=0.1, t_end=0.4, adaptive=True, tolerance=1e-3, must_hit=[0.2])
    reference = _strip(comm)
    history = dyn.integrate(reference, hf.NewtonSolver(reference), stepping)
    problem = _strip(comm)
    diagnostics = dyn.Diagnostics(problem, [(4.0, 0.5)])
    outputs = [Recorder(diagnostics), CSVLog(folder / "strip.csv"), VTX(folder / "strip.bp", times=[0.2, 0.4])]
    summary = Simulation(problem, hf.NewtonSolver(problem), stepping, outputs, name="strip").run()
    assert summary["stage"] == "dynamic" and summary["completed"]
    assert summary["steps"] == len(history) and summary["final_time"] == pytest.approx(0.4)
    assert [row["time"] for row in summary["rows"][1:]] == [r.time for r in history]
    assert np.array_equal(problem.u.x.array, reference.u.x.array)  # the same arithmetic
    MPI.COMM_WORLD.Barrier()
    rows = _csv_rows(folder / "strip.csv")
    assert len(rows) == len(history) + 1 and "kinetic_energy" in rows[0] and "p0_y" in rows[0]
    assert (folder / "strip.bp").is_dir()


def test_run_reports_mesh_quality_and_warns_on_a_poor_mesh(capsys):
    """seed 003 §5.6: quality statistics in the summary and a line before the first solve; a flat mesh warns."""
    from hyperfem.mesh.quality import MeshQualityWarning, mesh_quality

    problem = _pulled(degree=1)
    summary = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(), [Progress(lambda row: "row")]).run()
    expected = mesh_quality(problem.domain).stats
    assert summary["mesh_quality"] == expected
    assert 0.0 < expected["volume_length"]["min"] <= expected["volume_length"]["mean"] <= 1.0
    if MPI.COMM_WORLD.rank == 0:
        assert capsys.readouterr().out.splitlines()[0].startswith("mesh quality")

    flat = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([1.0, 1.0, 0.01])], [2, 2, 1])
    domain = hf.Domain.from_locators(flat, {"left": lambda x: np.isclose(x[0], 0.0)})
    squashed = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=[hf.Clamp("left")])
    sim = Simulation(squashed, hf.NewtonSolver(squashed), hf.StepPolicy())
    if MPI.COMM_WORLD.rank == 0:
        with pytest.warns(MeshQualityWarning):
            sim.run()
    else:
        sim.run()
    assert sim.mesh_quality.stats["volume_length"]["min"] < 0.1


def test_progress_bar_on_a_terminal_plain_lines_otherwise(capsys):
    """Progress redraws one bar line when asked (a terminal), and prints a line per state in logs."""
    problem = _pulled(degree=1)
    policy = hf.StepPolicy(increment=0.5, grow_after=99)
    Simulation(problem, hf.NewtonSolver(problem), policy, [Progress(lambda row: f"t={row['time']}", bar=True)]).run()
    out = capsys.readouterr().out
    if MPI.COMM_WORLD.rank == 0:
        assert "\r[" + "#" * 10 + "." * 10 + "]  50 %  t=0.5" in out and "\r[" + "#" * 20 + "] 100 %  t=1.0" in out
        assert out.endswith("\n")
    problem = _pulled(degree=1)
    Simulation(problem, hf.NewtonSolver(problem), policy, [Progress(lambda row: f"t={row['time']}")]).run()
    out = capsys.readouterr().out
    if MPI.COMM_WORLD.rank == 0:  # pytest's captured stdout is not a terminal
        assert "\r" not in out and out.splitlines()[1:] == ["t=0.0", "t=0.5", "t=1.0"]
