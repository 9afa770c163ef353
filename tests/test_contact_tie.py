r"""Gluing (tied contact, issue 19, seed 003 §6.2): :class:`~hyperfem.contact.TieContact`.

* A conforming split bar: the bar :math:`[0, 2]\times[0, 1]^2` as two halves of
  one mesh whose nodes are duplicated at :math:`x = 1`, glued there, pulled
  and bent at the free end: the reaction equals the merged mesh's (the same
  tetrahedra, shared nodes) to 1e-8.
* The patch test with non-matching meshes: two cubes (``stacked_blocks_mesh``)
  glued across the gap and pulled apart by 20 %: homogeneous uniaxial
  tension, the reaction equal to the closed form :math:`P_{zz}(1.1)` to 1e-7
  and to the tie's force; a one-pass tie would miss it by 0.22 % (module
  docstring of :mod:`hyperfem.contact.tie`).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

import basix.ufl
import ufl

import hyperfem as hf
from dolfinx import mesh as dmesh
from hyperfem.contact import TieContact
from hyperfem.errors import ParameterError, UnknownGroupError
from hyperfem.simulation.reactions import ReactionForce

PARAMS = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
TIGHT = {"snes_rtol": 1e-10, "snes_atol": 1e-7}  # the penalty's round-off floor of |r| is ~3e-8 here
N = 2
PULL = [0.1, 0.0, 0.2]  # the free end pulled along the bar and bent


def _split_bar(comm) -> hf.Domain:
    """Two halves of the bar, N x N x N boxes each, one mesh, their nodes at x = 1 duplicated (module docstring)."""
    parts = []
    for x0 in (0.0, 1.0):
        half = dmesh.create_box(MPI.COMM_SELF, [np.array([x0, 0.0, 0.0]), np.array([x0 + 1.0, 1.0, 1.0])], [N, N, N])
        dofmap = half.geometry.dofmaps[0] if hasattr(half.geometry, "dofmaps") else half.geometry.dofmap
        parts.append((half.geometry.x.copy(), np.asarray(dofmap).copy()))
    if comm.rank == 0:
        x = np.vstack([parts[0][0], parts[1][0]])
        cells = np.vstack([parts[0][1], parts[1][1] + len(parts[0][0])]).astype(np.int64)
    else:
        x, cells = np.zeros((0, 3)), np.zeros((0, 4), dtype=np.int64)
    element = ufl.Mesh(basix.ufl.element("Lagrange", "tetrahedron", 1, shape=(3,)))
    mesh = dmesh.create_mesh(comm, cells, element, x)
    mesh.topology.create_connectivity(2, 3)
    facets = dmesh.exterior_facet_indices(mesh.topology)
    f2c = mesh.topology.connectivity(2, 3)
    middle = dmesh.compute_midpoints(mesh, 2, facets)[:, 0]
    cell_middle = dmesh.compute_midpoints(mesh, 3, np.array([f2c.links(f)[0] for f in facets], dtype=np.int32))[:, 0]
    values = np.full(len(facets), 5, dtype=np.int32)
    values[np.isclose(middle, 0.0)] = 1
    values[np.isclose(middle, 2.0)] = 2
    values[np.isclose(middle, 1.0) & (cell_middle < 1.0)] = 3
    values[np.isclose(middle, 1.0) & (cell_middle > 1.0)] = 4
    facet_tags = dmesh.meshtags(mesh, 2, facets, values)
    ncells = mesh.topology.index_map(3).size_local + mesh.topology.index_map(3).num_ghosts
    cells_all = np.arange(ncells, dtype=np.int32)
    regions = np.where(dmesh.compute_midpoints(mesh, 3, cells_all)[:, 0] < 1.0, 1, 2).astype(np.int32)
    cell_tags = dmesh.meshtags(mesh, 3, cells_all, regions)
    groups = {"left_end": 1, "right_end": 2, "left_cut": 3, "right_cut": 4, "sides": 5}
    return hf.Domain(mesh, cell_tags, facet_tags, {"left": 1, "right": 2}, groups, source="split bar")


def _pulled(domain: hf.Domain, tie: TieContact | None):
    bcs = [hf.PrescribedDisplacement("left_end", [0.0, 0.0, 0.0]), hf.PrescribedDisplacement("right_end", PULL)]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)
    energies = [] if tie is None else [tie.bind(problem)]
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=energies)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    return problem, energies


def test_glued_conforming_split_bar_equals_the_merged_mesh():
    """The glued halves carry the reaction of the one-piece bar to 1e-8 (the same tetrahedra); the cut stays shut."""
    comm = MPI.COMM_WORLD
    glued, (tie,) = _pulled(_split_bar(comm), TieContact("right_cut", "left_cut"))
    merged_mesh = dmesh.create_box(comm, [np.zeros(3), np.array([2.0, 1.0, 1.0])], [2 * N, N, N])
    ends = {"left_end": lambda x: np.isclose(x[0], 0.0), "right_end": lambda x: np.isclose(x[0], 2.0)}
    merged, _ = _pulled(hf.Domain.from_locators(merged_mesh, ends, source="bar"), None)
    reaction = ReactionForce(merged, "right_end")()
    assert ReactionForce(glued, "right_end")() == pytest.approx(reaction, rel=1e-8, abs=1e-8 * np.abs(reaction).max())
    # The left half pulls the right one as the support pulls the left one: the force on the cut = the reaction there.
    assert tie.force() == pytest.approx(ReactionForce(glued, "left_end")(), rel=1e-6, abs=1e-6 * abs(reaction[0]))
    assert tie.max_gap() < 1e-8 * np.linalg.norm(PULL)


def _stacked_tension(comm, tie_groups=("upper_bottom", "lower_top"), degree=1, cell="tetrahedron", h=(0.5, 0.34)):
    domain = hf.mesh.stacked_blocks_mesh(*h, 5e-4, comm=comm, cell=cell)
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("lower_bottom", [0.0], components=[2]),
        hf.PrescribedDisplacement("upper_top", [0.2], components=[2]),
    ]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs, degree=degree)
    tie = TieContact(*tie_groups).bind(problem)
    solver = hf.NewtonSolver(problem, TIGHT, external_energies=[tie])
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.5, max_increment=0.5))
    return problem, tie


def _uniaxial_pzz(stretch: float) -> float:
    from scipy.optimize import brentq

    mu, lam = PARAMS.mu, PARAMS.lmbda
    lt = brentq(lambda s: mu * s + (lam * np.log(stretch * s * s) - mu) / s, 0.3, 2.0)
    return mu * stretch + (lam * np.log(stretch * lt * lt) - mu) / stretch


def test_glued_non_matching_blocks_pass_the_patch_test():
    """Two cubes of non-matching meshes glued and pulled 20 %: P_zz(1.1) of uniaxial tension to 1e-7."""
    problem, tie = _stacked_tension(MPI.COMM_WORLD)
    reaction = ReactionForce(problem, "upper_top")()
    assert reaction[2] == pytest.approx(_uniaxial_pzz(1.1), rel=1e-7)
    assert tie.force()[2] == pytest.approx(-reaction[2], rel=1e-7)
    assert tie.max_gap() < 1e-8


@pytest.mark.parametrize(
    ("cell", "degree", "h"),
    [("tetrahedron", 2, (1.0, 0.6)), ("hexahedron", 1, (1 / 3, 1 / 2)), ("hexahedron", 2, (0.5, 1.0))],
)
def test_glued_curved_and_bilinear_faces_pass_the_patch_test(cell, degree, h):
    """P2 tetrahedra, Q1 and Q2 hexahedra glued through the collision proxy and pulled 20 %: P_zz(1.1) to 1e-7
    (measured 2e-10 to 6e-10; on the nodes alone 0.43 %, 0.074 % and 3.7 % off, hyperfem.contact.tie)."""
    problem, tie = _stacked_tension(MPI.COMM_WORLD, degree=degree, cell=cell, h=h)
    assert tie.surface.proxy_map is not None
    reaction = ReactionForce(problem, "upper_top")()
    assert reaction[2] == pytest.approx(_uniaxial_pzz(1.1), rel=1e-7)
    assert tie.force()[2] == pytest.approx(-reaction[2], rel=1e-6)  # 1.1e-7 on 2 ranks: the penalty's k|BU| at rtol
    assert tie.max_gap() < 1e-8


def _tension_state(comm) -> tuple[float, float]:
    problem, tie = _stacked_tension(comm)
    return float(ReactionForce(problem, "upper_top")()[2]), float(problem.u.x.petsc_vec.norm())


def test_tie_one_rank_equals_two_ranks():
    """The glued blocks on 2 ranks equal 1 rank to 1e-10: reaction and displacement norm.

    (The tie's own force, k times gaps of 1e-10, is set only to ~1e-8 by round-off in the gaps.)
    """
    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")
    one = _tension_state(MPI.COMM_SELF) if comm.rank == 0 else None
    one = comm.bcast(one, root=0)
    assert _tension_state(comm) == pytest.approx(one, rel=1e-10)


def test_bad_ties_are_one_line():
    """Groups that do not face each other, an unknown group, the same group twice, a bad stiffness: one line."""
    domain = hf.mesh.stacked_blocks_mesh(0.5, 0.5, 5e-4)
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, PARAMS))
    with pytest.raises(ParameterError, match=r"the point of 'upper_top' at \(.*\) is .* from 'lower_top'.*do not face"):
        TieContact("upper_top", "lower_top").bind(problem)
    with pytest.raises(UnknownGroupError, match="available:.*lower_top"):
        TieContact("upper_botom", "lower_top").bind(problem)
    with pytest.raises(ParameterError, match="must be different"):
        TieContact("lower_top", "lower_top")
    with pytest.raises(ParameterError, match="stiffness must be"):
        TieContact("upper_bottom", "lower_top", stiffness=0.0)


def test_generalized_alpha_interpolates_the_tie_force():
    r"""Under generalized-:math:`\alpha` the tie force is taken between the step's ends like the internal forces
    (:mod:`hyperfem.contact.tie`): the light split bar pulled over :math:`t \in [0, 1]` in 10 steps
    (:math:`\rho_\infty = 0.8`) ends with the quasi-static tie force within 1 % (measured +0.14 %; with the tie
    force at :math:`u_{n+1}` alone -4.4 %, :math:`\alpha_f` times a step's pull behind) and the cut shut. The
    reaction at the pulled end is that of :math:`u_{n+1}` (of the body's own problem, not the step's energy at
    :math:`u_{n+1-\alpha_f}`): within 1 % of the quasi-static one (measured -0.34 %; the step's energy gave -4.4 %)."""
    from hyperfem import dynamics as dyn
    from hyperfem.simulation import Simulation

    comm = MPI.COMM_WORLD
    static_problem, (static,) = _pulled(_split_bar(comm), TieContact("right_cut", "left_cut"))
    bcs = [hf.PrescribedDisplacement("left_end", [0.0, 0.0, 0.0]), hf.PrescribedDisplacement("right_end", PULL)]
    base = hf.HyperelasticProblem(_split_bar(comm), lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=bcs)
    problem = dyn.IncrementalProblem(base, dyn.GeneralizedAlpha(rho_inf=0.8), dyn.MassDensity(1e-4))
    tie = TieContact("right_cut", "left_cut").bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10, "snes_atol": 1e-7}, external_energies=[tie])
    summary = Simulation(problem, solver, dyn.TimeStepping(dt=0.1, t_end=1.0), []).run()
    assert summary["completed"] and summary["rejected"] == 0
    assert tie.force()[0] == pytest.approx(static.force()[0], rel=1e-2)
    assert tie.max_gap() < 1e-8 * np.linalg.norm(PULL)
    reaction = ReactionForce(problem, "right_end")()
    np.testing.assert_array_equal(reaction, ReactionForce(base, "right_end")())
    assert reaction[0] == pytest.approx(ReactionForce(static_problem, "right_end")()[0], rel=1e-2)
