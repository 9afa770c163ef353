r"""Derived fields, the convergence log, plots, and the per-step files of the dynamics demo.

* Uniaxial stretch between rollers is homogeneous (exact in P1 and P2), so
  every cell holds the closed-form values: :math:`J = \lambda_1\lambda_2^2`,
  :math:`\sigma_{11} = P_{11}/\lambda_2^2` (the only non-zero Cauchy stress),
  von Mises :math:`|\sigma_{11}|`, fibre stretch :math:`\lambda_1` for fibres
  along :math:`x`, the activation value in its region — in DG0 and in the
  DG(k−1) of a P2 displacement, written as VTX or XDMF time series.
* :func:`~hyperfem.simulation.fields.von_mises` is :math:`|s|` in uniaxial
  stress and :math:`\sqrt3|\tau|` in shear.
* The convergence log holds the residual norm of every Newton iterate; the
  plots are made from the files of a run.
* ``demos/dynamics.py`` killed mid-run (SIGKILL) leaves a diagnostics CSV and
  a JSON summary with every completed step, and the CSV can be plotted.
"""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from dolfinx import fem

import hyperfem as hf
from hyperfem import dynamics as dyn
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube
from hyperfem.fibres import constant_fibres
from hyperfem.io import vtx_steps
from hyperfem.loading import Activation
from hyperfem.simulation import (
    CellFunctions,
    ConvergenceLog,
    CSVLog,
    FieldOutput,
    JSONSummary,
    Probe,
    Reactions,
    Recorder,
    Simulation,
    read_convergence,
    von_mises,
)
from hyperfem.simulation import plots

PARAMS = hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3)
ROOT = Path(__file__).resolve().parent.parent
STRETCH = 1.2


def psi(F):
    return hf.materials.neo_hookean(F, PARAMS)


@pytest.fixture
def folder(tmp_path):
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))


def _uniaxial(stretch: float) -> tuple[float, float]:
    r""":math:`(P_{11}, \lambda_2)` of neo-Hookean uniaxial stress (lateral stretch from :math:`P_{22} = 0`)."""
    mu, lm = PARAMS.mu, PARAMS.lmbda

    def p(l2, k):
        lk = (stretch, l2, l2)[k]
        return mu * lk - mu / lk + lm * math.log(stretch * l2 * l2) / lk

    l2 = 1.0
    for _ in range(50):
        f = p(l2, 1)
        l2 -= f / ((p(l2 + 1e-7, 1) - f) / 1e-7)
    return p(l2, 0), l2


def _cell_values(f: fem.Function) -> np.ndarray:
    bs = f.function_space.dofmap.index_map_bs
    n = f.function_space.dofmap.index_map.size_local * bs
    return f.x.array[:n].reshape(-1, bs)


def _all_close(values: np.ndarray, expected, rtol: float, comm) -> bool:
    local = bool(np.allclose(values, expected, rtol=rtol, atol=rtol * np.abs(expected).max()))
    return comm.allreduce(local, op=MPI.LAND)


@pytest.mark.parametrize("degree, field_degree", [(1, 0), (2, "auto")])
def test_derived_fields_of_a_homogeneous_stretch(degree, field_degree, folder, comm):
    domain = unit_cube(2, comm)
    fibres = constant_fibres(domain.mesh, (1.0, 0.0, 0.0))
    activation = Activation(domain.mesh, value=lambda t: 0.5 * t, name="activation")
    problem = hf.HyperelasticProblem(domain, psi, bcs=uniaxial_rollers(STRETCH), degree=degree, updaters=[activation])
    fields = FieldOutput(
        folder,
        psi,
        fields=("displacement", "cauchy_stress", "von_mises", "J", "fibre_stretch", "activation"),
        fibres=fibres,
        activation={"domain": activation},
        degree=field_degree,
        name="cube",
    )
    summary = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(increment=0.5), [fields], name="cube").run()
    P11, l2 = _uniaxial(STRETCH)
    J = STRETCH * l2 * l2
    sigma = np.zeros((3, 3))
    sigma[0, 0] = P11 / l2**2
    f = fields.cell_functions
    assert f["J"].function_space.ufl_element().embedded_superdegree == degree - 1
    assert _all_close(_cell_values(f["J"]), J, 1e-8, comm)
    assert _all_close(_cell_values(f["cauchy_stress"]), sigma.reshape(1, 9), 1e-7, comm)
    assert _all_close(_cell_values(f["von_mises"]), sigma[0, 0], 1e-7, comm)
    assert _all_close(_cell_values(f["fibre_stretch"]), STRETCH, 1e-8, comm)
    assert _all_close(_cell_values(f["activation"]), 0.5, 1e-12, comm)
    comm.Barrier()
    assert summary["files"]["cube"] == str(folder / "cube.bp")
    assert vtx_steps(folder / "cube.bp") == vtx_steps(folder / "cube_cells.bp") == 1 + summary["steps"]


def test_xdmf_fields_and_refused_options(folder, comm):
    domain = unit_cube(1, comm)
    problem = hf.HyperelasticProblem(domain, psi, bcs=uniaxial_rollers(1.1), degree=2)
    fields = FieldOutput(folder, {None: psi}, format="xdmf", degree="auto", name="cube")
    summary = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(increment=0.5), [fields]).run()
    assert fields.cell_functions["J"].function_space.ufl_element().embedded_superdegree == 0  # XDMF: DG0
    comm.Barrier()
    tree = ET.parse(folder / "cube.xdmf")
    times = {t.get("Value") for t in tree.iter("Time")}
    assert len(times) == 1 + summary["steps"]
    names = {a.get("Name") for a in tree.iter("Attribute")}
    assert {"displacement", "cauchy_stress", "von_mises", "J"} <= names
    assert (folder / "cube.h5").is_file()
    with pytest.raises(hf.ParameterError, match="XDMF stores cell fields as DG0 only"):
        FieldOutput(folder, psi, format="xdmf", degree=1)
    with pytest.raises(hf.ParameterError, match="unknown field 'von_mise' \\(did you mean 'von_mises'\\?\\)"):
        FieldOutput(folder, psi, fields=["von_mise"])
    with pytest.raises(hf.ParameterError, match="format must be one of vtx, xdmf"):
        FieldOutput(folder, psi, format="vtu")
    other = hf.HyperelasticProblem(domain, psi, bcs=uniaxial_rollers(1.1))
    sim = Simulation(other, hf.NewtonSolver(other), hf.StepPolicy(), [FieldOutput(folder / "x", None)])
    with pytest.raises(hf.ParameterError, match="cauchy_stress and von_mises need materials="):
        sim.run()


def test_von_mises_closed_forms(comm):
    domain = unit_cube(1, comm)
    s, tau = 3.0, 2.0

    def tensor(values):
        return fem.Constant(domain.mesh, np.array(values, dtype=float))

    uniaxial = tensor([[s, 0, 0], [0, 0, 0], [0, 0, 0]])
    shear = tensor([[0, tau, 0], [tau, 0, 0], [0, 0, 0]])
    hydrostatic = tensor(5.0 * np.eye(3))
    plane = tensor([[s, 0], [0, 0]])
    cells = CellFunctions(
        domain,
        {"a": von_mises(uniaxial), "b": von_mises(shear), "c": von_mises(hydrostatic), "d": von_mises(plane)},
    )
    cells.refresh()
    a, b, c, d = (_cell_values(f)[:, 0] for f in cells.functions)
    assert np.allclose(a, s) and np.allclose(b, math.sqrt(3.0) * tau) and np.allclose(c, 0.0, atol=1e-12)
    assert np.allclose(d, s)  # 2x2: plane stress


def test_convergence_log_and_plots_of_a_run(folder, comm):
    domain = unit_cube(2, comm)
    problem = hf.HyperelasticProblem(domain, psi, bcs=uniaxial_rollers(1.3))
    outputs = [
        Probe([(1.0, 0.5, 0.5)]),
        Reactions(),
        CSVLog(folder / "cube.csv"),
        JSONSummary(folder / "cube.json"),
        ConvergenceLog(folder / "cube.jsonl"),
    ]
    summary = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(increment=0.25), outputs).run()
    comm.Barrier()
    lines = read_convergence(folder / "cube.jsonl")
    assert [line["step"] for line in lines] == list(range(summary["steps"] + 1))
    assert lines[0]["accepted"] == []  # no initial solve
    for line, its in zip(lines[1:], summary["newton_iterations"], strict=True):
        (norms,) = line["accepted"]
        assert len(norms) == its + 1  # the initial residual, then one per iterate
        assert norms[-1] < 1e-6 * norms[0]
    rows = plots.read_rows(folder / "cube.csv")
    assert [r["time"] for r in rows] == pytest.approx([r["time"] for r in plots.read_rows(folder)])
    made = plots.plot_run(folder, comm=comm)
    if comm.rank == 0:
        assert sorted(p.name for p in made) == ["cube_load_displacement.png", "cube_newton.png"]
        assert all(p.stat().st_size > 1000 for p in made)
        path = plots.load_displacement(
            folder / "cube.csv", load="reaction_x1_Fx", displacement="probe_displacement_0_0"
        )
        assert path.is_file()
        with pytest.raises(hf.ParameterError, match="no load column 'nope'"):
            plots.load_displacement(folder / "cube.csv", load="nope")
    else:
        assert made == []


def test_dynamics_time_series_plot(folder, comm):
    from dolfinx import mesh as dmesh

    mesh = dmesh.create_rectangle(comm, [[0.0, 0.0], [4.0, 1.0]], [8, 2], dmesh.CellType.triangle)
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    base = hf.HyperelasticProblem(domain, psi, bcs=[hf.Clamp("left")])
    problem = dyn.IncrementalProblem(base, dyn.Newmark(), dyn.MassDensity(1000.0))
    problem.v.interpolate(lambda x: np.vstack([np.zeros(x.shape[1]), 4.0 * (x[0] / 4.0) ** 2]))
    problem.initial_acceleration()
    outputs = [Recorder(dyn.Diagnostics(problem, [(4.0, 0.5)])), CSVLog(folder / "strip" / "diagnostics.csv")]
    Simulation(problem, hf.NewtonSolver(problem), dyn.TimeStepping(dt=0.05, t_end=0.2), outputs).run()
    comm.Barrier()
    out = plots.dynamics_time_series(folder / "strip" / "diagnostics.csv", output=folder / "strip.png", comm=comm)
    if comm.rank == 0:
        assert out == folder / "strip.png" and out.stat().st_size > 1000


@pytest.mark.serial
def test_killed_dynamics_demo_keeps_every_completed_step(folder):
    """The issue's reproduction: ``demos/dynamics.py`` killed mid-run (here after 4 steps of 300)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "HYDRA_", "MPI_LOCALNRANKS"))}
    argv = ["--case", "bc-twist", "--h", "2", "--dt", "0.01", "--fixed", "--no-vtx", "--quiet", "--output", str(folder)]
    child = subprocess.Popen([sys.executable, str(ROOT / "demos" / "dynamics.py"), *argv], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    csv_file = folder / "bc-twist" / "diagnostics.csv"
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and child.poll() is None:
            if csv_file.is_file() and len(csv_file.read_text().splitlines()) >= 6:
                break
            time.sleep(0.05)
        assert child.poll() is None, child.stdout.read().decode()[-2000:]
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.wait(timeout=30)
    with csv_file.open() as fh:
        rows = list(csv.DictReader(fh))
    done = len(rows) - 1
    assert done >= 4 and [int(r["step"]) for r in rows] == list(range(done + 1))
    assert all(r["total_energy"] not in ("", None) for r in rows)
    summary = json.loads((folder / "bc-twist" / "summary.json").read_text())
    assert summary["completed"] is False and done - 1 <= summary["steps"] <= done + 1
    sys.path.insert(0, str(ROOT / "demos"))
    try:
        import plot_dynamics
    finally:
        sys.path.pop(0)
    png = plot_dynamics.main([str(csv_file), "-o", str(folder / "killed.png")])
    assert png.stat().st_size > 1000


def test_format_summary_names_every_part_of_a_restarted_series():
    """After a restart the output line names NAME.bp and NAME.restart-NNNNNN.bp, in order (before: the second only)."""
    from hyperfem.simulation import format_summary

    summary = {
        "name": "bend", "dofs": 10, "cells": 2, "ranks": 1, "stage": "quasi-static", "steps": 4,
        "newton_iterations": [3, 3], "wall_time": 0.1, "restarted_from": "out/bend.checkpoint/step-000002",
        "files": {"summary": "out/bend.json", "vtx": "out/bend.restart-000002.bp"},
        "vtx_parts": ["out/bend.bp", "out/bend.restart-000002.bp"],
    }
    line = format_summary(summary).splitlines()[-1]
    assert line == "  output: out/bend.json, out/bend.bp (ParaView), out/bend.restart-000002.bp (ParaView)"


def test_progress_line_has_units():
    from hyperfem.app.report import progress_line

    row = {"step": 1, "time": 0.05, "dt": 0.05, "newton_iterations": 3, "residual": 1e-9, "min_J": 0.99,
           "reaction_clamped_Fx": 1.0, "reaction_clamped_Fy": 2.0, "reaction_clamped_Fz": 3.0,
           "probe_displacement": [[0.1, 0.2, 0.3]]}
    static = progress_line(row)
    assert "load factor 0.05" in static and "F[clamped] = (1, 2, 3) N" in static
    assert "u(probe 0) = (0.1, 0.2, 0.3) m" in static
    dynamic = progress_line({**row, "kinetic_energy": 5.0})
    assert "t = 0.05 s" in dynamic and "dt = 0.05 s" in dynamic and "K = 5 J" in dynamic


def test_progress_line_names_contacts_and_ties():
    """A contact's columns (force, active, min distance) and a tie's gap reach the progress line."""
    from hyperfem.app.report import progress_line

    row = {"step": 2, "time": 0.5, "dt": 0.25, "newton_iterations": 4, "residual": 1e-9, "min_J": 0.9,
           "contact_force": [0.0, 0.0, 2.0], "contact_active": 20, "contact_min_distance": 2.5e-5,
           "glue_force": [1.0, 0.0, 0.0], "glue_max_gap": 1e-10}
    line = progress_line(row)
    assert "contact: 20 active, d_min 2.5e-05, F = (0, 0, 2) N" in line and "glue: gap 1e-10 m" in line
