"""The linear-solver layer: automatic choice, rigid-body near-nullspace, iterative = direct.

The iterative path (CG/GMRES + GAMG, or the p-multigrid from P2) is what large problems get; here it is
forced on small meshes (``threshold=0``) and compared with MUMPS LU on the
same problem: the Newton solutions agree to the nonlinear tolerance, serially
and on 2 ranks.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load, twist_load
from hyperfem.io import PointProbe
from hyperfem.kinematics import isochoric_invariants
from hyperfem.problem import SplitEnergy, solid_problem
from hyperfem.solver.inertia import negative_pivots
from hyperfem.solver.linear import (
    BLOCKED_TANGENT,
    DIRECT,
    DIRECT_THRESHOLD,
    MIXED_DIRECT_THRESHOLD,
    choose_linear_solver,
    describe,
    rigid_body_modes,
)

MESHES = Path(__file__).resolve().parent.parent / "meshes"


def _beam(load, degree=1):
    domain = hf.read_mesh(MESHES / "beam_h2.msh")
    params = CantileverSpec().lame
    return hf.HyperelasticProblem(
        domain, lambda F: hf.materials.neo_hookean(F, params), bcs=[hf.Clamp("clamped")], loads=[load], degree=degree
    )


def test_rigid_body_modes_are_the_tangent_kernel():
    """At the undeformed state (no Dirichlet rows) K r = 0 and r^T K r = 0 for all 6 modes; orthonormal."""
    problem = _beam(bend_load(), degree=2)
    A = fpetsc.assemble_matrix(fem.form(problem.jacobian))
    A.assemble()
    modes = rigid_body_modes(problem.V, A)
    assert len(modes) == 6
    scale = A.norm(PETSc.NormType.FROBENIUS)
    Kr = A.createVecLeft()
    for i, r in enumerate(modes):
        A.mult(r, Kr)
        assert Kr.norm() < 1e-10 * scale
        for j, s in enumerate(modes):
            assert r.dot(s) == pytest.approx(1.0 if i == j else 0.0, abs=1e-12)
    # ... and zero residual: a rigid translation/rotation of the unloaded body stores no energy
    problem.set_time(0.0)
    R = fem.form(problem.residual)
    for r in modes[:3]:  # translations are exact rigid motions at any amplitude
        problem.u.x.petsc_vec.array_w[:] = 0.3 * r.array_r
        problem.u.x.scatter_forward()
        b = fpetsc.assemble_vector(R)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        assert b.norm() < 1e-9 * scale


def test_rigid_body_modes_2d():
    mesh = dmesh.create_unit_square(MPI.COMM_WORLD, 3, 3)
    V = fem.functionspace(mesh, ("Lagrange", 1, (2,)))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    eps = ufl.sym(ufl.grad(u))
    A = fpetsc.assemble_matrix(fem.form(ufl.inner(eps, ufl.sym(ufl.grad(v))) * ufl.dx))
    A.assemble()
    modes = rigid_body_modes(V, A)
    assert len(modes) == 3
    Kr = A.createVecLeft()
    for r in modes:
        A.mult(r, Kr)
        assert Kr.norm() < 1e-12 * A.norm(PETSc.NormType.FROBENIUS)


def test_automatic_choice():
    small = _beam(bend_load())
    assert dict(choose_linear_solver(small).options) == DIRECT  # 1.1k unknowns < threshold
    assert small.u.function_space.dofmap.index_map.size_global * 3 < DIRECT_THRESHOLD
    bend = choose_linear_solver(small, threshold=0)
    assert bend.options["ksp_type"] == "cg" and bend.options["pc_type"] == "gamg" and bend.near_nullspace
    twist = choose_linear_solver(_beam(twist_load()), threshold=0)
    assert twist.options["ksp_type"] == "gmres"  # follower load: non-symmetric tangent
    mesh = dmesh.create_unit_cube(MPI.COMM_WORLD, 1, 1, 1)
    domain = hf.Domain.from_locators(mesh, {"x0": lambda x: np.isclose(x[0], 0.0)})
    mixed = solid_problem(domain, SplitEnergy(lambda F: 0.5 * (isochoric_invariants(F)[0] - 3.0), 1e3))
    assert dict(choose_linear_solver(mixed, threshold=0).options) == DIRECT  # below the mixed threshold: LU
    assert mixed.u.function_space.dofmap.index_map.size_global < MIXED_DIRECT_THRESHOLD
    split = choose_linear_solver(mixed, mixed_threshold=0)
    assert split.options["pc_type"] == "fieldsplit" and split.preconditioner_shift is not None and split.configure
    # P2 and up: the two-level p-multigrid, under CG, or GMRES with follower loads.
    p2 = choose_linear_solver(_beam(bend_load(), degree=2), threshold=0)
    assert describe(p2.options) == "cg+pmg" and p2.configure is not None
    p2_twist = choose_linear_solver(_beam(twist_load(), degree=2), threshold=0)
    assert describe(p2_twist.options) == "gmres+pmg" and p2_twist.configure is not None


def _p2_displacement(cell: str):
    """The P2 beam under the bend load (tetrahedra), or a P2 plane-strain strip bent by its end (triangles)."""
    if cell == "tetrahedron":
        return _beam(bend_load(), degree=2)
    mesh = dmesh.create_rectangle(MPI.COMM_WORLD, [[-5.0, -1.0], [5.0, 1.0]], [10, 3], dmesh.CellType.triangle)
    domain = hf.Domain.from_locators(
        mesh, {"clamped": lambda x: np.isclose(x[0], -5.0), "free_end": lambda x: np.isclose(x[0], 5.0)}
    )
    params = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
    bcs = [hf.Clamp("clamped"), hf.PrescribedDisplacement("free_end", [-1.0], components=[1])]
    return hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params), bcs=bcs, degree=2)


@pytest.mark.parametrize("cell", ["tetrahedron", "triangle"])
def test_p2_displacement_is_preconditioned_on_p1(cell):
    """The displacement problem of degree 2 on the iterative path: CG + the two-level p-multigrid of the mixed
    problem's displacement block (P1 Galerkin level, GAMG with the rigid-body modes), the solution LU's."""
    problem, solver, rec = _lu_then_iterative(lambda: _p2_displacement(cell), "threshold")
    assert rec.linear_solver == "cg+pmg"
    assert rec.linear_iterations < 100 * rec.iterations
    _assert_coarse_level_has_rigid_modes(solver.snes.getKSP().getPC().getPythonContext(), problem.domain.mesh)


def _lu_then_iterative(build, threshold: str):
    """Solve ``build()``'s problem at full load on LU, then on the iterative path (``threshold`` = 0): the same state
    to 1e-8 of its size. Returns the iterative run's problem, solver and record."""
    results = []
    for value in (10**12, 0):
        problem = build()
        solver = hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, **{threshold: value}))
        problem.set_time(1.0)
        rec = solver.solve(raise_on_failure=True)
        results.append(problem.u.x.array.copy())
    scale = MPI.COMM_WORLD.allreduce(float(np.abs(results[0]).max()), op=MPI.MAX)
    np.testing.assert_allclose(results[1], results[0], rtol=0, atol=1e-8 * scale)
    return problem, solver, rec


def _assert_coarse_level_has_rigid_modes(cycle, mesh) -> None:
    """The p-multigrid's coarse level: GAMG on the P1 operator (gdim x vertices, node blocks) with the rigid-body
    modes: its aggregates carry 6 (3D) or 3 (2D) vectors each, the block size of its next level (gdim with the
    translations alone)."""
    gdim = mesh.geometry.dim
    coarse = cycle._coarse.getPC()
    K1 = coarse.getOperators()[0]
    vertices = mesh.topology.index_map(0).size_global
    assert coarse.getType() == "gamg" and K1.getBlockSize() == gdim
    assert K1.getSize() == (gdim * vertices, gdim * vertices)
    assert coarse.getMGLevels() >= 2
    assert coarse.getMGSmoother(coarse.getMGLevels() - 2).getOperators()[0].getBlockSize() == 3 * (gdim - 1)


@pytest.mark.parametrize("load", [bend_load, twist_load], ids=["bend-cg", "twist-gmres"])
def test_iterative_equals_direct(load):
    results = []
    for threshold in (10**12, 0):
        problem = _beam(load())
        solver = hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, threshold=threshold))
        steps = hf.solve_quasistatic(solver)
        rec = steps[-1].solve
        assert rec.linear_solver == ("preonly+lu(mumps)" if threshold else f"{solver.options['ksp_type']}+gamg")
        assert rec.pc_setup_time >= 0.0
        if not threshold:
            assert rec.linear_iterations > rec.iterations  # Krylov iterations counted
        results.append(PointProbe(problem.domain.mesh, [TEST_POINT])(problem.u)[0])
    np.testing.assert_allclose(results[1], results[0], rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("load", [bend_load, twist_load], ids=["bend-cg", "twist-gmres"])
def test_blocked_tangent_equals_aij(load):
    """The iterative path assembles a BAIJ tangent, AMG gets an AIJ copy: same steps as an AIJ tangent."""
    results, types = [], []
    for kind in (BLOCKED_TANGENT, None):
        problem = _beam(load())
        linear = dataclasses.replace(choose_linear_solver(problem, threshold=0), matrix_kind=kind)
        solver = hf.NewtonSolver(problem, linear_solver=linear)
        steps = hf.solve_quasistatic(solver)
        A, P, _ = solver.snes.getJacobian()
        types.append((A.getType(), P.getType()))
        results.append(problem.u.x.array.copy())
        if kind is not None:  # the copy holds the tangent's values and rigid-body modes
            solver.snes.computeJacobian(solver.nonlinear_problem.x, A, P)  # outside SNES: the copy follows
            D = P.copy()
            D.axpy(-1.0, A.convert(PETSc.Mat.Type.AIJ, PETSc.Mat()))
            assert D.norm() <= 1e-14 * A.norm() and P.getNearNullSpace()
            pivots = negative_pivots(A)  # LDL^T of the blocked tangent through an AIJ copy
            assert pivots == negative_pivots(P) and A.getType().endswith("baij")
        assert len(steps) >= 1 and all(s.solve.converged for s in steps)
    assert types[0][0].endswith("baij") and types[0][1].endswith("aij") and not types[0][1].endswith("baij")
    assert types[1][0] == types[1][1] and not types[1][0].endswith("baij")
    scale = np.abs(results[1]).max()
    np.testing.assert_allclose(results[0], results[1], atol=1e-8 * scale)


@pytest.mark.parametrize("lag", [2, 3])
def test_the_copy_for_amg_is_made_only_when_the_hierarchy_is_rebuilt(lag, monkeypatch):
    """With a lagged preconditioner the AIJ copy is skipped at the iterations SNES reuses the hierarchy.

    It changes nothing: the same Newton and Krylov iterations and the same displacement as copying at every
    iteration (serially bit for bit; on 2 ranks GAMG's set-up differs between runs at round-off).
    """
    from hyperfem.solver.lag import PreconditionerLag, preconditioner_rebuilt
    from hyperfem.solver.linear import AIJPreconditioner

    assert [preconditioner_rebuilt(k, 3) for k in range(7)] == [True, False, False, True, False, False, True]
    assert all(preconditioner_rebuilt(k, 1) for k in range(4))
    assert [preconditioner_rebuilt(k, -1) for k in range(3)] == [True, False, False]
    copy = AIJPreconditioner.__call__
    calls: list[int] = []
    monkeypatch.setattr(AIJPreconditioner, "__call__", lambda self, A: calls.append(1) or copy(self, A))
    runs = []
    for always in (False, True):
        if always:
            monkeypatch.setattr(PreconditionerLag, "reused", property(lambda self: False))
        calls.clear()
        problem = _beam(bend_load())
        base = choose_linear_solver(problem, threshold=0)
        linear = dataclasses.replace(base, options={**base.options, "snes_lag_preconditioner": lag})
        solver = hf.NewtonSolver(problem, linear_solver=linear)
        problem.set_time(1.0)
        assert solver.solve(raise_on_failure=True).converged
        snes = solver.snes
        runs.append((snes.getIterationNumber(), snes.getLinearSolveIterations(), problem.u.x.array.copy(), len(calls)))
    (its, krylov, u, copies), (its_all, krylov_all, u_all, copies_all) = runs
    assert its >= 3 and its == its_all and abs(krylov - krylov_all) <= 2
    np.testing.assert_allclose(u, u_all, rtol=0, atol=1e-12 * np.abs(u_all).max())
    # a tangent at iterations 0 .. its-1; copied at the multiples of the lag only
    assert copies_all - copies == its - -(-its // lag)


def _lagged_run(lag: int, growth: float | None = None, monkeypatch=None):
    """The beam bent in one solve on the iterative path with ``snes_lag_preconditioner`` = ``lag``.

    Returns the solver, its Krylov iterations per Newton iteration, and the number of AIJ copies (the
    tangents at which SNES set the preconditioner up). ``growth`` replaces :data:`REBUILD_GROWTH` (and the
    slack is then 0).
    """
    import hyperfem.solver.lag as lag_module
    from hyperfem.solver.linear import AIJPreconditioner

    if growth is not None:
        monkeypatch.setattr(lag_module, "REBUILD_GROWTH", growth)
        monkeypatch.setattr(lag_module, "REBUILD_SLACK", 0)
    copies: list[int] = []
    copy = AIJPreconditioner.__call__
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(AIJPreconditioner, "__call__", lambda self, A: copies.append(1) or copy(self, A))
        problem = _beam(bend_load())
        base = choose_linear_solver(problem, threshold=0)
        linear = dataclasses.replace(base, options={**base.options, "snes_lag_preconditioner": lag})
        solver = hf.NewtonSolver(problem, linear_solver=linear)
        counts: list[int] = []
        ksp = solver.snes.getKSP()
        ksp.setMonitor(lambda _k, i, _r: counts.append(0) if i == 0 else counts.__setitem__(-1, i))
        problem.set_time(1.0)
        assert solver.solve(raise_on_failure=True).converged
    return solver, counts, len(copies)


def test_the_lagged_preconditioner_is_rebuilt_early_when_the_krylov_count_grows(monkeypatch):
    """A lagged preconditioner whose last Krylov solve took more than REBUILD_GROWTH times its first one's
    iterations (plus REBUILD_SLACK) is rebuilt at the next tangent: SNES itself sets it up again
    (``SNESSetLagPreconditioner`` through ``ctypes``), with the AIJ copy, and the Krylov iterations are those
    of a preconditioner rebuilt at every tangent. The bend's own counts (11-18 CG iterations on 28.6k unknowns
    with the first tangent's hierarchy) never trip the default rule: one set-up per solve."""
    from hyperfem.solver.lag import snes_lag

    solver, counts, copies = _lagged_run(10)
    assert len(counts) >= 3 and copies == 1 and solver._lag.early_rebuilds == 0
    assert snes_lag(solver.snes) == 10
    every, counts_every, copies_every = _lagged_run(1)
    assert copies_every == len(counts_every)
    # growth 0: every lagged tangent after the first solve counts as grown
    early, counts_early, copies_early = _lagged_run(10, growth=0.0, monkeypatch=monkeypatch)
    its = len(counts_early)
    assert its == len(counts_every) and copies_early == its and early._lag.early_rebuilds == its - 1
    if MPI.COMM_WORLD.size == 1:  # on 2 ranks GAMG's set-up differs between runs at round-off
        assert counts_early == counts_every
    assert snes_lag(early.snes) == 10  # the configured lag is back after each early rebuild


@pytest.mark.parametrize("lag", [1, 2, 10])
def test_a_lift_rebuilds_only_a_preconditioner_older_than_its_tangent(lag):
    """The predictor's lift solves with the preconditioner as SNES left it. Where SNES set it up at its last
    tangent, the lift's KSP sets it up again on the lift's own tangent, and a failed Krylov solve goes to LU at
    once; where SNES reused an older one there, the lift rebuilds it first. The beam's end is pulled down in 2
    steps; the second step's Krylov solves are cut to one iteration, so its lift fails either way and ends in
    LU. The answers equal the LU run's."""
    from hyperfem.solver.lag import preconditioner_rebuilt

    def run(options: dict | None):
        domain = hf.read_mesh(MESHES / "beam_h2.msh")
        bcs = [hf.Clamp("clamped"), hf.PrescribedDisplacement("free_end", [0.0, -1.0, 0.0])]
        problem = hf.HyperelasticProblem(
            domain, lambda F: hf.materials.neo_hookean(F, CantileverSpec().lame), bcs=bcs
        )
        linear = None
        if options is not None:
            base = choose_linear_solver(problem, threshold=0)
            linear = dataclasses.replace(base, options={**base.options, **options})
        solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10}, linear_solver=linear)
        problem.set_time(0.5)
        assert solver.solve().converged
        first = solver.snes.getIterationNumber()
        stale = solver._lag.reused
        predictor = solver._boundary_predictor
        before = predictor.preconditioner_rebuilds, predictor.direct_fallbacks
        ksp = solver.snes.getKSP()
        rtol, atol, divtol, _ = ksp.getTolerances()
        ksp.setTolerances(rtol=rtol, atol=atol, divtol=divtol, max_it=1)
        problem.set_time(1.0)
        assert solver.solve().converged
        after = predictor.preconditioner_rebuilds, predictor.direct_fallbacks
        return first, stale, (after[0] - before[0], after[1] - before[1]), problem.u.x.array.copy()

    _, _, _, u_lu = run(None)
    first, stale, (rebuilds, fallbacks), u = run({"snes_lag_preconditioner": lag})
    assert first >= 2 and stale == (not preconditioner_rebuilt(first - 1, lag))  # SNES's rule at its last tangent
    assert fallbacks == 1  # the lift
    assert rebuilds == (1 if stale else 0)
    np.testing.assert_allclose(u, u_lu, rtol=0, atol=1e-8 * np.abs(u_lu).max())


def test_iterative_prescribed_displacement_with_predictor():
    """The predictor's tangent solve goes through the same (iterative) KSP."""
    results = []
    for threshold in (10**12, 0):
        problem = hf.HyperelasticProblem(
            hf.read_mesh(MESHES / "beam_h2.msh"),
            lambda F: hf.materials.neo_hookean(F, CantileverSpec().lame),
            bcs=[hf.Clamp("clamped"), hf.PrescribedDisplacement("free_end", [-1.0], components=[1])],
        )
        solver = hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, threshold=threshold))
        steps = hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=0.5))
        assert steps[0].solve.predictor
        results.append(problem.u.x.array.copy())
    np.testing.assert_allclose(results[1], results[0], atol=1e-9)


def test_iterative_equals_direct_dynamic_step():
    """A Newmark step (mass-augmented tangent, CG + GAMG) equals the MUMPS step."""
    from hyperfem import dynamics as dyn

    results = []
    for threshold in (10**12, 0):
        base = _beam(bend_load())
        problem = dyn.IncrementalProblem(base, dyn.Newmark(), dyn.MassDensity(CantileverSpec().rho))
        assert choose_linear_solver(problem, threshold=0).options["ksp_type"] == "cg"
        solver = hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, threshold=threshold))
        problem.initial_acceleration()
        dyn.integrate(problem, solver, dyn.TimeStepping(dt=0.05, t_end=0.1, adaptive=False))
        results.append(problem.u.x.array.copy())
    scale = MPI.COMM_WORLD.allreduce(float(np.abs(results[0]).max()), op=MPI.MAX)
    np.testing.assert_allclose(results[1], results[0], rtol=0, atol=1e-9 * scale)  # measured 7e-12 * scale


# -- the mixed (u, p, theta) problem: Schur field split -----------------------------------------

MU, BULK = 3.0e5, 1.0e9 / 3.0  # nearly incompressible: K / mu ~ 1e3


def _mixed_beam(loads=(), bcs=None):
    box = [[-5.0, -2.0, -2.0], [5.0, 2.0, 2.0]]
    mesh = dmesh.create_box(MPI.COMM_WORLD, box, [4, 2, 2], dmesh.CellType.tetrahedron)
    domain = hf.Domain.from_locators(
        mesh, {"clamped": lambda x: np.isclose(x[0], -5.0), "free_end": lambda x: np.isclose(x[0], 5.0)}
    )
    material = SplitEnergy(lambda F: 0.5 * MU * (isochoric_invariants(F)[0] - 3.0), BULK)
    return solid_problem(domain, material, bcs=bcs or [hf.Clamp("clamped")], loads=list(loads))


def test_reference_shear_modulus_is_the_linearised_one():
    """2 mu of the isochoric energy from its deviatoric second derivative at F = I (Mooney-Rivlin: 2(c1 + c2))."""
    problem = _mixed_beam()
    assert problem.reference_shear_moduli()[None] == pytest.approx(MU, rel=1e-12)
    c1, c2 = 2.0, 0.5
    mr = solid_problem(
        problem.domain,
        SplitEnergy(lambda F: c1 * (isochoric_invariants(F)[0] - 3.0) + c2 * (isochoric_invariants(F)[1] - 3.0), 1e3),
    )
    assert mr.reference_shear_moduli()[None] == pytest.approx(2.0 * (c1 + c2), rel=1e-12)


@pytest.mark.parametrize("drive", ["traction", "displacement"])
def test_mixed_fieldsplit_equals_direct(drive):
    """FGMRES + Schur field split gives the LU solution (dead traction; prescribed displacement via the predictor)."""
    results = []
    for threshold in (10**12, 0):
        if drive == "traction":
            problem = _mixed_beam(loads=[bend_load()])
        else:
            problem = _mixed_beam(
                bcs=[hf.Clamp("clamped"), hf.PrescribedDisplacement("free_end", [-1.0], components=[1])]
            )
        solver = hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, mixed_threshold=threshold))
        problem.set_time(1.0)
        rec = solver.solve(raise_on_failure=True)
        assert rec.linear_solver == ("preonly+lu(mumps)" if threshold else "fgmres+fieldsplit")
        if not threshold:
            # a good Schur approximation: tens of Krylov iterations per Newton step, not hundreds
            assert rec.linear_iterations < 150 * rec.iterations
            u_block = solver.snes.getKSP().getPC().getFieldSplitSubKSP()[0].getOperators()[0]
            assert u_block.getBlockSize() == 3  # node blocks: GAMG aggregates nodes
        results.append(problem.u.x.array.copy())
    scale = MPI.COMM_WORLD.allreduce(float(np.abs(results[0]).max()), op=MPI.MAX)
    np.testing.assert_allclose(results[1], results[0], rtol=0, atol=1e-8 * scale)


def _mixed_block(cell: str):
    """A nearly incompressible P2/P1/P1 block pulled down at its free end (tets, hexahedra, or triangles in 2D)."""
    comm = MPI.COMM_WORLD
    if cell == "triangle":
        mesh = dmesh.create_rectangle(comm, [[-5.0, -2.0], [5.0, 2.0]], [8, 3], dmesh.CellType.triangle)
    else:
        box = [[-5.0, -2.0, -2.0], [5.0, 2.0, 2.0]]
        mesh = dmesh.create_box(comm, box, [4, 2, 2], getattr(dmesh.CellType, cell))
    domain = hf.Domain.from_locators(
        mesh, {"clamped": lambda x: np.isclose(x[0], -5.0), "free_end": lambda x: np.isclose(x[0], 5.0)}
    )
    material = SplitEnergy(lambda F: 0.5 * MU * (isochoric_invariants(F)[0] - 3.0), BULK)
    bcs = [hf.Clamp("clamped"), hf.PrescribedDisplacement("free_end", [-1.0], components=[1])]
    return solid_problem(domain, material, bcs=bcs)


@pytest.mark.parametrize("cell", ["tetrahedron", "hexahedron", "triangle"])
def test_mixed_displacement_block_is_preconditioned_on_p1(cell):
    """The split's displacement block: a two-level p-multigrid whose coarse level is the P1 displacement on the same
    mesh (Galerkin operator in node blocks, rigid-body modes from the P1 coordinates); the solution is LU's."""
    problem, solver, rec = _lu_then_iterative(lambda: _mixed_block(cell), "mixed_threshold")
    assert rec.linear_solver == "fgmres+fieldsplit"
    assert rec.linear_iterations < 150 * rec.iterations
    mesh = problem.domain.mesh
    gdim = mesh.geometry.dim
    split = solver.snes.getKSP().getPC()
    pc = split.getFieldSplitSubKSP()[0].getPC()
    assert pc.getType() == "python"
    cycle = pc.getPythonContext()
    _assert_coarse_level_has_rigid_modes(cycle, mesh)
    # The interpolation's rows follow the split's displacement index set: P maps the P1 field x to x at each dof.
    P = cycle._P
    V, to_mixed = problem.W.sub(0).collapse()
    owned = V.dofmap.index_map.size_local * gdim
    X1 = fem.functionspace(mesh, ("Lagrange", 1, (gdim,))).tabulate_dof_coordinates()
    coords = P.createVecRight()
    coords.array_w[:] = X1[: len(coords.array_r) // gdim, :gdim].reshape(-1)
    fine = P * coords
    W = problem.W
    u_set = split.getFieldSplitSubIS("u").getIndices() - W.dofmap.index_map.local_range[0] * W.dofmap.index_map_bs
    to_mixed = np.asarray(to_mixed).reshape(-1)  # collapsed (unrolled) -> mixed local dof
    collapsed = np.argsort(to_mixed)[np.searchsorted(to_mixed, u_set, sorter=np.argsort(to_mixed))]
    assert np.all(collapsed < owned)
    expected = V.tabulate_dof_coordinates()[collapsed // gdim, collapsed % gdim]
    np.testing.assert_allclose(fine.array_r, expected, atol=1e-12)


def test_mixed_displacement_block_takes_a_users_preconditioner():
    """Options that replace the p-multigrid (GAMG on the P2 block directly: only its type, or the split's earlier
    settings :data:`GAMG_U`) are taken as they are, same solution."""
    from hyperfem.solver.pmultigrid import GAMG_U

    results = []
    for kind, options in (("python", {}), ("gamg", {"fieldsplit_u_pc_type": "gamg"}), ("gamg", GAMG_U)):
        problem = _mixed_block("tetrahedron")
        linear = choose_linear_solver(problem, mixed_threshold=0)
        solver = hf.NewtonSolver(problem, linear_solver=linear, petsc_options=options)
        problem.set_time(1.0)
        solver.solve(raise_on_failure=True)
        assert solver.snes.getKSP().getPC().getFieldSplitSubKSP()[0].getPC().getType() == kind
        results.append(problem.u.x.array.copy())
    scale = MPI.COMM_WORLD.allreduce(float(np.abs(results[0]).max()), op=MPI.MAX)
    for other in results[1:]:
        np.testing.assert_allclose(other, results[0], rtol=0, atol=1e-8 * scale)


def test_a_mixed_lift_that_fails_keeps_its_field_split(monkeypatch):
    """A failed Krylov lift on the lagged field split is solved again with the preconditioner rebuilt, not reset:
    ``PC.reset()`` dropped the split's index sets and the next solve raised PETSc's "must have at least two
    fields". Here every Krylov solve stops after one iteration, so the lift ends on LU, and Newton too. The lift
    is the first solve's, so the preconditioner is marked as one SNES reused at its last tangent (the state in
    which a lift rebuilds it)."""
    from hyperfem.solver.lag import PreconditionerLag

    monkeypatch.setattr(PreconditionerLag, "reused", property(lambda self: True))
    results = []
    for threshold in (10**12, 0):
        problem = _mixed_block("tetrahedron")
        solver = hf.NewtonSolver(
            problem, linear_solver=choose_linear_solver(problem, mixed_threshold=threshold),
            petsc_options={"ksp_max_it": 1} if threshold == 0 else None,
        )
        problem.set_time(1.0)
        solver.solve(raise_on_failure=True)
        results.append(problem.u.x.array.copy())
    predictor = solver._boundary_predictor
    assert predictor.preconditioner_rebuilds == 1 and predictor.direct_fallbacks == 1
    assert solver.snes.getKSP().getPC().getType() == "fieldsplit"
    scale = MPI.COMM_WORLD.allreduce(float(np.abs(results[0]).max()), op=MPI.MAX)
    np.testing.assert_allclose(results[1], results[0], rtol=0, atol=1e-8 * scale)


def test_mixed_fieldsplit_dynamic_step():
    """A backward-Euler step of the mixed problem (mass in the displacement block) with the field split equals LU."""
    from hyperfem import dynamics as dyn

    results = []
    for threshold in (10**12, 0):
        problem = dyn.IncrementalProblem(
            _mixed_beam(loads=[bend_load()]), dyn.BackwardEuler(), dyn.MassDensity(CantileverSpec().rho)
        )
        solver = hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, mixed_threshold=threshold))
        dyn.integrate(problem, solver, dyn.TimeStepping(dt=0.05, t_end=0.1, adaptive=False))
        results.append(problem.u.x.array.copy())
    scale = MPI.COMM_WORLD.allreduce(float(np.abs(results[0]).max()), op=MPI.MAX)
    np.testing.assert_allclose(results[1], results[0], rtol=0, atol=1e-8 * scale)


def test_pc_setup_timing_never_waits_for_ranks_outside_the_solve(monkeypatch):
    """Starting PETSc's log is collective over PETSC_COMM_WORLD: a first solve on rank 0 alone (``COMM_SELF``, the
    other rank elsewhere) must not start it (it hung there); it reads 0 until a call on all ranks starts it."""
    from hyperfem.solver import linear

    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("needs a rank outside COMM_SELF: mpiexec -n 2")
    monkeypatch.setattr(linear, "_PC_SETUP_EVENTS", None)
    if comm.rank == 0:
        assert linear.pc_setup_seconds(MPI.COMM_SELF) == 0.0 and linear._PC_SETUP_EVENTS is None
    comm.Barrier()
    assert linear.pc_setup_seconds(comm) >= 0.0 and linear._PC_SETUP_EVENTS is not None
