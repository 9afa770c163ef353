"""TOML case files: the example cases validate, the schema's messages name the key, the case maps 1:1 onto the API.

In-process and cheap (no solve); runs serially and under ``mpiexec -n 2``
(every rank checks the same file and raises the same error).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

import hyperfem as hf
from hyperfem.app import check_groups, load_case, plan, script
from hyperfem.app.build import build_domain
from hyperfem.app.casefile import CaseFileError, apply_overrides, check_case, parse_toml
from hyperfem.app.calls import Call, evaluate, source
from hyperfem.app.plan import must_hit_times
from hyperfem.app.spec import LAME_LAWS
from hyperfem.loading import AffineField, Scaled, Table

from case_texts import BASE, MESH, ROOT

CASES = ROOT / "cases"


@pytest.fixture
def write(tmp_path):
    """Write a case file (each rank its own) and return its path."""

    def _write(text: str, name: str = "case.toml") -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path

    return _write


def _error(path: Path, overrides=()) -> str:
    with pytest.raises(CaseFileError) as info:
        load_case(path, overrides)
    return str(info.value)


# -- the example cases ------------------------------------------------------------------------
@pytest.mark.parametrize(
    "name, materials, dynamic, mixed",
    [
        ("bend", 1, False, False),
        ("twist", 1, False, False),
        ("block_mixed", 1, False, True),
        ("dynamics_bend", 1, True, False),
        ("muscle", 3, False, True),
    ],
)
def test_example_case_validates(name, materials, dynamic, mixed):
    """Each example case passes the schema, its script compiles, and every group it names is in its mesh."""
    case = load_case(CASES / f"{name}.toml")
    assert case.name == name
    assert len(case.materials) == materials and case.dynamic is dynamic and case.mixed is mixed
    compile(script(case), f"{name}.py", "exec")
    check_groups(case, build_domain(case, MPI.COMM_WORLD))


def test_case_maps_one_to_one_onto_the_api(write):
    """The statements are calls of the API objects themselves with exactly the given keys (defaults for the rest)."""
    case = load_case(write(BASE + "\n[stepping]\nincrement = 0.5\n[output]\nprobes = [[4.5, 1.5, 1.5]]\n"))
    by_target = {s.target: s for s in plan(case)}
    assert by_target["domain"].value.function is hf.read_mesh
    assert source(by_target["domain"].value) == f"hf.read_mesh({str(MESH)!r}, comm)"
    assert source(by_target["params"].value) == "hf.materials.LameParameters.from_youngs(E=1000000.0, nu=0.3)"
    assert source(by_target["material"].value) == "hf.materials.with_parameters(hf.materials.neo_hookean, params)"
    assert [(k, source(v)) for k, v in by_target["bcs"].items] == [("bc[0]", "hf.Clamp('clamped')")]
    assert by_target["bcs"].items[0][1].function is hf.Clamp
    loads = [(k, source(v)) for k, v in by_target["loads"].items]
    assert loads == [("load[0]", "hf.DeadTraction('free_end', (0.0, -5000.0, 0.0))")]
    assert source(by_target["problem"].value) == "hf.HyperelasticProblem(domain, material, bcs=bcs, loads=loads)"
    assert source(by_target["solver"].value) == "hf.NewtonSolver(problem)"
    assert source(by_target["stepping"].value) == "hf.LoadStepping(initial_increment=0.5)"
    outputs = [node.function.__name__ for _, node in by_target["outputs"].items]
    assert outputs == [
        "Probe", "Reactions", "CSVLog", "JSONSummary", "ConvergenceLog", "FieldOutput", "Checkpoint", "Progress"
    ]
    assert all(isinstance(node, Call) for _, node in by_target["outputs"].items)
    checkpoint = dict(by_target["outputs"].items)["output.checkpoint_every"]
    assert source(checkpoint) == "Checkpoint(out / 'case.checkpoint', every=10)"
    assert case.output.directory == Path("output") / "case"


def test_lame_laws_build_their_parameters(write, tmp_path):
    """Every isotropic law gets the Lamé pair of its E/nu, mu/lambda or mu/bulk_modulus."""
    expected = hf.materials.LameParameters.from_youngs(2.0e6, 0.25)
    for law in LAME_LAWS:
        for constants in ("E = 2.0e6\nnu = 0.25", f"mu = {expected.mu!r}\nlambda = {expected.lmbda!r}",
                          f"mu = {expected.mu!r}\nbulk_modulus = {expected.bulk_modulus!r}"):
            text = BASE.replace("E = 1.0e6\nnu = 0.3", constants).replace("neo_hookean", law)
            case = load_case(write(text), output=tmp_path / "out")
            variables = {"comm": MPI.COMM_WORLD}
            for statement in plan(case):
                if statement.target in ("params", "material"):
                    variables[statement.target] = evaluate(statement.value, variables)
            params = variables["params"]
            assert math.isclose(params.mu, expected.mu, rel_tol=1e-12)
            assert math.isclose(params.lmbda, expected.lmbda, rel_tol=1e-9)
            assert callable(variables["material"])


# -- the bad-input catalogue (in-process) -------------------------------------------------------
def test_toml_syntax_error_names_line_and_column(write):
    path = write("[mesh]\nfile = 'a.msh'\n[[material]\nlaw = 1\n")
    message = _error(path)
    assert message.startswith(f"{path}:3:") and "TOML syntax error" in message


@pytest.mark.parametrize(
    "old, new, expected",
    [
        ('boundary = "clamped"', 'boundry = "clamped"', "bc[0].boundry: unknown key (did you mean 'boundary'?)"),
        ("[[material]]", "[[materials]]", "materials: unknown key (did you mean 'material'?)"),
        ("nu = 0.3", "nu = 0.3\ndensty = 1000.0", "material[0].densty: unknown key (did you mean 'density'?)"),
        ('law = "neo_hookean"', 'law = "neohookean"', "material[0].law: unknown value 'neohookean' (did you mean"),
        ('type = "dead_traction"', 'type = "dead_tracton"', "load[0].type: unknown value 'dead_tracton' (did you mean"),
        ("E = 1.0e6", 'E = "1e6"', "material[0].E: expected a number, got a string ('1e6')"),
        ("value = [0.0, -5.0e3, 0.0]", 'value = "down"', "load[0].value: expected an array of numbers, got a string"),
        ('boundary = "clamped"', "", "bc[0]: missing required key 'boundary'"),
        ("nu = 0.3", "nu = 0.5", "material[0].nu: Poisson's ratio must lie in (-1, 0.5), got 0.5"),
        ("nu = 0.3", "nu = 0.3\ndensity = -1000.0", "material[0].density: must be > 0, got -1000.0"),
        ("E = 1.0e6", "E = 0.0", "material[0].E: must be > 0, got 0.0"),
        ("nu = 0.3", "nu = 0.3\nmu = 1.0", "material[0]: give the elastic constants as E and nu, mu and lambda"),
    ],
)
def test_bad_entry_names_its_key(write, old, new, expected):
    assert old in BASE
    path = write(BASE.replace(old, new, 1))
    message = _error(path)
    assert message.startswith(f"{path}: ") and expected in message, message


def test_conflicting_conditions_on_one_boundary(write):
    conflict = BASE + '\n[[bc]]\ntype = "displacement"\nboundary = "clamped"\nvalue = [0.1]\ncomponents = ["y"]\n'
    message = _error(write(conflict))
    assert "bc[1]: conflicts with bc[0] on boundary 'clamped': both prescribe component(s) y" in message
    # Different components of one boundary are fine.
    ok = BASE.replace('type = "clamp"\nboundary = "clamped"', 'type = "displacement"\nboundary = "clamped"\n'
                      'value = [0.0]\ncomponents = ["x"]')
    ok += '\n[[bc]]\ntype = "displacement"\nboundary = "clamped"\nvalue = [0.0, 0.0]\ncomponents = [1, 2]\n'
    case = load_case(write(ok))
    assert [bc.components for bc in case.bcs] == [(0,), (1, 2)]


@pytest.mark.parametrize(
    "extra, expected",
    [
        ('[problem]\nformulation = "mixed"\n', "material[0].law: 'saint_venant_kirchhoff' has no isochoric/volumetric"),
        ('[stepping]\ntype = "dynamic"\ndt = 0.1\nt_end = 1.0\n', "material[0]: missing required key 'density'"),
        ('[stepping]\nincrement = -0.5\n', "stepping.increment: must be > 0, got -0.5"),
        ('[stepping]\ntype = "dynamic"\ndt = 0.1\n', "stepping: missing required key 't_end'"),
        ('[stepping]\ntype = "static"\n', "stepping.type: unknown value 'static'"),
        ('[solver]\nrtol = 1e-8\npetsc_options = { snes_rtol = 1e-6 }\n', "solver.rtol: also given as"),
        ('[output]\ntimes = [0.5]\nevery = 0.25\n', "output.every: give either times or every, not both"),
        ('[output]\nreactions = ["free_end"]\n', "output.reactions[0]: boundary 'free_end' has no Dirichlet condition"),
        ('[output]\nfields = ["von_mieses"]\n', "output.fields[0]: unknown value 'von_mieses' (did you mean 'von_"),
        ('[output]\nfields = ["fibre_stretch"]\n', "output.fields: fibre_stretch needs a [fibres] table"),
        ('[output]\ncheckpoint = false\ncheckpoint_every = 3\n', "output.checkpoint_every: checkpoints are off"),
        ('[fibres]\ntype = "laplace"\nsource = "a"\ntarget = "b"\n', "fibres: no material uses fibres"),
    ],
)
def test_bad_section(write, extra, expected):
    text = BASE.replace("neo_hookean", "saint_venant_kirchhoff") if "mixed" in extra else BASE
    assert expected in _error(write(text + extra))


def test_muscle_needs_fibres_and_mixed_rejects_displacement_volumetric(write):
    muscle = BASE.replace('law = "neo_hookean"\nE = 1.0e6\nnu = 0.3', 'law = "muscle"\npreset = "muscle"')
    assert 'material[0]: law "muscle" needs fibre directions' in _error(write(muscle))
    vol = BASE.replace("nu = 0.3", 'nu = 0.3\nvolumetric = "log"')
    assert 'material[0].volumetric: only used with formulation = "mixed"' in _error(write(vol))


def test_missing_group_lists_the_available_ones(write):
    case = load_case(write(BASE.replace('boundary = "clamped"', 'boundary = "clampd"')))
    with pytest.raises(CaseFileError) as info:
        check_groups(case, hf.read_mesh(MESH))
    message = str(info.value)
    assert f"bc[0].boundary: no boundary 'clampd' in {MESH} (did you mean 'clamped'?)" in message
    assert "boundary groups of the mesh: clamped, free_end, surface" in message


# -- overrides ----------------------------------------------------------------------------------------
def test_overrides_set_nested_keys():
    data = parse_toml(BASE)
    apply_overrides(
        data,
        [
            "material[0].E=2e6",
            "material.0.nu=0.25",
            "stepping.increment=0.5",
            "solver.petsc_options.ksp_type=preonly",
            "output.probes=[[1, 2, 3]]",
            "output.fields=[]",
        ],
    )
    assert data["material"][0]["E"] == 2e6 and data["material"][0]["nu"] == 0.25
    assert data["stepping"] == {"increment": 0.5}
    assert data["solver"]["petsc_options"] == {"ksp_type": "preonly"}
    assert data["output"] == {"probes": [[1, 2, 3]], "fields": []}
    case = check_case(data, "x.toml")
    assert case.solver.petsc_options == {"ksp_type": "preonly"} and case.output.fields == ()


@pytest.mark.parametrize(
    "item, expected",
    [
        ("material[3].E=1", "material.3: there are 1 entries"),
        ("stepping", "expected key=value"),
        ("a..b=1", "malformed key"),
        ("output.probes=[[1, 2", "cannot parse the value"),
    ],
)
def test_bad_override(item, expected):
    with pytest.raises(CaseFileError) as info:
        apply_overrides(parse_toml(BASE), [item], "x.toml")
    assert expected in str(info.value)


def test_override_reaches_the_checks(write):
    message = _error(write(BASE), ["stepping.dtt=0.1"])
    assert "stepping.dtt: unknown key" in message


# -- profiles, must-hit times, functions ----------------------------------------------------------
def test_profiles_and_must_hit_times(write):
    ramp = 'value = [0.0, -5.0e3, 0.0]\nprofile = { type = "ramp", t1 = 0.3 }'
    text = BASE.replace("value = [0.0, -5.0e3, 0.0]", ramp)
    text = text.replace("nu = 0.3", "nu = 0.3\ndensity = 1000.0")
    text += '[stepping]\ntype = "dynamic"\ndt = 0.1\nt_end = 1.0\nmust_hit = [0.45]\n[output]\nevery = 0.25\n'
    case = load_case(write(text))
    assert case.loads[0].profile.kind == "ramp" and case.loads[0].profile.kinks == (0.0, 0.3)
    assert case.output.times == (0.25, 0.5, 0.75, 1.0)
    assert must_hit_times(case) == [0.25, 0.3, 0.45, 0.5, 0.75, 1.0]
    bad = text.replace("t1 = 0.3", "t1 = 0.3, t0 = 0.5")
    assert "load[0].profile: a ramp needs t1 > t0" in _error(write(bad))
    table = '{ type = "table", times = [0.0, 0.2, 0.1], values = [0, 1, 0] }'
    table = text.replace('{ type = "ramp", t1 = 0.3 }', table)
    assert "load[0].profile.times: must increase strictly" in _error(write(table))


def test_table_and_scaled_profiles():
    table = Table((0.0, 1.0, 3.0), (0.0, 2.0, -2.0))
    assert [table(t) for t in (-1.0, 0.5, 1.0, 2.0, 5.0)] == [0.0, 1.0, 2.0, 0.0, -2.0]
    assert table.kinks == (0.0, 1.0, 3.0)
    assert Scaled(table, 0.5)(0.5) == 0.5 and Scaled(table, 0.5).kinks == (0.0, 1.0, 3.0)
    with pytest.raises(hf.ParameterError):
        Table((0.0, 0.0), (1.0, 2.0))


def test_affine_field_interpolates_exactly():
    """A x + b in P1 equals the closed form at every node."""
    from dolfinx import mesh as dmesh

    mesh = dmesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    A = ((0.0, 0.0, 0.0), (0.0, 0.0, 5.0e3), (0.0, -5.0e3, 0.0))
    b = (1.0, 0.0, -2.0)
    V = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
    f = fem.Function(V)
    f.interpolate(fem.Expression(AffineField(A, b)(ufl.SpatialCoordinate(mesh)), V.element.interpolation_points))
    x = V.tabulate_dof_coordinates()
    expected = x @ np.asarray(A).T + np.asarray(b)
    np.testing.assert_allclose(f.x.array.reshape(-1, 3), expected, rtol=0, atol=1e-9)


def test_schema_reference_is_a_valid_case(capsys):
    """``hyperfem schema`` prints a case file that passes the checks (the reference cannot rot)."""
    from hyperfem.app.main import dispatch

    dispatch(["schema"])
    text = MPI.COMM_WORLD.bcast(capsys.readouterr().out, root=0)
    case = check_case(parse_toml(text), CASES / "schema.toml")
    assert case.name == "bend" and case.output.checkpoint_every == 10 and case.output.reactions is None
    assert case.mesh.file == MESH


def test_vector_lengths_are_checked_against_the_mesh(write):
    from hyperfem.app.build import check_mesh

    domain = hf.read_mesh(MESH)
    case = load_case(write(BASE.replace("value = [0.0, -5.0e3, 0.0]", "value = [0.0, -5.0e3]")))
    with pytest.raises(CaseFileError) as info:
        check_mesh(case, domain)
    assert f"load[0].value: 2 components (the mesh {MESH} has 3 displacement components)" in str(info.value)
    case = load_case(write(BASE + '[[bc]]\ntype = "displacement"\nboundary = "free_end"\nvalue = [0.0, 1.0]\n'))
    with pytest.raises(CaseFileError) as info:
        check_mesh(case, domain)
    assert "bc[1].value: 2 values; give 3, or components = [...] to prescribe fewer" in str(info.value)
