r"""Mixed three-field formulation: Taylor tests of the tangent, equivalence, and locking.

Equivalence. For :math:`U = \frac{K}{2}(J-1)^2` the three-field form
:math:`\int\psi_\text{iso} + U(\theta) + p(J - \theta)` has the same solutions as
the u–p form :math:`\int\psi_\text{iso} + p(J-1) - p^2/(2K)` (eliminate
:math:`\theta = 1 + p/K` exactly in the common :math:`P_1` space): its solution makes
the u–p residual vanish.

Locking. In uniaxial stretch :math:`\ell` of an incompressible solid with free
lateral faces the lateral displacement per unit width is :math:`1/\sqrt\ell - 1`.
With symmetry rollers on a cube the exact deformation is homogeneous and
therefore *in* the P1 space, so P1 reproduces it too (first test: both
formulations, the compressible answer solved independently, tending to
:math:`1/\sqrt\ell - 1` as :math:`K/\mu` grows). Locking shows when the
solution is not homogeneous: a unit-section bar gripped (clamped) at one end
and stretched at the other. Far from the grip the section contracts
homogeneously, so the free-end lateral displacement must approach
:math:`1/\sqrt\ell - 1`; the Taylor–Hood discretisation does, while P1 on the
same mesh with :math:`K/\mu = 10^3` locks and contracts far too little.
"""

from __future__ import annotations

import math

import basix.ufl
import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.errors import ParameterError
from hyperfem.kinematics import isochoric_invariants
from hyperfem.loading import Activation
from hyperfem.materials.muscle import MuscleParameters, muscle_isochoric
from hyperfem.problem import MixedHyperelasticProblem, SplitEnergy, solid_problem

STEPS = 2e-3 / 2.0 ** np.arange(4)


def _box(L=1.0, w=1.0, n=(2, 2, 2)):
    mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([L, w, w])], list(n), dmesh.CellType.tetrahedron)
    return hf.Domain.from_locators(
        mesh,
        {
            "x0": lambda x: np.isclose(x[0], 0.0),
            "x1": lambda x: np.isclose(x[0], L),
            "y0": lambda x: np.isclose(x[1], 0.0),
            "z0": lambda x: np.isclose(x[2], 0.0),
        },
    )


def _neo_hookean(mu, K):
    return SplitEnergy(lambda F: 0.5 * mu * (isochoric_invariants(F)[0] - 3.0), K)


def _smooth(x, c):
    out = np.zeros((3, x.shape[1]))
    for i in range(3):
        out[i] = c[i, 0] * x[0] + c[i, 1] * x[1] ** 2 + c[i, 2] * np.sin(3 * x[0] + x[2]) + c[i, 3] * x[0] * x[1] * x[2]
    return out


def _taylor_remainders(problem, state: fem.Function, direction: fem.Function):
    """e1(h) = ||R(w + h dw) - R(w) - h K(w) dw|| for the steps in STEPS (no Dirichlet conditions)."""
    w = problem.u
    R_form, K_form = fem.form(problem.residual), fem.form(problem.jacobian)

    def residual():
        b = fpetsc.assemble_vector(R_form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    w.x.array[:] = state.x.array
    R0 = residual()
    A = fpetsc.assemble_matrix(K_form)
    A.assemble()
    dw = direction.x.petsc_vec.copy()
    Kdw = R0.duplicate()
    A.mult(dw, Kdw)
    errors = []
    for h in STEPS:
        w.x.array[:] = state.x.array + h * direction.x.array
        Rh = residual()
        Rh.axpy(-1.0, R0)
        Rh.axpy(-h, Kdw)
        errors.append(Rh.norm())
        Rh.destroy()
    for v in (R0, Kdw, dw):
        v.destroy()
    A.destroy()
    return np.array(errors)


def _assert_second_order(e):
    rates = np.log2(e[:-1] / e[1:])
    assert np.all(rates > 1.8), rates


@pytest.mark.parametrize("law", ["log", "simo_taylor"])
def test_taylor_mixed_muscle(law):
    """Mixed muscle energy (active, fibres at an angle): the tangent is the derivative of the residual."""
    domain = _box(n=(2, 1, 1))
    mesh = domain.mesh
    act = Activation(mesh, 0.6)
    p = MuscleParameters.muscle(K=60e4)
    a0 = ufl.as_vector([1 / math.sqrt(2), 1 / math.sqrt(2), 0.0])
    problem = MixedHyperelasticProblem(
        domain, SplitEnergy(lambda F: muscle_isochoric(F, a0, act.expr, p), p.K, law), degree=2, updaters=[act]
    )
    W = problem.W
    coeffs = np.random.default_rng(1).uniform(-0.15, 0.15, (3, 4))
    state, direction = fem.Function(W), fem.Function(W)
    Vu, Vp, Vt = W.sub(0).collapse(), W.sub(1).collapse(), W.sub(2).collapse()
    ustate, pstate, tstate = fem.Function(Vu[0]), fem.Function(Vp[0]), fem.Function(Vt[0])
    ustate.interpolate(lambda x: _smooth(x, coeffs))
    pstate.interpolate(lambda x: 2e4 * np.cos(x[0] + 2 * x[1]))
    tstate.interpolate(lambda x: 0.1 * np.sin(2 * x[0] - x[2]))  # theta - 1
    state.x.array[Vu[1]] = ustate.x.array
    state.x.array[Vp[1]] = pstate.x.array
    state.x.array[Vt[1]] = tstate.x.array
    ustate.interpolate(lambda x: _smooth(x, coeffs[::-1]))
    pstate.interpolate(lambda x: 1e4 * np.sin(x[2] + x[0]))
    tstate.interpolate(lambda x: 0.2 * np.cos(x[1] + x[0]))
    direction.x.array[Vu[1]] = ustate.x.array
    direction.x.array[Vp[1]] = pstate.x.array
    direction.x.array[Vt[1]] = tstate.x.array
    _assert_second_order(_taylor_remainders(problem, state, direction))


def test_taylor_displacement_muscle_p2():
    """Pure displacement P2 muscle problem (energy through solid_problem)."""
    domain = _box(n=(2, 1, 1))
    act = Activation(domain.mesh, 1.0)
    p = MuscleParameters.muscle()
    a0 = ufl.as_vector([0.0, 0.0, 1.0])
    problem = solid_problem(
        domain, SplitEnergy(lambda F: muscle_isochoric(F, a0, act.expr, p), p.K), formulation="displacement", degree=2
    )
    coeffs = np.random.default_rng(2).uniform(-0.15, 0.15, (3, 4))
    state, direction = fem.Function(problem.V), fem.Function(problem.V)
    state.interpolate(lambda x: _smooth(x, coeffs))
    direction.interpolate(lambda x: _smooth(x, coeffs[[1, 2, 0]]))
    _assert_second_order(_taylor_remainders(problem, state, direction))


def test_split_energy_validation():
    with pytest.raises(ParameterError, match="bulk_modulus"):
        SplitEnergy(lambda F: ufl.tr(F), 0.0)
    with pytest.raises(ParameterError, match="volumetric law"):
        SplitEnergy(lambda F: ufl.tr(F), 1.0, "cubic")
    with pytest.raises(ParameterError, match="formulation"):
        solid_problem(None, SplitEnergy(lambda F: ufl.tr(F), 1.0), formulation="enhanced")


@pytest.mark.parametrize("law", ["log", "quadratic", "simo_taylor"])
def test_mixed_energy_reduces_to_energy(law):
    """Pointwise, with theta = J the three-field density is the displacement energy for any p."""
    mesh = dmesh.create_unit_cube(MPI.COMM_WORLD, 1, 1, 1, dmesh.CellType.tetrahedron)
    F = ufl.as_matrix([[1.3, 0.1, 0.0], [0.05, 0.9, 0.2], [0.0, -0.1, 0.85]])
    m = SplitEnergy(_neo_hookean(1.0, 50.0).isochoric, 50.0, law)
    J = ufl.det(F)
    form = fem.form((m.mixed_energy(F, 7.0, J) - m.energy(F)) ** 2 * ufl.dx(domain=mesh))
    assert MPI.COMM_WORLD.allreduce(fem.assemble_scalar(form)) < 1e-24


def _gripped_bar(lam: float, L: float, w: float):
    """A bar clamped at x = 0 and stretched to lam * L at x = L, on symmetry rollers y = 0, z = 0."""
    domain = _box(L=L, w=w, n=(6, 1, 1))
    bcs = [
        hf.Clamp("x0"),
        hf.PrescribedDisplacement("x1", [(lam - 1.0) * L], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("z0", [0.0], components=[2]),
    ]
    return domain, bcs


def test_quadratic_law_is_the_up_form():
    """U = K/2 (J-1)^2: the three-field solution of the gripped bar solves the two-field u-p equations."""
    mu, K, lam, L, w = 1.0, 1e3, 1.2, 3.0, 0.5
    domain, bcs = _gripped_bar(lam, L, w)
    material = SplitEnergy(_neo_hookean(mu, K).isochoric, K, "quadratic")
    problem = solid_problem(domain, material, bcs=bcs)
    u_h, p_h = _stretch(problem, lam, L, 2), problem.pressure
    # theta = 1 + p/K exactly: both live in P1
    theta = problem.volume.x.array
    assert np.max(np.abs(theta - 1.0 - p_h.x.array / K), initial=0.0) < 1e-12

    mesh = domain.mesh
    cell = mesh.basix_cell()
    el_u = basix.ufl.element("Lagrange", cell, 2, shape=(3,))
    W = fem.functionspace(mesh, basix.ufl.mixed_element([el_u, basix.ufl.element("Lagrange", cell, 1)]))
    w_h = fem.Function(W)
    for i, field in enumerate((u_h, p_h)):
        V, dofs = W.sub(i).collapse()
        copy = fem.Function(V)
        copy.interpolate(field)
        w_h.x.array[dofs] = copy.x.array
    u, p = ufl.split(w_h)
    F = ufl.Identity(3) + ufl.grad(u)
    Pi = (material.isochoric(F) + p * (ufl.det(F) - 1.0) - p**2 / (2.0 * K)) * ufl.dx(
        metadata={"quadrature_degree": problem.quadrature_degree}
    )
    b = fpetsc.assemble_vector(fem.form(ufl.derivative(Pi, w_h, ufl.TestFunction(W))))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fixed = {"x0": (0, 1, 2), "x1": (0,), "y0": (1,), "z0": (2,)}
    owned = b.getLocalSize()
    for name, components in fixed.items():
        for c in components:
            dofs = fem.locate_dofs_topological(W.sub(0).sub(c), 2, domain.facets(name))
            b.array[dofs[dofs < owned]] = 0.0
    assert b.norm() < 1e-8
    b.destroy()


def _lateral_stretch_compressible(lam, mu, K):
    """Homogeneous F = diag(lam, s, s) with zero lateral stress: dW/ds = 0 by bisection.

    W = mu/2 (J^(-2/3)(lam^2 + 2 s^2) - 3) + K/2 ln^2 J; dW/ds is explicit.
    """

    def dWds(s):
        J = lam * s * s
        I1 = lam**2 + 2 * s**2
        return 0.5 * mu * (J ** (-2 / 3) * 4 * s - (2 / 3) * J ** (-2 / 3) * I1 * 2 / s) + K * math.log(J) * 2 / s

    lo, hi = 0.3, 1.2
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if dWds(mid) < 0 else (lo, mid)
    return 0.5 * (lo + hi)


def _value_at(u: fem.Function, point, component) -> float:
    """Displacement component at a dof located at ``point`` (global, any rank)."""
    x = u.function_space.tabulate_dof_coordinates()
    sel = np.all(np.isclose(x, point), axis=1)
    vals = u.x.array.reshape(-1, 3)[sel, component]
    comm = u.function_space.mesh.comm
    found = comm.allreduce(int(vals.size > 0))
    assert found > 0
    return comm.allreduce(float(vals.sum()) if vals.size else 0.0) / comm.allreduce(vals.size)


def _stretch(problem, lam, L, increments):
    solver = hf.NewtonSolver(problem)
    hf.solve_quasistatic(solver, stepping=hf.LoadStepping(initial_increment=1.0 / increments))
    return problem.update_fields()[0] if getattr(problem, "saddle_point", False) else problem.u


@pytest.mark.parametrize("K", [1e3, 1e4])
def test_uniaxial_cube_homogeneous(K):
    """Rollers: both formulations give the homogeneous answer; it tends to 1/sqrt(l) - 1 as K/mu grows."""
    mu, lam = 1.0, 1.5
    domain = _box()
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("z0", [0.0], components=[2]),
        hf.PrescribedDisplacement("x1", [lam - 1.0], components=[0]),
    ]
    s = _lateral_stretch_compressible(lam, mu, K)
    incompressible = 1 / math.sqrt(lam) - 1
    assert abs(s - 1 - incompressible) < 2.0 / K
    for formulation in ("displacement", "mixed"):
        problem = solid_problem(domain, _neo_hookean(mu, K), formulation=formulation, bcs=bcs)
        u = _stretch(problem, lam, 1.0, 2)
        assert _value_at(u, (1.0, 1.0, 1.0), 1) == pytest.approx(s - 1, abs=1e-8)


def test_locking_gripped_bar():
    """K/mu = 1e3, bar 3 x 1 x 1 (quarter model), gripped at x = 0, stretched to l = 1.2.

    Measured: three-field P2/P1/P1 free-end lateral displacement -0.0904 (exact
    homogeneous limit -0.0871, 3.8 %; the old two-field ln J form gave -0.0903);
    P1 on the same mesh -0.0293 (locked, a third of it).
    """
    mu, K, lam, L, w = 1.0, 1e3, 1.2, 3.0, 0.5
    domain, bcs = _gripped_bar(lam, L, w)
    exact = 1 / math.sqrt(lam) - 1
    results = {}
    for formulation in ("displacement", "mixed"):
        problem = solid_problem(domain, _neo_hookean(mu, K), formulation=formulation, bcs=bcs)
        u = _stretch(problem, lam, L, 2)
        results[formulation] = _value_at(u, (L, w, w), 1) / w
    assert results["mixed"] == pytest.approx(exact, rel=0.06)
    assert abs(results["displacement"]) < 0.5 * abs(exact)


def test_roundoff_reference_of_theta_and_of_a_time_step():
    """The round-off floor's identity vector h: REFERENCE_SCALE_FRACTION of the cell size in the displacement dofs,
    1 (theta = 1 + w) in the volume dofs; a time step of the three-field body (dynamics) gets the body's (it had h
    in every dof: an estimate 18 times lower, 2.8e-10 against 5.2e-9, for the uniaxial cube at K/mu = 1e8)."""
    import hyperfem.dynamics as dyn
    from hyperfem.cases.uniaxial import unit_cube
    from hyperfem.solver.roundoff import REFERENCE_SCALE_FRACTION, VOLUME_REFERENCE, reference_scale

    problem = MixedHyperelasticProblem(unit_cube(1), SplitEnergy(lambda F: 0.5 * (isochoric_invariants(F)[0] - 3.0),
                                                                 1e4))
    template = problem.u.x.petsc_vec
    h = reference_scale(problem, template).array
    owned = template.getLocalSize()
    fields = {k: v[v < owned] for k, v in problem.field_dofs().items()}
    np.testing.assert_allclose(h[fields["volume"]], VOLUME_REFERENCE)
    cell = math.sqrt(3.0)  # the largest bounding-box diagonal of the unit cube's tetrahedra
    np.testing.assert_allclose(h[fields["displacement"]], REFERENCE_SCALE_FRACTION * cell, rtol=1e-12)
    step = dyn.IncrementalProblem(problem, dyn.QuasiStatic())
    np.testing.assert_allclose(reference_scale(step, template).array, h, rtol=1e-15)
