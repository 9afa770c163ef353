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
    OutputError,
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
    follower = hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("left")], loads=[hf.FollowerPressure("right", 1.0)])
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
    assert err.time == pytest.approx(0.5)
    assert [step.time for step in err.history] == pytest.approx([0.25, 0.5])
    assert all(step.solve.converged for step in err.history)
    assert seen == err.history  # completed steps were handed out before the failure
    assert "0.5" in str(err) and "0.25" in str(err)
    # The state is rolled back to the last converged load factor.
    assert problem.time == pytest.approx(0.5)
    local = np.max(np.abs(problem.u.x.array), initial=0.0)
    assert MPI.COMM_WORLD.allreduce(local, op=MPI.MAX) == 0.0


def test_newton_raise_on_failure():
    problem = _impossible_problem()
    solver = hf.NewtonSolver(problem, {"snes_max_it": 2})
    problem.set_time(1.0)
    record = solver.solve()
    assert not record.converged and record.reason < 0
    assert record.iterations <= 2
    problem.u.x.array[:] = 0.0
    with pytest.raises(ConvergenceError, match="did not converge") as info:
        solver.solve(raise_on_failure=True)
    assert info.value.time == pytest.approx(1.0)
    assert math.isfinite(info.value.time)


def test_max_steps_exceeded():
    problem = _impossible_problem()
    solver = hf.NewtonSolver(problem)
    stepping = hf.LoadStepping(initial_increment=0.125, min_increment=0.125, max_increment=0.125, max_steps=2)
    with pytest.raises(ConvergenceError, match="2 steps") as info:
        hf.solve_quasistatic(solver, target=0.5, stepping=stepping)
    assert info.value.time == pytest.approx(0.25)
    assert len(info.value.history) == 2


# --------------------------------------------------------------------------
# Non-finite and malformed load and boundary values (issue 7, part 3):
# ParameterError on construction, naming the load, the boundary and the component.
# --------------------------------------------------------------------------
NAN, INF = float("nan"), float("inf")


@pytest.mark.parametrize("bad", [NAN, INF, -INF])
@pytest.mark.parametrize(
    "make, pattern",
    [
        (lambda b: hf.DeadTraction("free_end", (0.0, b, 0.0)), r"DeadTraction on 'free_end': value component 1 \(y\)"),
        (
            lambda b: hf.FollowerTraction("free_end", (b, 0.0, 0.0)),
            r"FollowerTraction on 'free_end'.*component 0 \(x\)",
        ),
        (lambda b: hf.FollowerPressure("free_end", b), r"FollowerPressure on 'free_end': pressure value"),
        (lambda b: hf.BodyForce((0.0, 0.0, b)), r"BodyForce: value component 2 \(z\)"),
        (lambda b: hf.BodyForce((0.0, 0.0, b), region="beam"), r"BodyForce on 'beam': value component 2 \(z\)"),
        (
            lambda b: hf.PrescribedDisplacement("clamped", (0.0, b, 0.0)),
            r"PrescribedDisplacement on 'clamped'.*1 \(y\)",
        ),
    ],
)
def test_non_finite_load_and_displacement_values(make, pattern, bad):
    with pytest.raises(ParameterError, match=pattern) as info:
        make(bad)
    assert "finite" in str(info.value)


@pytest.mark.parametrize(
    "make, pattern",
    [
        (lambda: hf.DeadTraction("free_end", 5.0), r"DeadTraction on 'free_end'.*sequence of numbers or a callable"),
        (lambda: hf.DeadTraction("free_end", ("0", 0.0, 0.0)), r"component 0 \(x\) must be a finite number"),
        (lambda: hf.DeadTraction("free_end", ()), r"DeadTraction on 'free_end': value is empty"),
        (lambda: hf.DeadTraction(3, (0.0, 0.0, 1.0)), r"DeadTraction: boundary must be a physical-group name"),
        (lambda: hf.FollowerPressure("free_end", "1e3"), r"FollowerPressure on 'free_end': pressure value"),
        (lambda: hf.DeadTraction("free_end", (0, 1, 0), profile=2.0), r"DeadTraction on 'free_end': profile must be"),
        (lambda: hf.BodyForce((0.0, 1.0, 0.0), region=""), r"BodyForce: region must be"),
        (lambda: hf.Clamp(None), r"Clamp: boundary must be a physical-group name"),
        (lambda: hf.PrescribedDisplacement("left", 0.0), r"PrescribedDisplacement on 'left'.*sequence of numbers"),
        (lambda: hf.PrescribedDisplacement("left", [0.0, 1.0], components=[0]), r"'left': 2 values for 1 components"),
        (lambda: hf.PrescribedDisplacement("left", [0.0, 1.0], components=[0, 0]), r"'left': components .* duplicates"),
        (lambda: hf.PrescribedDisplacement("left", [0.0], components=[1.0]), r"'left': components must be"),
        (lambda: hf.PrescribedDisplacement("left", [0.0], components=1), r"'left': components must be"),
    ],
)
def test_malformed_load_and_displacement_values(make, pattern):
    with pytest.raises(ParameterError, match=pattern):
        make()


@pytest.mark.parametrize("rho", [NAN, INF, 0.0, -1.0, True, "1000"])
def test_mass_density_rejects_non_finite(rho):
    from hyperfem.dynamics import MassDensity

    with pytest.raises(ParameterError, match=r"MassDensity: rho must be a finite number > 0"):
        MassDensity(rho)
    with pytest.raises(ParameterError, match=r"MassDensity: density of region 'beam'"):
        MassDensity({"beam": rho})


def test_check_positive_rejects_nan_and_inf_but_takes_numpy_numbers():
    from hyperfem.validation import check_positive

    for bad in (NAN, INF, -INF, 0, -1.0, True, None, "1"):
        with pytest.raises(ParameterError, match="E must be a finite number > 0"):
            check_positive("E", bad, "here")
    for good in (1, 2.5, np.float32(3.0), np.int64(7), np.float64(1e6)):
        check_positive("E", good, "here")
    params = LameParameters.from_youngs(E=np.float32(1e6), nu=np.float64(0.3))
    assert params.mu == pytest.approx(1e6 / 2.6)
    with pytest.raises(ParameterError, match="lmbda must be a finite number"):
        LameParameters(mu=1.0, lmbda=NAN)
    with pytest.raises(ParameterError, match="nu must lie in"):
        LameParameters.from_youngs(E=1e6, nu=NAN)


def test_callable_prescribed_displacement_nan_names_boundary():
    domain = _small_domain()

    def nan_value(x):
        return np.full((3, x.shape[1]), np.nan)

    with pytest.raises(ParameterError, match=r"PrescribedDisplacement on 'left': the value is not finite"):
        hf.HyperelasticProblem(domain, _psi, bcs=[hf.PrescribedDisplacement("left", nan_value)])
    # One component only, inf.
    with pytest.raises(ParameterError, match=r"PrescribedDisplacement on 'right': the value is not finite"):
        hf.HyperelasticProblem(
            domain,
            _psi,
            bcs=[hf.Clamp("left"), hf.PrescribedDisplacement("right", lambda x: np.full((1, x.shape[1]), np.inf), [0])],
        )
    # NaN away from the boundary is no error: only boundary values matter.
    ok = hf.PrescribedDisplacement(
        "right", lambda x: np.vstack([np.where(x[0] > 0.5, 0.1, np.nan), 0 * x[0], 0 * x[0]])
    )
    hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("left"), ok])


def test_time_dependent_prescribed_displacement_nan_at_later_time():
    domain = _small_domain()

    def value(x, s):
        return np.full((3, x.shape[1]), np.nan if s > 0.5 else 0.1 * s)

    problem = hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("left"), hf.PrescribedDisplacement("right", value)])
    problem.set_time(0.25)
    with pytest.raises(ParameterError, match=r"'right': the value at load factor/time 0.75 is not finite"):
        problem.set_time(0.75)
    nan_profile = hf.PrescribedDisplacement("right", (0.1, 0.0, 0.0), profile=lambda s: NAN if s > 0.5 else s)
    problem = hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("left"), nan_profile])
    with pytest.raises(ParameterError, match=r"'right': profile\(1\) = nan is not finite"):
        problem.set_time(1.0)


def test_prescribed_displacement_callable_failing_on_one_rank():
    """The callable raises on the last rank only: every rank raises the same ParameterError."""
    comm = MPI.COMM_WORLD
    domain = _small_domain()

    def value(x):
        if comm.rank == comm.size - 1:
            raise ValueError("no value here")
        return np.zeros((3, x.shape[1]))

    with pytest.raises(ParameterError, match=r"'left': evaluating the value failed: no value here"):
        hf.HyperelasticProblem(domain, _psi, bcs=[hf.PrescribedDisplacement("left", value)])


# --------------------------------------------------------------------------
# Energies and problem arguments
# --------------------------------------------------------------------------
def test_non_scalar_energy():
    domain = _small_domain()
    with pytest.raises(ParameterError, match=r"whole domain: the energy psi\(F\) must be a scalar.*shape \(3, 3\)"):
        hf.HyperelasticProblem(domain, lambda F: F, bcs=[hf.Clamp("left")])
    with pytest.raises(ParameterError, match=r"region 'domain': the energy psi\(F\) must be a scalar.*shape \(3,\)"):
        hf.HyperelasticProblem(domain, {"domain": lambda F: F[0, :]})
    with pytest.raises(ParameterError, match=r"whole domain: evaluating the energy psi\(F\) failed: .*params"):
        hf.HyperelasticProblem(domain, lambda F: neo_hookean(F))  # forgot the parameters
    with pytest.raises(ParameterError, match=r"region 'domain'.*must return a UFL scalar expression, got str"):
        hf.HyperelasticProblem(domain, {"domain": lambda F: "psi"})
    with pytest.raises(ParameterError, match=r"region 'domain': the energy psi\(F\) must be callable"):
        hf.HyperelasticProblem(domain, {"domain": PARAMS})


def test_split_energy_isochoric_part_must_be_scalar():
    from hyperfem.problem import SplitEnergy

    with pytest.raises(
        ParameterError, match=r"SplitEnergy isochoric part: the energy psi\(F\) must be a scalar.*\(3, 3\)"
    ):
        SplitEnergy(lambda F: F, bulk_modulus=1e6)
    with pytest.raises(ParameterError, match=r"SplitEnergy isochoric part: the energy psi\(F\) must be callable"):
        SplitEnergy(1.0, bulk_modulus=1e6)
    SplitEnergy(lambda F: neo_hookean(F, PARAMS), bulk_modulus=1e6)  # a scalar energy is fine


def test_problem_argument_types():
    domain = _small_domain()
    with pytest.raises(ParameterError, match=r"material must be an energy psi\(F\) or a mapping.*LameParameters"):
        hf.HyperelasticProblem(domain, PARAMS)
    with pytest.raises(ParameterError, match=r"domain must be a hyperfem Domain.*got Mesh"):
        hf.HyperelasticProblem(domain.mesh, _psi)
    with pytest.raises(ParameterError, match=r"bcs must be a list or tuple, got Clamp"):
        hf.HyperelasticProblem(domain, _psi, bcs=hf.Clamp("left"))
    with pytest.raises(ParameterError, match=r"loads must be a list or tuple, got DeadTraction"):
        hf.HyperelasticProblem(domain, _psi, loads=hf.DeadTraction("right", (0.0, 0.0, 1.0)))
    with pytest.raises(ParameterError, match=r"boundary conditions must be Clamp or PrescribedDisplacement, got str"):
        hf.HyperelasticProblem(domain, _psi, bcs=["left"])
    for degree in (0, 1.5, True, "2"):
        with pytest.raises(ParameterError, match="degree must be an integer >= 1"):
            hf.HyperelasticProblem(domain, _psi, degree=degree)
    for q in (0, -1, 2.0):
        with pytest.raises(ParameterError, match="quadrature_degree must be an integer >= 1 or None"):
            hf.HyperelasticProblem(domain, _psi, quadrature_degree=q)


# --------------------------------------------------------------------------
# Output folders and files: the same OutputError on every rank, no hang
# --------------------------------------------------------------------------
UNWRITABLE = Path("/proc/hyperfem-cannot-exist")


def test_ensure_output_dir(shared_dir):
    from hyperfem.io import ensure_output_dir

    assert ensure_output_dir(shared_dir / "a" / "b", MPI.COMM_WORLD).is_dir()
    with pytest.raises(OutputError, match=rf"output folder {UNWRITABLE} cannot be created or written"):
        ensure_output_dir(UNWRITABLE, MPI.COMM_WORLD)
    a_file = shared_dir / "plain-file"
    if MPI.COMM_WORLD.rank == 0:
        a_file.write_text("x")
    MPI.COMM_WORLD.Barrier()
    with pytest.raises(OutputError, match=rf"output folder {a_file}/sub cannot be created or written"):
        ensure_output_dir(a_file / "sub", MPI.COMM_WORLD)
    assert issubclass(OutputError, HyperfemError) and issubclass(OutputError, OSError)


def test_write_json_and_vtx_to_unwritable_folder():
    from hyperfem.io import VTXWriter, write_json

    with pytest.raises(OutputError, match=rf"cannot write {UNWRITABLE}/summary.json"):
        write_json(UNWRITABLE / "summary.json", {"a": 1}, MPI.COMM_WORLD)
    domain = _small_domain()
    problem = hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("left")])
    with pytest.raises(OutputError, match=rf"output folder {UNWRITABLE} cannot"):
        VTXWriter(MPI.COMM_WORLD, UNWRITABLE / "u.bp", [problem.u])


def test_simulation_checks_output_folder_before_solving():
    from hyperfem.simulation import JSONSummary, Simulation

    domain = _small_domain()
    problem = hf.HyperelasticProblem(
        domain, _psi, bcs=[hf.Clamp("left")], loads=[hf.DeadTraction("right", (0.0, 0.0, -1e3))]
    )
    solver = hf.NewtonSolver(problem)
    simulation = Simulation(problem, solver, hf.LoadStepping(), [JSONSummary(UNWRITABLE / "box.json")], name="box")
    with pytest.raises(OutputError, match=rf"output folder {UNWRITABLE} cannot be created or written"):
        simulation.run()
    assert problem.time == 0.0  # nothing was solved


def _load_demo(name: str):
    import importlib.util

    path = Path(__file__).resolve().parent.parent / "demos" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"demo_{name}_errors", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("name", ["bend", "twist", "dynamics"])
def test_demo_unwritable_output_exits_1_before_any_work(name, shared_dir, capsys):
    from hyperfem.app.program import run

    demo = _load_demo(name)
    # The output folder is checked first: the missing mesh is never read, no mesh is generated.
    argv = ["--output", str(UNWRITABLE)] + (["--mesh", str(shared_dir / "missing.msh")] if name != "dynamics" else [])
    with pytest.raises(SystemExit) as exc:
        run(lambda: demo.main(argv))
    assert exc.value.code == 1
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert f"hyperfem: error: output folder {UNWRITABLE}" in err
        assert "Traceback" not in err and "missing.msh" not in err


@pytest.mark.parametrize(
    "name, argv, option",
    [
        ("bend", ["--h", "-1"], "--h"),
        ("bend", ["--h", "nan"], "--h"),
        ("bend", ["--degree", "0"], "--degree"),
        ("bend", ["--increment", "0"], "--increment"),
        ("bend", ["--increment", "1.5"], "--increment"),
        ("twist", ["--h", "0"], "--h"),
        ("twist", ["--degree", "two"], "--degree"),
        ("twist", ["--increment", "-0.5"], "--increment"),
        ("dynamics", ["--case", "nope"], "--case"),
        ("dynamics", ["--dt", "0"], "--dt"),
        ("dynamics", ["--t-end", "inf"], "--t-end"),
        ("dynamics", ["--h", "-2"], "--h"),
        ("dynamics", ["--degree", "0"], "--degree"),
        ("dynamics", ["--rho-inf", "2"], "--rho-inf"),
        ("dynamics", ["--tol", "0"], "--tol"),
        ("dynamics", ["--output-every", "-1"], "--output-every"),
        ("dynamics", ["--dt", "0.1", "--dt-max", "0.01"], "--dt-max"),
        ("dynamics", ["--lumped", "--degree", "2"], "--lumped"),
    ],
)
def test_demo_argument_errors(name, argv, option, capsys):
    """Bad demo arguments: argparse's one-line error (rank 0 prints), exit status 2 on every rank."""
    demo = _load_demo(name)
    with pytest.raises(SystemExit) as exc:
        demo.parse(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert f"error: argument {option}" in err
    else:
        assert err == ""


@pytest.mark.serial
@pytest.mark.parametrize("ranks", [1, 2])
def test_bend_demo_unwritable_output_subprocess(ranks):
    """End to end, as a user runs it: one line, exit 1 on every rank, no hang (bounded by a timeout)."""
    import os
    import subprocess
    import sys

    root = Path(__file__).resolve().parent.parent
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "MPICH_"))}
    env["PYTHONWARNINGS"] = "ignore"
    cmd = [sys.executable, str(root / "demos" / "bend.py"), "--output", str(UNWRITABLE)]
    if ranks > 1:
        # As the Makefile: the venv's mpiexec (wheel route, MPICH), else the system one (Debian, OpenMPI).
        import shutil

        mpiexec = Path(sys.executable).parent / "mpiexec"
        mpiexec = str(mpiexec) if mpiexec.exists() else shutil.which("mpiexec")
        if mpiexec is None:
            pytest.skip("no mpiexec found")
        cmd = [mpiexec, "-n", str(ranks), *cmd]
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=240, env=env, cwd=root)
    assert result.returncode == 1
    lines = [line for line in result.stderr.splitlines() if line.startswith("hyperfem:")]
    assert lines == [
        f"hyperfem: error: output folder {UNWRITABLE} cannot be created or written: No such file or directory"
    ]
    assert "Traceback" not in result.stderr


# --------------------------------------------------------------------------
# gmsh on rank 0: failures reach every rank
# --------------------------------------------------------------------------
def _write_gmsh(path: Path, build) -> None:
    """Write a gmsh file on rank 0 (``build(gmsh)`` adds the model) and wait for it on every rank."""
    from hyperfem.mesh.gmsh_session import gmsh_session

    if MPI.COMM_WORLD.rank == 0:
        with gmsh_session() as gmsh:
            build(gmsh)
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.write(str(path))
    MPI.COMM_WORLD.Barrier()


def _plate(gmsh, groups: bool = True, tag_half: bool = False) -> None:
    gmsh.model.add("plate")
    a = gmsh.model.occ.addRectangle(0.0, 0.0, 0.0, 2.0, 1.0)
    surfaces = [a]
    if tag_half:
        b = gmsh.model.occ.addRectangle(2.0, 0.0, 0.0, 1.0, 1.0)
        gmsh.model.occ.fragment([(2, a)], [(2, b)])
        surfaces = [a]
        gmsh.option.setNumber("Mesh.SaveAll", 1)  # write the untagged half too
    gmsh.model.occ.synchronize()
    if groups:
        gmsh.model.addPhysicalGroup(2, surfaces, 1, name="plate")
        left = [t for _, t in gmsh.model.getEntities(1) if abs(gmsh.model.occ.getCenterOfMass(1, t)[0]) < 1e-9]
        right = [t for _, t in gmsh.model.getEntities(1) if abs(gmsh.model.occ.getCenterOfMass(1, t)[0] - 2) < 1e-9]
        gmsh.model.addPhysicalGroup(1, left, 1, name="left")
        gmsh.model.addPhysicalGroup(1, right, 2, name="right")
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
    gmsh.model.mesh.generate(2)


def test_planar_gmsh_mesh_is_read_as_2d(shared_dir):
    path = shared_dir / "plate.msh"
    _write_gmsh(path, _plate)
    domain = hf.read_mesh(path)
    assert (domain.gdim, domain.tdim) == (2, 2)
    assert set(domain.facet_groups) == {"left", "right"} and set(domain.cell_groups) == {"plate"}
    # A planar traction has two components; the problem builds and solves.
    problem = hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("left")], loads=[hf.DeadTraction("right", (1e3, 0.0))])
    steps = hf.solve_quasistatic(hf.NewtonSolver(problem))
    assert steps[-1].solve.converged
    # The user may still ask for 3D coordinates, but not for fewer than the cells need.
    assert hf.read_mesh(path, gdim=3).gdim == 3
    with pytest.raises(MeshError, match=rf"{path}: gdim=1 is too small"):
        hf.read_mesh(path, gdim=1)
    with pytest.raises(MeshError, match=r"gdim must be 1, 2, 3 or None"):
        hf.read_mesh(path, gdim=4)
    # The 3D beam stays 3D.
    beam = Path(__file__).resolve().parent.parent / "meshes" / "beam_h2.msh"
    assert hf.read_mesh(beam).gdim == 3


def test_gmsh_mesh_without_physical_groups(shared_dir):
    path = shared_dir / "no_groups.msh"
    _write_gmsh(path, lambda gmsh: _plate(gmsh, groups=False))
    with pytest.raises(MeshError, match=rf"{path}: the mesh has no physical groups"):
        hf.read_mesh(path)


def test_a_mesh_of_another_format_points_to_convert(shared_dir):
    """A .vtu (or .inp, .mesh, ...) given where a gmsh file is read: the message says how to convert it."""
    path = shared_dir / "beam.vtu"
    if MPI.COMM_WORLD.rank == 0:
        path.write_text('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid"></VTKFile>\n')
    MPI.COMM_WORLD.Barrier()
    message = r"not a gmsh \.msh file; convert it with `hyperfem convert beam\.vtu beam\.msh`"
    with pytest.raises(MeshError, match=message):
        hf.read_mesh(path)


def test_gmsh_mesh_with_untagged_cells(shared_dir):
    """DOLFINx's RuntimeError ('All cells are expected to be tagged once') becomes a MeshError naming the file."""
    path = shared_dir / "half_tagged.msh"
    _write_gmsh(path, lambda gmsh: _plate(gmsh, tag_half=True))
    with pytest.raises(MeshError, match=rf"{path}: All cells are expected to be tagged once"):
        hf.read_mesh(path)


def test_gmsh_build_failure_on_rank0_reaches_every_rank():
    from hyperfem.mesh.gmsh_session import distribute_model

    def fails(gmsh):
        raise Exception("boom")  # gmsh raises bare Exceptions

    with pytest.raises(MeshError, match=r"test model: boom"):
        distribute_model(MPI.COMM_WORLD, fails, 3, "test model")

    def no_groups(gmsh):
        gmsh.model.add("box")
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.mesh.generate(3)

    with pytest.raises(MeshError, match=r"test model: No 'physical groups'"):
        distribute_model(MPI.COMM_WORLD, no_groups, 3, "test model")


# --------------------------------------------------------------------------
# The rest of the public API
# --------------------------------------------------------------------------
def test_point_probe_bad_points():
    from hyperfem.io import PointProbe

    mesh = _small_domain().mesh
    with pytest.raises(ParameterError, match=r"PointProbe: point \[0.5, nan, 0.1\] has a non-finite coordinate"):
        PointProbe(mesh, [(0.5, NAN, 0.1)])
    with pytest.raises(ParameterError, match=r"PointProbe: points must have shape \(n, 1..3\)"):
        PointProbe(mesh, [(0.5, 0.1, 0.1, 0.0)])
    with pytest.raises(ParameterError, match="outside the mesh"):
        PointProbe(mesh, [(5.0, 0.1, 0.1)])
    with pytest.raises(ParameterError, match="must be finite"):
        PointProbe(mesh, [(INF, 0.1, 0.1)])


@pytest.mark.parametrize(
    "kwargs, pattern",
    [
        ({"dt": INF, "t_end": 1.0}, "dt must be a finite number"),
        ({"dt": 0.1, "t_end": NAN}, "t_end must be a finite number"),
        ({"dt": 0.1, "t_end": INF}, "t_end must be a finite number"),
        ({"dt": 0.1, "t_end": 1.0, "tolerance": NAN}, "tolerance must be a finite number"),
        ({"dt": 0.1, "t_end": 1.0, "dt_max": INF}, "dt_max must be a finite number"),
        ({"dt": 0.1, "t_end": 1.0, "max_steps": 0}, "max_steps must be an integer >= 1"),
        ({"dt": 0.1, "t_end": 1.0, "grow_after": 2.5}, "grow_after must be an integer >= 1"),
        ({"dt": 0.1, "t_end": 1.0, "must_hit": [0.5, NAN]}, "must_hit times must be finite"),
    ],
)
def test_time_stepping_invalid(kwargs, pattern):
    from hyperfem.dynamics import TimeStepping

    with pytest.raises(ParameterError, match=rf"TimeStepping: {pattern}"):
        TimeStepping(**kwargs)


def test_profiles_and_rigid_motions_invalid():
    from hyperfem.loading import Ramp, RigidRotation, Steady, rotation_matrix

    with pytest.raises(ParameterError, match="Steady: value must be a finite number"):
        Steady(NAN)
    with pytest.raises(ParameterError, match="Ramp: t1 must be a finite number"):
        Ramp(INF)
    with pytest.raises(ParameterError, match="Ramp: final must be a finite number"):
        Ramp(1.0, final=NAN)
    with pytest.raises(ParameterError, match="axis must be a non-zero finite 3-vector"):
        rotation_matrix((0.0, NAN, 1.0), 0.1)
    with pytest.raises(ParameterError, match="angle must be a finite number"):
        rotation_matrix((0.0, 0.0, 1.0), NAN)
    with pytest.raises(ParameterError, match="center must be 3 finite coordinates"):
        RigidRotation((0.0, 0.0, 1.0), lambda t: t, (0.0, NAN, 0.0))
    with pytest.raises(ParameterError, match="angle must be a callable"):
        RigidRotation((0.0, 0.0, 1.0), 0.5)


def test_damping_and_integrators_invalid():
    from hyperfem.dynamics import GeneralizedAlpha, Newmark, RayleighDamping

    with pytest.raises(ParameterError, match="from_damping_ratios: omega1 must be a finite number"):
        RayleighDamping.from_damping_ratios(0.01, NAN, 0.02, 10.0)
    with pytest.raises(ParameterError, match="RayleighDamping: beta must be a finite number >= 0"):
        RayleighDamping(0.1, INF)
    with pytest.raises(ParameterError, match="Newmark: beta must be a finite number > 0"):
        Newmark(beta=NAN)
    with pytest.raises(ParameterError, match="GeneralizedAlpha: rho_inf must lie in"):
        GeneralizedAlpha(NAN)


def test_rigid_rotation_with_nan_angle_names_boundary():
    from hyperfem.loading import rotating_surface

    domain = _small_domain()
    bc = rotating_surface("right", (1.0, 0.0, 0.0), lambda t: NAN if t > 0.5 else t)
    problem = hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("left"), bc])
    with pytest.raises(ParameterError, match=r"PrescribedDisplacement on 'right': evaluating the value at .* 1 failed"):
        problem.set_time(1.0)


def test_activation_invalid():
    from hyperfem.loading import Activation

    mesh = _small_domain().mesh
    for bad in (NAN, INF, 1.5, "0.5", None):
        with pytest.raises(ParameterError, match="belly: activation must"):
            Activation(mesh, bad, name="belly")
    with pytest.raises(ParameterError, match="belly: activation must"):
        Activation(mesh, lambda t: NAN, name="belly")
    with pytest.raises(ParameterError, match=r"belly: activation field has \d+ non-finite value"):
        Activation(mesh, 1.0, field=lambda x: np.full(x.shape[1], np.nan), name="belly")
    with pytest.raises(ParameterError, match="belly: field must be a dolfinx Function or a callable"):
        Activation(mesh, 1.0, field=0.5, name="belly")
    a = Activation(mesh, lambda t: t, name="belly")
    with pytest.raises(ParameterError, match="belly: activation must lie in"):
        a.update(2.0)


def test_fibre_fields_invalid(shared_dir):
    from hyperfem.errors import MeshError as _MeshError
    from hyperfem.fibres import fibre_space, fibres_from_callable, fibres_from_file

    domain = _small_domain()
    mesh = domain.mesh
    with pytest.raises(ParameterError, match=r"fibre field has \d+ non-finite vector"):
        fibres_from_callable(mesh, lambda x: np.full((3, x.shape[1]), np.nan))
    with pytest.raises(ParameterError, match="quadrature_degree must be an integer >= 0"):
        fibre_space(mesh, "quadrature", -1)
    with pytest.raises(ParameterError, match="unknown fibre representation 'P3'.*available: P1, DG0, quadrature"):
        fibre_space(mesh, "P3")
    junk = shared_dir / "junk.vtu"
    if MPI.COMM_WORLD.rank == 0:
        junk.write_text("this is not a VTK file\n")
    MPI.COMM_WORLD.Barrier()
    with pytest.raises(_MeshError, match=rf"{junk}: meshio cannot read the file"):
        fibres_from_file(domain, junk, "fibres")


def test_mesh_generators_invalid():
    from hyperfem.mesh import FusiformGeometry, fusiform_mesh

    with pytest.raises(ParameterError, match=r"beam mesh: element size h"):
        hf.beam_mesh(h=True)
    with pytest.raises(ParameterError, match="sections must be odd and >= 3"):
        FusiformGeometry(sections=9.0)
    with pytest.raises(ParameterError, match="belly_length must be > 0"):
        FusiformGeometry(belly_length=NAN)
    with pytest.raises(ParameterError, match="fusiform mesh: element size h"):
        fusiform_mesh(h=INF)
