r"""Taylor (consistency) tests of energy, residual and tangent.

For a smooth functional the Taylor remainders

.. math::
    e_0(h) = |\Pi(u + h\,\delta u) - \Pi(u) - h\,R(u)\cdot\delta u|, \qquad
    e_1(h) = \|R(u + h\,\delta u) - R(u) - h\,K(u)\,\delta u\|

decay like :math:`h^2` exactly when :math:`R` is the derivative of
:math:`\Pi` and :math:`K` the derivative of :math:`R`. Everything is
assembled *without* Dirichlet conditions, on a small 3D box in a perturbed,
non-trivial state. Works in serial and in parallel (all reductions global).
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem
from dolfinx import mesh as dmesh

from taylor_checks import smooth_field

import hyperfem as hf
from hyperfem.materials import LameParameters, neo_hookean

PARAMS = LameParameters.from_youngs(E=1e6, nu=0.3)
STEPS = 4e-3 / 2.0 ** np.arange(5)


def _box_domain() -> hf.Domain:
    mesh = dmesh.create_box(
        MPI.COMM_WORLD, [np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.4, 0.3])], [4, 2, 2],
        dmesh.CellType.tetrahedron,
    )
    return hf.Domain.from_locators(
        mesh,
        {
            "left": lambda x: np.isclose(x[0], 0.0),
            "right": lambda x: np.isclose(x[0], 1.0),
            "top": lambda x: np.isclose(x[2], 0.3),
        },
    )


_state = smooth_field  # a smooth, partition-independent 'random' vector field (tests/taylor_checks.py)


def _make_problem(loads) -> hf.HyperelasticProblem:
    domain = _box_domain()
    problem = hf.HyperelasticProblem(
        domain, lambda F: neo_hookean(F, PARAMS), bcs=[hf.Clamp("left")], loads=loads
    )
    problem.set_time(1.0)
    rng = np.random.default_rng(17)  # same numbers on every rank
    cu = 0.08 * rng.standard_normal((3, 4))
    problem.u.interpolate(lambda x: _state(x, cu))
    return problem


class _Assembler:
    """Energy / residual / tangent of a problem at ``u + h du`` (no BCs).

    Every PETSc object is created and destroyed explicitly (``du.x.petsc_vec`` is
    deliberately not used): a Function sits in a reference cycle, and the PETSc
    vector it caches is destroyed by ``la.Vector.__del__`` whenever the cyclic
    garbage collector runs -- at different moments on different ranks. If it
    is the last PETSc object on its communicator, PETSc frees its inner
    communicator on one rank only, and the next collective PETSc creation
    deadlocks.
    """

    def __init__(self, problem: hf.HyperelasticProblem, jacobian=None):
        self.problem = problem
        self.comm = problem.domain.comm
        self.energy = fem.form(problem.energy)
        self.residual = fem.form(problem.residual)
        self.jacobian = fem.form(problem.jacobian if jacobian is None else jacobian)
        self.u0 = problem.u.x.array.copy()
        self.du = fem.Function(problem.V)
        rng = np.random.default_rng(23)
        cd = rng.standard_normal((3, 4))
        self.du.interpolate(lambda x: _state(x, cd))

    def set(self, h: float) -> None:
        self.problem.u.x.array[:] = self.u0 + h * self.du.x.array
        self.problem.u.x.scatter_forward()

    def Pi(self, h: float) -> float:
        self.set(h)
        return self.comm.allreduce(fem.assemble_scalar(self.energy), op=MPI.SUM)

    def R(self, h: float) -> PETSc.Vec:
        self.set(h)
        b = fpetsc.assemble_vector(self.residual)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    def K_du(self, h: float) -> PETSc.Vec:
        self.set(h)
        A = fpetsc.assemble_matrix(self.jacobian)
        A.assemble()
        x, y = A.createVecs()
        x.array[:] = self.du.x.array[: x.getLocalSize()]  # owned entries
        A.mult(x, y)
        x.destroy()
        A.destroy()
        return y

    def dot_du(self, b: PETSc.Vec) -> float:
        """b . du over all ranks."""
        n = b.getLocalSize()
        return self.comm.allreduce(float(np.dot(b.array_r, self.du.x.array[:n])), op=MPI.SUM)


def _rates(errors, steps=STEPS) -> np.ndarray:
    errors = np.asarray(errors)
    return np.log(errors[:-1] / errors[1:]) / np.log(steps[:-1] / steps[1:])


def _residual_tangent_remainders(asm: _Assembler, steps=STEPS) -> tuple[np.ndarray, float]:
    R0 = asm.R(0.0)
    Kdu = asm.K_du(0.0)
    errors = []
    for h in steps:
        Rh = asm.R(h)
        Rh.axpy(-1.0, R0)
        Rh.axpy(-h, Kdu)
        errors.append(Rh.norm())
        Rh.destroy()
    scale = Kdu.norm()
    R0.destroy()
    Kdu.destroy()
    asm.set(0.0)
    return np.array(errors), scale


def test_energy_residual_taylor():
    problem = _make_problem([hf.DeadTraction("right", (0.0, -5e3, 2e3))])
    asm = _Assembler(problem)
    Pi0 = asm.Pi(0.0)
    R0 = asm.R(0.0)
    dPi = asm.dot_du(R0)  # R(u) . du, all ranks
    R0.destroy()
    assert abs(dPi) > 1.0  # a genuinely non-trivial directional derivative
    errors = np.array([abs(asm.Pi(h) - Pi0 - h * dPi) for h in STEPS])
    rates = _rates(errors)
    # The first-order term dominates the remainder by orders of magnitude.
    assert errors[-1] < 1e-2 * abs(STEPS[-1] * dPi)
    assert rates.min() > 1.9, rates
    assert rates.max() < 2.1, rates
    # Control: dropping the derivative gives first-order decay only.
    wrong = np.array([abs(asm.Pi(h) - Pi0) for h in STEPS])
    assert np.all(np.abs(_rates(wrong) - 1.0) < 0.1)


def test_residual_tangent_taylor_dead_load():
    problem = _make_problem([hf.DeadTraction("right", (0.0, -5e3, 2e3))])
    errors, scale = _residual_tangent_remainders(_Assembler(problem))
    rates = _rates(errors)
    assert scale > 1.0
    assert errors[-1] < 1e-3 * STEPS[-1] * scale
    assert rates.min() > 1.9, rates


def _follower_traction(x):
    return 5e3 * ufl.as_vector((0.0, x[2], -x[1]))


@pytest.mark.parametrize(
    "load",
    [hf.FollowerTraction("right", _follower_traction), hf.FollowerPressure("top", 2e4)],
    ids=["follower_traction", "follower_pressure"],
)
def test_residual_tangent_taylor_follower(load):
    """The follower tangent derived by ufl.derivative is consistent."""
    problem = _make_problem([load])
    assert not problem.conservative and problem.follower_residual is not None
    errors, scale = _residual_tangent_remainders(_Assembler(problem))
    rates = _rates(errors)
    assert errors[-1] < 1e-3 * STEPS[-1] * scale
    assert rates.min() > 1.9, rates

    # Control: the tangent of the conservative part alone (follower
    # linearisation dropped) must visibly fail the test, otherwise the check
    # above would be vacuous.
    v = ufl.TestFunction(problem.V)
    du = ufl.TrialFunction(problem.V)
    K_no_follower = ufl.derivative(ufl.derivative(problem.energy, problem.u, v), problem.u, du)
    # Smaller steps, where the missing O(h) term dominates the O(h^2) one.
    control_steps = STEPS * 1e-2
    bad, _ = _residual_tangent_remainders(_Assembler(problem, jacobian=K_no_follower), control_steps)
    bad_rates = _rates(bad, control_steps)
    assert np.all(np.abs(bad_rates - 1.0) < 0.1), bad_rates
    assert bad[-1] > 100 * errors[-1] * 1e-4  # vs. the O(h^2) remainder of the true tangent


@pytest.mark.parametrize(
    "load,expected",
    [
        # t = 5e3 (0, z, -y) on x = 1, [0, 0.4] x [0, 0.3]: int z dA = 0.4 * 0.3^2/2, int y dA = 0.3 * 0.4^2/2
        (hf.FollowerTraction("right", _follower_traction), -5e3 * np.array([0.0, 0.4 * 0.045, -0.3 * 0.08])),
        # p = 2e4 on z = 0.3 (outward normal +z, area 0.4): residual + p N . v
        (hf.FollowerPressure("top", 2e4), np.array([0.0, 0.0, 2e4 * 0.4])),
    ],
    ids=["follower_traction", "follower_pressure"],
)
def test_follower_load_resultant_at_reference(load, expected):
    """At u = 0 (stress free) the residual sums, per component, to the load resultant."""
    problem = _make_problem([load])
    problem.u.x.array[:] = 0.0
    b = fpetsc.assemble_vector(fem.form(problem.residual))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    local = b.array_r.reshape(-1, 3).sum(axis=0)
    b.destroy()
    total = problem.domain.comm.allreduce(local, op=MPI.SUM)
    np.testing.assert_allclose(total, expected, rtol=1e-12, atol=1e-9)
