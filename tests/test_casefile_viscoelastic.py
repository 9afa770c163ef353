"""Viscoelastic materials in case files: ``[material.viscoelastic] g, tau, time_scale``.

``cases/relaxation.toml`` is the ramp-and-hold of ``demos/relaxation.py`` (a Yeoh bar
pulled to stretch 1.5 in 0.5 s, held to 3 s) on the meshed unit cube of
``meshes/block_h0.34.msh``: the deformation is homogeneous, so its reaction is the
demo's nominal stress at every step (the demo runs the 6-tetrahedron cube in MPa,
the case the 184-tetrahedron cube in Pa). Besides:

* ``time_scale`` reads the load factor in other units: the ramp in load-factor units
  of 2 s gives the run in s, row for row;
* the three-field formulation gives the same rows, and the same Cauchy stress field;
* a time integration without inertia (``scheme = "quasi_static"``) moves the history as
  the quasi-static ramp does;
* a run killed after a step and restarted from its last checkpoint (mid-hold) gives the
  rows of the uninterrupted one (the history is in the checkpoint);
* 1 rank = 2 ranks;
* one-line errors for the laws without a split, the stepping that has no clock,
  generalized-alpha, a dynamic time scale, a bad series.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from mpi4py import MPI

from hyperfem.app import build, load_case, script
from hyperfem.app.casefile import CaseFileError
from hyperfem.app.plan import checkpoint_folder
from hyperfem.materials import Viscoelastic
from hyperfem.simulation import Output
from hyperfem.simulation.measures import CellFunctions, cauchy_stress

from case_texts import ROOT

CASE = ROOT / "cases" / "relaxation.toml"
QUIET = ["output.progress=false", "output.fields=[]"]
SHORT = ["stepping.end=1.0"]  # the ramp and half a second of the hold: 20 steps


def _case(folder, *overrides):
    return load_case(CASE, [f"output.directory={str(folder)!r}", *QUIET, *overrides])


def _rows(summary: dict) -> tuple[np.ndarray, np.ndarray]:
    """Times and the reaction on the top face (the nominal stress in Pa) of every row."""
    rows = summary["rows"]
    return np.array([r["time"] for r in rows]), np.array([r["reaction_top_Fz"] for r in rows])


def _demo():
    path = ROOT / "demos" / "relaxation.py"
    spec = importlib.util.spec_from_file_location("demo_relaxation", path)
    assert spec is not None and spec.loader is not None
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    return demo


def test_the_example_case_is_the_demo(shared_tmp):
    """The case's reaction is the demo's stress (MPa) at every step; it relaxes to 0.7354 of the ramp's end."""
    built = build(_case(shared_tmp))
    assert isinstance(built.material, Viscoelastic) and built.material.time_scale == 1.0
    t, P = _rows(built.simulation.run())
    P = P / 1e6  # MPa, as the demo
    demo = _demo().relaxation(MPI.COMM_WORLD, 1.5, 3.0, 0.05)
    assert len(t) == len(demo["time"]) == 61
    assert np.max(np.abs(t - demo["time"])) < 1e-12  # measured 2.7e-15 (the case's steps are added up)
    assert np.max(np.abs(P - demo["stress"])) < 1e-8 * np.max(P)  # measured 1.3e-13
    ramp_end = int(np.argmin(np.abs(t - 0.5)))
    assert P[ramp_end] == pytest.approx(0.7053, abs=1e-4) and P[-1] == pytest.approx(0.5187, abs=1e-4)
    assert P[-1] / P[ramp_end] == pytest.approx(0.7354, abs=1e-4)  # demos/relaxation.py's P(3 s)/P(t_r)


def test_print_python_names_the_prony_series(shared_tmp):
    text = script(_case(shared_tmp, "material[0].viscoelastic.time_scale=2.0"))
    compile(text, "relaxation.py", "exec")
    split = "elastic = SplitEnergy(lambda F: hf.materials.yeoh_isochoric(F, params), params.K, params.volumetric)"
    assert split in text
    assert ("    material = hf.materials.Viscoelastic(\n        elastic,\n"
            "        hf.materials.PronySeries(g=(0.3, 0.2), tau=(0.1, 1.0)),\n        time_scale=2.0,\n    )") in text
    assert "problem = hf.HyperelasticProblem(domain, material," in text


def test_time_scale_reads_the_load_factor_in_other_units(shared_tmp):
    """The ramp in load-factor units of 2 s (t1 = 0.25, end = 0.5, steps of 0.025) is the run in s, row for row."""
    t, P = _rows(build(_case(shared_tmp / "s", *SHORT)).simulation.run())
    scaled = _case(shared_tmp / "scaled", "material[0].viscoelastic.time_scale=2.0", "bc[3].profile.t1=0.25",
                   "stepping.end=0.5", "stepping.increment=0.025", "stepping.max_increment=0.025")
    t2, P2 = _rows(build(scaled).simulation.run())
    assert np.max(np.abs(2.0 * t2 - t)) < 1e-12
    assert np.max(np.abs(P2 - P)) < 1e-10 * np.max(P)  # measured 0 (the same arithmetic)
    assert P[-1] < 0.9 * P[10]  # it relaxed in the hold: 0.85 of the ramp's end after 0.5 s


def test_a_time_integration_without_inertia_moves_the_history_as_the_ramp_does(shared_tmp):
    t, P = _rows(build(_case(shared_tmp / "ramp", *SHORT)).simulation.run())
    dynamic = _case(shared_tmp / "dyn", 'stepping={type = "dynamic", scheme = "quasi_static", dt = 0.05, t_end = 1.0}')
    t2, P2 = _rows(build(dynamic).simulation.run())
    assert np.max(np.abs(t2 - t)) < 1e-12
    assert np.max(np.abs(P2 - P)) < 1e-8 * np.max(P)  # measured 1.1e-15


def test_the_mixed_formulation_relaxes_as_the_displacement_one(shared_tmp):
    """formulation = "mixed": Viscoelastic(SplitEnergy) in MixedHyperelasticProblem (P2/P1/P1), the same rows
    (the homogeneous stretch is exact in both) to the tolerance of the three-field Newton."""
    over = ["stepping.end=0.7", 'output.fields=["von_mises"]', "output.times=[0.7]"]  # ramp, 0.2 s of hold
    u = build(_case(shared_tmp / "u", *over))
    t, P = _rows(u.simulation.run())
    mixed = _case(shared_tmp / "mixed", *over, 'problem.formulation="mixed"')
    assert "problem = MixedHyperelasticProblem(domain, material," in script(mixed)
    m = build(mixed)
    t2, P2 = _rows(m.simulation.run())
    assert np.max(np.abs(t2 - t)) < 1e-12
    assert np.max(np.abs(P2 - P)) < 1e-6 * np.max(P)  # measured 1.9e-7
    # the stress fields of the three-field problem (its p, theta and the history) = the displacement one's;
    # homogeneous: sigma_zz = P_zz / a^2 everywhere; measured 1.2e-7 apart (0.956 against P_zz 0.638 MPa)
    sigma = {}
    for name, built in (("u", u), ("mixed", m)):
        cells = CellFunctions(built.domain, {"s": cauchy_stress(built.problem, {None: built.material})})
        cells.refresh()
        local = cells.functions[0].x.array.reshape(-1, 3, 3)
        sigma[name] = MPI.COMM_WORLD.allreduce(local[:, 2, 2].max() if local.size else -np.inf, op=MPI.MAX)
    assert abs(sigma["mixed"] - sigma["u"]) < 1e-6 * sigma["u"] and sigma["u"] > P[-1]


class _Interrupt(Exception):
    """Stands for a kill after a given step."""


class _StopAfter(Output):
    def __init__(self, step: int):
        self.stop = step

    def write(self, sim, step) -> None:
        if step is not None and step.step >= self.stop:
            raise _Interrupt(f"interrupted after step {step.step}")


def test_a_killed_run_restarted_from_its_checkpoint_is_the_uninterrupted_one(shared_tmp):
    """Checkpoints every 7 steps; killed after step 16 (t = 0.8, in the hold), continued from step 14."""
    over = [*SHORT, "output.checkpoint_every=7"]
    reference = build(_case(shared_tmp / "full", *over)).simulation.run()
    cut = build(_case(shared_tmp / "cut", *over)).simulation
    cut.outputs.append(_StopAfter(16))
    with pytest.raises(_Interrupt):
        cut.run()
    case = _case(shared_tmp / "cut", *over)
    summary = build(case).simulation.run(restart=checkpoint_folder(case))
    assert summary["restarted_from"].endswith("step-000014") and summary["completed"]
    assert summary["steps"] == reference["steps"] == 20
    (t, P), (t_ref, P_ref) = _rows(summary), _rows(reference)
    assert np.array_equal(t, t_ref)
    assert np.max(np.abs(P - P_ref)) <= 1e-10 * np.max(np.abs(P_ref))  # measured 0 on 1 and on 2 ranks


def test_one_rank_equals_two_ranks(shared_tmp):
    comm = MPI.COMM_WORLD
    if comm.size < 2:
        pytest.skip("compares a 1-rank run with the run on the ranks of mpiexec -n 2")
    one = _rows(build(_case(shared_tmp / "one", *SHORT), MPI.COMM_SELF).simulation.run()) if comm.rank == 0 else None
    t1, P1 = comm.bcast(one, root=0)
    t2, P2 = _rows(build(_case(shared_tmp / "two", *SHORT), comm).simulation.run())
    assert np.array_equal(t1, t2)
    assert np.max(np.abs(P2 - P1)) < 1e-9 * np.max(np.abs(P1))


_NO_SPLIT = 'material[0]={law = "saint_venant_kirchhoff", E = 1e6, nu = 0.3, viscoelastic = {g = [0.3], tau = [1.0]}}'
_MUSCLE = 'material[0]={law = "muscle", preset = "muscle", viscoelastic = {g = [0.3], tau = [1.0]}}'
_DYNAMIC = 'stepping={type = "dynamic", scheme = "quasi_static", dt = 0.05, t_end = 1.0}'


@pytest.mark.parametrize(
    ("overrides", "expected"),
    [
        ([_NO_SPLIT], "material[0].viscoelastic: law 'saint_venant_kirchhoff' cannot be viscoelastic: it has no "
                      "isochoric/volumetric split"),
        ([_MUSCLE], "material[0].viscoelastic: law 'muscle' cannot be viscoelastic: its isochoric part holds the "
                    "active fibre stress"),
        (["material[0].viscoelastic.g=[0.6, 0.5]"], "material[0].viscoelastic: PronySeries: the moduli must sum to "
                                                    "less than 1"),
        (["material[0].viscoelastic.tau=[0.1]"], "material[0].viscoelastic: PronySeries: 2 moduli g but 1 relaxation"),
        (["material[0].viscoelastic.tau=[0.1, -1.0]"], "material[0].viscoelastic.tau[1]: must be > 0"),
        (["material[0].viscoelastic.taus=[1.0]"], "material[0].viscoelastic.taus: unknown key (did you mean 'tau'?)"),
        (["material[0].viscoelastic.time_scale=0.0"], "material[0].viscoelastic.time_scale: must be > 0"),
        (['stepping={type = "arc_length"}'], 'material[0].viscoelastic: not with stepping type = "arc_length"'),
        (['stepping={type = "dynamic", scheme = "generalized_alpha", dt = 0.05, t_end = 1.0}'],
         'material[0].viscoelastic: not with scheme = "generalized_alpha"'),
        ([_DYNAMIC, "material[0].viscoelastic.time_scale=2.0"],
         "material[0].viscoelastic.time_scale: a dynamic run's time is in s, so time_scale must be 1, got 2.0"),
        (["stepping.end=-1.0"], "stepping.end: a viscoelastic material (material[0]) needs time to run forward"),
    ],
)
def test_bad_viscoelastic_cases_are_one_line_errors(overrides, expected):
    with pytest.raises(CaseFileError) as info:
        load_case(CASE, overrides)
    message = str(info.value)
    assert expected in message and "\n" not in message, message


def test_every_split_law_takes_a_prony_series():
    """neo_hookean, mooney_rivlin, the rubber and the tissue laws: each material becomes Viscoelastic(SplitEnergy)."""
    from hyperfem.app.spec import FIBRE_LAWS, SECOND_FIBRE_LAWS, VISCOELASTIC_LAWS

    laws = {
        "neo_hookean": 'E = 1e6, nu = 0.45, volumetric = "quadratic"',
        "mooney_rivlin": "c1 = 3e4, c2 = 1e4, K = 3e6",
        "yeoh": "c10 = 2e5, c20 = -2e3, c30 = 1e2, K = 5e7",
        "reduced_polynomial": "coefficients = [2e5, -2e3], K = 5e7",
        "gent": "mu = 4e5, Jm = 30.0, K = 5e7",
        "arruda_boyce": "mu = 4e5, lambda_m = 3.0, K = 5e7",
        "veronda_westmann": "c1 = 2e3, c2 = 10.0, K = 5e7",
        "ogden": "mu = [6.3e5, 1.2e3], alpha = [1.3, 5.0], K = 5e7",
        "holzapfel_gasser_ogden": "mu = 7.64e3, k1 = 9.966e5, k2 = 524.6, kappa = 0.226, K = 5e7",
        "weiss": "c1 = 1.44e6, c2 = 0.0, c3 = 5.7e5, c4 = 48.0, c5 = 4.671e8, lambda_star = 1.062, K = 5e7",
        "fung_orthotropic": "c = 1e4, b1 = 10.0, b2 = 5.0, b3 = 5.0, b4 = 1.0, b5 = 1.0, b6 = 1.0, b7 = 3.0, "
                            "b8 = 3.0, b9 = 3.0, K = 5e7",
    }
    assert set(laws) == set(VISCOELASTIC_LAWS)
    fibres = 'fibres={type = "constant", direction = [0.0, 0.0, 1.0]}'
    second = 'second_fibres={type = "constant", direction = [1.0, 0.0, 0.0]}'
    for law, constants in laws.items():
        table = f'material[0]={{law = "{law}", {constants}, viscoelastic = {{g = [0.3], tau = [1.0]}}}}'
        directions = [fibres] if law in FIBRE_LAWS else []
        directions += [second] if law in SECOND_FIBRE_LAWS else []
        case = load_case(CASE, [table, *directions])
        assert case.materials[0].viscoelastic is not None
        text = script(case)
        assert "elastic = SplitEnergy(" in text and "_isochoric(F, " in text, law
        assert "material = hf.materials.Viscoelastic(elastic, hf.materials.PronySeries(g=(0.3,), tau=(1.0,)))" in text
