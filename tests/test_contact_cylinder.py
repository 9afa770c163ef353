r"""Contact with a rigid infinite cylinder (issue 19): :class:`~hyperfem.contact.CylinderContact`.

The sphere's formulas in the plane normal to the axis: a Taylor test of the
barrier's gradient and exact Hessian, the collision filter's quadratic on
projected offsets and steps, and the pressed cube of ``test_contact.py`` on a
roller (axis along :math:`y`, under the bottom face): force = reaction, no
iterate penetrates, 1 rank = 2 ranks.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

ipctk = pytest.importorskip("ipctk")

import hyperfem as hf  # noqa: E402
from hyperfem.contact import CylinderContact, SphereCollisionFilter, sphere_step_fraction  # noqa: E402
from hyperfem.errors import ParameterError  # noqa: E402
from hyperfem.simulation.reactions import ReactionForce  # noqa: E402
from test_contact import TIGHT, _block, _watch  # noqa: E402

RADIUS = 2.0


def _roller(**kwargs) -> CylinderContact:
    """A roller of radius 2 along y under the middle of the bottom face, 2e-3 below it."""
    return CylinderContact("bottom", point=(0.5, 0.0, -RADIUS - 2e-3), axis=(0.0, 3.0, 0.0), radius=RADIUS, **kwargs)


def test_cylinder_barrier_taylor():
    """Gradient and exact Hessian of kappa*B for a cylinder against its energy: errors O(eps^2), O(eps^3)."""
    problem = _block(n=2)
    barrier = _roller(dhat=5e-2, stiffness=0.5).bind(problem)
    comm = problem.domain.comm
    rng = np.random.default_rng(comm.rank + 3)
    u = 1e-4 * rng.standard_normal(problem.u.x.array.size)
    du = 1e-3 * rng.standard_normal(u.size)
    dofs, g = barrier.gradient(u)
    hdofs, exact = barrier.hessian(u, project=False)
    assert comm.allreduce(len(dofs), op=MPI.SUM) >= 3
    G = np.zeros(u.size)
    np.add.at(G, dofs.ravel(), g.ravel())
    Hdu = np.zeros(u.size)
    np.add.at(Hdu, hdofs.ravel(), np.einsum("mij,mj->mi", exact, du[hdofs]).ravel())

    def total(values):
        return comm.allreduce(barrier.energy(values), op=MPI.SUM)

    E0, first, second = total(u), [], []
    gdu = comm.allreduce(float(G @ du), op=MPI.SUM)
    duHdu = comm.allreduce(float(du @ Hdu), op=MPI.SUM)
    for eps in (1e-1, 1e-2, 1e-3):
        E1 = total(u + eps * du)
        first.append(abs(E1 - E0 - eps * gdu))
        second.append(abs(E1 - E0 - eps * gdu - 0.5 * eps * eps * duHdu))
    assert first[1] / first[0] == pytest.approx(1e-2, rel=0.2) and first[2] / first[1] == pytest.approx(1e-2, rel=0.2)
    assert second[2] / second[1] < 2e-3  # O(eps^3)
    _, projected = barrier.hessian(u, project=True)
    if len(projected):
        assert np.linalg.eigvalsh(projected).min() > -1e-12 * np.abs(projected).max()
        # Along the axis the block is zero: a cylinder does not push along its axis.
        axis = np.array([0.0, 1.0, 0.0])
        assert np.abs(projected @ axis).max() < 1e-12 * np.abs(projected).max()


def test_cylinder_filter_is_the_sphere_quadratic_in_the_normal_plane():
    """The filter's fraction for a node moving toward the axis (with a component along it) is the circle's root."""
    comm = MPI.COMM_SELF
    P = np.eye(3) - np.outer([0.0, 1.0, 0.0], [0.0, 1.0, 0.0])
    from petsc4py import PETSc

    x = PETSc.Vec().createSeq(3, comm=comm)
    y = PETSc.Vec().createSeq(3, comm=comm)
    x.array[:] = 0.0
    y.array[:] = [0.0, -5.0, 1.0]  # the step x - y: 1 down toward the axis, 5 along it
    center = np.array([0.0, 0.0, -1.5])
    filt = SphereCollisionFilter(np.array([[0, 1, 2]]), np.zeros((1, 3)), lambda: center, 1.0, 0.9, P)
    expected = sphere_step_fraction(np.array([[0.0, 0.0, 1.5]]), np.array([[0.0, 0.0, 1.0]]), 1.0, 0.9)
    assert filt.step_fraction(x, y) == pytest.approx(expected, rel=1e-14) and expected < 1.0


def _pressed_on_roller(comm) -> tuple:
    problem = _block(comm, n=3, delta=0.05)
    barrier = _roller(dhat=1e-3).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[barrier])
    iterates = _watch(solver, barrier)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    return problem, barrier, iterates


def test_block_pressed_on_a_roller_balances_the_reaction():
    """The cube pressed 0.05 onto the roller: the contact force = -(top reaction) to 1e-8, along the normals only
    (no force along the axis), no iterate inside the cylinder."""
    problem, barrier, iterates = _pressed_on_roller(MPI.COMM_WORLD)
    reaction = ReactionForce(problem, "top")()
    force = barrier.force()
    assert force[2] == pytest.approx(-reaction[2], rel=1e-8) and force[2] > 0.0
    assert abs(force[1]) < 1e-12 * force[2]
    assert min(iterates) > 0.0 and barrier.active_count() > 0


def test_cylinder_one_rank_equals_two_ranks():
    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")

    def state(c):
        problem, barrier, _ = _pressed_on_roller(c)
        return [*barrier.force(), barrier.min_distance(), float(problem.u.x.petsc_vec.norm())]

    one = state(MPI.COMM_SELF) if comm.rank == 0 else None
    one = comm.bcast(one, root=0)
    assert state(comm) == pytest.approx(one, rel=1e-10, abs=1e-14)


def test_cylinder_bad_input_is_one_line():
    with pytest.raises(ParameterError, match="CylinderContact on 'bottom': axis must be a non-zero vector"):
        CylinderContact("bottom", point=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 0.0), radius=1.0)
    with pytest.raises(ParameterError, match="radius must be"):
        CylinderContact("bottom", point=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0), radius=-1.0)
    with pytest.raises(ParameterError, match="3 components"):
        CylinderContact("bottom", point=(0.0, 0.0), axis=(0.0, 1.0), radius=1.0)
    problem = _block(n=2)
    with pytest.raises(ParameterError, match="starts on the wrong side of the cylinder"):
        CylinderContact("bottom", point=(0.5, 0.0, 0.0), axis=(0.0, 1.0, 0.0), radius=0.3).bind(problem)
