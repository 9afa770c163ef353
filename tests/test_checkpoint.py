r"""Never lose a run: checkpoints, restart, and what a killed run leaves on disk.

* A restarted run repeats the uninterrupted one: the same steps (the step-size
  control continues where it was: nominal increment, growth), the same rows
  and the same final state to :math:`10^{-10}` relative, for a quasi-static
  ramp with growth (displacement and three-field problem) and for dynamic
  runs (Backward Euler with fixed steps, Newmark with step doubling), on one
  and on two ranks.
* A checkpoint of one rank continues on two, and one of two ranks on one,
  reproducing the uninterrupted runs to :math:`10^{-10}`: the state is found
  by partition-independent dof keys, checked to be unique and the same on one
  and two ranks for P1, P2, mixed, DG and quadrature spaces.
* A checkpoint that does not belong to the run is refused with a message
  naming the difference (mesh, case, a missing rank file), before any output
  is opened.
* A step that fails after all cutbacks leaves a checkpoint of the last
  converged state, named in the error.
* ``meta.json`` does not grow with the run: the rows (and an output's list of
  rows) are in one history file per run, each once; a restart from an earlier
  checkpoint of the same folder reads its rows from it and leaves only the
  new run's history when the old checkpoints are gone.
* SIGKILL mid-run (serial subprocess) leaves every completed step in the CSV,
  JSON summary, VTX frames and convergence log, and a checkpoint from which
  the run completes as if it had not been killed.
"""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem import dynamics as dyn
from hyperfem.problem import SplitEnergy, solid_problem
from hyperfem.io import CheckpointError, read_functions, read_meta, vtx_steps
from hyperfem.io.checkpoint import dof_keys
from hyperfem.io.results import jsonable
from hyperfem.simulation import (
    VTX,
    Checkpoint,
    ConvergenceLog,
    CSVLog,
    JSONSummary,
    Output,
    Probe,
    Quantity,
    Reactions,
    Recorder,
    Simulation,
    read_convergence,
)

PARAMS = hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3)
# Row entries that are measurements or round-off noise, not results: the PC set-up time, and the
# final Newton residual (below the tolerance it is round-off, different between any two runs).
TIMING = {"pc_setup_time", "residual"}
# Between runs on different numbers of ranks, iteration counts are not results either (a solve that ends at
# round-off may take one more iteration on one partition than on another).
COUNTS = {"newton_iterations", "krylov_iterations", "solves"}


def psi(F):
    return hf.materials.neo_hookean(F, PARAMS)


@pytest.fixture
def folder(tmp_path):
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))


class _Interrupt(Exception):
    """Stands for a kill: raised by an output after a given step."""


class _StopAfter(Output):
    def __init__(self, step: int):
        self.stop = step

    def write(self, sim, step) -> None:
        if step is not None and step.step >= self.stop:
            raise _Interrupt(f"interrupted after step {step.step}")


def _family(key: str) -> str:
    """Columns compared on one scale: the components of a force or moment (``reaction_left_Fx`` ...)."""
    return re.sub(r"_([FM])[xyz]$", r"_\1", key)


def _same_rows(a: list[dict], b: list[dict], rtol: float = 1e-10, ignore: frozenset = frozenset()) -> None:
    """Rows agree to ``rtol`` relative to the largest magnitude of each quantity over the run.

    Not bit for bit: on two ranks MUMPS and the MPI reductions already make two
    uninterrupted runs differ at round-off (1e-14 relative), which is all a
    component that should vanish (a lateral reaction force) consists of.
    """
    assert len(a) == len(b)
    ignore = TIMING | set(ignore)
    scales: dict[str, float] = {}
    for row in b:
        for key, value in row.items():
            if key in ignore or isinstance(value, str) or value is None:
                continue
            v = np.abs(np.asarray(value, dtype=float))
            v = v[np.isfinite(v)]
            scales[_family(key)] = max(scales.get(_family(key), 0.0), float(v.max()) if v.size else 0.0)
    for ra, rb in zip(a, b, strict=True):
        assert set(ra) == set(rb)
        for key in ra:
            if key in ignore:
                continue
            va, vb = ra[key], rb[key]
            if isinstance(va, str) or va is None:
                assert va == vb, key
                continue
            va, vb = np.asarray(va, dtype=float), np.asarray(vb, dtype=float)
            atol = rtol * scales[_family(key)]
            assert np.allclose(va, vb, rtol=0.0, atol=atol, equal_nan=True), (key, va, vb)


def _relative(a: np.ndarray, b: np.ndarray, comm) -> float:
    num = comm.allreduce(float(np.sum((a - b) ** 2)), op=MPI.SUM)
    den = comm.allreduce(float(np.sum(b**2)), op=MPI.SUM)
    return (num / den) ** 0.5 if den > 0 else num**0.5


# -- quasi-static -------------------------------------------------------------------------------
def _box(comm, n=2) -> hf.Domain:
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([1.0, 0.3, 0.3])], [2 * n, n, n])
    return hf.Domain.from_locators(
        mesh, {"left": lambda x: np.isclose(x[0], 0.0), "right": lambda x: np.isclose(x[0], 1.0)}, source="box"
    )


def _ramp(comm, folder: Path, extra=(), every=2, n=2, formulation="displacement"):
    """A pulled box, ramped up with a growing increment (growth after two easy steps).

    ``formulation="mixed"``: the three-field problem (P2/P1/P1) on a coarser box.
    """
    bcs, loads = [hf.Clamp("left")], [hf.DeadTraction("right", (0.0, 0.0, -3e3))]
    if formulation == "mixed":
        material = SplitEnergy(psi, 20.0 * PARAMS.mu)
        problem = solid_problem(_box(comm, 1), material, formulation="mixed", bcs=bcs, loads=loads)
    else:
        problem = hf.HyperelasticProblem(_box(comm, n), psi, bcs=bcs, loads=loads)
    policy = hf.StepPolicy(increment=0.05, max_increment=0.4, growth=1.5, grow_after=2, easy_iterations=None)
    outputs = [
        *extra,
        Probe([(1.0, 0.15, 0.15)]),
        Reactions(),
        CSVLog(folder / "ramp.csv"),
        JSONSummary(folder / "ramp.json"),
        ConvergenceLog(folder / "ramp.jsonl"),
        VTX(folder / "ramp.bp"),
        Checkpoint(folder / "ckpt", every=every),
    ]
    sim = Simulation(problem, hf.NewtonSolver(problem), policy, outputs, name="ramp", info={"case": "ramp"})
    return sim


@pytest.mark.parametrize("formulation", ["displacement", "mixed"])
def test_quasistatic_restart_reproduces_the_uninterrupted_run(formulation, folder, comm):
    full = _ramp(comm, folder / "full", formulation=formulation)
    reference = full.run()
    increments = [row["dt"] for row in reference["rows"][1:]]
    assert max(increments) > 2 * increments[0]  # the increment grew

    cut = _ramp(comm, folder / "cut", extra=[_StopAfter(5)], every=3, formulation=formulation)
    with pytest.raises(_Interrupt):
        cut.run()
    meta = read_meta(folder / "cut" / "ckpt", comm)
    # every 3 steps exactly, although one easy step of the two before the next growth is counted then
    assert meta["step"] == 3 and meta["stepper"]["streak"] == 1
    resumed = _ramp(comm, folder / "cut", every=3, formulation=formulation)
    summary = resumed.run(restart=folder / "cut" / "ckpt")

    assert summary["completed"]
    assert summary["restarted_from"] == str(folder / "cut" / "ckpt" / f"step-{meta['step']:06d}")
    assert summary["steps"] == reference["steps"] and summary["newton_iterations"] == reference["newton_iterations"]
    _same_rows(summary["rows"], reference["rows"])
    assert _relative(resumed.problem.u.x.array, full.problem.u.x.array, comm) < 1e-10  # mixed: (u, p, theta - 1)
    force = np.array(reference["reactions"]["left"]["force"])
    assert summary["reactions"]["left"]["force"] == pytest.approx(force, abs=1e-10 * np.abs(force).max())
    comm.Barrier()
    # the files continue those of the first run: every row once, the lines of the lost step dropped
    with (folder / "cut" / "ramp.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["step"]) for r in rows] == list(range(reference["steps"] + 1))
    written = json.loads((folder / "cut" / "ramp.json").read_text())
    assert written["completed"] and written["steps"] == reference["steps"]
    lines = read_convergence(folder / "cut" / "ramp.jsonl")
    assert [line["step"] for line in lines] == list(range(reference["steps"] + 1))
    continued = folder / "cut" / f"ramp.restart-{meta['step']:06d}.bp"
    assert written["files"]["vtx"] == str(continued)
    assert written["vtx_parts"] == [str(folder / "cut" / "ramp.bp"), str(continued)]
    assert vtx_steps(continued) == 1 + reference["steps"] - meta["step"]  # the restart state, then every step
    # a checkpoint at the end: restarting a finished run is a run of no steps with the same result
    final = read_meta(folder / "cut" / "ckpt", comm)
    assert final["step"] == reference["steps"] and final["completed"]
    again = _ramp(comm, folder / "again", formulation=formulation).run(restart=folder / "cut" / "ckpt")
    assert again["steps"] == reference["steps"] and again["completed"]


def _on_rank0(comm, action):
    """``action()`` on rank 0 only; its result (or its failure) on every rank."""
    result, error = None, None
    if comm.rank == 0:
        try:
            result = action()
        except BaseException as exc:  # noqa: B036 - re-raised on every rank below
            error = exc
    result, error = comm.bcast((result, repr(error) if error is not None else None), root=0)
    if error is not None:
        raise AssertionError(f"rank 0: {error}")
    return result


def _norm(sim) -> float:
    from dolfinx import fem
    import ufl

    u = sim.problem.u
    form = fem.form(ufl.inner(u, u) * ufl.dx(domain=u.function_space.mesh))
    return u.function_space.mesh.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM) ** 0.5


@pytest.mark.parametrize("formulation", ["displacement", "mixed"])
def test_restart_on_another_number_of_ranks(formulation, folder, comm):
    if comm.size < 2:
        pytest.skip("needs 2 ranks: a 1-rank checkpoint continued on 2 ranks, and the reverse")
    one = MPI.COMM_SELF

    def run(c, name):
        sim = _ramp(c, folder / name, every=3, formulation=formulation)
        return sim, sim.run()

    def full_one():
        sim, summary = run(one, "full1")
        return summary["rows"], _norm(sim)

    rows1, norm1 = _on_rank0(comm, full_one)
    full2, summary2 = run(comm, "full2")
    _same_rows(summary2["rows"], rows1, ignore=COUNTS)  # the two references agree to round-off

    def cut_one():
        with pytest.raises(_Interrupt):
            _ramp(one, folder / "cut1", extra=[_StopAfter(5)], every=3, formulation=formulation).run()

    _on_rank0(comm, cut_one)
    resumed = _ramp(comm, folder / "cut1", every=3, formulation=formulation)
    summary = resumed.run(restart=folder / "cut1" / "ckpt")  # written on 1 rank, continued on 2
    assert summary["restarted_from"].endswith("step-000003") and summary["completed"]
    _same_rows(summary["rows"], summary2["rows"], ignore=COUNTS)  # rows 1-3 come from the 1-rank run
    assert _norm(resumed) == pytest.approx(_norm(full2), rel=1e-10)

    with pytest.raises(_Interrupt):
        _ramp(comm, folder / "cut2", extra=[_StopAfter(5)], every=3, formulation=formulation).run()

    def resume_one():
        sim = _ramp(one, folder / "cut2", every=3, formulation=formulation)
        summary = sim.run(restart=folder / "cut2" / "ckpt")  # written on 2 ranks, continued on 1
        _same_rows(summary["rows"], rows1, ignore=COUNTS)
        return _norm(sim)

    assert _on_rank0(comm, resume_one) == pytest.approx(norm1, rel=1e-10)


def _spaces():
    import basix.ufl

    cell = "tetrahedron"
    return {
        "P1 vector": ("Lagrange", 1, (3,)),
        "P2 vector": ("Lagrange", 2, (3,)),
        "DG0": ("DG", 0),
        "DG1 tensor": ("DG", 1, (3, 3)),
        "mixed P2-P1-DG0": basix.ufl.mixed_element(
            [
                basix.ufl.element("Lagrange", cell, 2, shape=(3,)),
                basix.ufl.element("Lagrange", cell, 1),
                basix.ufl.element("DG", cell, 0),
            ]
        ),
        "quadrature": basix.ufl.quadrature_element(cell, value_shape=(), degree=2),
    }


@pytest.mark.parametrize("name", sorted(_spaces()))
def test_dof_keys_are_unique_and_partition_independent(name, comm):
    from dolfinx import fem

    element = _spaces()[name]

    def keys_on(c):
        mesh = dmesh.create_box(c, [np.zeros(3), np.array([1.0, 0.5, 0.5])], [3, 2, 2])
        V = fem.functionspace(mesh, element)
        local = dof_keys(V)
        n = V.dofmap.index_map.size_local
        assert local is not None and local.shape == (n, 6)
        # where each dof sits (point-evaluation spaces), to check that a key names the same dof everywhere
        at = V.tabulate_dof_coordinates()[:n] if V.num_sub_spaces == 0 and name != "quadrature" else np.zeros((n, 3))
        everything = c.gather(np.hstack([local.astype(float), at]), root=0)
        if c.rank == 0:
            everything = np.concatenate(everything)
            keys = everything[:, :6]
            assert len(np.unique(keys, axis=0)) == V.dofmap.index_map.size_global  # one key per dof block
            return everything[np.lexsort(keys.T[::-1])]
        return None

    here = keys_on(comm)
    alone = _on_rank0(comm, lambda: keys_on(MPI.COMM_SELF))
    if comm.rank == 0:
        assert np.array_equal(here[:, :6], alone[:, :6])
        np.testing.assert_allclose(here[:, 6:], alone[:, 6:], rtol=0, atol=1e-12)  # the same point per key


def test_spaces_whose_dofs_depend_on_orientation_have_no_keys(comm):
    from dolfinx import fem

    mesh = dmesh.create_box(comm, [np.zeros(3), np.ones(3)], [1, 1, 1])
    assert dof_keys(fem.functionspace(mesh, ("Lagrange", 3))) is None  # two dofs on an edge
    assert dof_keys(fem.functionspace(mesh, ("N1curl", 1))) is None  # dof transformations


def test_restart_refuses_what_does_not_match(folder, comm):
    _ramp(comm, folder).run()
    ckpt = folder / "ckpt"
    with pytest.raises(CheckpointError, match=r"does not match this run: mesh cells: 96 in the checkpoint, 324 in"):
        _ramp(comm, folder / "other", n=3).run(restart=ckpt)
    other_case = _ramp(comm, folder / "other")
    other_case.case = {"case": "another"}
    with pytest.raises(CheckpointError, match=r"does not match this run: the case \(hash of the case description\)"):
        other_case.run(restart=ckpt)
    assert not (folder / "other").exists()  # refused before any output was opened
    with pytest.raises(CheckpointError, match=rf"cannot restart from {folder / 'missing'}: no checkpoint there"):
        _ramp(comm, folder / "other").run(restart=folder / "missing")
    # a checkpoint with a rank file missing
    meta = read_meta(ckpt, comm)
    step = Path(meta["path"])
    if comm.rank == 0:
        (step / f"rank-0000-of-{comm.size:04d}.npz").rename(step / "moved.npz")
    comm.Barrier()
    with pytest.raises(CheckpointError, match=r"incomplete checkpoint \(missing rank-0000|no rank files"):
        _ramp(comm, folder / "other").run(restart=ckpt)


def _late_huge_load(s: float) -> float:
    """Nothing up to s = 1/2, then an impossible traction."""
    return 0.0 if s <= 0.5 + 1e-12 else 1e12 * (s - 0.5)


def test_failed_step_checkpoints_the_last_converged_state(folder, comm):
    load = hf.DeadTraction("right", (0.0, 0.0, -1e3), profile=_late_huge_load)
    problem = hf.HyperelasticProblem(_box(comm, 1), psi, bcs=[hf.Clamp("left")], loads=[load])
    policy = hf.StepPolicy(increment=0.25, min_increment=0.25, max_increment=0.25)
    outputs = [JSONSummary(folder / "fail.json"), Checkpoint(folder / "ckpt", every=None)]
    sim = Simulation(problem, hf.NewtonSolver(problem, {"snes_max_it": 2}), policy, outputs, name="fail")
    with pytest.raises(hf.ConvergenceError) as info:
        sim.run()
    step = folder / "ckpt" / "step-000002"
    assert f"last converged state checkpointed in {step}" in str(info.value)
    assert f"completed steps written to {folder / 'fail.json'}" in str(info.value)
    meta = read_meta(folder / "ckpt", comm)
    assert meta["step"] == 2 and meta["time"] == pytest.approx(0.5) and not meta["completed"]
    assert len(meta["rows"]) == 3
    stored = problem.u.copy()
    stored.x.array[:] = 0.0
    read_functions(step, {"u": stored}, comm)
    assert np.array_equal(stored.x.array, problem.u.x.array)  # the state the failure left: the last converged one


class _Counter:
    """A recorder that keeps a list of rows (as :class:`~hyperfem.dynamics.Diagnostics` does)."""

    def __init__(self):
        self.rows: list[dict] = []

    def record(self, step) -> dict:
        self.rows.append({"recorded": len(self.rows)})
        return dict(self.rows[-1])


def _pulled(comm, folder: Path, keep):
    problem = hf.HyperelasticProblem(
        _box(comm, 1), psi, bcs=[hf.Clamp("left")], loads=[hf.DeadTraction("right", (0.0, 0.0, -1e3))]
    )
    policy = hf.StepPolicy(increment=0.1, min_increment=0.1, max_increment=0.1)
    outputs = [Reactions(), Recorder(_Counter()), Checkpoint(folder / "ckpt", every=1, keep=keep)]
    return Simulation(problem, hf.NewtonSolver(problem), policy, outputs, name="pulled")


def _text(rows: list[dict]) -> str:
    """The JSON text of rows (compares exactly, NaN included)."""
    return json.dumps(jsonable(rows), default=str)


def test_checkpoint_records_do_not_grow_with_the_run(folder, comm):
    reference = _pulled(comm, folder, keep=None).run()
    assert reference["steps"] == 10
    ckpt = folder / "ckpt"
    comm.Barrier()
    sizes = [(ckpt / f"step-{k:06d}" / "meta.json").stat().st_size for k in (1, 10)]
    assert sizes[1] < sizes[0] + 200  # not the rows again: a few digits more at most
    # every row is in the run's history file once, however many checkpoints name it
    histories = sorted(ckpt.glob("history-*.jsonl"))
    assert len(histories) == 1
    keys = [json.loads(line)["k"] for line in histories[0].read_text().splitlines()]
    assert keys.count("rows") == 11 and keys.count("outputs/1/rows") == 11  # the Recorder's list, too
    meta = read_meta(ckpt / "step-000004", comm)
    assert _text(meta["rows"]) == _text(reference["rows"][:5])
    assert meta["outputs"][1]["state"]["rows"] == [{"recorded": k} for k in range(5)]
    # continued from step 4 into the same folder: the same rows, and only the new run's history is left
    resumed = _pulled(comm, folder, keep=2).run(restart=ckpt / "step-000004")
    _same_rows(resumed["rows"], reference["rows"])
    assert _text(read_meta(ckpt, comm)["rows"]) == _text(resumed["rows"])
    comm.Barrier()
    left = sorted(ckpt.glob("history-*.jsonl"))
    assert len(left) == 1 and left != histories
    assert sorted(p.name for p in ckpt.glob("step-*")) == ["step-000009", "step-000010"]


# -- dynamics -----------------------------------------------------------------------------------
def _strip(comm, scheme):
    mesh = dmesh.create_rectangle(comm, [[0.0, 0.0], [4.0, 1.0]], [8, 2], dmesh.CellType.triangle)
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    base = hf.HyperelasticProblem(domain, psi, bcs=[hf.Clamp("left")])
    problem = dyn.IncrementalProblem(base, scheme, dyn.MassDensity(1000.0), dyn.viscous_damping(0.1))
    problem.v.interpolate(lambda x: np.vstack([np.zeros(x.shape[1]), 4.0 * (x[0] / 4.0) ** 2]))
    problem.initial_acceleration()
    return problem


SCHEMES = {
    "backward-euler-fixed": (dyn.BackwardEuler, dyn.TimeStepping(dt=0.05, t_end=0.4)),
    "newmark-adaptive": (
        dyn.Newmark,
        dyn.TimeStepping(dt=0.02, t_end=0.4, adaptive=True, tolerance=1e-2, grow_after=2),
    ),
}


def _dynamic(comm, folder: Path, name: str, extra=()):
    scheme, stepping = SCHEMES[name]
    problem = _strip(comm, scheme())
    diagnostics = dyn.Diagnostics(problem, [(4.0, 0.5)])
    outputs = [
        *extra,
        Recorder(diagnostics),
        Reactions(),
        CSVLog(folder / "d.csv"),
        Checkpoint(folder / "ckpt", every=2),
    ]
    return Simulation(problem, hf.NewtonSolver(problem), stepping, outputs, name=name), diagnostics


@pytest.mark.parametrize("name", sorted(SCHEMES))
def test_dynamic_restart_reproduces_the_uninterrupted_run(name, folder, comm):
    full, full_diag = _dynamic(comm, folder / "full", name)
    reference = full.run()
    cut, _ = _dynamic(comm, folder / "cut", name, extra=[_StopAfter(5)])
    with pytest.raises(_Interrupt):
        cut.run()
    meta = read_meta(folder / "cut" / "ckpt", comm)
    assert 2 <= meta["step"] < 5
    resumed, diag = _dynamic(comm, folder / "cut", name)
    summary = resumed.run(restart=folder / "cut" / "ckpt")
    assert summary["steps"] == reference["steps"] and summary["final_time"] == pytest.approx(0.4)
    _same_rows(summary["rows"], reference["rows"])
    _same_rows(diag.rows, full_diag.rows)  # the recorder's own rows came back with the checkpoint
    for f in ("u", "v", "a"):
        assert _relative(getattr(resumed.problem, f).x.array, getattr(full.problem, f).x.array, comm) < 1e-10
    if name == "newmark-adaptive":
        dts = [row["dt"] for row in reference["rows"][1:]]
        assert max(dts) > 3 * min(dts) and sum(row["rejected"] for row in reference["rows"]) >= 1  # grew, and cut back


# -- SIGKILL ------------------------------------------------------------------------------------
def _killed_run(folder: str) -> None:
    """What the subprocess runs: the ramp, slowed down so that it can be killed mid-run."""
    sim = _ramp(MPI.COMM_WORLD, Path(folder), extra=[Quantity("pause", lambda: time.sleep(0.3) or 0.0)], every=2)
    sim.run()


@pytest.mark.serial
def test_sigkill_leaves_every_completed_step_and_a_checkpoint(folder, comm):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "HYDRA_", "MPI_LOCALNRANKS"))}
    here = Path(__file__).resolve().parent
    code = f"import sys; sys.path.insert(0, {str(here)!r}); import test_checkpoint as t; t._killed_run({str(folder)!r})"
    child = subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    csv_file = folder / "ramp.csv"
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and child.poll() is None:
            if csv_file.is_file() and len(csv_file.read_text().splitlines()) >= 6:  # header, initial state, 4 steps
                break
            time.sleep(0.05)
        assert child.poll() is None, child.stdout.read().decode()[-2000:]
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.wait(timeout=30)
    assert child.returncode == -signal.SIGKILL
    with csv_file.open() as fh:
        rows = list(csv.DictReader(fh))
    # The CSV is written first in a step: the outputs after it are at its step or, killed
    # in between, one behind.
    done = len(rows) - 1
    assert done >= 4 and [int(r["step"]) for r in rows] == list(range(done + 1))
    assert all(r["reaction_left_Fz"] not in ("", None) for r in rows)  # every line complete
    summary = json.loads((folder / "ramp.json").read_text())  # never a truncated file
    assert summary["completed"] is False and done - 1 <= summary["steps"] <= done
    assert [r["step"] for r in summary["rows"]] == list(range(summary["steps"] + 1))
    assert done <= vtx_steps(folder / "ramp.bp") <= done + 1  # the initial frame, then one per step
    logged = [line["step"] for line in read_convergence(folder / "ramp.jsonl")]
    assert logged == list(range(len(logged))) and done - 1 <= logged[-1] <= done
    meta = read_meta(folder / "ckpt", comm)
    assert 2 <= meta["step"] <= done + 1

    reference = _ramp(comm, folder / "reference").run()
    resumed = _ramp(comm, folder)
    summary = resumed.run(restart=folder / "ckpt")
    assert summary["completed"] and summary["steps"] == reference["steps"]
    _same_rows([{k: v for k, v in r.items() if k != "pause"} for r in summary["rows"]], reference["rows"])


def test_checkpoints_hold_the_current_state_of_nested_output_lists(folder, comm):
    """A field writer's pending output times (a list inside a list of the output's state) are those of
    the step of each checkpoint; the history kept the first checkpoint's, and a restart then wrote
    frames the uninterrupted run did not."""
    from hyperfem.simulation import FieldOutput

    problem = hf.HyperelasticProblem(_box(comm), psi, bcs=[hf.Clamp("left")],
                                     loads=[hf.DeadTraction("right", (0.0, 0.0, -3e3))])
    times = [0.25, 0.5, 0.75, 1.0]
    outputs = [FieldOutput(folder, fields=("displacement",), times=times, name="f"),
               VTX(folder / "plain.bp", times=times), Checkpoint(folder / "ckpt", every=1, keep=None)]
    policy = hf.StepPolicy(increment=0.25, easy_iterations=None, growth=1.0)
    Simulation(problem, hf.NewtonSolver(problem), policy, outputs, name="nested").run()
    for step in (1, 2, 3, 4):
        meta = read_meta(folder / "ckpt" / f"step-{step:06d}", comm)
        assert meta["outputs"][0]["state"]["writers"][0]["pending"] == times[step:]
        assert meta["outputs"][1]["state"]["pending"] == times[step:]
