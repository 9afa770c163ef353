r"""Fitting material parameters to homogeneous test data (issue 21): ``hf.materials.fit``, ``hyperfem fit``.

Analytic checks first: the homogeneous response of :mod:`hyperfem.materials.homogeneous`
(the law's own UFL energy, compiled once) against closed forms —

* incompressible neo-Hookean and Mooney–Rivlin: :math:`P = 2(c_1 + c_2/\lambda_k)(\lambda - \lambda_3^2/\lambda)`
  with :math:`\lambda_3` the free face's stretch and :math:`\lambda_k` the third stretch
  (uniaxial :math:`P = 2(c_1 + c_2/\lambda)(\lambda - \lambda^{-2})`, equibiaxial
  :math:`2(c_1 + c_2\lambda^2)(\lambda - \lambda^{-5})`, pure shear :math:`2(c_1 + c_2)(\lambda - \lambda^{-3})`);
* Ogden's closed forms (:func:`~hyperfem.materials.ogden.ogden_uniaxial_stress`, ...), and
  the fit's Ogden energy (exponents as constants) against ``ogden_isochoric`` (exponents as numbers);
* a compressible state: the lateral stretch solved so that the closed-form
  ``mooney_rivlin_stress`` has a traction-free face, and its :math:`P_{11}`;
* Drucker's check against the Hessian of :math:`W = f(I_1)` in log-strains,
  :math:`H_{ij} = 4f''\lambda_i^2\lambda_j^2 + 4f'\lambda_i^2\delta_{ij}`, restricted to
  :math:`\sum d\varepsilon_i = 0` (a Yeoh law with :math:`C_{20} < 0` loses it).

Then fits that must recover the parameters of synthetic data (compressible, with
volumetric data), the Treloar regression of ``demos/fit_treloar.py`` (six laws,
Ogden against Ogden's 1972 parameters, a finite-element run), the case-file table
read back by the case-file checker, and the command (JSON, PNG, one-line errors).
"""

from __future__ import annotations

import importlib.util
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem.materials.fitting as fitting
from hyperfem.app.main import dispatch
from hyperfem.app.program import run
from hyperfem.errors import ParameterError
from hyperfem.materials.fitting import Curve, fit, read_curves, treloar_data
from hyperfem.materials.homogeneous import HomogeneousResponse, mode_stretches
from hyperfem.materials.mooney_rivlin import MooneyRivlinParameters, mooney_rivlin, mooney_rivlin_isochoric
from hyperfem.materials.mooney_rivlin import mooney_rivlin_stress
from hyperfem.materials.ogden import (
    ogden_equibiaxial_stress,
    ogden_isochoric,
    ogden_pure_shear_stress,
    ogden_uniaxial_stress,
)
from hyperfem.materials.yeoh import yeoh_isochoric
from hyperfem.materials.neo_hookean import neo_hookean_isochoric
from hyperfem.materials.prony import PronySeries
from hyperfem.materials.prony_fit import PronyFit, RelaxationCurve, fit_prony
from hyperfem.materials.viscoelastic import Viscoelastic
from hyperfem.problem import SplitEnergy

ROOT = Path(__file__).resolve().parent.parent
STRETCH = np.array([0.6, 0.9, 1.0, 1.3, 2.0, 4.0])
INCOMPRESSIBLE = ("uniaxial", "equibiaxial", "pure_shear")


def _ns(**kw):
    from types import SimpleNamespace

    return SimpleNamespace(**kw)


# -- data ------------------------------------------------------------------------------------------------
def test_treloar_data_as_shipped():
    """The packaged copy: 25 / 17 / 14 points, each with the origin, stresses in MPa, sorted by stretch."""
    data = treloar_data()
    assert {m: c.stretch.size for m, c in data.items()} == {"uniaxial": 25, "equibiaxial": 17, "pure_shear": 14}
    for curve in data.values():
        assert curve.stretch[0] == 1.0 and curve.stress[0] == 0.0
        assert np.all(np.diff(curve.stretch) > 0)
    assert data["uniaxial"].stretch[-1] == 7.6 and data["uniaxial"].stress[-1] == pytest.approx(6.3, abs=0.05)
    assert (fitting.TRELOAR.parent / "README.md").is_file()  # the source note ships beside it


BAD_FILES = {
    "missing": (None, "fit: data file not found: "),
    "column": ("mode,stretch,nominal_stress\nuniaxial,1.0,0.0\n",
               "no column 'nominal_stress_MPa' (did you mean 'nominal_stress'?)"),
    "mode": ("mode,stretch,nominal_stress_MPa\nuniaxal,1.0,0.0\n",
             ":2: unknown mode 'uniaxal' (did you mean 'uniaxial'?)"),
    "number": ("mode,stretch,nominal_stress_MPa\nuniaxial,1.2,abc\n", ":2: nominal_stress_MPa must be a number"),
    "stretch": ("mode,stretch,nominal_stress_MPa\nuniaxial,-1,0.1\n", ":2: stretch must be > 0"),
    "empty": ("mode,stretch,nominal_stress_MPa\n", "has no data rows"),
}


@pytest.mark.parametrize("name", list(BAD_FILES))
def test_read_curves_refuses_bad_files(name, tmp_path):
    text, expected = BAD_FILES[name]
    path = tmp_path / f"{name}.csv"
    if text is not None:
        path.write_text(text)
    with pytest.raises(ParameterError) as info:
        read_curves(path)
    assert expected in str(info.value)


# -- the homogeneous response against closed forms ----------------------------------------------------------
def test_incompressible_response_equals_mooney_rivlin_closed_form():
    response = HomogeneousResponse(lambda F, c: mooney_rivlin_isochoric(F, c["c1"], c["c2"]), ["c1", "c2"],
                                   incompressible=True)
    c1, c2 = 0.3, 0.07
    response.set_parameters({"c1": c1, "c2": c2})
    lam = STRETCH
    exact = {
        "uniaxial": 2.0 * (c1 + c2 / lam) * (lam - lam**-2),
        "equibiaxial": 2.0 * (c1 + c2 * lam**2) * (lam - lam**-5),
        "pure_shear": 2.0 * (c1 + c2) * (lam - lam**-3),
    }
    for mode, P in exact.items():
        np.testing.assert_allclose(response.nominal_stress(mode, lam), P, rtol=1e-12, atol=1e-14)


def test_ogden_response_equals_closed_forms_and_ogden_isochoric():
    """The fit's Ogden energy (exponents as constants) is ogden_isochoric's (exponents as numbers), in every mode."""
    mu, alpha = (0.63, 0.0012, -0.01), (1.3, 5.0, -2.0)
    model = fitting._MODELS["ogden"](3, 1.0)
    response = HomogeneousResponse(model.isochoric, model.names, incompressible=True)
    response.set_parameters([*mu, *alpha])
    reference = HomogeneousResponse(lambda F, c: ogden_isochoric(F, mu, alpha), [], incompressible=True)
    reference.set_parameters([])
    closed = {"uniaxial": ogden_uniaxial_stress, "equibiaxial": ogden_equibiaxial_stress,
              "pure_shear": ogden_pure_shear_stress}
    for mode, formula in closed.items():
        P = response.nominal_stress(mode, STRETCH)
        np.testing.assert_allclose(P, formula(STRETCH, mu, alpha), rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(P, reference.nominal_stress(mode, STRETCH), rtol=1e-12, atol=1e-15)


def _closed_form_P(params, stretches):
    """``mooney_rivlin_stress`` at each F = diag(stretches) (one-cell Expression on COMM_SELF)."""
    mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    F = fem.Constant(mesh, np.eye(3))
    expr = fem.Expression(mooney_rivlin_stress(F, params), np.array([[0.25, 0.25, 0.25]]))
    out = []
    for s in stretches:
        F.value = np.diag(s)
        out.append(np.diag(expr.eval(mesh, np.array([0], dtype=np.int32)).reshape(3, 3)))
    return np.array(out)


def test_compressible_response_solves_the_free_face():
    """The lateral stretch makes the closed-form P traction free; P11 is the closed form's."""
    params = MooneyRivlinParameters(c1=0.3, c2=0.07, K=2.0)
    response = HomogeneousResponse(
        lambda F, c: mooney_rivlin(F, _ns(c1=c["c1"], c2=c["c2"], K=c["K"], volumetric="log")),
        ["c1", "c2", "K"], incompressible=False)
    response.set_parameters([0.3, 0.07, 2.0])
    for mode, free in (("uniaxial", (1, 2)), ("equibiaxial", (2,)), ("pure_shear", (2,)), ("volumetric", ())):
        states = response.states(mode, STRETCH)
        P = _closed_form_P(params, states)
        for f in free:
            np.testing.assert_allclose(P[:, f], 0.0, atol=1e-12)
        np.testing.assert_allclose(response.nominal_stress(mode, STRETCH), P[:, 0], rtol=1e-12, atol=1e-13)
        if mode != "volumetric":  # compressible: J != 1 away from the reference
            assert np.ptp(np.prod(states, axis=1)) > 1e-3


def test_drucker_equals_the_log_strain_hessian():
    r"""Yeoh, :math:`C_{20} < 0`: :math:`f = C_{10}(I_1 - 3) + C_{20}(I_1 - 3)^2` is stable, then not, as H says."""
    c10, c20 = 0.5, -0.05
    response = HomogeneousResponse(lambda F, c: yeoh_isochoric(F, _ns(coefficients=(c["c10"], c["c20"], 0.0))),
                                   ["c10", "c20"], incompressible=True)
    response.set_parameters([c10, c20])
    basis = np.array([[1.0, -1.0, 0.0], [1.0, 1.0, -2.0]]).T / np.sqrt([2.0, 6.0])
    lam = np.linspace(0.3, 3.0, 28)
    for mode in INCOMPRESSIBLE:
        s = mode_stretches(mode, lam)
        I1 = np.sum(s**2, axis=1)
        f1, f2 = c10 + 2.0 * c20 * (I1 - 3.0), 2.0 * c20
        sq = s**2
        H = 4.0 * f2 * sq[:, :, None] * sq[:, None, :] + 4.0 * f1[:, None, None] * np.einsum("ni,ij->nij", sq,
                                                                                              np.eye(3))
        exact = np.linalg.eigvalsh(np.einsum("ia,nij,jb->nab", basis, H, basis))[:, 0]
        smallest = response.drucker(mode, lam)
        np.testing.assert_allclose(smallest, exact, rtol=1e-6, atol=1e-7 * np.abs(exact).max())
        assert (smallest > 0).any() and (smallest < 0).any()  # lost within the range, in every mode
    np.testing.assert_allclose(response.drucker("uniaxial", [1.0]), 2.0 * 2.0 * c10, rtol=1e-7)  # 2 mu0


# -- fits ------------------------------------------------------------------------------------------------
def test_fit_recovers_compressible_parameters():
    """Data made by a compressible Mooney-Rivlin law (with volumetric points): c1, c2 and K come back."""
    truth = [0.2, 0.05, 5.0]
    response = fitting._response("mooney_rivlin", 1, False, "log")
    response.set_parameters(truth)
    lam, vol = np.linspace(0.7, 3.0, 12), np.linspace(0.9, 1.1, 9)
    curves = {m: Curve(m, lam, response.nominal_stress(m, lam)) for m in INCOMPRESSIBLE}
    curves["volumetric"] = Curve("volumetric", vol, response.nominal_stress("volumetric", vol))
    result = fit("mooney_rivlin", curves)
    assert not result.incompressible and result.converged
    np.testing.assert_allclose([result.parameters[k] for k in ("c1", "c2", "K")], truth, rtol=1e-8)
    assert result.material == MooneyRivlinParameters(c1=result.parameters["c1"], c2=result.parameters["c2"],
                                                     K=result.parameters["K"])
    fixed = fit("mooney_rivlin", curves, modes=["uniaxial"], bulk_modulus=5.0)  # K given: c1, c2 only
    assert set(fixed.parameters) == {"c1", "c2"} and fixed.bulk_modulus == 5.0
    np.testing.assert_allclose([fixed.parameters["c1"], fixed.parameters["c2"]], truth[:2], rtol=1e-8)


LAME = {"uniaxial": np.linspace(0.85, 1.3, 9), "equibiaxial": np.linspace(0.9, 1.2, 8),
        "volumetric": np.linspace(0.95, 1.05, 6)}  # no point at 1: its round-off stress would get weight 1e16


@pytest.mark.parametrize("law", list(fitting._LAME_ENERGIES))
def test_fit_recovers_a_two_constant_law(law):
    """Data of a compressible two-constant law (lateral faces free): mu and K come back from uniaxial with
    equibiaxial, or with volumetric, data; the [[material]] reads back through the case-file checker."""
    from hyperfem.app.sections import check_materials

    truth = [0.7, 2.3]  # nu = 0.36
    response = fitting._response(law, 1, False, "log")  # the one fit() uses (cached): set before each use
    for second in ("equibiaxial", "volumetric"):
        response.set_parameters(truth)
        curves = {m: Curve(m, LAME[m], response.nominal_stress(m, LAME[m])) for m in ("uniaxial", second)}
        result = fit(law, curves)
        assert not result.incompressible and result.converged and result.stable
        np.testing.assert_allclose([result.parameters["mu"], result.parameters["K"]], truth, rtol=1e-6)
        assert max(e.relative_rms for e in result.errors.values()) < 1e-6
    response.set_parameters(truth)
    lateral = response.states("uniaxial", LAME["uniaxial"])[:, 1]  # the free face: P22 = 0
    assert np.abs(response.principal_stress(response.states("uniaxial", LAME["uniaxial"]))[:, 1]).max() < 1e-9
    assert (np.diff(lateral) < 0).all()
    (material,) = check_materials(tomllib.loads(result.case_table(stress_factor=1e6))["material"], mixed=False,
                                  has_fibres=False)
    np.testing.assert_allclose([material.parameters["mu"], material.parameters["bulk_modulus"]],
                               np.array(truth) * 1e6, rtol=1e-6)
    fixed = fit(law, curves, modes=["uniaxial"], bulk_modulus=2.3)  # K given: mu from one mode
    assert set(fixed.parameters) == {"mu"} and fixed.bulk_modulus == 2.3
    np.testing.assert_allclose(fixed.parameters["mu"], 0.7, rtol=1e-6)


def test_a_round_off_stress_at_the_reference_state_does_not_dominate_the_fit():
    """Data generated at stretch 1 hold a stress of round-off size there, not 0: it is weighted as a zero
    (fitting.ZERO_STRESS), not by 1/|P| ~ 1e16 (stable neo-Hookean came back 10 % off before)."""
    truth = [0.7, 2.3]
    response = fitting._response("stable_neo_hookean", 1, False, "log")
    response.set_parameters(truth)
    stretches = {"uniaxial": np.linspace(0.8, 1.3, 11), "equibiaxial": np.linspace(0.9, 1.2, 7)}  # both hold 1.0
    curves = {m: Curve(m, s, response.nominal_stress(m, s)) for m, s in stretches.items()}
    assert 0.0 < min(np.abs(c.stress).min() for c in curves.values()) < 1e-12  # the point at 1: round-off, not 0
    result = fit("stable_neo_hookean", curves)
    np.testing.assert_allclose([result.parameters["mu"], result.parameters["K"]], truth, rtol=1e-6)


HGO = {"mu": 0.02, "k1": 0.3, "k2": 2.0, "kappa": 0.1}  # MPa, an arterial layer


def _fibre_csv(path, law, parameters, angles, stretches):
    """Data of a fibre law at the given fibre angles (degrees), ``{mode: stretches}``, as a CSV file."""
    response = fitting._response(law, 1, True, "log")  # cached, shared with fit()
    response.set_parameters(parameters)
    lines = ["mode,fibre_angle_deg,stretch,nominal_stress_MPa"]
    for angle in angles:
        for mode, lam in stretches.items():
            P = response.nominal_stress(mode, lam, np.radians(angle))
            lines += [f"{mode},{angle:g},{float(x)!r},{float(y)!r}" for x, y in zip(lam, P, strict=True)]
    if MPI.COMM_WORLD.rank == 0:
        path.write_text("\n".join(lines) + "\n")
    MPI.COMM_WORLD.barrier()
    return path


def _hgo_csv(path):
    """Uniaxial and equibiaxial data of HGO at fibre angles 30 and 60 degrees, as a CSV file."""
    stretches = {"uniaxial": np.linspace(1.02, 1.25, 8), "equibiaxial": np.linspace(1.02, 1.15, 7)}
    return _fibre_csv(path, "holzapfel_gasser_ogden", HGO, (30.0, 60.0), stretches)


def test_hgo_uniaxial_lateral_faces_are_free():
    """Fibres at 30 degrees: the two lateral stretches differ, det F = 1 and tau_22 = tau_33 (no lateral load)."""
    response = fitting._response("holzapfel_gasser_ogden", 1, True, "log")
    response.set_parameters(HGO)
    lam = np.linspace(1.05, 1.3, 6)
    states = response.states("uniaxial", lam, np.radians(30.0))
    assert (states[:, 1] < 0.95 * states[:, 2]).all()  # the fibres pull the width in, the thickness less
    np.testing.assert_allclose(np.prod(states, axis=1), 1.0, rtol=1e-12)
    tau = states * response.principal_stress(states, np.radians(30.0))
    np.testing.assert_allclose(tau[:, 1], tau[:, 2], rtol=1e-8, atol=1e-9 * np.abs(tau).max())
    iso = response.states("uniaxial", lam, np.radians(80.0))  # fibres in compression: isotropic, a = lam^-1/2
    np.testing.assert_allclose(iso[:, 1], lam**-0.5, rtol=1e-8)


def test_fit_recovers_hgo_from_two_angles(shared_tmp):
    """mu, k1, k2, kappa come back from uniaxial and equibiaxial tests at 30 and 60 degrees (a CSV with
    fibre_angle_deg); the [[material]] with its [fibres] and [second_fibres] reads back as a case file."""
    from hyperfem.app.sections import check_fibres, check_materials

    curves = read_curves(_hgo_csv(shared_tmp / "hgo.csv"))
    assert list(curves) == ["uniaxial@30", "uniaxial@60", "equibiaxial@30", "equibiaxial@60"]
    result = fit("holzapfel_gasser_ogden", curves)
    assert result.incompressible and result.converged and result.stable
    np.testing.assert_allclose([result.parameters[k] for k in HGO], list(HGO.values()), rtol=1e-6)
    assert set(result.errors) == set(curves) and max(e.relative_rms for e in result.errors.values()) < 1e-6
    np.testing.assert_allclose(result.nominal_stress("uniaxial", curves["uniaxial@60"].stretch, angle=60.0),
                               curves["uniaxial@60"].stress, rtol=1e-6)
    table = tomllib.loads(result.case_table(stress_factor=1e6))
    (material,) = check_materials(table["material"], mixed=True, has_fibres=True, has_second_fibres=True)
    np.testing.assert_allclose([material.parameters[k] for k in HGO],
                               [HGO["mu"] * 1e6, HGO["k1"] * 1e6, HGO["k2"], HGO["kappa"]], rtol=1e-5)
    check_fibres(table["fibres"])
    np.testing.assert_allclose(table["second_fibres"]["direction"], [np.cos(np.pi / 6), -0.5, 0.0], rtol=1e-5)
    summary = dispatch(["fit", str(shared_tmp / "hgo.csv"), "--law", "holzapfel_gasser_ogden", "--json"])
    np.testing.assert_allclose(summary["parameters"]["k2"], HGO["k2"], rtol=1e-6)
    assert set(summary["rms_MPa"]) == set(curves)


WEISS = {"c1": 1.44, "c2": 0.0, "c3": 0.57, "c4": 48.0, "c5": 467.0, "lambda_star": 1.062}  # MPa, Weiss's tendon


def test_fit_recovers_weiss_along_and_across():
    """Tendon data along (0) and across (90 degrees) the fibres, toe and linear regions: the six constants come
    back; the fitted energy with the law's own toe quadrature gives the same stresses; [fibres] reads back."""
    from hyperfem.app.sections import check_fibres, check_materials
    from hyperfem.materials.weiss import weiss_isochoric

    response = fitting._response("weiss", 1, True, "log")  # cached, shared with fit()
    response.set_parameters(WEISS)
    lam = {"uniaxial": np.linspace(1.01, 1.1, 10), "equibiaxial": np.linspace(1.01, 1.08, 8)}
    curves = [Curve(m, lam[m], response.nominal_stress(m, lam[m], np.radians(a)), a) for a in (0.0, 90.0) for m in lam]
    result = fit("weiss", curves)
    assert result.converged and result.stable
    np.testing.assert_allclose([result.parameters[k] for k in WEISS], list(WEISS.values()), rtol=1e-6, atol=1e-9)
    own = HomogeneousResponse(lambda F, c: weiss_isochoric(F, ufl.as_vector([1.0, 0.0, 0.0]), result.material), [],
                              incompressible=True)  # the case file's energy: its own Gauss points
    np.testing.assert_allclose(own.nominal_stress("uniaxial", lam["uniaxial"]), curves[0].stress, rtol=1e-8)
    table = tomllib.loads(result.case_table(stress_factor=1e6))
    (material,) = check_materials(table["material"], mixed=True, has_fibres=True)
    np.testing.assert_allclose(material.parameters["lambda_star"], 1.062, rtol=1e-6)
    assert check_fibres(table["fibres"]) and "second_fibres" not in table


FUNG = {"c": 0.02, "b1": 12.0, "b2": 6.0, "b3": 4.0, "b4": 2.0, "b5": 1.0, "b6": 1.5,  # c in MPa
        "b7": 3.0, "b8": 2.0, "b9": 2.5}
FUNG_SHEAR = {k: FUNG[k] for k in ("b7", "b8", "b9")}


def _fung_csv(path):
    """Uniaxial and equibiaxial data of Fung orthotropic along (0) and across (90 degrees) its axis a1, as a CSV."""
    stretches = {"uniaxial": np.linspace(1.02, 1.3, 12), "equibiaxial": np.linspace(1.02, 1.2, 10)}
    return _fibre_csv(path, "fung_orthotropic", FUNG, (0.0, 90.0), stretches)


def test_fit_recovers_fung_along_and_across_its_axes(shared_tmp, capsys):
    """c and the normal block b1-b6 come back from uniaxial and equibiaxial tests at 0 and 90 degrees with the shear
    constants b7-b9 fixed (no such test strains them); the fitted energy is fung_orthotropic_isochoric's; the table
    with [fibres] (a1) and [second_fibres] (a2) reads back; the command takes --fix; without b7-b9: one line."""
    from hyperfem.app.sections import check_fibres, check_materials
    from hyperfem.materials.fung import fung_orthotropic_isochoric

    path = _fung_csv(shared_tmp / "fung.csv")
    curves = read_curves(path)
    assert list(curves) == ["uniaxial@0", "uniaxial@90", "equibiaxial@0", "equibiaxial@90"]
    result = fit("fung_orthotropic", curves, fixed=FUNG_SHEAR)
    assert result.incompressible and result.converged and result.stable
    assert result.fixed == ("b7", "b8", "b9")
    np.testing.assert_allclose([result.parameters[k] for k in FUNG], list(FUNG.values()), rtol=1e-6)
    assert max(e.relative_rms for e in result.errors.values()) < 1e-6
    a1, a2 = ufl.as_vector([0.0, 1.0, 0.0]), ufl.as_vector([-1.0, 0.0, 0.0])  # 90 degrees
    own = HomogeneousResponse(lambda F, c: fung_orthotropic_isochoric(F, a1, a2, result.material), [],
                              incompressible=True)  # isotropic lateral stretches: equibiaxial only
    np.testing.assert_allclose(own.nominal_stress("equibiaxial", curves["equibiaxial@90"].stretch),
                               curves["equibiaxial@90"].stress, rtol=1e-6)
    table = tomllib.loads(result.case_table(stress_factor=1e6))
    (material,) = check_materials(table["material"], mixed=True, has_fibres=True, has_second_fibres=True)
    np.testing.assert_allclose(material.parameters["c"], FUNG["c"] * 1e6, rtol=1e-5)
    np.testing.assert_allclose(material.parameters["b7"], FUNG["b7"], rtol=1e-12)
    check_fibres(table["fibres"])
    assert table["second_fibres"]["direction"] == [0.0, 1.0, 0.0]
    summary = dispatch(["fit", str(path), "--law", "fung_orthotropic", "--fix", "b7=3,b8=2,b9=2.5", "--json"])
    assert summary["fixed"] == ["b7", "b8", "b9"] and summary["parameters"]["b9"] == 2.5
    np.testing.assert_allclose(summary["parameters"]["b1"], FUNG["b1"], rtol=1e-6)
    for fixed, expected in (({"b7": 3.0}, "fit: fung_orthotropic needs b8, b9 given in fixed (e.g. --fix b8=1.0): "
                                          "no test along the material axes strains them"),
                            ({**FUNG_SHEAR, "b8": -1.0}, "fit: fixed b8 = -1 is outside the range of "
                                                         "fung_orthotropic [1e-06, 1000]")):
        with pytest.raises(ParameterError) as info:
            fit("fung_orthotropic", curves, fixed=fixed)
        assert str(info.value).startswith(expected) and "\n" not in str(info.value), str(info.value)


MOONEY = {"c1": 0.3, "c2": 0.05}


def test_fit_with_fixed_parameters():
    """Mooney-Rivlin with c2 fixed at its true value gives c1 back, fixed at 0 it stays 0 (c1 takes up the rest);
    Ogden with both exponents fixed gives both mu back; the result, the table and the JSON name them fixed."""
    response = fitting._response("mooney_rivlin", 1, True, "log")
    response.set_parameters(MOONEY)
    lam = np.linspace(1.1, 3.0, 10)
    curves = [Curve(m, lam, response.nominal_stress(m, lam)) for m in ("uniaxial", "equibiaxial")]
    result = fit("mooney_rivlin", curves, fixed={"c2": MOONEY["c2"]})
    assert result.fixed == ("c2",) and result.parameters["c2"] == MOONEY["c2"]
    np.testing.assert_allclose(result.parameters["c1"], MOONEY["c1"], rtol=1e-8)
    assert "  (fixed)" in result.summary() and "# fixed, not fitted: c2" in result.case_table()
    assert result.to_json()["fixed"] == ["c2"] and result.to_json()["parameters"]["c2"] == MOONEY["c2"]
    off = fit("mooney_rivlin", curves, fixed={"c2": 0.0})
    assert off.parameters["c2"] == 0.0 and off.parameters["c1"] > MOONEY["c1"]
    assert max(e.relative_rms for e in off.errors.values()) > 1e-2
    assert fit("mooney_rivlin", curves).fixed == ()

    true = {"mu_1": 0.6, "mu_2": -0.01, "alpha_1": 1.5, "alpha_2": -2.5}
    ogden = fitting._response("ogden", 2, True, "log")
    ogden.set_parameters(true)
    curves = [Curve(m, lam, ogden.nominal_stress(m, lam)) for m in ("uniaxial", "equibiaxial")]
    result = fit("ogden", curves, terms=2, fixed={"alpha_1": 1.5, "alpha_2": -2.5})
    np.testing.assert_allclose([result.parameters[k] for k in true], list(true.values()), rtol=1e-8)
    assert result.fixed == ("alpha_1", "alpha_2") and result.material.alpha == (1.5, -2.5)


def test_fixed_parameter_refusals_are_one_line():
    cases = [
        ("mooney_rivlin", {"c22": 1.0}, "fit: mooney_rivlin has no parameter 'c22' (did you mean 'c2'?) to fix; "
                                        "parameters: c1, c2"),
        ("mooney_rivlin", {"C1": 1.0}, "fit: mooney_rivlin has no parameter 'C1' (did you mean 'c1'?) to fix"),
        ("mooney_rivlin", {"c2": float("nan")}, "fit: fixed c2 must be a finite number, got nan"),
        ("mooney_rivlin", {"c2": -1.0}, "fit: fixed c2 = -1 is outside the range of mooney_rivlin [0, inf]"),
        ("mooney_rivlin", [("c2", 1.0)], "fit: fixed must map parameter names to values, got list"),
        ("ogden", {"mu_1": -1.0}, "fit: fixed mu_1 = -1 is outside the range of ogden [1e-12, inf]"),
        ("neo_hookean", {"bulk_modulus": 1.0}, "fit: neo_hookean has no parameter 'bulk_modulus' to fix; "
                                               "parameters: mu"),
    ]
    for law, fixed, expected in cases:
        with pytest.raises(ParameterError) as info:
            fit(law, treloar_data(), fixed=fixed)
        assert str(info.value).startswith(expected) and "\n" not in str(info.value), str(info.value)
    with pytest.raises(ParameterError, match="fit: fixed is an option of the hyperelastic laws, not of prony"):
        fit("prony", _relaxation(0.0), fixed={"g_1": 0.3})


def test_fibre_angle_refusals(shared_tmp):
    curves = read_curves(_hgo_csv(shared_tmp / "hgo_refusals.csv"))
    cases = [
        ("holzapfel_gasser_ogden", treloar_data(), {}, "fit: holzapfel_gasser_ogden needs the fibre angle of every "
                                                       "curve (a column fibre_angle_deg); uniaxial has none"),
        ("holzapfel_gasser_ogden", curves, {"bulk_modulus": 1.0}, "fit: holzapfel_gasser_ogden is fitted "
                                                                  "incompressible"),
        ("yeoh", curves, {}, "fit: yeoh is isotropic: the fibre angle (fibre_angle_deg, uniaxial@30) is for"),
        ("weiss", curves, {}, "fit: weiss has one fibre family: a test at fibre angle uniaxial@30 shears"),
        ("fung_orthotropic", curves, {}, "fit: fung_orthotropic is orthotropic: a test at fibre angle uniaxial@30 "
                                         "shears, which these homogeneous modes do not; angles 0"),
    ]
    for law, data, kwargs, expected in cases:
        with pytest.raises(ParameterError) as info:
            fit(law, data, **kwargs)
        assert expected in str(info.value), str(info.value)


def test_unstable_fit_says_where():
    """Veronda-Westmann (a skin law) on Treloar: its -c1 c2/2 (I2bar - 3) term loses Drucker stability early."""
    result = fit("veronda_westmann", treloar_data())
    assert not result.stable and result.to_json()["stable"] is False
    lost = {s.mode: s.stretch for s in result.stability_lost}
    assert lost.keys() == set(INCOMPRESSIBLE)
    np.testing.assert_allclose([lost[m] for m in INCOMPRESSIBLE], [1.462, 1.242, 1.397], atol=0.05)
    assert "Drucker stability lost: uniaxial at stretch 1.4" in result.summary()


def test_fit_refuses_bad_requests():
    data = treloar_data()
    cases = [
        (dict(law="ogdn"), "fit: unknown law 'ogdn' (did you mean 'ogden'?); laws: neo_hookean, "),
        (dict(law="yeoh", terms=2), "fit: law 'yeoh' has no terms to choose (only reduced_polynomial, ogden"),
        (dict(law="yeoh", modes=["volumetric"]), "fit: no volumetric data (the data have uniaxial, "),
        (dict(law="yeoh", modes=["pure_sheer"]), "fit: unknown mode 'pure_sheer' (did you mean 'pure_shear'?)"),
        (dict(law="gent", initial={"jm": 3.0}), "fit: gent has no parameter 'jm' (did you mean 'Jm'?)"),
        (dict(law="gent", weighting="log"), "fit: weighting must be one of relative, absolute"),
        (dict(law="hencky", modes=["uniaxial"]), "fit: hencky is compressible and one uniaxial curve does not "
                                                 "determine both mu and the bulk modulus"),
        (dict(law="hencky", volumetric="quadratic"), "fit: hencky has its own volume term"),
        (dict(law="arap"), "fit: law 'arap' is not fitted to test data (mu |F - R|^2 has no volume term"),
    ]
    for kwargs, expected in cases:
        law = kwargs.pop("law")
        with pytest.raises(ParameterError) as info:
            fit(law, data, **kwargs)
        assert expected in str(info.value), str(info.value)


# -- Treloar: the demo -----------------------------------------------------------------------------------
def _demo():
    spec = importlib.util.spec_from_file_location("demo_fit_treloar", ROOT / "demos" / "fit_treloar.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# rms per mode in MPa (uniaxial, equibiaxial, pure shear) of demos/fit_treloar.py, relative weighting
TRELOAR_RMS = {
    "neo_hookean": (1.20439, 0.245288, 0.138081),
    "mooney_rivlin": (1.25047, 0.068817, 0.120602),
    "yeoh": (0.140648, 0.173145, 0.037461),
    "arruda_boyce": (0.359717, 0.088593, 0.150223),
    "gent": (0.390623, 0.085379, 0.158628),
    "ogden (3 terms)": (0.184733, 0.017239, 0.036729),
}


def test_fit_treloar_demo(shared_tmp, capsys):
    """Six laws on Treloar's three modes; Ogden near Ogden (1972); a cube of the fitted Yeoh law reproduces it."""
    summary = _demo().main(["--output", str(shared_tmp)])
    for label, rms in TRELOAR_RMS.items():
        got = summary["laws"][label]
        np.testing.assert_allclose([got["rms_MPa"][m] for m in INCOMPRESSIBLE], rms, rtol=2e-3, err_msg=label)
        assert got["stable"] and got["converged"], label
    ogden = summary["laws"]["ogden (3 terms)"]["parameters"]
    np.testing.assert_allclose(ogden["alpha"], [1.263, 5.145, -2.151], rtol=1e-2)
    np.testing.assert_allclose(ogden["mu"], [0.6352, 0.001002, -0.007162], rtol=2e-2)
    # Ogden's published parameters, through the same response: no better than the fit in uniaxial and equibiaxial
    published = summary["ogden_1972"]["rms_MPa"]
    np.testing.assert_allclose([published[m] for m in INCOMPRESSIBLE], (0.303126, 0.036518, 0.023737), rtol=1e-4)
    assert published["uniaxial"] > TRELOAR_RMS["ogden (3 terms)"][0]
    fe = summary["fe"]
    assert fe["completed"] and fe["law"] == "yeoh"
    assert fe["max_relative_to_homogeneous"] < 1e-7  # the finite elements and the homogeneous response agree
    assert fe["max_relative_to_fit"] < 1e-2  # K = 1e4 mu0 against the incompressible fit (0.68 % at 7.6)
    assert abs(fe["rms_to_data_MPa"] - fe["fit_rms_MPa"]) < 0.01
    if MPI.COMM_WORLD.rank == 0:
        assert (shared_tmp / "fit_treloar.png").stat().st_size > 10_000
        assert json.loads((shared_tmp / "fit_treloar.json").read_text())["fe"]["law"] == "yeoh"
        assert "ogden 1972 (published)" in capsys.readouterr().out


def test_case_table_is_a_case_file():
    """The printed [[material]] reads back through the case-file checker with the fitted values (in Pa)."""
    from hyperfem.app.sections import check_materials
    from hyperfem.app.spec import LAWS

    data = treloar_data()
    for law, terms in (("neo_hookean", None), ("mooney_rivlin", None), ("yeoh", None), ("gent", None),
                       ("arruda_boyce", None), ("reduced_polynomial", 2), ("ogden", 3)):
        result = fit(law, data, terms=terms)
        table = tomllib.loads(result.case_table(stress_factor=1e6))
        if law not in LAWS:  # case files do not read it yet
            continue
        (material,) = check_materials(table["material"], mixed=True, has_fibres=False)
        keys = result.keys()
        for key, value in material.parameters.items():
            expected = np.asarray(keys[key], dtype=float) * (1.0 if key in ("Jm", "lambda_m", "alpha") else 1e6)
            np.testing.assert_allclose(value, expected, rtol=1e-5, err_msg=f"{law}.{key}")


# -- the command ------------------------------------------------------------------------------------------
def test_cli_fit_json_and_png(shared_tmp, capsys):
    png = shared_tmp / "gent.png"
    summary = dispatch(["fit", str(fitting.TRELOAR), "--law", "gent", "--modes", "uniaxial,pure_shear", "--json",
                        "--png", str(png)])
    assert summary["law"] == "gent" and set(summary["rms_MPa"]) == {"uniaxial", "pure_shear"}
    if MPI.COMM_WORLD.rank == 0:
        printed = json.loads(capsys.readouterr().out)
        assert printed["parameters"].keys() == {"mu", "Jm"} and printed["stable"] is True
        assert png.stat().st_size > 10_000
    dispatch(["fit", str(fitting.TRELOAR), "--law", "mooney_rivlin"])
    if MPI.COMM_WORLD.rank == 0:
        out = capsys.readouterr().out
        assert "Drucker stable over the data range" in out and 'law = "mooney_rivlin"' in out
        assert "rms [MPa]" in out and "pure_shear       14" in out


def test_cli_fit_help(capsys):
    with pytest.raises(SystemExit) as exc:
        dispatch(["fit", "--help"])
    assert exc.value.code == 0
    if MPI.COMM_WORLD.rank == 0:
        out = capsys.readouterr().out
        assert out.startswith("usage: hyperfem fit") and "mode,stretch,nominal_stress_MPa" in out


CLI_ERRORS = {
    "missing": (["nofile.csv", "--law", "yeoh"], "fit: data file not found: nofile.csv"),
    "law": ([str(fitting.TRELOAR), "--law", "mooney"], "fit: unknown law 'mooney' (did you mean 'mooney_rivlin'?)"),
    "mode": ([str(fitting.TRELOAR), "--law", "yeoh", "--modes", "uniaxial,equi_biaxial"],
             "fit: unknown mode 'equi_biaxial' (did you mean 'equibiaxial'?)"),
    "fibre law": ([str(fitting.TRELOAR), "--law", "fung_orthotropic"],
                  "fit: fung_orthotropic needs the fibre angle of every curve (a column fibre_angle_deg)"),
    "fixed name": ([str(fitting.TRELOAR), "--law", "mooney_rivlin", "--fix", "c3=0.1"],
                   "fit: mooney_rivlin has no parameter 'c3' to fix; parameters: c1, c2"),
    "fixed range": ([str(fitting.TRELOAR), "--law", "mooney_rivlin", "--fix", "c2=-0.1"],
                    "fit: fixed c2 = -0.1 is outside the range of mooney_rivlin [0, inf]"),
    "no angle": ([str(fitting.TRELOAR), "--law", "holzapfel_gasser_ogden"],
                 "fit: holzapfel_gasser_ogden needs the fibre angle of every curve (a column fibre_angle_deg)"),
    "one mode, two constants": ([str(fitting.TRELOAR), "--law", "hencky", "--modes", "pure_shear"],
                                "fit: hencky is compressible and one pure_shear curve does not determine both"),
}


def test_every_case_file_law_is_fitted_or_says_why():
    from hyperfem.app.spec import LAWS

    assert set(LAWS) <= set(fitting.FIT_LAWS) | set(fitting._NOT_FITTED)
    assert not set(fitting.FIT_LAWS) & set(fitting._NOT_FITTED)


@pytest.mark.parametrize("name", list(CLI_ERRORS))
def test_cli_fit_errors_are_one_line(name, capsys):
    args, expected = CLI_ERRORS[name]
    with pytest.raises(SystemExit) as info:
        run(lambda: dispatch(["fit", *args]))
    assert info.value.code == 1
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert err.startswith("hyperfem: error: " + expected) and err.count("\n") == 1, err
        assert "Traceback" not in err
    else:
        assert err == ""


# -- relaxation: a Prony series ---------------------------------------------------------------------------
TRUE_PRONY = PronySeries(g=(0.3, 0.2), tau=(0.2, 1.0))
RELAX_TIMES = np.linspace(0.0, 5.0, 51)


def _relaxation(ramp: float, P0: float = 2.5, series: PronySeries = TRUE_PRONY, times=RELAX_TIMES) -> RelaxationCurve:
    """Synthetic stress data of a ramp over ``ramp`` then held: P0 r(t) [g_inf + sum g_i a_i e^(-(t - t_r)/tau_i)]."""
    if ramp > 0:
        y = P0 * np.minimum(times / ramp, 1.0) * series.ramp_and_hold(times, ramp)
    else:
        y = P0 * series.relaxation(times)
    return RelaxationCurve(times, y, "stress", ramp)


@pytest.mark.parametrize("ramp", [0.0, 0.5])
def test_prony_fit_recovers_a_two_term_series(ramp):
    """Exact data of (g, tau) = ((0.3, 0.2), (0.2, 1)) s, P0 = 2.5: the times fitted from log-spaced starts."""
    result = fit("prony", _relaxation(ramp), terms=2)
    assert isinstance(result, PronyFit) and result.converged and result.tau_fitted
    np.testing.assert_allclose(result.prony.g, TRUE_PRONY.g, rtol=1e-6)
    np.testing.assert_allclose(result.prony.tau, TRUE_PRONY.tau, rtol=1e-6)  # measured ~1e-15
    assert result.instantaneous == pytest.approx(2.5, rel=1e-6)
    assert result.errors["relaxation"].relative_rms < 1e-6
    # the series is the solver's: a PronySeries a Viscoelastic takes, and its response is ramp_and_hold's
    Viscoelastic(SplitEnergy(lambda F: neo_hookean_isochoric(F, 1.0), 100.0), result.prony)
    np.testing.assert_allclose(result.response(RELAX_TIMES), _relaxation(ramp).value, rtol=1e-6)
    fixed = fit("prony", _relaxation(ramp), tau=(1.0, 0.2))  # given times: linear, non-negative least squares
    assert not fixed.tau_fitted and fixed.prony.tau == (0.2, 1.0)
    np.testing.assert_allclose(fixed.prony.g, TRUE_PRONY.g, rtol=1e-9)


def test_prony_fit_of_the_normalised_modulus():
    curve = RelaxationCurve(RELAX_TIMES, TRUE_PRONY.relaxation(RELAX_TIMES), "modulus")
    result = fit_prony(curve, terms=2)
    np.testing.assert_allclose([*result.prony.g, *result.prony.tau], [0.3, 0.2, 0.2, 1.0], rtol=1e-6)
    assert result.instantaneous == 1.0 and "rms" in result.to_json() and "rms_MPa" not in result.to_json()
    table = tomllib.loads(result.case_table())["material"]["viscoelastic"]
    np.testing.assert_allclose([*table["g"], *table["tau"]], [0.3, 0.2, 0.2, 1.0], rtol=1e-5)


def test_prony_fit_of_noisy_data_is_sensible():
    """1 % multiplicative noise: the fit's rms is the noise's, the curve and the series near the truth.

    Measured over the seeds 0-7: relative rms 0.008-0.010, the curve within 0.2-0.7 % of the clean one
    (of its peak), g_inf 0.491-0.510; seed 1: g = (0.286, 0.218), tau = (0.182, 0.920).
    """
    rng = np.random.default_rng(1)
    clean = _relaxation(0.5)
    noisy = RelaxationCurve(clean.time, clean.value * (1.0 + 0.01 * rng.standard_normal(clean.time.size)), "stress",
                            0.5)
    result = fit("prony", noisy, terms=2)
    assert 0.005 < result.errors["relaxation"].relative_rms < 0.012
    assert np.max(np.abs(result.response(clean.time) - clean.value)) < 0.01 * clean.value.max()
    assert result.prony.g_inf == pytest.approx(0.5, abs=0.02)
    np.testing.assert_allclose(result.prony.g, TRUE_PRONY.g, atol=0.04)
    np.testing.assert_allclose(result.prony.tau, TRUE_PRONY.tau, rtol=0.2)
    assert all(r > 10.0 * result.errors["relaxation"].rms for r in result.term_rms)  # every term carries the fit


RELAXATION_ERRORS = {
    "negative time": ("time_s,nominal_stress_MPa\n-1,1\n0,1\n1,0.8\n", {}, ":2: time_s must be >= 0"),
    "too few points": ("time_s,nominal_stress_MPa\n0,1\n1,0.8\n2,0.7\n3,0.65\n", {"terms": 2},
                       "fit: 4 relaxation points for 5 unknowns (2 g_i, 2 tau_i, P0): need at least 6"),
    "relaxes to zero": ("time_s,nominal_stress_MPa\n" + "".join(f"{t},{np.exp(-t)!s}\n" for t in range(8)),
                        {"terms": 1}, "fit: the fitted series relaxes completely (g_inf = 0, sum of g_i = 1)"),
    "no value column": ("time_s,stress\n0,1\n", {}, "neither of the columns nominal_stress_MPa and relaxation_modulus"),
    "sign": ("time_s,nominal_stress_MPa\n0,1\n1,-0.8\n2,0.7\n", {}, "must keep one sign"),
    "tau": ("time_s,nominal_stress_MPa\n0,1\n1,0.8\n2,0.7\n", {"tau": (0.5, -1.0)},
            "tau must hold relaxation times > 0"),
}


@pytest.mark.parametrize("name", list(RELAXATION_ERRORS))
def test_prony_fit_refuses_bad_data(name, tmp_path):
    text, kwargs, expected = RELAXATION_ERRORS[name]
    path = tmp_path / f"{name.replace(' ', '_')}.csv"
    path.write_text(text)
    with pytest.raises(ParameterError) as info:
        fit("prony", path, **kwargs)
    assert expected in str(info.value) and "\n" not in str(info.value), str(info.value)
    with pytest.raises(ParameterError, match="fit: bulk_modulus is an option of the hyperelastic laws, not of prony"):
        fit("prony", _relaxation(0.0), bulk_modulus=1.0)
    with pytest.raises(ParameterError, match="fit: tau is an option of law 'prony'"):
        fit("yeoh", treloar_data(), tau=(1.0,))


def test_cli_fit_prony_json(shared_tmp, capsys):
    """``hyperfem fit RELAX.csv --law prony --ramp-time 0.5 --json``: g, tau, rms by mode; the text has the table."""
    curve = _relaxation(0.5, times=np.linspace(0.0, 5.0, 26))
    path = shared_tmp / "relax.csv"
    if MPI.COMM_WORLD.rank == 0:
        path.write_text("time_s,nominal_stress_MPa\n" + "".join(f"{t:.17g},{y:.17g}\n" for t, y in
                                                                 zip(curve.time, curve.value, strict=True)))
    MPI.COMM_WORLD.Barrier()
    png = shared_tmp / "relax.png"
    summary = dispatch(["fit", str(path), "--law", "prony", "--terms", "2", "--ramp-time", "0.5", "--json",
                        "--png", str(png)])
    np.testing.assert_allclose(summary["parameters"]["g"], [0.3, 0.2], rtol=1e-6)
    if MPI.COMM_WORLD.rank == 0:
        printed = json.loads(capsys.readouterr().out)
        assert printed["law"] == "prony" and set(printed["rms_MPa"]) == {"relaxation"}
        np.testing.assert_allclose(printed["parameters"]["tau"], [0.2, 1.0], rtol=1e-6)
        assert printed["instantaneous_stress_MPa"] == pytest.approx(2.5) and png.stat().st_size > 10_000
    dispatch(["fit", str(path), "--law", "prony", "--tau", "0.2,1", "--ramp-time", "0.5"])
    if MPI.COMM_WORLD.rank == 0:
        out = capsys.readouterr().out
        assert "[material.viscoelastic]\ng = [0.3, 0.2]\ntau = [0.2, 1]" in out and "relaxation times given" in out
    with pytest.raises(SystemExit) as info:
        run(lambda: dispatch(["fit", str(path), "--law", "yeoh"]))
    assert info.value.code == 1
    if MPI.COMM_WORLD.rank == 0:
        err = capsys.readouterr().err
        assert err.startswith("hyperfem: error: fit: ") and "fit them with law 'prony'" in err
        assert err.count("\n") == 1


@pytest.mark.parametrize("name", ["negative time", "too few points", "relaxes to zero"])
def test_cli_fit_prony_errors_are_one_line(name, shared_tmp, capsys):
    text, kwargs, expected = RELAXATION_ERRORS[name]
    path = shared_tmp / f"cli_{name.replace(' ', '_')}.csv"
    if MPI.COMM_WORLD.rank == 0:
        path.write_text(text)
    MPI.COMM_WORLD.Barrier()
    with pytest.raises(SystemExit) as info:
        run(lambda: dispatch(["fit", str(path), "--law", "prony", "--terms", str(kwargs.get("terms", 3))]))
    assert info.value.code == 1
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert err.startswith("hyperfem: error: fit: ") and expected in err and err.count("\n") == 1, err
    else:
        assert err == ""


# -- relaxation rows in a file of hyperelastic test data ----------------------------------------------------
def _combined_csv(path: Path, stretches=(1.5,)) -> RelaxationCurve:
    """Treloar's uniaxial rows, then the relaxation rows of ``_relaxation(0.5)`` held at ``stretches`` (cycled)."""
    curve = _relaxation(0.5, times=np.linspace(0.0, 5.0, 26))
    uniaxial = treloar_data()["uniaxial"]
    lines = ["mode,stretch,nominal_stress_MPa,time_s"]
    lines += [f"uniaxial,{lam:.17g},{P:.17g}," for lam, P in zip(uniaxial.stretch, uniaxial.stress, strict=True)]
    lines += [f"relaxation,{stretches[i % len(stretches)]:g},{y:.17g},{t:.17g}"
              for i, (t, y) in enumerate(zip(curve.time, curve.value, strict=True))]
    if MPI.COMM_WORLD.rank == 0:
        path.write_text("\n".join(lines) + "\n")
    MPI.COMM_WORLD.Barrier()
    return curve


def test_relaxation_rows_of_a_test_data_file(shared_tmp, capsys):
    """One file, uniaxial and relaxation rows: the hyperelastic laws fit the former and say the latter are prony's;
    prony fits the latter (exact data: the series back to 1e-6)."""
    path = shared_tmp / "combined.csv"
    curve = _combined_csv(path)
    curves = read_curves(path)
    assert list(curves) == ["uniaxial"] and fitting.relaxation_rows(path) == curve.time.size
    np.testing.assert_array_equal(curves["uniaxial"].stretch, treloar_data()["uniaxial"].stretch)
    result = fit("prony", path, terms=2, ramp_time=0.5)
    np.testing.assert_allclose([*result.prony.g, *result.prony.tau], [0.3, 0.2, 0.2, 1.0], rtol=1e-6)
    assert result.instantaneous == pytest.approx(2.5, rel=1e-6)
    summary = dispatch(["fit", str(path), "--law", "neo_hookean"])
    assert summary["relaxation_rows_left_out"] == 26 and set(summary["rms_MPa"]) == {"uniaxial"}
    if MPI.COMM_WORLD.rank == 0:
        assert "26 rows of mode relaxation left out: fit them with hyperfem fit" in capsys.readouterr().out
    with pytest.raises(ParameterError, match="fit: relaxation data are fitted by law 'prony'"):
        fit("yeoh", path, modes=["uniaxial", "relaxation"])


COMBINED_ERRORS = {
    "two stretches": (None, "prony", "relaxation rows at 2 stretches (1.5, 2): one relaxation test"),
    "no time column": ("mode,stretch,nominal_stress_MPa\nuniaxial,1.5,0.3\nrelaxation,1.5,0.3\n", "prony",
                       "no column 'time_s' (its rows of mode relaxation need the time of each point)"),
    "only relaxation": ("mode,stretch,nominal_stress_MPa,time_s\nrelaxation,1.5,0.3,0\nrelaxation,1.5,0.2,1\n",
                        "yeoh", "only relaxation rows (mode relaxation): fit them with law 'prony'"),
    "no relaxation rows": ("mode,stretch,nominal_stress_MPa,time_s\nuniaxial,1.5,0.3,\n", "prony",
                           "no rows of mode relaxation (modes found: uniaxial): fit these data with a hyperelastic"),
    "misspelt": ("mode,stretch,nominal_stress_MPa,time_s\nrelax,1.5,0.3,0\n", "yeoh",
                 ":2: unknown mode 'relax' (did you mean 'relaxation'?)"),
}


@pytest.mark.parametrize("name", list(COMBINED_ERRORS))
def test_relaxation_rows_refused_in_one_line(name, shared_tmp, capsys):
    text, law, expected = COMBINED_ERRORS[name]
    path = shared_tmp / f"combined_{name.replace(' ', '_')}.csv"
    if text is None:
        _combined_csv(path, stretches=(1.5, 2.0))
    elif MPI.COMM_WORLD.rank == 0:
        path.write_text(text)
    MPI.COMM_WORLD.Barrier()
    with pytest.raises(SystemExit) as info:
        run(lambda: dispatch(["fit", str(path), "--law", law]))
    assert info.value.code == 1
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert err.startswith("hyperfem: error: fit: ") and expected in err and err.count("\n") == 1, err
    else:
        assert err == ""
