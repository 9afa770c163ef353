r"""Invertible energies and the ``invertible`` flag of problems.

* Which laws are invertible (finite and restoring for :math:`J \le 0`) and
  how a problem infers its flag from its energies.
* Seed 000's point (§6: the logarithm of Neo-Hookean makes a discretely
  inverted element fatal; its cubic replacement :math:`r(J)` "allows the
  simulation to continue if a few tetrahedrons invert"): a cube starts with
  one node pushed through the opposite faces of its cells (:math:`J = -0.2`
  there) and is then compressed by 30 %. Neo-Hookean cannot evaluate the
  start state: with the inversion guard every attempt is refused and
  stepping cuts back to its minimum increment at :math:`t = 0`. The robust
  Neo-Hookean law (and the other invertible laws) with
  ``NewtonSolver(problem, min_jacobian=None)`` reaches the full compression
  in one step and un-inverts the cells.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.errors import ConvergenceError, ParameterError
from hyperfem.materials import (
    ARAP,
    CorotationalLinear,
    FixedCorotated,
    LameParameters,
    invertible,
    is_invertible,
    linear_elastic,
    mooney_rivlin,
    muscle,
    neo_hookean,
    robust_neo_hookean,
    saint_venant_kirchhoff,
    stable_neo_hookean,
    with_parameters,
)
from hyperfem.problem.base import EnergyProblem

PARAMS = LameParameters.from_youngs(E=1e3, nu=0.3)


# --------------------------------------------------------------------------
# Flags
# --------------------------------------------------------------------------
def test_which_laws_are_invertible():
    for law in (robust_neo_hookean, stable_neo_hookean, linear_elastic):
        assert is_invertible(law), law
    for law in (neo_hookean, saint_venant_kirchhoff, mooney_rivlin, muscle):
        assert not is_invertible(law), law
    for material in (FixedCorotated(PARAMS), ARAP(PARAMS), CorotationalLinear(PARAMS)):
        assert is_invertible(material)
    # A plain lambda hides the law; with_parameters keeps its flag, invertible() sets one.
    assert not is_invertible(lambda F: robust_neo_hookean(F, PARAMS))
    assert is_invertible(with_parameters(robust_neo_hookean, PARAMS))
    assert not is_invertible(with_parameters(neo_hookean, PARAMS))
    assert is_invertible(invertible(lambda F: neo_hookean(F, PARAMS)))
    assert not is_invertible(invertible(with_parameters(robust_neo_hookean, PARAMS), False))


def test_saint_venant_kirchhoff_is_not_invertible_by_decision():
    """SVK is finite for J <= 0 but a reflection is stress free to it: nothing pushes an inverted cell back."""
    mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    Fc = fem.Constant(mesh, np.diag([-1.0, 1.0, 1.0]))
    F = ufl.variable(Fc)
    laws = [saint_venant_kirchhoff, robust_neo_hookean, stable_neo_hookean, linear_elastic]
    entries = []
    for law in laws:
        psi = law(F, PARAMS)
        entries += [psi, ufl.inner(ufl.diff(psi, F), ufl.diff(psi, F))]
    expr = fem.Expression(ufl.as_vector(entries), np.full((1, 3), 0.25), jit_options={"timeout": 300})
    values = expr.eval(mesh, np.array([0], dtype=np.int32)).reshape(-1, 2)
    svk, others = values[0], values[1:]
    assert abs(svk[0]) < 1e-12 * PARAMS.mu and svk[1] < 1e-20 * PARAMS.mu**2  # energy and stress vanish
    assert np.all(others[:, 0] > 0.5 * PARAMS.mu) and np.all(others[:, 1] > 0.1 * PARAMS.mu**2)


def _two_region_domain(comm) -> hf.Domain:
    mesh = dmesh.create_unit_square(comm, 4, 2)
    tdim = mesh.topology.dim
    n = mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts
    left = dmesh.locate_entities(mesh, tdim, lambda x: x[0] <= 0.5 + 1e-12)
    values = np.full(n, 2, dtype=np.int32)
    values[left] = 1
    cell_tags = dmesh.meshtags(mesh, tdim, np.arange(n, dtype=np.int32), values)
    base = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    return hf.Domain(mesh, cell_tags, base.facet_tags, {"soft": 1, "hard": 2}, base.facet_groups)


def test_problem_infers_invertible(comm):
    assert EnergyProblem.invertible is False
    assert hf.problem.MixedHyperelasticProblem.invertible is False
    domain = _two_region_domain(comm)
    bcs = [hf.Clamp("left")]
    robust = with_parameters(robust_neo_hookean, PARAMS)
    stable = with_parameters(stable_neo_hookean, PARAMS)
    nh = lambda F: neo_hookean(F, PARAMS)  # noqa: E731

    def flag(material, **kwargs):
        return hf.HyperelasticProblem(domain, material, bcs=bcs, **kwargs).invertible

    assert flag(robust) is True
    assert flag(nh) is False
    assert flag({"soft": robust, "hard": stable}) is True
    assert flag({"soft": robust, "hard": nh}) is False
    # An explicit flag wins (the user vouches for it).
    assert flag(robust, invertible=False) is False
    assert flag(nh, invertible=True) is True
    with pytest.raises(ParameterError, match="invertible"):
        flag(robust, invertible="yes")


# --------------------------------------------------------------------------
# Seed 000: continuing through a few inverted elements
# --------------------------------------------------------------------------
PUSH = 0.4  # one node (1/3, 1/3, 1/3) moved down by 0.4 > h = 1/3: J = 1 - 3 * 0.4 = -0.2 in the cells below it
COMPRESSION = 0.3


def _pushed_cube(comm, material):
    mesh = dmesh.create_box(comm, [np.zeros(3), np.ones(3)], [3, 3, 3], dmesh.CellType.tetrahedron)
    domain = hf.Domain.from_locators(
        mesh, {"bottom": lambda x: np.isclose(x[2], 0.0), "top": lambda x: np.isclose(x[2], 1.0)}
    )
    problem = hf.HyperelasticProblem(
        domain,
        material,
        bcs=[hf.Clamp("bottom"), hf.PrescribedDisplacement("top", (0.0, 0.0, -COMPRESSION))],
    )

    def pushed(x):
        out = np.zeros((3, x.shape[1]))
        at_node = np.sum((x - 1.0 / 3.0) ** 2, axis=0) < 1e-12
        out[2, at_node] = -PUSH
        return out

    problem.u.interpolate(pushed)
    return problem


def test_neo_hookean_cannot_start_from_inverted_elements(comm):
    problem = _pushed_cube(comm, with_parameters(neo_hookean, PARAMS))
    assert not problem.invertible
    assert problem.nonfinite_terms() == ["the stored energy (material)"]
    solver = hf.NewtonSolver(problem)  # the inversion guard (min_jacobian = 1e-6)
    assert solver.min_J() == pytest.approx(1.0 - 3.0 * PUSH, abs=1e-12)
    with pytest.raises(ConvergenceError) as info:
        hf.solve_quasistatic(solver)
    assert info.value.time == 0.0  # every increment, however short, starts inverted
    assert "J <=" in str(info.value)


@pytest.mark.parametrize(
    "name", ["robust_neo_hookean", "stable_neo_hookean", "fixed_corotated", "arap"]
)
def test_invertible_laws_recover_from_inverted_elements(comm, name):
    material = {
        "robust_neo_hookean": with_parameters(robust_neo_hookean, PARAMS),
        "stable_neo_hookean": with_parameters(stable_neo_hookean, PARAMS),
        "fixed_corotated": FixedCorotated(PARAMS),
        "arap": ARAP(PARAMS),
    }[name]
    problem = _pushed_cube(comm, material)
    assert problem.invertible
    assert problem.nonfinite_terms() == []  # finite energy in the inverted start state
    solver = hf.NewtonSolver(problem, min_jacobian=None)
    assert solver.min_J() < -0.1
    steps = hf.solve_quasistatic(solver)
    assert steps[-1].time == pytest.approx(1.0)
    assert all(s.rejected == 0 for s in steps)  # no cutback
    record = steps[-1].solve_records[-1]
    assert record.converged
    assert record.min_J > 0.3  # un-inverted
    # The prescribed compression was reached: the top moved down by 30 %.
    top = fem.locate_dofs_topological(problem.V.sub(2), 2, problem.domain.facets("top"))
    values = problem.u.x.array[top]
    local = np.abs(values + COMPRESSION).max(initial=0.0)
    assert comm.allreduce(local, op=MPI.MAX) < 1e-12
