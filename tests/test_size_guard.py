"""The size guard (issue 17, item 1): sizes and degrees that cannot fit are refused in one line, before any work.

Most tests shrink the memory the guard sees (``_mem_available``) so that small,
fast meshes stand in for impossible ones; without the guard those calls simply
succeed, so the tests fail. The estimates themselves are checked against real
meshes and spaces with tolerances far above the variation between gmsh builds.
"""

import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import pytest

import hyperfem as hf
from hyperfem.app.main import dispatch
from hyperfem.errors import HyperfemError, ParameterError, ProblemSizeError
from hyperfem.mesh import budget

MESHES = Path(__file__).resolve().parent.parent / "meshes"
TINY = 2**16  # 64 KiB: less than the beam at h = 2 needs (~100 tetrahedra, ~1 kB each)


@pytest.fixture
def shared_dir():
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="hyperfem-size-") if comm.rank == 0 else None, root=0))
    yield path
    comm.Barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture
def tiny_machine(monkeypatch):
    """The guard sees 64 KiB available on every node."""
    monkeypatch.delenv(budget.ALLOW_LARGE_ENV, raising=False)
    monkeypatch.setattr(budget, "_mem_available", lambda: TINY)


def _psi(F):
    return hf.materials.neo_hookean(F, hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3))


# -- the estimates -------------------------------------------------------------------------------------
def test_cell_estimate_matches_gmsh_within_a_quarter():
    """gmsh's beam at h = 0.5 has 6308 tetrahedra; the estimate 160 / (0.2 h^3) = 6400."""
    domain = hf.beam_mesh(h=0.5, comm=MPI.COMM_WORLD)
    cells = domain.mesh.topology.index_map(3).size_global
    assert budget.estimate_cells(160.0, 0.5) == pytest.approx(cells, rel=0.25)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_unknown_estimate_matches_the_space_within_a_fifth(degree):
    domain = hf.read_mesh(MESHES / "beam_h1.msh")
    topology = domain.mesh.topology
    estimate = budget.estimate_space(
        "tetrahedron", topology.index_map(0).size_global, topology.index_map(3).size_global, [(3, degree)], 2 * degree
    )
    V = hf.HyperelasticProblem(domain, _psi, degree=degree).V
    assert estimate.unknowns == pytest.approx(3 * V.dofmap.index_map.size_global, rel=0.2)


def test_estimates_grow_as_expected():
    """Halving h gives 8x the cells; a degree-40 space needs tens of GiB on a single cell (its element tensor)."""
    assert budget.estimate_cells(160.0, 0.25) == pytest.approx(8 * budget.estimate_cells(160.0, 0.5))
    one_cell = budget.estimate_space("tetrahedron", 4, 1, [(3, 40)], 80)
    assert one_cell.bytes > 2.0**30 * 20


# -- the mesh generators -------------------------------------------------------------------------------
def test_impossible_beam_size_is_refused_in_one_line_with_estimate_and_limit(monkeypatch):
    monkeypatch.delenv(budget.ALLOW_LARGE_ENV, raising=False)
    with pytest.raises(ProblemSizeError) as info:
        budget.check_mesh_size("beam mesh", 160.0, 0.001, MPI.COMM_WORLD)
    message = str(info.value)
    assert message.startswith("beam mesh: h = 0.001 gives ~8.0e11 tetrahedra (~")
    assert "GiB to mesh" in message and "GiB available; pass --allow-large" in message
    assert "HYPERFEM_ALLOW_LARGE=1" in message and "\n" not in message


def test_beam_and_fusiform_generators_refuse_before_meshing(tiny_machine, shared_dir):
    limit = r"this machine has 6\.1e-05 GiB available"
    with pytest.raises(ProblemSizeError, match=rf"^beam mesh: h = 0.5 gives ~6400 tetrahedra .* {limit}"):
        hf.beam_mesh(h=0.5)
    with pytest.raises(ProblemSizeError, match=r"^fusiform mesh: h = 0\.002 gives ~"):
        hf.mesh.fusiform_mesh(h=0.002)
    target = shared_dir / "beam.msh"
    if MPI.COMM_WORLD.rank == 0:
        with pytest.raises(ProblemSizeError, match=r"^beam mesh: h = 0.5"):
            hf.mesh.write_beam_mesh(target, h=0.5)
        with pytest.raises(ProblemSizeError, match=r"^fusiform mesh: h = 0.002"):
            hf.mesh.write_fusiform_mesh(shared_dir / "f.msh", h=0.002)
        assert not target.exists()


def test_allow_large_keyword_and_environment_pass(tiny_machine, monkeypatch):
    assert hf.beam_mesh(h=2.0, allow_large=True).mesh.topology.index_map(3).size_global > 0
    monkeypatch.setenv(budget.ALLOW_LARGE_ENV, "1")
    assert hf.beam_mesh(h=2.0).mesh.topology.index_map(3).size_global > 0
    with pytest.raises(ProblemSizeError):
        hf.beam_mesh(h=2.0, allow_large=False)  # the keyword wins over the environment
    monkeypatch.setenv(budget.ALLOW_LARGE_ENV, "maybe")
    with pytest.raises(ParameterError, match=r"^HYPERFEM_ALLOW_LARGE must be 1 or 0, got 'maybe'"):
        hf.beam_mesh(h=2.0)


def test_ranks_agree_when_only_one_rank_allows(tiny_machine, monkeypatch):
    """Rank 0 decides: an environment set on the other ranks alone changes nothing, and nobody hangs."""
    if MPI.COMM_WORLD.rank != 0:
        monkeypatch.setenv(budget.ALLOW_LARGE_ENV, "1")
    with pytest.raises(ProblemSizeError):
        hf.beam_mesh(h=2.0)


def test_available_memory_is_the_same_on_every_rank():
    comm = MPI.COMM_WORLD
    limit, nodes = budget.available_memory(comm)
    assert comm.allgather((limit, nodes)) == [(limit, nodes)] * comm.size
    assert limit > 0 and nodes >= 1


# -- the command line and case files --------------------------------------------------------------------
def test_cli_mesh_refuses_and_allow_large_flag_passes(tiny_machine, shared_dir):
    target = shared_dir / "beam.msh"
    with pytest.raises(ProblemSizeError, match=r"^beam mesh: h = 2 gives"):
        dispatch(["mesh", "beam", "--size", "2", "-o", str(target)])
    dispatch(["mesh", "beam", "--size", "2", "-o", str(target), "--allow-large"])
    assert target.is_file()
    with pytest.raises(ProblemSizeError, match=r"^fusiform mesh: h = 0.004 gives"):
        dispatch(["mesh", "fusiform", "-o", str(shared_dir / "f.msh")])


@pytest.mark.serial
def test_cli_mesh_default_output_is_printed_as_an_absolute_path(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    dispatch(["mesh", "beam", "--size", "2.5"])
    out = capsys.readouterr().out
    assert f"wrote {tmp_path / 'beam_h2.5.msh'}: " in out  # before: "wrote beam_h2.5.msh: ..."
    assert (tmp_path / "beam_h2.5.msh").is_file()


def test_case_file_generator_honours_the_environment(tiny_machine, monkeypatch, shared_dir):
    case = shared_dir / "gen.toml"
    if MPI.COMM_WORLD.rank == 0:
        text = (Path(__file__).resolve().parent.parent / "cases" / "bend.toml").read_text()
        text = text.replace('file = "../meshes/beam_h1.msh"', 'generator = "beam"\nsize = 2.0')
        case.write_text(text)
    MPI.COMM_WORLD.Barrier()
    with pytest.raises(HyperfemError, match=r"mesh\.generator: beam mesh: h = 2 gives ~100 tetrahedra"):
        dispatch(["check", str(case)])
    monkeypatch.setenv(budget.ALLOW_LARGE_ENV, "1")
    dispatch(["check", str(case)])


# -- the problems ------------------------------------------------------------------------------------------
def test_degree_40_is_refused_before_the_space_is_built(monkeypatch):
    monkeypatch.delenv(budget.ALLOW_LARGE_ENV, raising=False)
    domain = hf.read_mesh(MESHES / "beam_h2.msh")
    with pytest.raises(ProblemSizeError) as info:
        hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("clamped")], degree=40)
    message = str(info.value)
    assert message.startswith("HyperelasticProblem: P40 on 164 cells gives ~")
    assert "GiB to build and solve); this machine has" in message and "HYPERFEM_ALLOW_LARGE=1" in message


def test_problems_refuse_and_the_override_passes(tiny_machine):
    domain = hf.read_mesh(MESHES / "beam_h2.msh")
    with pytest.raises(ProblemSizeError, match=r"^HyperelasticProblem: P2 on 164 cells gives ~"):
        hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("clamped")], degree=2)
    split = hf.problem.SplitEnergy(lambda F: hf.materials.neo_hookean(F, hf.materials.LameParameters(1.0, 0.0)), 10.0)
    with pytest.raises(ProblemSizeError, match=r"^MixedHyperelasticProblem: P2/P1/P1 on 164 cells gives ~"):
        hf.problem.MixedHyperelasticProblem(domain, split, bcs=[hf.Clamp("clamped")])
    with budget.allow_large_problems():
        problem = hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("clamped")], degree=2)
    assert problem.V.dofmap.index_map.size_global > 0
