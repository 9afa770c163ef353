"""Ctrl-C and SIGTERM stop a run after the current step, on every rank, with a clear line.

Before, Ctrl-C during a solve surfaced as ``NewtonSolver: PETSc error 101 …
a failure of PETSc itself`` (or a 40-line traceback), was stored as the run's
``error``, and ``mpiexec -n 2`` could hang (1 in 5 tries). Now the first
signal sets a flag (:class:`~hyperfem.simulation.interrupt.InterruptGuard`),
the ranks agree on it after every accepted step, the outputs and the
checkpoint are written, and :class:`~hyperfem.errors.Interrupted` names the
step, the time and the checkpoint to continue from; the command exits 130.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

import hyperfem as hf
from hyperfem.errors import Interrupted
from hyperfem.simulation import Checkpoint, JSONSummary, Output, Probe, Simulation
from hyperfem.simulation.interrupt import InterruptGuard

from case_texts import ROOT

PARAMS = hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3)


def psi(F):
    return hf.materials.neo_hookean(F, PARAMS)


@pytest.fixture
def folder(tmp_path):
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))


class _SignalAt(Output):
    """Sends SIGINT to its own process on rank 0 after step ``step`` (as a Ctrl-C would arrive)."""

    def __init__(self, step: int):
        self.at = step

    def write(self, sim, step) -> None:
        if step is not None and step.step == self.at and sim.comm.rank == 0:
            os.kill(os.getpid(), signal.SIGINT)


def _ramp(folder: Path, extra=()):
    mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([1.0, 0.3, 0.3])], [4, 2, 2])
    domain = hf.Domain.from_locators(
        mesh, {"left": lambda x: np.isclose(x[0], 0.0), "right": lambda x: np.isclose(x[0], 1.0)}, source="box"
    )
    load = hf.DeadTraction("right", (0, 0, -3e3))
    problem = hf.HyperelasticProblem(domain, psi, bcs=[hf.Clamp("left")], loads=[load])
    policy = hf.StepPolicy(increment=0.125, easy_iterations=None, growth=1.0)
    outputs = [
        *extra,
        Probe([(1.0, 0.15, 0.15)]),
        JSONSummary(folder / "ramp.json"),
        Checkpoint(folder / "ckpt", every=None),
    ]
    return Simulation(problem, hf.NewtonSolver(problem), policy, outputs, name="ramp")


def test_guard_turns_the_first_signal_into_a_request_and_restores_the_handler(comm):
    before = signal.getsignal(signal.SIGINT)
    with InterruptGuard(comm) as guard:
        assert guard.requested() == 0
        if comm.rank == 0:
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGINT)  # the launcher's forwarded copy: the same request
        assert guard.requested() == signal.SIGINT  # on every rank
    assert signal.getsignal(signal.SIGINT) is before


def test_an_interrupted_run_keeps_its_steps_and_continues(folder, comm):
    reference = _ramp(folder / "full").run()
    cut = _ramp(folder / "cut", extra=[_SignalAt(3)])
    with pytest.raises(Interrupted) as info:
        cut.run()
    message = str(info.value)
    assert message.startswith("ramp: interrupted (Ctrl-C) after step 3, t = 0.375 (completed steps written to ")
    assert "continue with --restart from " in message and "step-000003" in message
    assert info.value.time == pytest.approx(0.375)
    written = json.loads((folder / "cut" / "ramp.json").read_text())
    assert written["error"] == "interrupted (Ctrl-C) after step 3, t = 0.375"
    assert not written["completed"] and len(written["rows"]) == 4  # the initial state and 3 steps
    resumed = _ramp(folder / "cut").run(restart=folder / "cut" / "ckpt")
    assert resumed["completed"] and resumed["steps"] == reference["steps"]
    tip = np.array([np.ravel(r["probe_displacement"]) for r in resumed["rows"]])
    expected = np.array([np.ravel(r["probe_displacement"]) for r in reference["rows"]])
    np.testing.assert_allclose(tip, expected, rtol=1e-9, atol=1e-12)


def _env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "MPICH_"))}
    env["PYTHONWARNINGS"] = "ignore"
    return env


@pytest.mark.serial
@pytest.mark.parametrize("ranks", [1, 2])
def test_ctrl_c_through_the_command(ranks, tmp_path):
    """A long dynamic run, Ctrl-C to the whole process group once steps are being written."""
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "hyperfem.app.main", "run", str(ROOT / "cases" / "dynamics_bend.toml"),
           "--set", "stepping.t_end=500", "--output", str(out)]
    if ranks > 1:
        mpiexec = Path(sys.executable).parent / "mpiexec"
        if not mpiexec.exists():
            pytest.skip("no mpiexec beside the interpreter")
        cmd = [str(mpiexec), "-n", str(ranks), *cmd]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(), cwd=ROOT,
                            start_new_session=True, restore_signals=True)
    try:
        csv = out / "dynamics_bend.csv"
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and (not csv.exists() or len(csv.read_text().splitlines()) < 12):
            time.sleep(0.2)
        assert proc.poll() is None, proc.communicate()[1]
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: mpiexec and every rank
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "PETSc error" not in stderr, stderr
    errors = [line for line in stderr.splitlines() if line.startswith("hyperfem: error: ")]
    assert len(errors) == 1, stderr
    assert "dynamics_bend: interrupted (Ctrl-C) after step " in errors[0]
    assert "continue with --restart from " in errors[0]
    summary = json.loads((out / "dynamics_bend.json").read_text())
    assert summary["error"].startswith("interrupted (Ctrl-C) after step ") and not summary["completed"]
    assert summary["steps"] >= 10  # 12 CSV lines when signalled: the header, step 0 (the initial state), steps 1-10
