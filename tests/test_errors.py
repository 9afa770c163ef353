"""Error handling: every bad input raises a HyperfemError subclass with a
message that says what and where, on every rank, without hanging."""

from __future__ import annotations

import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.errors import (
    ConvergenceError,
    HyperfemError,
    MeshError,
    MeshFileNotFoundError,
    ParameterError,
    UnknownGroupError,
)
from hyperfem.materials import LameParameters, neo_hookean

PARAMS = LameParameters.from_youngs(E=1e6, nu=0.3)


@pytest.fixture
def shared_dir():
    """A temporary directory every rank sees (made by rank 0; one machine)."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="hyperfem-test-") if comm.rank == 0 else None, root=0))
    yield path
    comm.Barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def _small_domain() -> hf.Domain:
    mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([1.0, 0.3, 0.3])], [3, 1, 1])
    return hf.Domain.from_locators(
        mesh,
        {"left": lambda x: np.isclose(x[0], 0.0), "right": lambda x: np.isclose(x[0], 1.0)},
        source="test-box",
    )


def _psi(F):
    return neo_hookean(F, PARAMS)


def test_error_hierarchy():
    assert issubclass(MeshFileNotFoundError, MeshError)
    assert issubclass(MeshFileNotFoundError, FileNotFoundError)
    assert issubclass(UnknownGroupError, MeshError)
    assert issubclass(UnknownGroupError, LookupError)
    assert issubclass(ConvergenceError, RuntimeError)
    for cls in (MeshError, ParameterError, ConvergenceError):
        assert issubclass(cls, HyperfemError)


# --------------------------------------------------------------------------
# Meshes
# --------------------------------------------------------------------------
def test_read_mesh_missing_file(shared_dir):
    path = shared_dir / "does_not_exist" / "beam.msh"
    with pytest.raises(MeshFileNotFoundError) as info:
        hf.read_mesh(path)
    assert str(path) in str(info.value)


def test_read_mesh_not_a_gmsh_file(shared_dir):
    path = shared_dir / "not_a_mesh.msh"
    if MPI.COMM_WORLD.rank == 0:
        path.write_text("solid cube\n  facet normal 0 0 1\nendsolid cube\n")
    MPI.COMM_WORLD.Barrier()
    with pytest.raises(MeshError) as info:
        hf.read_mesh(path)
    assert not isinstance(info.value, MeshFileNotFoundError)
    assert str(path) in str(info.value)


def test_read_mesh_empty_file(shared_dir):
    path = shared_dir / "empty.msh"
    if MPI.COMM_WORLD.rank == 0:
        path.write_bytes(b"")
    MPI.COMM_WORLD.Barrier()
    with pytest.raises(MeshError):
        hf.read_mesh(path)


def test_unknown_facet_group_lists_available_names():
    domain = _small_domain()
    with pytest.raises(UnknownGroupError) as info:
        domain.facets("clamped")
    msg = str(info.value)
    assert "'clamped'" in msg
    assert "left" in msg and "right" in msg
    assert "test-box" in msg
    # str() is the plain message (no KeyError-style quoting).
    assert not msg.startswith('"')
    with pytest.raises(UnknownGroupError, match="left, right"):
        domain.ds("nope")


def test_unknown_cell_group_lists_available_names():
    domain = _small_domain()
    with pytest.raises(UnknownGroupError, match=r"'muscle'.*available: domain"):
        domain.cells("muscle")
    with pytest.raises(UnknownGroupError, match="available: domain"):
        domain.dx("muscle")


def test_unknown_group_with_no_groups_says_none():
    mesh = dmesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    domain = hf.Domain.from_locators(mesh)
    with pytest.raises(UnknownGroupError, match=r"available: none"):
        domain.facet_tag("left")


def test_clamp_on_unknown_group():
    domain = _small_domain()
    with pytest.raises(UnknownGroupError) as info:
        hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("clamped")])
    assert "'clamped'" in str(info.value) and "left, right" in str(info.value)


def test_load_on_unknown_group():
    domain = _small_domain()
    with pytest.raises(UnknownGroupError, match="'free_end'"):
        hf.HyperelasticProblem(domain, _psi, loads=[hf.DeadTraction("free_end", (0.0, 0.0, -1.0))])
    with pytest.raises(UnknownGroupError, match="'muscle'"):
        hf.HyperelasticProblem(domain, {"muscle": _psi})


@pytest.mark.parametrize("h", [-1.0, 0.0, float("nan"), "1"])
def test_beam_mesh_bad_size(h):
    with pytest.raises(ParameterError, match=r"\bh\b"):
        hf.beam_mesh(h=h)


def test_beam_mesh_bad_order():
    with pytest.raises(ParameterError, match="order"):
        hf.beam_mesh(h=2.0, order=3)


# --------------------------------------------------------------------------
# Problem definition
# --------------------------------------------------------------------------
def test_problem_parameter_errors():
    domain = _small_domain()
    with pytest.raises(ParameterError, match="degree"):
        hf.HyperelasticProblem(domain, _psi, degree=0)
    with pytest.raises(ParameterError, match="empty"):
        hf.HyperelasticProblem(domain, {})
    with pytest.raises(ParameterError, match=r"DeadTraction on 'right'.*3 components, got 2"):
        hf.HyperelasticProblem(domain, _psi, loads=[hf.DeadTraction("right", (0.0, 1.0))])
    with pytest.raises(ParameterError, match=r"'left'.*component 3"):
        hf.HyperelasticProblem(domain, _psi, bcs=[hf.PrescribedDisplacement("left", [0.0], components=[3])])
    with pytest.raises(ParameterError, match=r"'left'.*2 values for 3 components"):
        hf.HyperelasticProblem(domain, _psi, bcs=[hf.PrescribedDisplacement("left", [0.0, 1.0])])


def test_solver_parameter_errors():
    domain = _small_domain()
    problem = hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("left")])
    with pytest.raises(ParameterError, match="prefix"):
        hf.NewtonSolver(problem, prefix="no_trailing_underscore")
    follower = hf.HyperelasticProblem(
        domain, _psi, bcs=[hf.Clamp("left")], loads=[hf.FollowerPressure("right", 1.0)]
    )
    with pytest.raises(ParameterError, match="conservative"):
        hf.NewtonSolver(follower, energy_line_search=True)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"min_increment": 0.0},
        {"min_increment": -0.1},
        {"initial_increment": 0.0},
        {"initial_increment": 2.0, "max_increment": 1.0},
        {"initial_increment": 0.1, "min_increment": 0.2},
        {"growth": 0.5},
    ],
)
def test_load_stepping_invalid(kwargs):
    with pytest.raises(ParameterError, match="LoadStepping"):
        hf.LoadStepping(**kwargs)


# --------------------------------------------------------------------------
# Failed solves
# --------------------------------------------------------------------------
def _late_huge_load(s: float) -> float:
    """Nothing up to s = 1/2, then an impossible traction."""
    return 0.0 if s <= 0.5 + 1e-12 else 1e12 * (s - 0.5)


def _impossible_problem():
    domain = _small_domain()
    return hf.HyperelasticProblem(
        domain,
        _psi,
        bcs=[hf.Clamp("left")],
        loads=[hf.DeadTraction("right", (0.0, 0.0, -1.0), profile=_late_huge_load)],
    )


def test_impossible_solve_raises_convergence_error():
    problem = _impossible_problem()
    solver = hf.NewtonSolver(problem, {"snes_max_it": 2})
    stepping = hf.LoadStepping(initial_increment=0.25, min_increment=0.25, max_increment=0.25)
    seen = []
    with pytest.raises(ConvergenceError) as info:
        hf.solve_quasistatic(solver, target=1.0, stepping=stepping, on_step=seen.append)
    err = info.value
    assert err.load_factor == pytest.approx(0.5)
    assert [step.load_factor for step in err.history] == pytest.approx([0.25, 0.5])
    assert all(step.solve.converged for step in err.history)
    assert seen == err.history  # completed steps were handed out before the failure
    assert "0.5" in str(err) and "0.25" in str(err)
    # The state is rolled back to the last converged load factor.
    assert problem.load_factor == pytest.approx(0.5)
    local = np.max(np.abs(problem.u.x.array), initial=0.0)
    assert MPI.COMM_WORLD.allreduce(local, op=MPI.MAX) == 0.0


def test_newton_raise_on_failure():
    problem = _impossible_problem()
    solver = hf.NewtonSolver(problem, {"snes_max_it": 2})
    problem.set_load_factor(1.0)
    record = solver.solve()
    assert not record.converged and record.reason < 0
    assert record.iterations <= 2
    problem.u.x.array[:] = 0.0
    with pytest.raises(ConvergenceError, match="did not converge") as info:
        solver.solve(raise_on_failure=True)
    assert info.value.load_factor == pytest.approx(1.0)
    assert math.isfinite(info.value.load_factor)


def test_max_steps_exceeded():
    problem = _impossible_problem()
    solver = hf.NewtonSolver(problem)
    stepping = hf.LoadStepping(initial_increment=0.125, min_increment=0.125, max_increment=0.125, max_steps=2)
    with pytest.raises(ConvergenceError, match="2 steps") as info:
        hf.solve_quasistatic(solver, target=0.5, stepping=stepping)
    assert info.value.load_factor == pytest.approx(0.25)
    assert len(info.value.history) == 2
