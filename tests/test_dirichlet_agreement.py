"""Dirichlet conditions on boundaries that share nodes must agree there.

A clamp on ``clamped`` and a prescribed displacement on ``surface`` share the
nodes of the edges between the two groups. Before, the last condition won on
those nodes without a word (through the CLI the run went on to min J 0.08);
now the problem refuses the pair at construction, naming both conditions, and
again at any load factor/time at which their values part.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import hyperfem as hf
from hyperfem.cases import CantileverSpec
from hyperfem.errors import ParameterError

from case_texts import BASE, ROOT

MESH = ROOT / "meshes" / "beam_h2.msh"
PARAMS = CantileverSpec().lame


def _problem(domain, bcs):
    return hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), degree=1, bcs=bcs)


@pytest.fixture(scope="module")
def beam():
    from mpi4py import MPI

    return hf.read_mesh(MESH, MPI.COMM_WORLD)


def test_a_clamp_next_to_a_moving_face_is_refused(beam):
    bcs = [hf.Clamp("clamped"), hf.PrescribedDisplacement("surface", (0.0, -0.5, 0.0))]
    with pytest.raises(ParameterError) as info:
        _problem(beam, bcs)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("bc[1] (PrescribedDisplacement on 'surface') and bc[0] (Clamp on 'clamped') prescribe "
                              "different values on 8 dof(s)")  # the 8 nodes of the clamped face's rim, component y
    assert "differing by up to 0.5" in message


@pytest.mark.parametrize(
    "second",
    [
        hf.Clamp("surface"),  # both zero on the shared edge
        hf.PrescribedDisplacement("surface", (0.0,), components=[0]),  # a roller: zero in x, as the clamp
        hf.PrescribedDisplacement("free_end", (0.0, -0.5, 0.0)),  # no shared nodes with 'clamped'
    ],
)
def test_conditions_that_agree_on_shared_nodes_are_accepted(beam, second):
    problem = _problem(beam, [hf.Clamp("clamped"), second])
    problem.set_time(0.7)
    assert problem.time == pytest.approx(0.7)


def test_values_that_part_later_are_refused_when_they_part(beam):
    """Agreeing at s = 0 and s = 1 (the construction check) but not in between: refused at that time."""

    def bump(x, s):
        return np.vstack([np.zeros(x.shape[1]), np.full(x.shape[1], 0.1 * s * (1.0 - s)), np.zeros(x.shape[1])])

    problem = _problem(beam, [hf.Clamp("clamped"), hf.PrescribedDisplacement("surface", bump)])
    with pytest.raises(ParameterError, match=r"at load factor/time 0\.5, differing by up to 0\.025"):
        problem.set_time(0.5)


@pytest.mark.serial
def test_the_command_refuses_the_pair_in_one_line(tmp_path):
    case = tmp_path / "case.toml"
    case.write_text(BASE + '\n[[bc]]\ntype = "displacement"\nboundary = "surface"\nvalue = [0.0, -0.5, 0.0]\n')
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "MPICH_"))}
    env["PYTHONWARNINGS"] = "ignore"
    result = subprocess.run(
        [sys.executable, "-m", "hyperfem.app.main", "run", str(case), "--output", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=240, cwd=ROOT, env=env,
    )
    assert result.returncode == 1, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert "bc[1] (PrescribedDisplacement on 'surface') and bc[0] (Clamp on 'clamped') prescribe different" in lines[0]


@pytest.mark.parametrize("n", [3, 4])
def test_callable_values_are_exact_on_every_boundary_dof_and_its_ghosts(comm, n):
    """Callable values are interpolated on the cells that hold a boundary dof, then scattered.

    On 2 ranks: with the cells next to the local boundary facets, the ghost copies kept their previous
    values (n = 3: a cube with a prescribed affine face stalled, DIVERGED_LINE_SEARCH at t = 0.25), and
    with n = 4 one owned dof sat on a rank that has none of its facets and was never set (its node did
    not move; an error of 100 % of the value).
    """
    from dolfinx import mesh as dmesh
    from mpi4py import MPI

    mesh = dmesh.create_unit_cube(MPI.COMM_WORLD, n, n, n)
    domain = hf.Domain.from_locators(
        mesh, {"x0": lambda x: np.isclose(x[0], 0.0), "x1": lambda x: np.isclose(x[0], 1.0)}
    )
    shear = lambda x: np.vstack([0.1 * x[1], 0.1 * x[2], 0.0 * x[0]])  # noqa: E731
    rotating = lambda x, s: np.vstack([0.0 * x[0], -s * x[2], s * x[1]])  # noqa: E731
    for value, at in ((shear, 1.0), (rotating, 0.5)):
        problem = _problem(domain, [hf.Clamp("x0"), hf.PrescribedDisplacement("x1", value)])
        problem.set_time(at)
        values = np.full(problem.u.x.array.size, np.nan)
        problem.bcs[-1].set(values)  # owned and ghost entries of the prescribed dofs
        prescribed = np.flatnonzero(np.isfinite(values))
        X = problem.V.tabulate_dof_coordinates()
        expected = (value(X.T) if value is shear else value(X.T, at)) * (1.0 if value is rotating else at)
        exact = expected.T.reshape(-1)[prescribed]
        error = MPI.COMM_WORLD.allreduce(float(np.max(np.abs(values[prescribed] - exact), initial=0.0)), op=MPI.MAX)
        assert error < 1e-14
