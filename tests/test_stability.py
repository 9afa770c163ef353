"""Stability of states (issue 22): eigenvalues of the tangent, linearised buckling of an Euler column.

Analytic and independent checks first: the spectrum of the assembled tangent
against dense NumPy (the bc rows and columns removed; for the mixed problem
the Schur complement of the pressure/volume block), Euler's clamped-free load
:math:`\\pi^2 EI/(4L^2)` under mesh refinement, a column compressed past its
critical strain with exactly one negative eigenvalue. Regressions (the same
numbers on 1 and 2 ranks to 1e-8) second.
"""

import math

import numpy as np
import pytest
from mpi4py import MPI

import hyperfem as hf
from hyperfem.cases.column import ColumnSpec, column_domain
from hyperfem.cases.uniaxial import unit_cube
from hyperfem.errors import ParameterError
from hyperfem.materials.neo_hookean import neo_hookean, neo_hookean_isochoric
from hyperfem.problem import SplitEnergy
from hyperfem.problem.mixed import MixedHyperelasticProblem
from hyperfem.stability import TangentEigensolver, TangentPencil, lowest_eigenvalues
from hyperfem.stability.buckling import buckling_analysis, write_buckling_modes

SOFT = hf.materials.LameParameters.from_youngs(E=1.0, nu=0.3)
COLUMN = ColumnSpec()  # b = 1, h = 1.5, L = 20, E = 1, nu = 0.3


def _cube(comm, degree=1):
    """The unit cube (2 x 2 x 2 boxes) clamped on x = 0, at rest."""
    return hf.HyperelasticProblem(
        unit_cube(2, comm), lambda F: neo_hookean(F, SOFT), bcs=[hf.Clamp("x0")], degree=degree
    )


def _mixed_cube(comm):
    psi = SplitEnergy(lambda F: neo_hookean_isochoric(F, 1.0), 10.0)
    return MixedHyperelasticProblem(unit_cube(2, comm), psi, bcs=[hf.Clamp("x0")])


def _dense(A):
    return A.duplicate(copy=True).convert("dense").getDenseArray()  # convert() alone works in place


def _generalized_eigvalsh(K, B):
    """Eigenvalues of K x = lambda B x, B symmetric positive definite (NumPy only)."""
    Linv = np.linalg.inv(np.linalg.cholesky(B))
    return np.linalg.eigvalsh(Linv @ K @ Linv.T)


# Unit cube P1, E = 1, nu = 0.3, clamped on x = 0, at rest; serial (equal on 2 ranks to 1e-15).
CUBE_MASS_SPECTRUM = [0.6278487381955815, 0.7028952605991504, 1.8988267430272223, 2.894116044126759,
                      5.0856386547998165, 5.769647106799135]
CUBE_EUCLIDEAN_SPECTRUM = [0.01702390748111339, 0.02003074950585303, 0.03169013816140014, 0.07682071880440214,
                           0.09129641207662953, 0.09271509011216915]
# The mixed problem (P2/P1/P1, mu = 1, K = 10) on the same cube: the Schur complement's spectrum.
MIXED_MASS_SPECTRUM = [1.3889791002047696, 1.4031684963221724, 2.27278768558267, 7.962450513115064,
                       8.933840322958623]


@pytest.mark.serial
@pytest.mark.parametrize("metric", ["mass", "euclidean"])
def test_spectrum_at_rest_matches_dense_numpy(metric):
    """The 6 lowest eigenvalues equal NumPy's of the assembled tangent with the bc rows and columns removed."""
    problem = _cube(MPI.COMM_SELF)
    spectrum = lowest_eigenvalues(problem, 6, metric=metric)
    pencil = TangentPencil(problem, metric)
    K, B = _dense(pencil.K), _dense(pencil.B)
    free = np.flatnonzero(np.diag(B) != 0.0)
    assert len(free) == 3 * 18  # 27 nodes, 9 clamped
    if metric == "mass":
        reference = _generalized_eigvalsh(K[np.ix_(free, free)], B[np.ix_(free, free)])
    else:
        reference = np.linalg.eigvalsh(K[np.ix_(free, free)])
    np.testing.assert_allclose(spectrum.eigenvalues, reference[:6], rtol=1e-10)
    assert spectrum.stable and spectrum.negative == 0 and spectrum.negative_counted == "inertia"
    assert spectrum.converged >= 6 and spectrum.requested == 6 and spectrum.metric == metric
    pencil.destroy()


def test_spectrum_same_on_every_partition(comm):
    """1 and 2 ranks give the serial eigenvalues to 1e-8 (both metrics)."""
    problem = _cube(comm)
    for metric, expected in (("mass", CUBE_MASS_SPECTRUM), ("euclidean", CUBE_EUCLIDEAN_SPECTRUM)):
        spectrum = lowest_eigenvalues(problem, 6, metric=metric)
        np.testing.assert_allclose(spectrum.eigenvalues, expected, rtol=1e-8)
        assert spectrum.negative == 0 and spectrum.max_imaginary == 0.0


@pytest.mark.serial
def test_mixed_spectrum_is_the_schur_complement():
    """Mixed (u, p, theta): the eigenvalues are those of the displacement-reduced tangent S = K_uu - K_uq K_qq^-1 K_qu.

    The three-field tangent itself is indefinite, one negative eigenvalue per
    pressure dof (27 here); the stability count subtracts them (Haynsworth).
    """
    problem = _mixed_cube(MPI.COMM_SELF)
    spectrum = lowest_eigenvalues(problem, 5)
    pencil = TangentPencil(problem, "mass")
    K, B = _dense(pencil.K), _dense(pencil.B)
    free = np.flatnonzero(np.diag(B) != 0.0)
    q = np.setdiff1d(np.arange(len(K)), problem.field_dofs()["displacement"])
    S = K[np.ix_(free, free)] - K[np.ix_(free, q)] @ np.linalg.solve(K[np.ix_(q, q)], K[np.ix_(q, free)])
    reference = _generalized_eigvalsh(S, B[np.ix_(free, free)])
    np.testing.assert_allclose(spectrum.eigenvalues, reference[:5], rtol=1e-9)
    n_pressure = len(problem.field_dofs()["pressure"])
    assert int(np.sum(np.linalg.eigvalsh(K) < 0)) == n_pressure == pencil.constraint_negatives() == 27
    assert spectrum.negative == 0 and spectrum.stable
    pencil.destroy()


def test_mixed_spectrum_same_on_every_partition(comm):
    spectrum = lowest_eigenvalues(_mixed_cube(comm), 5)
    np.testing.assert_allclose(spectrum.eigenvalues, MIXED_MASS_SPECTRUM, rtol=1e-8)
    assert spectrum.negative == 0


def test_modes_are_normalised_displacements(comm):
    problem = _cube(comm)
    spectrum = lowest_eigenvalues(problem, 2, modes=True)
    assert len(spectrum.modes) == 2
    for mode in spectrum.modes:
        assert mode.function_space is problem.V
        nodal = np.linalg.norm(mode.x.array.reshape(-1, 3), axis=1)
        assert comm.allreduce(float(nodal.max(initial=0.0)), op=MPI.MAX) == pytest.approx(1.0)
    assert set(spectrum.as_dict()) >= {"eigenvalues", "negative", "stable", "converged"}


def _euler_column(comm, divisions, degree=2):
    domain = column_domain(COLUMN, divisions, comm)
    return hf.HyperelasticProblem(
        domain,
        lambda F: neo_hookean(F, COLUMN.lame),
        bcs=[hf.Clamp("bottom")],
        loads=[hf.DeadTraction("top", (0.0, 0.0, -COLUMN.euler_traction))],
        degree=degree,
    )


# Critical load factors (t = 1: Euler's load) of the P2 tetrahedral column, serial.
COLUMN_LOAD_FACTORS = {
    (1, 1, 10): (1.0175265938968057, 2.2850044821942097),
    (2, 2, 20): (1.0063771940893813, 2.262535098051554),
}


def test_euler_column_buckling_converges(comm):
    """Linearised buckling of a clamped-free Neo-Hookean column against pi^2 EI / (4 L^2).

    b x h x L = 1 x 1.5 x 20, E = 1, nu = 0.3, dead traction on the top face;
    P2 tetrahedra. Measured t_cr / Euler (serial and 2 ranks alike): 1.0175
    (1 x 1 x 10 boxes, 567 dofs), 1.0064 (2 x 2 x 20, 3,075 dofs); 1.0045
    (3 x 3 x 30), 1.0038 (4 x 4 x 40), and 1.0034 with P3 hexahedra: the
    continuum column sits 0.34 % above the beam formula (the clamp holds the
    Poisson contraction; 0.99953 with nu = 0). The second mode bends about the
    strong axis at 2.2625 (beam theory (h/b)^2 = 2.25).
    """
    errors = []
    for divisions, expected in COLUMN_LOAD_FACTORS.items():
        problem = _euler_column(comm, divisions)
        result = buckling_analysis(problem, 2)
        np.testing.assert_allclose(result.load_factors, expected, rtol=1e-8)
        errors.append(abs(result.critical_load_factor - 1.0))
        assert result.load_factors[1] / result.load_factors[0] == pytest.approx(COLUMN.mode_ratio, rel=0.02)
        # Mode 1 bends about the weak axis (along x), mode 2 about the strong one (along y).
        for mode, bends in zip(result.modes, (0, 1), strict=True):
            u = mode.x.array.reshape(-1, 3)
            largest = np.empty(3)
            comm.Allreduce(np.abs(u).max(axis=0, initial=0.0), largest, op=MPI.MAX)
            assert largest[bends] > 0.99 and largest[1 - bends] < 0.01  # 0.002: the tetrahedra are not symmetric
        assert problem.time == 0.0 and not np.any(problem.u.x.array)  # the reference state is restored
    assert errors[1] < errors[0] < 0.03 and errors[1] < 0.01


def test_mixed_column_buckling(comm):
    """The three-field column (P2/P1/P1, split Neo-Hookean of the same E, nu): the pencil's finite eigenvalues
    are the displacement-reduced ones. Measured t_cr / Euler 1.0122 (1 x 1 x 10 boxes; 1.0057 on 2 x 2 x 20),
    second mode 2.2741; no reversed-load multiplier among those found."""
    psi = SplitEnergy(lambda F: neo_hookean_isochoric(F, COLUMN.lame.mu), COLUMN.lame.bulk_modulus)
    problem = MixedHyperelasticProblem(
        column_domain(COLUMN, (1, 1, 10), comm), psi, bcs=[hf.Clamp("bottom")],
        loads=[hf.DeadTraction("top", (0.0, 0.0, -COLUMN.euler_traction))],
    )
    result = buckling_analysis(problem, 2)
    np.testing.assert_allclose(result.load_factors, [1.0121846409738562, 2.274052778839427], rtol=1e-7)
    assert result.reversed_multipliers == () and result.modes[0].function_space is not problem.W


def test_nonlinear_prestress_and_the_lowest_eigenvalue_agree(comm):
    """Three routes to the critical load of the coarse column (1 x 1 x 10 boxes, P2).

    Linear prestress 1.0175, Newton-solved prestress at t = 1: 1.0181; the
    lowest eigenvalue of the tangent along the loaded path (Newton at each t),
    extrapolated to zero through t = 0.9 and 0.95: 1.0189 (through 0.4 and 0.8:
    1.030, the eigenvalue is concave in t). Dead-load states beyond t = 1.02
    are out of reach: the unsymmetric tetrahedra act as an imperfection, and
    the column bends away.
    """
    problem = _euler_column(comm, (1, 1, 10))
    linear = buckling_analysis(problem, 1).critical_load_factor
    solver = hf.NewtonSolver(problem)
    nonlinear = buckling_analysis(problem, 1, prestress="nonlinear", solver=solver).critical_load_factor
    assert nonlinear == pytest.approx(1.0181321, rel=1e-6) and linear == pytest.approx(1.0175266, rel=1e-6)
    eigensolver = TangentEigensolver(problem, 1)
    lowest = []
    for t in (0.9, 0.95):
        problem.set_time(t)
        assert solver.solve().converged
        spectrum = eigensolver.solve()
        assert spectrum.stable and spectrum.time == t
        lowest.append(spectrum.lowest)
    t_zero = 0.95 + lowest[1] * 0.05 / (lowest[0] - lowest[1])
    assert t_zero == pytest.approx(nonlinear, rel=1e-3)


def _fixed_fixed_column(comm, factor, mixed=False):
    """The column clamped at both ends, its top pushed down by factor x the critical shortening, solved."""
    strain = 4 * math.pi**2 * (COLUMN.width**2 / 12) / COLUMN.length**2  # P = 4 pi^2 EI / L^2
    bcs = [hf.Clamp("bottom"), hf.PrescribedDisplacement("top", (0.0, 0.0, -factor * strain * COLUMN.length))]
    domain = column_domain(COLUMN, (1, 1, 10), comm)
    if mixed:
        psi = SplitEnergy(lambda F: neo_hookean_isochoric(F, COLUMN.lame.mu), COLUMN.lame.bulk_modulus)
        problem = MixedHyperelasticProblem(domain, psi, bcs=bcs)
    else:
        problem = hf.HyperelasticProblem(domain, lambda F: neo_hookean(F, COLUMN.lame), bcs=bcs, degree=2)
    problem.set_time(1.0)
    assert hf.NewtonSolver(problem).solve().converged
    return problem


@pytest.mark.parametrize("mixed", [False, True])
def test_column_compressed_past_buckling_is_unstable(comm, mixed):
    """Displacement control keeps the column straight past its critical strain: then one eigenvalue is negative.

    Half the critical shortening: stable; 1.5 times: exactly one negative
    eigenvalue (the weak-axis mode; the strong-axis one needs 2.25 times), from
    the inertia and among the computed eigenvalues alike. For the mixed
    problem the count is the Schur complement's (the three-field tangent has
    one more negative eigenvalue per pressure dof).
    """
    stable = lowest_eigenvalues(_fixed_fixed_column(comm, 0.5, mixed), 3)
    assert stable.stable and stable.lowest > 0.0
    unstable = lowest_eigenvalues(_fixed_fixed_column(comm, 1.5, mixed), 3)
    assert not unstable.stable and unstable.negative == 1
    assert unstable.lowest < 0.0 < unstable.eigenvalues[1]


def test_follower_load_spectrum_is_counted_from_the_eigenvalues(comm):
    """A follower traction makes the tangent non-symmetric: a general eigenproblem, no inertia."""
    problem = hf.HyperelasticProblem(
        unit_cube(2, comm), lambda F: neo_hookean(F, SOFT), bcs=[hf.Clamp("x0")],
        loads=[hf.FollowerPressure("x1", 0.05)],
    )
    problem.set_time(1.0)
    assert hf.NewtonSolver(problem).solve().converged
    spectrum = lowest_eigenvalues(problem, 3)
    assert spectrum.negative_counted == "computed" and spectrum.negative == 0
    assert len(spectrum.eigenvalues) == 3 and spectrum.lowest > 0.0


def test_buckling_modes_to_vtx(comm, shared_tmp):
    from hyperfem.io.results import vtx_steps

    result = buckling_analysis(_euler_column(comm, (1, 1, 10)), 2)
    path = write_buckling_modes(result, shared_tmp / "modes.bp")
    comm.Barrier()
    assert vtx_steps(path) == 2
    assert result.as_dict()["load_factors"] == list(result.load_factors)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda p: lowest_eigenvalues(p, 0), "lowest_eigenvalues: n must be an integer >= 1, got 0"),
        (lambda p: lowest_eigenvalues(p, 2.5), "lowest_eigenvalues: n must be an integer >= 1, got 2.5"),
        (lambda p: lowest_eigenvalues(p, True), "lowest_eigenvalues: n must be an integer >= 1, got True"),
        (lambda p: lowest_eigenvalues(p, metric="l2"), "metric must be one of mass, euclidean, got 'l2'"),
        (lambda p: TangentEigensolver(p, tol=0.0), "TangentEigensolver: tol must be a finite number > 0"),
        (lambda p: TangentEigensolver(p, tol=1.0), "TangentEigensolver: tol must be < 1, got 1.0"),
        (lambda p: TangentEigensolver(p, max_it=0), "TangentEigensolver: max_it must be an integer >= 1"),
        (lambda p: buckling_analysis(p, 0), "buckling_analysis: n must be an integer >= 1, got 0"),
        (lambda p: buckling_analysis(p, increment=0.0), "increment must be a finite nonzero number, got 0.0"),
        (lambda p: buckling_analysis(p, increment=math.nan), "increment must be a finite nonzero number, got nan"),
        (lambda p: buckling_analysis(p, prestress="exact"), "prestress must be one of linear, nonlinear"),
        (lambda p: buckling_analysis(p, solver=object()), "a solver is used with prestress='nonlinear' only"),
        (lambda p: buckling_analysis(p, prestress="nonlinear", solver=object()), "solver must be a NewtonSolver"),
    ],
)
def test_bad_input_is_one_line(comm, call, message):
    with pytest.raises(ParameterError) as info:
        call(_cube(comm))
    assert message in str(info.value) and "\n" not in str(info.value)


def test_free_rigid_motion_is_refused(comm):
    problem = hf.HyperelasticProblem(unit_cube(1, comm), lambda F: neo_hookean(F, SOFT))
    with pytest.raises(ParameterError, match="leave rigid-body motion free .*singular at every state"):
        lowest_eigenvalues(problem)
    with pytest.raises(ParameterError, match="^buckling_analysis: the Dirichlet conditions"):
        buckling_analysis(problem)
