"""The ``hyperfem`` command: ``run`` gives what the Python API gives, ``--print-python`` runs, the tools work.

* ``hyperfem run`` of the bend case (beam_h2, P1) equals a script written with
  the API as the demos are (to 1e-10), and the printed Python equals both;
* the dynamic case equals its API script; the mixed case balances its
  reaction forces; under ``mpiexec -n 2`` the run equals the serial one;
* ``mesh beam``, ``mesh-quality``, ``convert`` (round trip through .vtu,
  medit and Abaqus files), ``demo``, ``--version``, ``--help``.

Subprocess tests (``serial``) run the command as a user does, with
``[sys.executable, "-m", "hyperfem.app.main", ...]``; the others run in
process, serially and under ``mpiexec -n 2``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

import hyperfem as hf
from hyperfem import dynamics as dyn
from hyperfem.app import build, load_case
from hyperfem.app.main import dispatch, make_parser
from hyperfem.simulation import JSONSummary, Probe, Reactions, Simulation

ROOT = Path(__file__).resolve().parent.parent
CASES = ROOT / "cases"
MESH = ROOT / "meshes" / "beam_h2.msh"
SMALL = ["--set", f"mesh.file={MESH}", "--set", "problem.degree=1"]
BEND_P1_H2 = [0.135077318161, -0.852854731738, 0.003404957717]  # tests/test_demos.py


def _env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "MPICH_"))}
    env["PYTHONWARNINGS"] = "ignore"
    return env


def _mpiexec() -> str | None:
    candidate = Path(sys.executable).parent / "mpiexec"
    return str(candidate) if candidate.exists() else shutil.which("mpiexec")


def hyperfem(*args: str, ranks: int = 1, timeout: float = 240) -> subprocess.CompletedProcess:
    """Run ``python -m hyperfem.app.main ARGS`` (under mpiexec for ranks > 1)."""
    cmd = [sys.executable, "-m", "hyperfem.app.main", *args]
    if ranks > 1:
        mpiexec = _mpiexec()
        if mpiexec is None:
            pytest.skip("no mpiexec found")
        cmd = [mpiexec, "-n", str(ranks), *cmd]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=_env(), cwd=ROOT)


def _bend_api(output: Path) -> dict:
    """The bend case written with the Python API, as demos/bend.py is (P1, beam_h2)."""
    domain = hf.read_mesh(MESH)
    params = hf.materials.LameParameters.from_youngs(E=1.0e6, nu=0.3)
    problem = hf.HyperelasticProblem(
        domain,
        lambda F: hf.materials.neo_hookean(F, params),
        bcs=[hf.Clamp("clamped")],
        loads=[hf.DeadTraction("free_end", (0.0, -5.0e3, 0.0))],
        degree=1,
    )
    outputs = [Probe([(4.5, 1.5, 1.5)]), Reactions(), JSONSummary(output / "api.json")]
    stepping = hf.LoadStepping(initial_increment=1.0)
    return Simulation(problem, hf.NewtonSolver(problem), stepping, outputs, name="bend").run()


# -- run ----------------------------------------------------------------------------------------------
@pytest.mark.serial
def test_run_and_print_python_equal_the_api_script(tmp_path):
    """``hyperfem run``, its printed Python and a hand-written API script give one result (1e-10)."""
    cli = hyperfem("run", str(CASES / "bend.toml"), *SMALL, "--output", str(tmp_path / "cli"))
    assert cli.returncode == 0, cli.stderr
    assert "load steps: 1" in cli.stdout and "Traceback" not in cli.stderr
    run = json.loads((tmp_path / "cli" / "bend.json").read_text())
    assert run["completed"] and run["degree"] == 1

    printed = hyperfem("run", str(CASES / "bend.toml"), *SMALL, "--output", str(tmp_path / "py"), "--print-python")
    assert printed.returncode == 0, printed.stderr
    script = tmp_path / "bend.py"
    script.write_text(printed.stdout)
    ran = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=240, env=_env())
    assert ran.returncode == 0, ran.stderr
    python = json.loads((tmp_path / "py" / "bend.json").read_text())

    api = _bend_api(tmp_path)
    for other in (python, api):
        np.testing.assert_allclose(other["probe_displacement"], run["probe_displacement"], rtol=1e-10, atol=1e-12)
        for key in ("force", "moment"):
            np.testing.assert_allclose(
                other["reactions"]["clamped"][key], run["reactions"]["clamped"][key], rtol=1e-10, atol=1e-6
            )
    np.testing.assert_allclose(run["probe_displacement"][0], BEND_P1_H2, rtol=1e-6)
    # The traction (0, -5, 0) kPa on the 4 x 4 m end: the support carries 80 kN upwards.
    np.testing.assert_allclose(run["reactions"]["clamped"]["force"], [0.0, 8.0e4, 0.0], atol=1e-6 * 8.0e4)
    assert run["newton_iterations"] == python["newton_iterations"] == api["newton_iterations"]


def test_build_in_process_equals_the_api_script(shared_tmp):
    """The same comparison in process, serially and on 2 ranks."""
    case = load_case(CASES / "bend.toml", SMALL[1::2], output=shared_tmp / "cli")
    built = build(case, MPI.COMM_WORLD)
    assert isinstance(built.problem, hf.HyperelasticProblem) and built.problem.degree == 1
    summary = built.simulation.run()
    api = _bend_api(shared_tmp)
    np.testing.assert_allclose(summary["probe_displacement"], api["probe_displacement"], rtol=1e-10, atol=1e-12)
    assert summary["ranks"] == MPI.COMM_WORLD.size


def test_dynamic_case_equals_the_api_script(shared_tmp):
    """cases/dynamics_bend.toml to t = 0.15 s equals IncrementalProblem + Newmark written by hand (1e-10)."""
    case = load_case(CASES / "dynamics_bend.toml", ["stepping.t_end=0.15", "output.fields=[]"], output=shared_tmp)
    summary = build(case, MPI.COMM_WORLD).simulation.run()

    domain = hf.read_mesh(MESH)
    params = hf.materials.LameParameters.from_youngs(E=1.0e6, nu=0.3)
    base = hf.HyperelasticProblem(
        domain,
        lambda F: hf.materials.neo_hookean(F, params),
        bcs=[hf.Clamp("clamped")],
        loads=[hf.DeadTraction("free_end", (0.0, -5.0e3, 0.0), profile=dyn.Steady())],
        degree=1,
    )
    problem = dyn.IncrementalProblem(base, dyn.Newmark(), dyn.MassDensity(1000.0), dyn.RayleighDamping(alpha=0.0004))
    options = {"snes_rtol": 1e-8, "snes_atol": 1e-8, "snes_stol": 1e-10, "snes_max_it": 25}
    solver = hf.NewtonSolver(problem, options)
    problem.initial_acceleration()
    stepping = dyn.TimeStepping(dt=0.05, t_end=0.15, must_hit=[0.1])  # every = 0.1: a must-hit time
    api = Simulation(problem, solver, stepping, [Probe([(4.5, 1.5, 1.5)])], name="api").run()

    assert summary["steps"] == api["steps"] == 3
    np.testing.assert_allclose(summary["probe_displacement"], api["probe_displacement"], rtol=1e-10, atol=1e-13)
    assert summary["probe_displacement"][0][1] < -1e-3  # the end moves down


def test_mixed_case_balances_its_reactions(shared_tmp):
    """The gripped, nearly incompressible block: equal and opposite end forces, the end at x = 2 m."""
    case = load_case(CASES / "block_mixed.toml", ["stepping.increment=1.0", "output.fields=[]"], output=shared_tmp)
    built = build(case, MPI.COMM_WORLD)
    assert isinstance(built.problem, hf.problem.MixedHyperelasticProblem)
    summary = built.simulation.run()
    left, right = (np.array(summary["reactions"][b]["force"]) for b in ("clamped", "free_end"))
    np.testing.assert_allclose(left, -right, rtol=0, atol=1e-6 * abs(right[0]))
    assert right[0] > 0
    np.testing.assert_allclose(summary["probe_displacement"][0], [2.0, 0.0, 0.0], atol=1e-9)
    # Incompressible uniaxial stretch 1.2 of neo-Hookean: P = mu (l - 1/l^2) over 16 m^2; the grips stiffen it.
    nominal = 1.0e5 * (1.2 - 1.2**-2) * 16.0
    assert nominal < right[0] < 1.2 * nominal


@pytest.mark.serial
def test_run_under_mpiexec_equals_serial(tmp_path):
    serial = hyperfem("run", str(CASES / "bend.toml"), *SMALL, "--output", str(tmp_path / "1"))
    parallel = hyperfem("run", str(CASES / "bend.toml"), *SMALL, "--output", str(tmp_path / "2"), ranks=2, timeout=300)
    assert serial.returncode == 0 and parallel.returncode == 0, parallel.stderr
    one = json.loads((tmp_path / "1" / "bend.json").read_text())
    two = json.loads((tmp_path / "2" / "bend.json").read_text())
    assert two["ranks"] == 2
    np.testing.assert_allclose(two["probe_displacement"], one["probe_displacement"], rtol=1e-8)
    assert parallel.stdout.count("load steps:") == 1  # rank 0 prints


# -- tools -------------------------------------------------------------------------------------------
def test_version_and_help(capsys):
    dispatch(["--version"])
    out = capsys.readouterr().out
    if MPI.COMM_WORLD.rank == 0:
        assert out.startswith(f"hyperfem {hf.__version__} (DOLFINx ")
    for command in (["run"], ["check"], ["schema"], ["demo"], ["mesh"], ["mesh", "beam"], ["mesh", "fusiform"],
                    ["mesh-quality"], ["convert"], ["plot"], []):
        with pytest.raises(SystemExit) as exc:
            make_parser().parse_args([*command, "--help"])
        assert exc.value.code == 0
        out = capsys.readouterr().out
        if MPI.COMM_WORLD.rank == 0:
            assert out.startswith("usage: hyperfem") and len(out.splitlines()) > 4
        else:
            assert out == ""


def test_mesh_beam_and_quality(shared_tmp, capsys):
    path = shared_tmp / "beam.msh"
    dispatch(["mesh", "beam", "--size", "2.5", "-o", str(path)])
    domain = hf.read_mesh(path)
    assert sorted(domain.facet_groups) == ["clamped", "free_end", "surface"] and list(domain.cell_groups) == ["beam"]
    capsys.readouterr()
    dispatch(["mesh-quality", str(path), "--png", str(shared_tmp / "q.png")])
    out = capsys.readouterr().out
    quality = hf.mesh.mesh_quality(domain)
    if MPI.COMM_WORLD.rank == 0:
        rows = [line.split() for line in out.splitlines() if line.startswith(("radius ratio", "volume-length"))]
        assert len(rows) == 2
        assert float(rows[0][2]) == pytest.approx(quality.stats["radius_ratio"]["min"], abs=5e-4)
        assert float(rows[1][-1]) == pytest.approx(quality.stats["volume_length"]["max"], abs=5e-4)
        assert "orientation: 0 inverted, 0 degenerate" in out
        assert (shared_tmp / "q.png").stat().st_size > 1000


def _groups(path: Path) -> tuple[dict[str, int], list[str]]:
    """Cells per region (over all ranks) and the boundary names of a mesh file."""
    domain = hf.read_mesh(path)
    owned = domain.mesh.topology.index_map(domain.tdim).size_local
    cells = {n: domain.comm.allreduce(int((domain.cells(n) < owned).sum())) for n in domain.cell_groups}
    return cells, sorted(domain.facet_groups)


def _area(domain, name: str) -> float:
    from dolfinx import fem

    return domain.comm.allreduce(fem.assemble_scalar(fem.form(1.0 * domain.ds(name))))


def test_convert_round_trip_keeps_groups(shared_tmp):
    """beam_h2.msh → .vtu and medit .mesh (meshio) → hyperfem convert → the same groups, cells and areas."""
    import meshio

    original = meshio.read(MESH)
    sources = {"vtu": shared_tmp / "beam.vtu", "medit": shared_tmp / "beam.mesh", "gmsh": MESH}
    if MPI.COMM_WORLD.rank == 0:
        meshio.write(sources["vtu"], original)  # keeps gmsh:physical as cell data, not the names
        blocks = [(c.type, c.data) for c in original.cells]
        refs = {"medit:ref": original.cell_data["gmsh:physical"]}
        meshio.write(sources["medit"], meshio.Mesh(original.points, blocks, cell_data=refs))
    MPI.COMM_WORLD.Barrier()
    reference = hf.read_mesh(MESH)
    names = {"clamped": "boundary_1", "free_end": "boundary_2", "surface": "boundary_3"}
    for kind, source in sources.items():
        target = shared_tmp / f"{kind}.msh"
        dispatch(["convert", str(source), str(target)])
        cells, boundaries = _groups(target)
        named = kind == "gmsh"  # names from the gmsh field data; the others keep the tags
        assert cells == ({"beam": 164} if named else {"region_1": 164})
        assert boundaries == sorted(names if named else names.values())
        converted = hf.read_mesh(target)
        for name, tag in names.items():
            assert _area(converted, name if named else tag) == pytest.approx(_area(reference, name), rel=1e-12)


ABAQUS = """*Heading
unit cube in five tetrahedra
*Node
1, 0.0, 0.0, 0.0
2, 1.0, 0.0, 0.0
3, 1.0, 1.0, 0.0
4, 0.0, 1.0, 0.0
5, 0.0, 0.0, 1.0
6, 1.0, 0.0, 1.0
7, 1.0, 1.0, 1.0
8, 0.0, 1.0, 1.0
*Element, type=C3D4, elset=cube
1, 1, 2, 4, 5
2, 2, 3, 4, 7
3, 2, 4, 5, 7
4, 2, 6, 7, 5
5, 4, 5, 7, 8
*Nset, nset=bottom
1, 2, 3, 4
*Nset, nset=top
5, 6, 7, 8
"""


def test_convert_abaqus_sets(shared_tmp):
    """*ELSET → region, *NSET → the exterior faces with all corners in the set; the cube has volume 1."""
    from dolfinx import fem

    source = shared_tmp / "cube.inp"
    if MPI.COMM_WORLD.rank == 0:
        source.write_text(ABAQUS)
    MPI.COMM_WORLD.Barrier()
    target = shared_tmp / "cube.msh"
    dispatch(["convert", str(source), str(target)])
    domain = hf.read_mesh(target)
    assert list(domain.cell_groups) == ["cube"] and sorted(domain.facet_groups) == ["bottom", "top"]
    volume = domain.comm.allreduce(fem.assemble_scalar(fem.form(1.0 * domain.dx("cube"))))
    assert volume == pytest.approx(1.0, rel=1e-12)
    for name in ("bottom", "top"):
        assert _area(domain, name) == pytest.approx(1.0, rel=1e-12)


def test_demo_lists_and_runs(shared_tmp, capsys):
    dispatch(["demo"])
    out = capsys.readouterr().out
    if MPI.COMM_WORLD.rank == 0:
        assert "bend" in out and "muscle_dynamics" in out
    dispatch(["demo", "bend", "--mesh", str(MESH), "--degree", "1", "--output", str(shared_tmp)])
    summary = json.loads((shared_tmp / "bend.json").read_text())
    np.testing.assert_allclose(summary["probe_displacement"][0], BEND_P1_H2, rtol=1e-6)


# -- never lose a run ---------------------------------------------------------------------------------
STEPS = ["stepping.increment=0.25", "stepping.max_increment=0.25", "output.progress=false"]


def test_restart_continues_as_the_uninterrupted_run(shared_tmp):
    """Stop at load factor 0.5, continue from the checkpoint to 1: the rows equal the uninterrupted run's."""
    over = [*SMALL[1::2], *STEPS, "output.fields=[]"]
    full = build(load_case(CASES / "bend.toml", over, output=shared_tmp / "full")).simulation.run()
    part = load_case(CASES / "bend.toml", [*over, "stepping.end=0.5"], output=shared_tmp / "part")
    first = build(part).simulation.run()
    assert first["steps"] == 2 and first["completed"]
    from hyperfem.app.plan import checkpoint_folder

    case = load_case(CASES / "bend.toml", over, output=shared_tmp / "part")
    again = build(case).simulation.run(restart=checkpoint_folder(case))
    assert again["steps"] == full["steps"] == 4 and again["restarted_from"]
    np.testing.assert_allclose(again["probe_displacement"], full["probe_displacement"], rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(
        again["reactions"]["clamped"]["force"], full["reactions"]["clamped"]["force"], rtol=1e-10, atol=1e-6
    )
    # The rows of both parts are in one CSV: five states, the load-displacement plot has them all.
    dispatch(["plot", str(shared_tmp / "part")])
    if MPI.COMM_WORLD.rank == 0:
        rows = (shared_tmp / "part" / "bend.csv").read_text().splitlines()
        assert len(rows) == 1 + 5
        for name in ("bend_load_displacement.png", "bend_convergence_newton.png"):
            assert (shared_tmp / "part" / name).stat().st_size > 1000


@pytest.mark.serial
def test_restart_through_the_command(tmp_path):
    common = ["run", str(CASES / "bend.toml"), *SMALL, *(a for s in STEPS for a in ("--set", s)), "--output"]
    assert hyperfem(*common, str(tmp_path / "full")).returncode == 0
    assert hyperfem(*common, str(tmp_path / "part"), "--set", "stepping.end=0.5").returncode == 0
    printed = hyperfem(*common, str(tmp_path / "part"), "--restart", "--print-python")
    assert f"simulation.run(restart=Path({str(tmp_path / 'part' / 'bend.checkpoint')!r}))" in printed.stdout
    again = hyperfem(*common, str(tmp_path / "part"), "--restart")
    assert again.returncode == 0, again.stderr
    full = json.loads((tmp_path / "full" / "bend.json").read_text())
    part = json.loads((tmp_path / "part" / "bend.json").read_text())
    assert part["steps"] == full["steps"] == 4
    np.testing.assert_allclose(part["probe_displacement"], full["probe_displacement"], rtol=1e-10, atol=1e-14)
    # The summary names both parts of the ParaView series, in order (before: only the continuation file).
    first, second = tmp_path / "part" / "bend.bp", tmp_path / "part" / "bend.restart-000002.bp"
    assert f"{first} (ParaView), {second} (ParaView)" in again.stdout


def test_fields_in_xdmf(shared_tmp):
    """Stress, von Mises and J as XDMF; the CSV row 0 is the unloaded state."""
    over = [*SMALL[1::2], "output.progress=false", 'output.fields=["displacement", "von_mises", "J"]',
            'output.format="xdmf"', "output.checkpoint=false"]
    summary = build(load_case(CASES / "bend.toml", over, output=shared_tmp)).simulation.run()
    assert summary["completed"]
    assert (shared_tmp / "bend.xdmf").is_file() and (shared_tmp / "bend.h5").is_file()
    assert not (shared_tmp / "bend.checkpoint").exists()


# -- what a newcomer sees (issue 17) ------------------------------------------------------------------
@pytest.mark.serial
def test_print_python_names_the_mesh_relative_to_the_case_and_runs_from_any_folder(tmp_path):
    """``--print-python``: the mesh as the case file gives it (``case_dir / '../meshes/...'``), runnable anywhere."""
    printed = hyperfem("run", str(CASES / "bend.toml"), "--set", "problem.degree=1", "--set",
                       "mesh.file=../meshes/beam_h2.msh", "--output", str(tmp_path / "py"), "--print-python")
    assert printed.returncode == 0, printed.stderr
    assert f"case_dir = Path({str(CASES)!r})" in printed.stdout
    assert "hf.read_mesh(case_dir / '../meshes/beam_h2.msh', comm)" in printed.stdout
    assert str(MESH) not in printed.stdout  # before: the absolute mesh path
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "bend.py").write_text(printed.stdout)
    ran = subprocess.run([sys.executable, "bend.py"], capture_output=True, text=True, timeout=240, env=_env(),
                         cwd=elsewhere)
    assert ran.returncode == 0, ran.stderr
    python = json.loads((tmp_path / "py" / "bend.json").read_text())
    np.testing.assert_allclose(python["probe_displacement"][0], BEND_P1_H2, rtol=1e-6)


def test_convert_names_tags(shared_tmp, capsys):
    """A .vtu keeps tags but not names: --names gives them; tags left unnamed are listed in a note."""
    import meshio

    source = shared_tmp / "beam.vtu"
    if MPI.COMM_WORLD.rank == 0:
        meshio.write(source, meshio.read(MESH))
    MPI.COMM_WORLD.Barrier()
    target = shared_tmp / "named.msh"
    dispatch(["convert", str(source), str(target), "--names", "region:1=beam,1=clamped,2=free_end"])
    out = capsys.readouterr().out
    cells, boundaries = _groups(target)
    assert cells == {"beam": 164} and boundaries == ["boundary_3", "clamped", "free_end"]
    if MPI.COMM_WORLD.rank == 0:
        assert ("note: no names for boundary 3 (kept as boundary_3); name them with --names TAG=NAME,...") in out
    with pytest.raises(hf.ParameterError, match=r"has no region or boundary with tag 7 \(region tags: 1; boundary "
                       r"tags: 1, 2, 3\)"):
        dispatch(["convert", str(source), str(target), "--names", "7=x"])
    with pytest.raises(hf.ParameterError, match="'1beam' is not TAG=NAME"):
        dispatch(["convert", str(source), str(target), "--names", "1beam"])


def test_plot_of_a_dynamic_run_labels_quantities(shared_tmp):
    """``hyperfem plot`` of a CLI dynamic run: the test point from the probe, displacement/reaction against time."""
    from hyperfem.simulation import plots

    case = load_case(CASES / "dynamics_bend.toml", ["stepping.t_end=0.15", "output.fields=[]", "output.progress=false"],
                     output=shared_tmp)
    build(case).simulation.run()
    dispatch(["plot", str(shared_tmp)])
    if MPI.COMM_WORLD.rank == 0:
        for name in ("dynamics_bend_dynamics.png", "dynamics_bend_history.png", "dynamics_bend_convergence_newton.png"):
            assert (shared_tmp / name).stat().st_size > 1000
        assert not (shared_tmp / "run_dynamics.png").exists() and not list(shared_tmp.glob("*load_displacement*"))
        rows = plots.read_rows(shared_tmp)
        d = {k: [r[k] for r in rows] for k in rows[0]}
        meta = json.loads((shared_tmp / "dynamics_bend.json").read_text())
        shown, label = plots._test_point(d, meta)  # before: p0_* only, an empty panel for a CLI run
        assert [c for c, _ in shown] == [f"probe_displacement_0_{i}" for i in range(3)]
        assert label == "test point displacement at (4.5, 1.5, 1.5) [m]"
        assert plots.quantity("probe_displacement_0_1", meta) == "displacement u_y at (4.5, 1.5, 1.5) [m]"
        assert plots.quantity("reaction_clamped_Fy", meta) == "reaction force F_y on 'clamped' [N]"
        assert plots.quantity("time", meta) == "time t [s]"
        assert plots.quantity("time", {"stage": "quasi-static"}) == "load factor"
