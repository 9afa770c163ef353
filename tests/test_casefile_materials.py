"""Laws of a case file, run: the polar-rotation laws (``fixed_corotated``, ``arap``, ``corotational_linear``)
and the rubber and tissue laws of issue 21 (``yeoh``, ``reduced_polynomial``, ``gent``, ``arruda_boyce``,
``veronda_westmann``, ``holzapfel_gasser_ogden``, ``weiss``, ``fung_orthotropic``) and its principal-stretch
laws (``ogden``, ``hencky``).

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

The rubber and tissue laws stretch a unit cube on rollers on its six faces to
:math:`F = \\operatorname{diag}(1.3, 0.9, 1.1)`; their directions (``[fibres]``,
``[second_fibres]``) keep :math:`P` diagonal, so the reaction of each moved face
is the law's closed-form ``*_stress`` (evaluated by DOLFINx at that :math:`F`)
times its unit area; yeoh, gent and both HGO switches also with
``formulation = "mixed"``, HGO also through its ``--print-python`` script. Bad
values, keys and directions are refused in one line before anything is built,
also through the ``hyperfem`` command.

The principal-stretch laws (``ogden``, ``hencky``) take the same stretch. Ogden's
three terms are Ogden's 1972 fit of Treloar's data, :math:`\\mu_p = (0.63, 0.0012,
-0.01)` MPa, :math:`\\alpha_p = (1.3, 5, -2)`, given in each of the three
conventions (the same parameters to the bit, so one compiled form serves all
three), also mixed and through its ``--print-python`` script; the references
are NumPy's derivatives of the energies in the stretches, checked by central
differences. Their spectral tangents are compiled with ``-O0`` (``fast_jit``):
4 s instead of 18 s of CPU for Ogden's.

Runs serially and under ``mpiexec -n 2``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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
        _write_box(path / "box.msh", BOX, 0.5)
        _write_box(path / "cube.msh", (1.0, 1.0, 1.0), 0.5)
    comm.Barrier()
    return path


def _write_box(path: Path, box: tuple[float, float, float], size: float) -> None:
    """The box [0, box[0]] x [0, box[1]] x [0, box[2]], element size ``size``, a group per face (gmsh, one rank)."""
    from hyperfem.mesh.gmsh_session import gmsh_session

    with gmsh_session() as gmsh:
        gmsh.model.add("box")
        gmsh.model.occ.addBox(0.0, 0.0, 0.0, *box)
        gmsh.model.occ.synchronize()
        for dim, tag in gmsh.model.getEntities(2):
            centre = gmsh.model.occ.getCenterOfMass(dim, tag)
            axis = next(i for i in range(3) if abs(centre[i] - 0.5 * box[i]) > 1e-8)
            side = 0 if centre[axis] < 1e-8 else 1
            name = f"{'xyz'[axis]}{side}"
            gmsh.model.addPhysicalGroup(2, [tag], FACES.index(name) + 1, name=name)
        gmsh.model.addPhysicalGroup(3, [t for _, t in gmsh.model.getEntities(3)], 1, name="box")
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.mesh.generate(3)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))


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


# -- the rubber and tissue laws (issue 21) -----------------------------------------------------------------
STRETCH3 = (1.3, 0.9, 1.1)  # F = diag(a, b, c) of the unit cube: stretch, contraction and volume change J = 1.287
C30, S30 = math.cos(math.pi / 6), math.sin(math.pi / 6)


@dataclass(frozen=True)
class NewLaw:
    """A law of a case file: its keys (the fields of its parameter class), directions and closed-form stress."""

    parameters: type
    stress: Callable[..., Any]
    keys: dict
    directions: tuple[tuple[float, float, float], ...] = ()


def _new_laws() -> dict[str, NewLaw]:
    from hyperfem import materials as hm

    # HGO: two families at +-30 degrees in the xy-plane; Weiss: fibres along x; Fung: a1 = y, a2 = z (a3 = x).
    # Each set keeps P diagonal at F = diag(a, b, c), so that rollers on the six faces hold the homogeneous state.
    hgo = (C30, S30, 0.0), (C30, -S30, 0.0)
    return {
        "yeoh": NewLaw(hm.YeohParameters, hm.yeoh_stress, {"c10": 2.0e5, "c20": -5.0e4, "c30": 2.0e4, "K": 2.0e6}),
        "reduced_polynomial": NewLaw(
            hm.ReducedPolynomialParameters,
            hm.reduced_polynomial_stress,
            {"coefficients": [2.0e5, -3.0e4, 1.0e4, 5.0e3], "K": 2.0e6},
        ),
        "gent": NewLaw(hm.GentParameters, hm.gent_stress, {"mu": 4.0e5, "Jm": 0.2, "K": 4.0e6}),
        "arruda_boyce": NewLaw(
            hm.ArrudaBoyceParameters, hm.arruda_boyce_stress, {"mu": 4.0e5, "lambda_m": 1.5, "K": 4.0e6}
        ),
        "veronda_westmann": NewLaw(
            hm.VerondaWestmannParameters, hm.veronda_westmann_stress, {"c1": 2.0e4, "c2": 5.0, "K": 2.0e6}
        ),
        "holzapfel_gasser_ogden": NewLaw(
            hm.HolzapfelGasserOgdenParameters,
            hm.holzapfel_gasser_ogden_stress,
            {"mu": 1.0e5, "k1": 2.0e5, "k2": 2.0, "kappa": 0.1, "K": 2.0e6},
            hgo,
        ),
        "weiss": NewLaw(
            hm.WeissParameters,
            hm.weiss_stress,
            {"c1": 1.0e5, "c2": 2.0e4, "c3": 5.0e3, "c4": 20.0, "c5": 5.0e6, "lambda_star": 1.05, "K": 2.0e6},
            ((1.0, 0.0, 0.0),),
        ),
        "fung_orthotropic": NewLaw(
            hm.FungOrthotropicParameters,
            hm.fung_orthotropic_stress,
            {"c": 1.0e4, "b1": 10.0, "b2": 5.0, "b3": 3.0, "b4": 1.0, "b5": 0.5, "b6": 0.8, "b7": 4.0, "b8": 3.0,
             "b9": 2.0, "K": 2.0e6},
            ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
        ),
    }


NEW_LAWS = _new_laws()


def closed_form_stress(law: NewLaw, keys: dict, F: np.ndarray) -> np.ndarray:
    """The law's closed-form ``*_stress`` at a constant ``F``, as numbers (one-cell Expression on ``COMM_SELF``)."""
    import ufl
    from dolfinx import fem
    from dolfinx import mesh as dmesh

    mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    params = law.parameters(**{k: tuple(v) if isinstance(v, list) else v for k, v in keys.items()})
    P = law.stress(fem.Constant(mesh, F), *(ufl.as_vector(d) for d in law.directions), params)
    expr = fem.Expression(P, np.array([[0.25, 0.25, 0.25]]))
    return expr.eval(mesh, np.array([0], dtype=np.int32)).reshape(3, 3)


def _toml(value: object) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)


def _triaxial_case(folder: Path, law: str, keys: dict, mixed: bool) -> str:
    """The unit cube on rollers on all six faces, x1, y1, z1 moved to F = diag(STRETCH3) in one load step."""
    constants = "".join(f"{k} = {_toml(v)}\n" for k, v in keys.items())
    rollers = "".join(_roller(f) for f in ("x0", "y0", "z0"))
    rollers += "".join(_roller(f"{axis}1", s - 1.0) for axis, s in zip("xyz", STRETCH3, strict=True))
    fibres = ""
    directions = NEW_LAWS[law].directions if law in NEW_LAWS else ()
    for table, direction in zip(("fibres", "second_fibres"), directions, strict=False):
        fibres += f'[{table}]\ntype = "constant"\ndirection = {_toml(direction)}\n\n'
    problem = '[problem]\nformulation = "mixed"\n\n' if mixed else ""
    return (
        f'[mesh]\nfile = "{folder / "cube.msh"}"\n\n{problem}[[material]]\nlaw = "{law}"\n{constants}\n{fibres}'
        f"{rollers}\n[stepping]\nincrement = 1.0\n\n[solver]\natol = 1.0e-4\n\n"  # N: forces are 1e5 N
        + QUIET.format(probes="[0.5, 0.5, 1.0]")
    )


def _run(folder: Path, name: str, text: str) -> dict:
    """``hyperfem run`` of ``text`` in process."""
    comm = MPI.COMM_WORLD
    path = folder / f"{name}.toml"
    if comm.rank == 0:
        path.write_text(text)
    comm.Barrier()
    summary = dispatch(["run", str(path), "--output", str(folder / name / "run")])
    assert summary["completed"], summary.get("error")
    return summary


TRIAXIAL = [
    ("yeoh", {}, False),
    ("yeoh", {}, True),
    ("reduced_polynomial", {}, False),
    ("gent", {}, False),
    ("gent", {"lock_fraction": 0.5}, True),  # (I1bar - 3)/Jm = 0.68: on the quadratic continuation
    ("arruda_boyce", {}, False),
    ("veronda_westmann", {}, False),
    ("holzapfel_gasser_ogden", {}, False),
    ("holzapfel_gasser_ogden", {"switch": "stretch", "smoothing": 0.05}, True),
    ("weiss", {}, False),  # the fibre stretch 1.195 > lambda_star: the linear branch with c6
    ("fung_orthotropic", {"volumetric": "log"}, False),
]


def _triaxial_name(law: str, extra: dict, mixed: bool) -> str:
    return "_".join([law, *(["mixed"] if mixed else []), *extra])


@pytest.mark.parametrize("law, extra, mixed", TRIAXIAL, ids=[_triaxial_name(*case) for case in TRIAXIAL])
def test_new_law_triaxial_stretch(law, extra, mixed, folder, capsys):
    """F = diag(1.3, 0.9, 1.1) of a unit cube: the reaction of each moved face is the law's closed-form P_ii.

    The rollers hold the homogeneous state because every direction set keeps P diagonal; P1 (P2-P1-P1 with
    formulation = "mixed", where the volumetric part is U(theta) of the SplitEnergy) holds it exactly, so the
    reactions are P_11, P_22, P_33 times the unit areas up to the Newton tolerance. The HGO case also runs its
    ``--print-python`` script, which must give the same reactions.
    """
    keys = {**NEW_LAWS[law].keys, **extra}
    name = f"triaxial_{_triaxial_name(law, extra, mixed)}"
    text = _triaxial_case(folder, law, keys, mixed)
    if law == "holzapfel_gasser_ogden" and not mixed:
        summary = run_case(folder, name, text, capsys)
    else:
        summary = _run(folder, name, text)
    P = closed_form_stress(NEW_LAWS[law], keys, np.diag(STRETCH3))
    assert np.abs(P - np.diag(np.diag(P))).max() < 1e-9 * np.abs(P).max()  # diagonal: the rollers suffice
    scale = np.abs(P).max()
    for i, axis in enumerate("xyz"):
        expected = np.zeros(3)
        expected[i] = P[i, i]
        np.testing.assert_allclose(_force(summary, f"{axis}1"), expected, rtol=0, atol=1e-6 * scale)
        np.testing.assert_allclose(_force(summary, f"{axis}0"), -expected, rtol=0, atol=1e-6 * scale)
    X = np.array([0.5, 0.5, 1.0])  # the top face's centre: its x and y displacements are free
    np.testing.assert_allclose(summary["probe_displacement"][0], (np.array(STRETCH3) - 1.0) * X, rtol=0, atol=1e-9)


# -- what a case file of these laws may not say ------------------------------------------------------------
BAD_PARAMETERS = {
    "yeoh": ({"c10": 0.0}, "material[0].c10: must be > 0, got 0.0"),
    "reduced_polynomial": (
        {"coefficients": [-1.0e5, 1.0e3]},
        "material[0]: ReducedPolynomialParameters: coefficients[0] (C10) must be a finite number > 0, got -100000.0",
    ),
    "gent": ({"lock_fraction": 1.0}, "material[0].lock_fraction: must be < 1, got 1.0"),
    "arruda_boyce": ({"lambda_m": 1.0}, "material[0].lambda_m: must be > 1, got 1.0"),
    "veronda_westmann": ({"c2": -1.0}, "material[0].c2: must be > 0, got -1.0"),
    "holzapfel_gasser_ogden": (
        {"kappa": 0.5},
        "material[0]: HolzapfelGasserOgdenParameters: kappa must be a number in [0, 1/3], got 0.5",
    ),
    "weiss": ({"lambda_star": 0.9}, "material[0].lambda_star: must be > 1, got 0.9"),
    "fung_orthotropic": (
        {"b4": 10.0},
        "material[0]: FungOrthotropicParameters: the normal block [[b1, b4, b6], [b4, b2, b5], [b6, b5, b3]] must be "
        "positive definite (Q > 0 for every nonzero strain), its eigenvalues are ",
    ),
}


def _check_error(folder: Path, text: str) -> str:
    from hyperfem.app.casefile import CaseFileError, check_case, parse_toml

    with pytest.raises(CaseFileError) as info:
        check_case(parse_toml(text), folder / "bad.toml")
    message = str(info.value)
    assert "\n" not in message
    return message


@pytest.mark.parametrize("law", list(BAD_PARAMETERS))
def test_new_law_bad_parameter(law, folder):
    """A value the law refuses is one line naming the entry: the key's range, or the parameter class's own check."""
    change, expected = BAD_PARAMETERS[law]
    text = _triaxial_case(folder, law, {**NEW_LAWS[law].keys, **change}, mixed=False)
    assert f"bad.toml: {expected}" in _check_error(folder, text)


def test_new_law_case_errors(folder):
    """Unknown keys (did-you-mean), missing keys, missing or unused directions, non-orthogonal Fung axes."""
    gent = _triaxial_case(folder, "gent", NEW_LAWS["gent"].keys, mixed=False)
    typo = gent.replace("K = ", "lock_fracton = 0.9\nK = ")
    expected = "material[0].lock_fracton: unknown key (did you mean 'lock_fraction'?); keys of a material with law"
    assert expected in _check_error(folder, typo)
    yeoh = _triaxial_case(folder, "yeoh", NEW_LAWS["yeoh"].keys, mixed=False)
    assert "material[0]: missing required key 'c30'" in _check_error(folder, yeoh.replace("c30 = 20000.0\n", ""))

    weiss = _triaxial_case(folder, "weiss", NEW_LAWS["weiss"].keys, mixed=False)
    no_fibres = weiss.replace('[fibres]\ntype = "constant"\ndirection = [1.0, 0.0, 0.0]\n', "")
    assert 'material[0]: law "weiss" needs fibre directions: add a [fibres] table' in _check_error(folder, no_fibres)
    extra = weiss + '\n[second_fibres]\ntype = "constant"\ndirection = [0.0, 1.0, 0.0]\n'
    assert "second_fibres: no material uses a second direction" in _check_error(folder, extra)

    hgo = _triaxial_case(folder, "holzapfel_gasser_ogden", NEW_LAWS["holzapfel_gasser_ogden"].keys, mixed=False)
    head, _, tail = hgo.partition("[second_fibres]")
    no_second = head + tail[tail.index("[[bc]]") :]
    message = _check_error(folder, no_second)
    assert 'material[0]: law "holzapfel_gasser_ogden" needs a second direction, its family a02: add a ' in message
    typo = head + "[second_fibres]" + tail.replace("direction", "directon", 1)
    assert "second_fibres.directon: unknown key (did you mean 'direction'?)" in _check_error(folder, typo)

    fung = _triaxial_case(folder, "fung_orthotropic", NEW_LAWS["fung_orthotropic"].keys, mixed=False)
    skew = fung.replace("direction = [0.0, 0.0, 1.0]", "direction = [0.0, 0.6, 0.8]")
    expected = 'second_fibres.direction: the axes of law "fung_orthotropic" must be orthogonal'
    assert expected in _check_error(folder, skew)


def test_check_sees_the_second_direction(folder):
    """``hyperfem check`` (check_dimensions, check_groups) reads [second_fibres] as it reads [fibres]."""
    from hyperfem.app.build import build_domain, check_dimensions, check_groups
    from hyperfem.app.casefile import CaseFileError, check_case, parse_toml
    from mpi4py import MPI

    import re

    hgo = _triaxial_case(folder, "holzapfel_gasser_ogden", NEW_LAWS["holzapfel_gasser_ogden"].keys, mixed=False)
    head, _, tail = hgo.partition("[second_fibres]")
    short = head + "[second_fibres]" + re.sub(r"direction = \[[^]]*\]", "direction = [0.0, 1.0]", tail, count=1)
    case = check_case(parse_toml(short), folder / "short.toml")
    domain = build_domain(case, MPI.COMM_WORLD)
    with pytest.raises(CaseFileError, match=r"second_fibres.direction: 2 components"):
        check_dimensions(case, domain)
    laplace = head + '[second_fibres]\ntype = "laplace"\nsource = "x9"\ntarget = "x1"\n\n' + tail[tail.index("[[bc]]"):]
    case = check_case(parse_toml(laplace), folder / "laplace.toml")
    with pytest.raises(CaseFileError, match=r"second_fibres.source: no boundary 'x9'"):
        check_groups(case, build_domain(case, MPI.COMM_WORLD))


@pytest.mark.serial  # each run starts its own process
@pytest.mark.parametrize("law", ["reduced_polynomial", "fung_orthotropic"])
def test_new_law_bad_parameter_through_the_command(law, folder):
    """``hyperfem run`` of a refused value: exit status 1, one line ``hyperfem: error: ...``, no traceback."""
    import os
    import subprocess
    import sys

    change, expected = BAD_PARAMETERS[law]
    path = folder / f"bad_{law}.toml"
    path.write_text(_triaxial_case(folder, law, {**NEW_LAWS[law].keys, **change}, mixed=False))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "MPICH_"))}
    env["PYTHONWARNINGS"] = "ignore"
    result = subprocess.run(
        [sys.executable, "-m", "hyperfem.app.main", "run", str(path), "--output", str(folder / f"bad_{law}")],
        capture_output=True, text=True, timeout=240, env=env,
    )
    assert result.returncode == 1, (result.stdout, result.stderr)
    assert "Traceback" not in result.stdout + result.stderr and result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"hyperfem: error: {path}: {expected}"), result.stderr


def test_json_schema_knows_the_new_laws(folder):
    """``hyperfem schema --json`` takes every case above, [second_fibres] included, and refuses the bad values
    it can see (all but the reduced polynomial's C10 > 0 and Fung's positive definite block)."""
    jsonschema = pytest.importorskip("jsonschema")
    from hyperfem.app.casefile import parse_toml
    from hyperfem.app.reference import json_schema

    validator = jsonschema.Draft202012Validator(json_schema())
    for law, extra, mixed in TRIAXIAL:
        data = parse_toml(_triaxial_case(folder, law, {**NEW_LAWS[law].keys, **extra}, mixed))
        assert [e.message for e in validator.iter_errors(data)] == [], law
    for law, (change, _) in BAD_PARAMETERS.items():
        data = parse_toml(_triaxial_case(folder, law, {**NEW_LAWS[law].keys, **change}, mixed=False))
        assert validator.is_valid(data) == (law in ("reduced_polynomial", "fung_orthotropic")), law


# -- the principal-stretch laws (issue 21): Ogden and Hencky ---------------------------------------------
TRELOAR_MU = (0.63e6, 0.0012e6, -0.01e6)  # Pa: R. W. Ogden, Proc. R. Soc. Lond. A 326 (1972) 565, Treloar's rubber
TRELOAR_ALPHA = (1.3, 5.0, -2.0)
OGDEN_K = 4.0e6  # Pa: ten times the shear modulus sum(mu_p alpha_p) / 2 = 0.4225 MPa
FEBIO_C = tuple(m * a for m, a in zip(TRELOAR_MU, TRELOAR_ALPHA, strict=True))  # c_p = mu_p alpha_p
OGDEN_COEFFICIENTS = {  # each converts to the same mu_p = c_p / alpha_p, bit for bit (Abaqus: 2 (c_p / 2) / alpha_p)
    "ogden": [c / a for c, a in zip(FEBIO_C, TRELOAR_ALPHA, strict=True)],  # Treloar's mu_p to round-off
    "febio": list(FEBIO_C),
    "abaqus": [c / 2.0 for c in FEBIO_C],  # mu_i = mu_p alpha_p / 2
}
HENCKY_KEYS = {"E": 1.0e6, "nu": 0.3}


def _ogden_keys(convention: str) -> dict:
    keys: dict[str, Any] = {"mu": OGDEN_COEFFICIENTS[convention], "alpha": list(TRELOAR_ALPHA), "K": OGDEN_K}
    return keys if convention == "ogden" else {**keys, "convention": convention}


def ogden_energy(stretches: np.ndarray, mu, alpha, K: float) -> float:
    r""":math:`\sum_p \frac{\mu_p}{\alpha_p}(\sum_i \bar\lambda_i^{\alpha_p} - 3) + \frac{K}{2}\ln^2 J`."""
    J = np.prod(stretches)
    bar = stretches * J ** (-1.0 / 3.0)
    return sum(m / a * (np.sum(bar**a) - 3.0) for m, a in zip(mu, alpha, strict=True)) + 0.5 * K * np.log(J) ** 2


def ogden_P(stretches, mu, alpha, K: float) -> np.ndarray:
    r""":math:`P_{ii} = \partial\psi/\partial\lambda_i
    = \lambda_i^{-1}\big(\sum_p\mu_p(\bar\lambda_i^{\alpha_p} - \frac13\sum_j\bar\lambda_j^{\alpha_p}) + K\ln J\big)`
    at :math:`F = \operatorname{diag}(\lambda_i)`."""
    lam = np.asarray(stretches, dtype=float)
    J = np.prod(lam)
    bar = lam * J ** (-1.0 / 3.0)
    tau = sum(m * (bar**a - np.sum(bar**a) / 3.0) for m, a in zip(mu, alpha, strict=True)) + K * np.log(J)
    return np.diag(tau / lam)


def hencky_energy(stretches: np.ndarray, mu: float, lmbda: float) -> float:
    r""":math:`\mu\sum_i\ln^2\lambda_i + \frac\lambda2\ln^2 J` (seed 003 eq. 4.73b)."""
    return mu * np.sum(np.log(stretches) ** 2) + 0.5 * lmbda * np.log(np.prod(stretches)) ** 2


def hencky_P(stretches, mu: float, lmbda: float) -> np.ndarray:
    r""":math:`P_{ii} = (2\mu\ln\lambda_i + \lambda\ln J)/\lambda_i` at :math:`F = \operatorname{diag}(\lambda_i)`."""
    lam = np.asarray(stretches, dtype=float)
    return np.diag((2.0 * mu * np.log(lam) + lmbda * np.log(np.prod(lam))) / lam)


def test_principal_closed_forms_are_the_energy_derivatives():
    """The NumPy stresses are central differences of the energies in the stretches (isotropy: P diagonal)."""
    lam = np.array(STRETCH3)
    cases = [
        (
            lambda x: ogden_energy(x, TRELOAR_MU, TRELOAR_ALPHA, OGDEN_K),
            ogden_P(lam, TRELOAR_MU, TRELOAR_ALPHA, OGDEN_K),
        ),
        (lambda x: hencky_energy(x, MU, LMBDA), hencky_P(lam, MU, LMBDA)),
    ]
    h = 1e-6
    for psi, P in cases:
        numeric = [(psi(lam + h * e) - psi(lam - h * e)) / (2.0 * h) for e in np.eye(3)]
        np.testing.assert_allclose(numeric, np.diag(P), rtol=0, atol=1e-7 * np.abs(P).max())


@pytest.fixture
def fast_jit(monkeypatch):
    """Forms compiled with ``-O0`` while the test runs (the spectral tangents: 4 s instead of 18 s at ``-O2``)."""
    from dolfinx import jit

    doc = jit.DOLFINX_DEFAULT_JIT_OPTIONS["cffi_extra_compile_args"][1]
    monkeypatch.setitem(jit.DOLFINX_DEFAULT_JIT_OPTIONS, "cffi_extra_compile_args", (["-O0", "-g0"], doc))


def _check_triaxial(summary: dict, P: np.ndarray) -> None:
    """Each moved face reacts with P_ii (unit areas), each fixed one with -P_ii; the homogeneous displacement."""
    scale = np.abs(P).max()
    for i, axis in enumerate("xyz"):
        expected = np.zeros(3)
        expected[i] = P[i, i]
        np.testing.assert_allclose(_force(summary, f"{axis}1"), expected, rtol=0, atol=1e-6 * scale)
        np.testing.assert_allclose(_force(summary, f"{axis}0"), -expected, rtol=0, atol=1e-6 * scale)
    X = np.array([0.5, 0.5, 1.0])
    np.testing.assert_allclose(summary["probe_displacement"][0], (np.array(STRETCH3) - 1.0) * X, rtol=0, atol=1e-9)


def test_ogden_conventions_triaxial_stretch(folder, capsys, fast_jit):
    """Ogden's Treloar fit at F = diag(1.3, 0.9, 1.1), its mu given as Ogden's mu_p, FEBio's c_p = mu_p alpha_p and
    Abaqus's mu_p alpha_p / 2: the same parameters, the reactions P_ii of NumPy's formula, the same to round-off
    in all three; the FEBio case also through its ``--print-python`` script (OgdenParameters.from_convention)."""
    from hyperfem.materials import OgdenParameters

    made = {c: OgdenParameters.from_convention(**_ogden_keys(c)) for c in OGDEN_COEFFICIENTS}
    assert made["febio"] == made["ogden"] == made["abaqus"]  # one compiled form for the three runs
    np.testing.assert_allclose(made["ogden"].mu, TRELOAR_MU, rtol=1e-15)
    P = ogden_P(STRETCH3, made["ogden"].mu, TRELOAR_ALPHA, OGDEN_K)
    summaries = {}
    for convention in ("febio", "ogden", "abaqus"):
        text = _triaxial_case(folder, "ogden", _ogden_keys(convention), mixed=False)
        name = f"triaxial_ogden_{convention}"
        run = run_case(folder, name, text, capsys) if convention == "febio" else _run(folder, name, text)
        summaries[convention] = run
        _check_triaxial(summaries[convention], P)
    for convention in ("ogden", "abaqus"):
        for boundary, reaction in summaries["febio"]["reactions"].items():
            got = summaries[convention]["reactions"][boundary]["force"]
            np.testing.assert_allclose(got, reaction["force"], rtol=0, atol=1e-9 * np.abs(P).max())


def test_ogden_mixed_triaxial_stretch(folder, capsys, fast_jit):
    """formulation = "mixed": ogden_isochoric through SplitEnergy (with Ogden's known shear modulus, so that the
    Schur preconditioner would not compile its tangent at I), U(theta) at theta = J: the same reactions."""
    keys = {**_ogden_keys("abaqus"), "volumetric": "log"}
    summary = run_case(folder, "triaxial_ogden_mixed", _triaxial_case(folder, "ogden", keys, mixed=True), capsys)
    _check_triaxial(summary, ogden_P(STRETCH3, OGDEN_COEFFICIENTS["ogden"], TRELOAR_ALPHA, OGDEN_K))


def test_ogden_split_energy_carries_its_shear_modulus(folder):
    """The mixed Ogden material of a case is a SplitEnergy with shear_modulus = sum(mu_p alpha_p) / 2, which
    reference_shear_moduli returns as it is (nothing compiled)."""
    from dolfinx import mesh as dmesh

    import hyperfem as hf
    from hyperfem.app.calls import evaluate
    from hyperfem.app.casefile import check_case, parse_toml
    from hyperfem.app.plan import plan
    from hyperfem.errors import ParameterError
    from hyperfem.problem.mixed import MixedHyperelasticProblem, SplitEnergy

    case = check_case(parse_toml(_triaxial_case(folder, "ogden", _ogden_keys("febio"), mixed=True)), folder / "a.toml")
    variables: dict[str, Any] = {"comm": MPI.COMM_WORLD}
    for statement in plan(case):
        if statement.target in ("params", "material"):
            variables[statement.target] = evaluate(statement.value, variables)
    material = variables["material"]
    assert isinstance(material, SplitEnergy)
    mu0 = 0.5 * sum(FEBIO_C)
    assert material.shear_modulus == pytest.approx(mu0, rel=1e-15)
    domain = hf.Domain.from_locators(dmesh.create_unit_cube(MPI.COMM_WORLD, 1, 1, 1), {})
    problem = MixedHyperelasticProblem(domain, material)
    assert problem.reference_shear_moduli() == {None: material.shear_modulus}
    with pytest.raises(ParameterError, match="SplitEnergy: shear_modulus must be"):
        SplitEnergy(material.isochoric, OGDEN_K, shear_modulus=0.0)


def test_hencky_triaxial_stretch(folder, fast_jit):
    """Hencky with E and nu, like the other Lame laws: the reactions P_ii = (2 mu ln l_i + lambda ln J) / l_i."""
    summary = _run(folder, "triaxial_hencky", _triaxial_case(folder, "hencky", HENCKY_KEYS, mixed=False))
    _check_triaxial(summary, hencky_P(STRETCH3, MU, LMBDA))


PRINCIPAL_BAD = [
    ("ogden", {"alpha": [1.3, 5.0]}, "material[0]: OgdenParameters: mu and alpha need equal lengths, got 3 and 2"),
    ("ogden", {"mu": [6.3e5, 1.2e3, 1.0e4]},
     "material[0]: OgdenParameters: term 2 needs mu*alpha > 0 (Ogden's stability condition), got mu=10000.0, "
     "alpha=-2.0"),
    ("ogden", {"alpha": [1.3, 0.0, -2.0]}, "material[0]: OgdenParameters: alpha[1] must be nonzero"),
    ("ogden", {"convention": "febio", "mu": [8.19e5, 6.0e3, -2.0e4]},
     "material[0].mu[2]: must be > 0 in the febio convention (it is mu_p alpha_p, > 0 by Ogden's stability "
     "condition), got -20000.0"),
    ("ogden", {"convention": "abaqs"},
     "material[0].convention: unknown value 'abaqs' (did you mean 'abaqus'?); choose from abaqus, febio, ogden"),
    ("ogden", {"mu": 6.3e5}, "material[0].mu: expected an array of numbers, got a number"),
    ("ogden", {"alpah": [1.3, 5.0, -2.0]}, "material[0].alpah: unknown key (did you mean 'alpha'?)"),
    ("ogden", {"K": 0.0}, "material[0].K: must be > 0, got 0.0"),
    ("hencky", {"nu": 0.5}, "material[0].nu: Poisson's ratio must lie in (-1, 0.5), got 0.5"),
    ("hencky", {"K": 1.0e6}, "material[0].K: unknown key"),
]


@pytest.mark.parametrize("law, change, expected", PRINCIPAL_BAD, ids=[f"{c[0]}-{next(iter(c[1]))}-{i}" for i, c in
                                                                       enumerate(PRINCIPAL_BAD)])
def test_principal_law_bad_parameter(law, change, expected, folder):
    """One line naming the entry: a key's type, range or choice (did-you-mean), or OgdenParameters' own check."""
    base = _ogden_keys("ogden") if law == "ogden" else HENCKY_KEYS
    keys = {k: v for k, v in {**base, **change}.items() if not (k == "alpha" and "alpah" in change)}
    assert f"bad.toml: {expected}" in _check_error(folder, _triaxial_case(folder, law, keys, mixed=False))


def test_hencky_is_not_mixed(folder):
    """Hencky has no isochoric/volumetric split: formulation = "mixed" is refused, naming the mixed laws."""
    message = _check_error(folder, _triaxial_case(folder, "hencky", HENCKY_KEYS, mixed=True))
    assert "material[0].law: 'hencky' has no isochoric/volumetric split" in message and "ogden" in message


@pytest.mark.serial  # starts its own process
def test_ogden_bad_parameter_through_the_command(folder):
    """``hyperfem run`` of mismatched mu and alpha: exit status 1, one line ``hyperfem: error: ...``."""
    import os
    import subprocess
    import sys

    law, change, expected = PRINCIPAL_BAD[0]
    path = folder / "bad_ogden.toml"
    path.write_text(_triaxial_case(folder, law, {**_ogden_keys("ogden"), **change}, mixed=False))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "MPICH_"))}
    env["PYTHONWARNINGS"] = "ignore"
    result = subprocess.run(
        [sys.executable, "-m", "hyperfem.app.main", "run", str(path), "--output", str(folder / "bad_ogden")],
        capture_output=True, text=True, timeout=240, env=env,
    )
    assert result.returncode == 1, (result.stdout, result.stderr)
    assert "Traceback" not in result.stdout + result.stderr and result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0] == f"hyperfem: error: {path}: {expected}", result.stderr


def test_schema_knows_the_principal_laws(folder):
    """``hyperfem schema`` lists ogden's keys with their help (units, the conventions), ``--json`` takes the
    cases above and refuses what it can see (an unknown convention, a scalar mu, K <= 0)."""
    from hyperfem.app.casefile import parse_toml
    from hyperfem.app.reference import json_schema, reference

    text = " ".join(reference().replace("\n" + " " * 40 + "#   ", " ").split())  # comments unwrapped
    assert '# law = "ogden"' in text and '# law = "hencky"' not in text  # hencky: a Lame law, listed with them
    for needle in ("# mu = [6.3e5, 1200.0, -10000.0] # [numbers], required: coefficients in Pa",
                   "# alpha = [1.3, 5.0, -2.0]", '# convention = "ogden" # "abaqus" | "febio" | "ogden", default',
                   "FEBio's c_p = mu_p alpha_p", "Abaqus's mu_i = mu_p alpha_p / 2", "R. W. Ogden, Proc. R. Soc."):
        assert needle in text, needle
    assert '| "hencky" | "saint_venant_kirchhoff_principal" |' in text
    jsonschema = pytest.importorskip("jsonschema")
    validator = jsonschema.Draft202012Validator(json_schema())
    good = [("ogden", _ogden_keys(c), m) for c in OGDEN_COEFFICIENTS for m in (False, True)]
    good += [("hencky", HENCKY_KEYS, False), ("saint_venant_kirchhoff_principal", HENCKY_KEYS, False)]
    for law, keys, mixed in good:
        data = parse_toml(_triaxial_case(folder, law, keys, mixed))
        assert [e.message for e in validator.iter_errors(data)] == [], (law, keys)
    for change in ({"convention": "abaqs"}, {"mu": 6.3e5}, {"K": 0.0}):
        data = parse_toml(_triaxial_case(folder, "ogden", {**_ogden_keys("ogden"), **change}, mixed=False))
        assert not validator.is_valid(data), change
