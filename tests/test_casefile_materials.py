"""The polar-rotation laws of a case file, run: ``fixed_corotated``, ``arap``, ``corotational_linear``.

Each case runs in process through the path of ``hyperfem run``
(:func:`hyperfem.app.main.dispatch`), and its ``--print-python`` script,
executed, gives the same reactions and probe displacements. The deformations
are homogeneous, so P1 holds them exactly and the reactions equal the closed
forms of the law (first Piola stress times the reference area) up to the
Newton tolerance:

* uniaxial stretch and compression of a 2 x 1 x 1 box on rollers (the
  faces x = 0, y = 0, z = 0 slide, the face x = 2 is pulled, y = 1 and z = 1
  are free): :math:`F = \\operatorname{diag}(a, b, b)` with the lateral
  stretch :math:`b` from :math:`P_{22} = 0` (bisection);
* confined compression (every face on rollers): :math:`F = \\operatorname{diag}(a, 1, 1)`,
  which also checks the lateral stress :math:`P_{22} = \\lambda (J - 1) J`;
* a rotated stretch of the beam (both ends prescribed as rigid rotations
  about different centres, so that :math:`x = Q D X`): the end force turns
  with the body, :math:`Q\\,P(D) N A`. For ``corotational_linear`` the
  rotation :math:`R^n` is that of the start of each step (the updater), so the
  rotation is ramped in and then held: once :math:`R^n` has caught up with the
  body the result is that of the rotated small-strain law, where small-strain
  elasticity alone is far off.

The NumPy stresses are checked against central differences of the energies
first. ``output.fields = ["von_mises"]`` with these laws gives the exact
stress in every cell, on P1 (rotation at the cell's one quadrature point) and
on P2 (rotation at quadrature points: the cell average on their rule).

Runs serially and under ``mpiexec -n 2``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from hyperfem.app.main import dispatch

E, NU = 1.0e6, 0.3
MU, LMBDA = E / (2.0 * (1.0 + NU)), E * NU / ((1.0 + NU) * (1.0 - 2.0 * NU))
BOX = (2.0, 1.0, 1.0)  # [0, 2] x [0, 1] x [0, 1]
FACES = ("x0", "x1", "y0", "y1", "z0", "z1")


# -- closed forms (NumPy) -------------------------------------------------------------------------
def _polar_rotation(F: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(F)
    R = U @ Vt
    assert np.linalg.det(R) > 0  # no inversion in these tests
    return R


def fixed_corotated_P(F: np.ndarray, mu: float, lmbda: float) -> np.ndarray:
    """:math:`P = 2\\mu(F - R) + \\lambda (J - 1) J F^{-T}`.

    Of :math:`\\psi = \\mu\\|F - R\\|^2 + \\lambda/2 (J - 1)^2` (:mod:`hyperfem.materials.fixed_corotated`).
    """
    J = np.linalg.det(F)
    return 2.0 * mu * (F - _polar_rotation(F)) + lmbda * (J - 1.0) * J * np.linalg.inv(F).T


def arap_P(F: np.ndarray, mu: float) -> np.ndarray:
    """:math:`P = 2\\mu(F - R)` of :math:`\\psi = \\mu\\|F - R\\|^2`."""
    return 2.0 * mu * (F - _polar_rotation(F))


def corotational_linear_P(F: np.ndarray, R: np.ndarray, mu: float, lmbda: float) -> np.ndarray:
    """:math:`P = R\\,\\sigma_\\text{lin}(R^T F)` for the rotation ``R`` of the step (COR).

    :math:`\\sigma_\\text{lin} = 2\\mu\\varepsilon + \\lambda \\operatorname{tr}(\\varepsilon) I`,
    :math:`\\varepsilon = \\operatorname{sym}(R^T F) - I` (:mod:`hyperfem.materials.corotational_linear`).
    """
    G = R.T @ F
    eps = 0.5 * (G + G.T) - np.eye(3)
    return R @ (2.0 * mu * eps + lmbda * np.trace(eps) * np.eye(3))


def lateral_stretch(P, a: float) -> float:
    """The lateral stretch ``b`` of ``F = diag(a, b, b)`` with ``P(F)[1, 1] = 0`` (bisection on [0.3, 1.7])."""

    def p22(b: float) -> float:
        return P(np.diag([a, b, b]))[1, 1]

    lo, hi = 0.3, 1.7
    assert p22(lo) < 0.0 < p22(hi)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if p22(mid) < 0.0 else (lo, mid)
    return 0.5 * (lo + hi)


def test_closed_forms_are_the_energy_derivatives():
    """The NumPy stresses are the central-difference derivatives of the energies of the laws (as in hyperfem)."""
    F = np.array([[1.2, 0.1, -0.05], [0.02, 0.9, 0.1], [0.03, -0.08, 1.1]])
    Rn = _polar_rotation(np.array([[1.0, -0.3, 0.0], [0.3, 1.0, 0.0], [0.0, 0.0, 1.0]]))

    def fixed_corotated(G):  # R(G) varies with G: P is the full derivative
        R = _polar_rotation(G)
        return MU * np.sum((G - R) ** 2) + 0.5 * LMBDA * (np.linalg.det(G) - 1.0) ** 2

    def corotational_linear(G):  # R^n is fixed within a step
        H = Rn.T @ G
        eps = 0.5 * (H + H.T) - np.eye(3)
        return MU * np.sum(eps * eps) + 0.5 * LMBDA * np.trace(eps) ** 2

    cases = [
        (fixed_corotated, fixed_corotated_P(F, MU, LMBDA)),
        (lambda G: MU * np.sum((G - _polar_rotation(G)) ** 2), arap_P(F, MU)),
        (corotational_linear, corotational_linear_P(F, Rn, MU, LMBDA)),
    ]
    h = 1e-6
    for psi, P in cases:
        numeric = np.zeros((3, 3))
        for i in range(3):
            for j in range(3):
                dF = np.zeros((3, 3))
                dF[i, j] = h
                numeric[i, j] = (psi(F + dF) - psi(F - dF)) / (2.0 * h)
        np.testing.assert_allclose(numeric, P, rtol=0, atol=1e-6 * np.abs(P).max())


LAWS = {
    "fixed_corotated": (f"E = {E!r}\nnu = {NU!r}", lambda F: fixed_corotated_P(F, MU, LMBDA)),
    "arap": (f"mu = {MU!r}", lambda F: arap_P(F, MU)),  # ARAP(mu): the mu-alone route
    "corotational_linear": (f"E = {E!r}\nnu = {NU!r}", lambda F: corotational_linear_P(F, np.eye(3), MU, LMBDA)),
}


# -- meshes, case files, runs -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """A folder every rank agrees on, with ``box.msh``: the box, h = 0.5, a group per face."""
    comm = MPI.COMM_WORLD
    path = Path(tmp_path_factory.mktemp("materials")) if comm.rank == 0 else None
    path = comm.bcast(path, root=0)
    if comm.rank == 0:
        from hyperfem.mesh.gmsh_session import gmsh_session

        with gmsh_session() as gmsh:
            gmsh.model.add("box")
            gmsh.model.occ.addBox(0.0, 0.0, 0.0, *BOX)
            gmsh.model.occ.synchronize()
            for dim, tag in gmsh.model.getEntities(2):
                centre = gmsh.model.occ.getCenterOfMass(dim, tag)
                axis = next(i for i in range(3) if abs(centre[i] - 0.5 * BOX[i]) > 1e-8)
                side = 0 if centre[axis] < 1e-8 else 1
                name = f"{'xyz'[axis]}{side}"
                gmsh.model.addPhysicalGroup(2, [tag], FACES.index(name) + 1, name=name)
            gmsh.model.addPhysicalGroup(3, [t for _, t in gmsh.model.getEntities(3)], 1, name="box")
            gmsh.option.setNumber("Mesh.MeshSizeMin", 0.5)
            gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
            gmsh.option.setNumber("Mesh.Algorithm3D", 1)
            gmsh.option.setNumber("General.NumThreads", 1)
            gmsh.model.mesh.generate(3)
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.write(str(path / "box.msh"))
    comm.Barrier()
    return path


def _roller(face: str, value: float = 0.0) -> str:
    axis = face[0]
    return f'[[bc]]\ntype = "displacement"\nboundary = "{face}"\nvalue = [{value!r}]\ncomponents = ["{axis}"]\n'


QUIET = "[output]\nfields = []\ncheckpoint = false\nprogress = false\nprobes = [{probes}]\n"


def _box_case(folder: Path, law: str, constants: str, a: float, faces: tuple[str, ...]) -> str:
    """The box on rollers on ``faces``, the face x1 moved to x = 2a in one load step."""
    rollers = "".join(_roller(f) for f in faces)
    return (
        f'[mesh]\nfile = "{folder / "box.msh"}"\n\n[[material]]\nlaw = "{law}"\n{constants}\n\n{rollers}'
        f"{_roller('x1', BOX[0] * (a - 1.0))}\n[stepping]\nincrement = 1.0\n\n"
        + QUIET.format(probes="[2.0, 1.0, 1.0]")
    )


def run_case(folder: Path, name: str, text: str, capsys) -> dict:
    """``hyperfem run`` of ``text`` (in process); its ``--print-python`` script must give the same result."""
    comm = MPI.COMM_WORLD
    path = folder / f"{name}.toml"
    if comm.rank == 0:
        path.write_text(text)
    comm.Barrier()
    summary = dispatch(["run", str(path), "--output", str(folder / name / "run")])
    assert summary["completed"], summary.get("error")

    capsys.readouterr()
    dispatch(["run", str(path), "--output", str(folder / name / "python"), "--print-python"])
    source = comm.bcast(capsys.readouterr().out, root=0)
    namespace = {"__name__": f"{name}_python"}
    exec(compile(source, f"{name}.py", "exec"), namespace)  # noqa: S102 - the printed script of our case
    python = namespace["main"]()
    capsys.readouterr()
    assert python["steps"] == summary["steps"]
    np.testing.assert_allclose(python["probe_displacement"], summary["probe_displacement"], rtol=1e-9, atol=1e-12)
    for boundary, reaction in summary["reactions"].items():
        scale = max(1.0, float(np.abs(reaction["force"]).max()))
        np.testing.assert_allclose(python["reactions"][boundary]["force"], reaction["force"], rtol=0, atol=1e-9 * scale)
    return summary


def _force(summary: dict, boundary: str) -> np.ndarray:
    return np.asarray(summary["reactions"][boundary]["force"])


# -- uniaxial stretch and compression, laterally free ----------------------------------------------------
@pytest.mark.parametrize(
    "law, a",
    [("fixed_corotated", 1.25), ("fixed_corotated", 0.8), ("arap", 1.25), ("corotational_linear", 1.25)],
)
def test_uniaxial_laterally_free(law, a, folder, capsys):
    """F = diag(a, b, b): the pull on x1 is P11 times the area 1, b from P22 = 0, the rollers balance it."""
    constants, P = LAWS[law]
    name = f"uniaxial_{law}_{'stretch' if a > 1 else 'compression'}"
    summary = run_case(folder, name, _box_case(folder, law, constants, a, ("x0", "y0", "z0")), capsys)

    b = lateral_stretch(P, a)
    F = np.diag([a, b, b])
    if law == "arap":
        assert b == pytest.approx(1.0, abs=1e-12)  # no volume term: no lateral contraction
    if law == "corotational_linear":
        # R^n = I throughout: linear elasticity with (E, nu) exactly, at any stretch.
        assert b - 1.0 == pytest.approx(-NU * (a - 1.0), rel=1e-12)
        assert P(F)[0, 0] == pytest.approx(E * (a - 1.0), rel=1e-12)
    pull = P(F)[0, 0] * BOX[1] * BOX[2]
    np.testing.assert_allclose(_force(summary, "x1"), [pull, 0.0, 0.0], rtol=0, atol=1e-6 * abs(pull))
    np.testing.assert_allclose(_force(summary, "x0"), [-pull, 0.0, 0.0], rtol=0, atol=1e-6 * abs(pull))
    for face in ("y0", "z0"):
        np.testing.assert_allclose(_force(summary, face), 0.0, atol=1e-6 * abs(pull))  # laterally free
    corner = [BOX[0] * (a - 1.0), BOX[1] * (b - 1.0), BOX[2] * (b - 1.0)]
    np.testing.assert_allclose(summary["probe_displacement"][0], corner, rtol=0, atol=1e-6)


def test_fixed_corotated_confined_compression(folder, capsys):
    """F = diag(0.8, 1, 1): P11 = (2 mu + lambda)(a - 1) and the side walls carry P22 = lambda (J - 1) J."""
    a = 0.8
    constants, P = LAWS["fixed_corotated"]
    text = _box_case(folder, "fixed_corotated", constants, a, ("x0", "y0", "y1", "z0", "z1"))
    summary = run_case(folder, "confined_fixed_corotated", text, capsys)
    stress = P(np.diag([a, 1.0, 1.0]))
    assert stress[0, 0] == pytest.approx((2.0 * MU + LMBDA) * (a - 1.0), rel=1e-12)
    assert stress[1, 1] == pytest.approx(LMBDA * (a - 1.0) * a, rel=1e-12)
    area = BOX[1] * BOX[2]
    np.testing.assert_allclose(_force(summary, "x1"), [stress[0, 0] * area, 0, 0], atol=1e-6 * abs(stress[0, 0]))
    side = stress[1, 1] * BOX[0] * BOX[2]  # the face y1, normal +y, reference area 2
    np.testing.assert_allclose(_force(summary, "y1"), [0.0, side, 0.0], rtol=0, atol=1e-6 * abs(stress[0, 0]))
    np.testing.assert_allclose(_force(summary, "y0"), [0.0, -side, 0.0], rtol=0, atol=1e-6 * abs(stress[0, 0]))
    np.testing.assert_allclose(summary["probe_displacement"][0], [BOX[0] * (a - 1.0), 0.0, 0.0], atol=1e-6)


# -- a rotated stretch of the beam ---------------------------------------------------------------------------
THETA, STRETCH = 0.4, 1.1  # radians about z; the beam's stretch along its axis
BEAM_LENGTH, BEAM_AREA = 10.0, 16.0  # hyperfem.mesh.beam: x in [-5, 5], a 4 x 4 section


def _rotation(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rotated_stretch_case(law: str, constants: str, steps: str) -> str:
    """Both ends rotated by THETA about z: x = Q (X + (a - 1)(X1 + 5) e1), x = Q D X up to a translation.

    The end x = -5 turns about the origin; the end x = 5 about the centre c with
    (I - Q) c = (a - 1) L Q e1 (in the xy-plane), which stretches the beam by a.
    """
    Q = _rotation(THETA)
    shift = (STRETCH - 1.0) * BEAM_LENGTH * Q[:, 0]
    centre = np.zeros(3)
    centre[:2] = np.linalg.solve((np.eye(3) - Q)[:2, :2], shift[:2])
    ends = ""
    for boundary, c in (("clamped", np.zeros(3)), ("free_end", centre)):
        ends += (
            f'[[bc]]\ntype = "rotation"\nboundary = "{boundary}"\naxis = [0.0, 0.0, 1.0]\n'
            f"center = [{', '.join(repr(float(v)) for v in c)}]\nangle = {THETA!r}\nprofile = {steps}\n"
        )
    return (
        f'[mesh]\ngenerator = "beam"\nsize = 2.5\n\n[[material]]\nlaw = "{law}"\n{constants}\n\n{ends}\n'
        + QUIET.format(probes="[5.0, 2.0, 2.0]")
    )


def test_arap_rotated_stretch(folder, capsys):
    """ARAP is frame-indifferent: the end force of Q diag(a, 1, 1) is Q e1 2 mu (a - 1) A."""
    text = _rotated_stretch_case("arap", f"E = {E!r}\nnu = {NU!r}", '"linear"')
    text += "[stepping]\nincrement = 0.5\nmax_increment = 0.5\n"
    summary = run_case(folder, "rotated_arap", text, capsys)
    Q = _rotation(THETA)
    D = np.diag([STRETCH, 1.0, 1.0])
    force = arap_P(Q @ D, MU)[:, 0] * BEAM_AREA
    assert force == pytest.approx(Q[:, 0] * 2.0 * MU * (STRETCH - 1.0) * BEAM_AREA, rel=1e-12)
    np.testing.assert_allclose(_force(summary, "free_end"), force, rtol=0, atol=1e-6 * np.abs(force).max())
    np.testing.assert_allclose(_force(summary, "clamped"), -force, rtol=0, atol=1e-6 * np.abs(force).max())
    X = np.array([5.0, 2.0, 2.0])
    expected = Q @ (X + (STRETCH - 1.0) * (X[0] + 5.0) * np.array([1.0, 0.0, 0.0])) - X
    np.testing.assert_allclose(summary["probe_displacement"][0], expected, rtol=0, atol=1e-6)


@pytest.mark.parametrize("law", ["corotational_linear", "linear_elastic"])
def test_corotational_linear_follows_the_rotation(law, folder, capsys):
    """COR (nu = 0): rotation ramped in over [0, 0.25], then held; R^n catches up with the body step by step.

    At the end the pull is Q e1 E (a - 1) A, the rotated small-strain result;
    small-strain elasticity itself (the control) misses it by far more than the tolerance.
    """
    text = _rotated_stretch_case(law, f"E = {E!r}\nnu = 0.0", '{ type = "ramp", t1 = 0.25 }')
    text += "[stepping]\nincrement = 0.125\nmax_increment = 0.125\n"
    summary = run_case(folder, f"rotated_{law}", text, capsys)
    Q = _rotation(THETA)
    D = np.diag([STRETCH, 1.0, 1.0])
    force = corotational_linear_P(Q @ D, Q, E / 2.0, 0.0)[:, 0] * BEAM_AREA
    assert force == pytest.approx(Q[:, 0] * E * (STRETCH - 1.0) * BEAM_AREA, rel=1e-12)
    error = np.abs(_force(summary, "free_end") - force).max() / np.abs(force).max()
    if law == "corotational_linear":
        assert error < 1e-4, error
    else:
        assert error > 1e-2, error


# -- stress fields of the polar-rotation laws ------------------------------------------------------------------
@pytest.mark.parametrize("degree", [1, 2])
@pytest.mark.parametrize("law", list(LAWS))
def test_von_mises_field(law, degree, folder):
    """``output.fields = ["von_mises"]`` of the uniaxial stretch: every cell has |sigma_11| = |P11| a / J."""
    from hyperfem.app import build, load_case
    from hyperfem.simulation import FieldOutput

    comm = MPI.COMM_WORLD
    a = 1.25
    constants, P = LAWS[law]
    text = _box_case(folder, law, constants, a, ("x0", "y0", "z0")).replace("fields = []", 'fields = ["von_mises"]')
    text = text.replace("checkpoint = false", "checkpoint_every = 1")
    text += f"[problem]\ndegree = {degree}\n"
    path = folder / f"von_mises_{law}_{degree}.toml"
    if comm.rank == 0:
        path.write_text(text)
    comm.Barrier()
    built = build(load_case(path, output=folder / f"von_mises_{law}_{degree}"), comm)
    assert built.simulation.run()["completed"]
    b = lateral_stretch(P, a)
    sigma = P(np.diag([a, b, b]))[0, 0] * a / (a * b * b)
    (output,) = [o for o in built.outputs if isinstance(o, FieldOutput)]
    values = output.cell_functions["von_mises"].x.array
    np.testing.assert_allclose(values, abs(sigma), rtol=1e-6)
    # the same field from the run's checkpoint, in a model built afresh: the rotation is that of the loaded state
    from hyperfem.simulation.checkpoint import load_checkpoint
    from hyperfem.simulation.fields import cell_field_expressions
    from hyperfem.simulation.measures import CellFunctions

    again = build(load_case(path, output=folder / f"von_mises_{law}_{degree}"), comm)
    load_checkpoint(again.simulation, folder / f"von_mises_{law}_{degree}" / f"{again.case.name}.checkpoint")
    field = CellFunctions(again.domain, cell_field_expressions(again.problem, ["von_mises"], again.material), 0)
    field.refresh()
    np.testing.assert_allclose(field.functions[0].x.array, abs(sigma), rtol=1e-6)


def test_stress_field_from_a_checkpoint_of_a_rotated_state(folder):
    """ARAP, x = Q D X: a model built afresh from the run's checkpoint has the rotation of the loaded state.

    sigma = 2 mu Q (D - I) D Q^T / J, whose von Mises value needs R = Q: with R left at I (the rotation of
    the undeformed state) the field would be that of 2 mu (Q D - I) D^T Q^T / J, far off.
    """
    from hyperfem.app import build, load_case
    from hyperfem.simulation.checkpoint import load_checkpoint
    from hyperfem.simulation.fields import cell_field_expressions
    from hyperfem.simulation.measures import CellFunctions

    comm = MPI.COMM_WORLD
    text = _rotated_stretch_case("arap", f"E = {E!r}\nnu = {NU!r}", '"linear"').replace(
        "checkpoint = false", "checkpoint_every = 1"
    )
    path = folder / "rotated_checkpoint.toml"
    if comm.rank == 0:
        path.write_text(text)
    comm.Barrier()
    out = folder / "rotated_checkpoint"
    assert build(load_case(path, output=out), comm).simulation.run()["completed"]
    again = build(load_case(path, output=out), comm)
    load_checkpoint(again.simulation, out / f"{again.case.name}.checkpoint")
    field = CellFunctions(again.domain, cell_field_expressions(again.problem, ["von_mises"], again.material), 0)
    field.refresh()

    Q, D = _rotation(THETA), np.diag([STRETCH, 1.0, 1.0])
    J = STRETCH

    def mises(s: np.ndarray) -> float:
        dev = s - np.trace(s) / 3.0 * np.eye(3)
        return float(np.sqrt(1.5 * np.sum(dev * dev)))

    right = mises(2.0 * MU * (Q @ D - Q) @ (Q @ D).T / J)
    wrong = mises(2.0 * MU * (Q @ D - np.eye(3)) @ (Q @ D).T / J)
    assert abs(wrong - right) > 0.1 * right  # the check can tell the two apart
    np.testing.assert_allclose(field.functions[0].x.array, right, rtol=1e-6)
