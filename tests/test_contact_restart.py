r"""A generalized-:math:`\alpha` run with contact and friction, interrupted and restarted from its checkpoint, equals
the uninterrupted run (issue 19).

Under generalized-:math:`\alpha` a contact's force is interpolated between the ends of a step,
:math:`(1-\alpha_f)f_c(u_{n+1}) + \alpha_f f_c(u_n)`, the second term frozen at the step's start with the
friction's lag of the step that reached :math:`u_n` (:mod:`hyperfem.contact.interpolation`). That lag is not the
one a restart takes again (the lag *at* :math:`u_n`, for the next step), so the checkpoint holds the frozen force
itself. A light cube (rollers on ``x0``, ``y0``, its top held in :math:`z`) is pushed up and dragged sideways by a
rough obstacle, a plane (nodal barrier) and a triangulated plate (``ipctk``); interrupted in step 3 (its outputs:
the last checkpoint is of step 2).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

pytest.importorskip("ipctk")

import hyperfem as hf  # noqa: E402
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.contact import PlaneContact, ToolContact  # noqa: E402
from test_contact_dynamics import DHAT, TIGHT, _held_cube  # noqa: E402

MOTION = (0.02, 0.0, 0.1)  # sideways (friction) and up (the push), over t in [0, 1]
PLATE = np.array([[-1.0, -1.0, -DHAT / 2], [3.0, -1.0, -DHAT / 2], [3.0, 3.0, -DHAT / 2], [-1.0, 3.0, -DHAT / 2]])


def _obstacle(kind: str, problem):
    rough = {"friction": 0.3, "friction_epsilon": 1e-4}
    if kind == "plane":
        return PlaneContact("bottom", point=(0.0, 0.0, -DHAT / 2), normal=(0.0, 0.0, 1.0), dhat=DHAT, stiffness=1.0,
                            motion=MOTION, **rough).bind(problem)
    return ToolContact.from_arrays(["bottom"], PLATE, np.array([[0, 1, 2], [0, 2, 3]]), dhat=DHAT, stiffness=1e3,
                                   motion=MOTION, **rough).bind(problem)


def _run(kind: str, folder, stop_after: int | None = None, restart=None) -> dict:
    from hyperfem.simulation import Checkpoint, Recorder, Simulation
    from hyperfem.simulation.outputs import Output

    class StopAfter(Output):
        def write(self, sim, step) -> None:
            if stop_after is not None and step is not None and step.step >= stop_after:
                raise KeyboardInterrupt(f"interrupted after step {step.step}")

    comm = MPI.COMM_WORLD
    problem = dyn.IncrementalProblem(_held_cube(comm), dyn.GeneralizedAlpha(rho_inf=0.8), dyn.MassDensity(1e-4))
    contact = _obstacle(kind, problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[contact])
    outputs = [Recorder(contact), StopAfter(), Checkpoint(folder / "ckpt", every=1)]
    sim = Simulation(problem, solver, dyn.TimeStepping(dt=0.05, t_end=0.3), outputs, name="push")
    return sim.run(restart=restart)


@pytest.mark.parametrize("kind", ["plane", "tool"])
def test_generalized_alpha_restart_with_friction_equals_the_uninterrupted_run(kind, shared_tmp):
    r"""Restarted from step 2 of 6: every later row's normal and friction force equals the uninterrupted run's to
    1e-10 (measured: the plane's bit for bit, the tool's to 4e-13, ``ipctk``'s own run-to-run round-off). Before,
    the restart took the friction's lag with the obstacle where it was at :math:`t = 0` and :math:`f_c(u_n)` without
    its friction part: the first step after it had the normal force 3.2 % (tool 2.2 %) and the friction force 100 %
    off; with the lag fixed but :math:`f_c(u_n)` not in the checkpoint, 0.2 % (0.6 %) and 180 % (29 %)."""
    reference = _run(kind, shared_tmp / "full")
    with pytest.raises(KeyboardInterrupt):
        _run(kind, shared_tmp / "cut", stop_after=3)
    resumed = _run(kind, shared_tmp / "cut", restart=shared_tmp / "cut" / "ckpt")
    assert resumed["completed"] and resumed["steps"] == reference["steps"] == 6
    friction = [row["contact_friction_force"] if kind == "plane" else row["tool_friction_force"]
                for row in reference["rows"]]
    assert abs(friction[-1][0]) > 0.0
    for row, expected in zip(resumed["rows"][2:], reference["rows"][2:], strict=True):
        for key in ("force", "friction_force"):
            name = f"{'contact' if kind == 'plane' else 'tool'}_{key}"
            scale = max(abs(v) for v in expected[name])
            assert row[name] == pytest.approx(expected[name], rel=1e-10, abs=1e-10 * scale)
