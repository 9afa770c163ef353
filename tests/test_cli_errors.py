"""The bad-input catalogue through the ``hyperfem`` command, as a user meets it.

Each bad input — a TOML syntax error, an unknown key, a wrong type, an unknown
material or load, a group missing from the mesh, conflicting conditions, a
negative density, Poisson's ratio 1/2, a missing mesh, a bad ``--set``, a step
that fails after all cutbacks, a restart from a checkpoint of another model,
mixed/unsupported/surface cells, inverted and
degenerate cells in ``convert`` — must give exit status 1, exactly one line
``hyperfem: error: <specific message>``, no traceback, and no result (no
summary on stdout; for a failed step the JSON says ``"completed": false``).
Inverted cells in a mesh that ``run`` reads are a warning (the result is
unchanged). Under ``mpiexec -n 2`` no rank is left hanging (a timeout bounds
every run) and only rank 0 prints.

All subprocess tests: ``serial`` (each starts its own ranks).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from case_texts import BASE, MESH, ROOT

pytestmark = pytest.mark.serial

CONFLICT = '\n[[bc]]\ntype = "displacement"\nboundary = "clamped"\nvalue = [0.1, 0.0, 0.0]\n'

# name: (replace old, by new | appended text, expected message after "hyperfem: error: CASE: ")
CASES = {
    "syntax": (('law = "neo_hookean"', 'law = "neo_hookean'), ":5:19: TOML syntax error: Illegal character"),
    "unknown_key": (
        ('boundary = "clamped"', 'boundry = "clamped"'),
        "bc[0].boundry: unknown key (did you mean 'boundary'?); keys of a bc of type 'clamp': type, boundary",
    ),
    "wrong_type": (("E = 1.0e6", 'E = "1e6"'), "material[0].E: expected a number, got a string ('1e6')"),
    "unknown_law": (
        ('law = "neo_hookean"', 'law = "neohookean"'),
        "material[0].law: unknown value 'neohookean' (did you mean 'neo_hookean'?); choose from neo_hookean, ",
    ),
    "unknown_load": (
        ('type = "dead_traction"', 'type = "dead_tracton"'),
        "load[0].type: unknown value 'dead_tracton' (did you mean 'dead_traction'?); choose from dead_traction, ",
    ),
    "missing_group": (
        ('boundary = "clamped"', 'boundary = "clampd"'),
        f"bc[0].boundary: no boundary 'clampd' in {MESH} (did you mean 'clamped'?); boundary groups of the mesh: "
        "clamped, free_end, surface",
    ),
    "conflicting_bcs": (
        CONFLICT,
        "bc[1]: conflicts with bc[0] on boundary 'clamped': both prescribe component(s) x, y, z "
        "(clamp and displacement); give each component of a boundary one condition",
    ),
    "negative_density": (("nu = 0.3", "nu = 0.3\ndensity = -1000.0"), "material[0].density: must be > 0, got -1000.0"),
    "nu_one_half": (("nu = 0.3", "nu = 0.5"), "material[0].nu: Poisson's ratio must lie in (-1, 0.5), got 0.5; "),
    "missing_mesh": ((str(MESH), "/nonexistent/beam.msh"), "mesh.file: mesh file not found: /nonexistent/beam.msh"),
}


def _env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "MPICH_"))}
    env["PYTHONWARNINGS"] = "ignore"
    return env


def hyperfem(*args: str, ranks: int = 1, timeout: float = 240) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "hyperfem.app.main", *args]
    if ranks > 1:
        mpiexec = Path(sys.executable).parent / "mpiexec"
        mpiexec = str(mpiexec) if mpiexec.exists() else shutil.which("mpiexec")
        if mpiexec is None:
            pytest.skip("no mpiexec found")
        cmd = [mpiexec, "-n", str(ranks), *cmd]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=_env(), cwd=ROOT)


def _case(tmp_path: Path, name: str) -> Path:
    change = CASES[name][0]
    text = BASE + change if isinstance(change, str) else BASE.replace(*change)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _one_error(result: subprocess.CompletedProcess) -> str:
    """The run failed with one error line, no traceback; returns the message."""
    assert result.returncode == 1, (result.returncode, result.stdout, result.stderr)
    assert "Traceback" not in result.stdout + result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("hyperfem: error: ")]
    assert len(errors) == 1, result.stderr
    return errors[0][len("hyperfem: error: ") :]


@pytest.mark.parametrize("name", list(CASES))
def test_bad_case_file(name, tmp_path):
    path = _case(tmp_path, name)
    out = tmp_path / "out"
    result = hyperfem("run", str(path), "--output", str(out))
    message = _one_error(result)
    expected = CASES[name][1]
    assert message.startswith(str(path)) and expected in message, message
    assert result.stdout == ""  # nothing presented: the checks run before the run starts
    assert not (out / f"{name}.json").exists()
    assert len(result.stderr.splitlines()) == 1


@pytest.mark.parametrize(
    "args, expected",
    [
        (["--set", "stepping.dt=0.1"], 'stepping.dt: a key of dynamic stepping, not of quasi-static stepping (set '
                                       'type = "dynamic" for a time integration)'),
        (["--set", "material[2].E=1"], "--set 'material[2].E=1': material.2: there are 1 entries"),
    ],
)
def test_bad_override(args, expected, tmp_path):
    path = tmp_path / "case.toml"
    path.write_text(BASE)
    assert expected in _one_error(hyperfem("run", str(path), *args, "--output", str(tmp_path / "out")))


def test_failed_step_reports_and_keeps_what_converged(tmp_path):
    """A load no step can carry: one line naming the time reached; the summary says completed = false."""
    path = tmp_path / "heavy.toml"
    path.write_text(BASE.replace("-5.0e3", "-5.0e7") + "\n[stepping]\nincrement = 0.5\nmax_increment = 0.5\n"
                    "min_increment = 0.125\n[output]\nprogress = false\n")
    result = hyperfem("run", str(path), "--output", str(tmp_path / "out"))
    message = _one_error(result)
    assert message.startswith("heavy: stepping failed: reached t = 0 of 1; step 0.0625 below the minimum 0.125")
    out = tmp_path / "out"
    assert f"(completed steps written to {out / 'heavy.json'}; last converged state checkpointed in " in message
    assert "load steps" not in result.stdout  # no summary presented as a result
    summary = json.loads((tmp_path / "out" / "heavy.json").read_text())
    assert summary["completed"] is False and summary["steps"] == 0 and "stepping failed" in summary["error"]


def test_restart_that_does_not_match(tmp_path):
    """A checkpoint of another model (a changed E), and a folder without a checkpoint: one line each."""
    path = tmp_path / "case.toml"
    path.write_text(BASE + "\n[output]\nprogress = false\n")
    out = str(tmp_path / "out")
    assert hyperfem("run", str(path), "--output", out).returncode == 0
    message = _one_error(hyperfem("run", str(path), "--output", out, "--set", "material[0].E=2e6", "--restart"))
    assert message == (
        f"cannot restart from {tmp_path / 'out' / 'case.checkpoint' / 'step-000001'}: it does not match this run: "
        "the case (hash of the case description) differs"
    )
    message = _one_error(hyperfem("run", str(path), "--output", str(tmp_path / "none"), "--restart"))
    assert message.startswith(f"cannot restart from {tmp_path / 'none' / 'case.checkpoint'}: no checkpoint there")


def test_unknown_demo():
    message = _one_error(hyperfem("demo", "bnd"))
    assert message.startswith("demo: unknown demo 'bnd' (did you mean 'bend'?); demos in ")


# -- meshes -----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bad_meshes(tmp_path_factory):
    """.vtu files with mixed, hexahedral-only, surface-only, inverted, degenerate cells; a .msh with inverted ones."""
    import meshio

    folder = tmp_path_factory.mktemp("meshes")
    m = meshio.read(MESH)
    tets = next(c.data for c in m.cells if c.type == "tetra").copy()
    pts = m.points
    cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    hexes = np.arange(len(pts), len(pts) + 8)[None, :]
    mixed = meshio.Mesh(np.vstack([pts, cube + 20.0]), [("tetra", tets), ("hexahedron", hexes)])
    meshio.write(folder / "mixed.vtu", mixed)
    meshio.write(folder / "hex.vtu", meshio.Mesh(cube, [("hexahedron", np.arange(8)[None, :])]))
    triangles = np.concatenate([c.data for c in m.cells if c.type == "triangle"])
    meshio.write(folder / "surface.vtu", meshio.Mesh(pts, [("triangle", triangles)]))
    inverted = tets.copy()
    inverted[:7, [0, 1]] = inverted[:7, [1, 0]]
    meshio.write(folder / "inverted.vtu", meshio.Mesh(pts, [("tetra", inverted)]))
    flat = np.array([[30, 0, 0], [31, 0, 0], [30, 1, 0], [31, 1, 0]], float)
    extra = np.arange(len(pts), len(pts) + 4)[None, :]
    meshio.write(folder / "degenerate.vtu", meshio.Mesh(np.vstack([pts, flat]), [("tetra", np.vstack([tets, extra]))]))
    tags = m.cell_data["gmsh:physical"]
    blocks = [(c.type, inverted if c.type == "tetra" else c.data) for c in m.cells]
    data = {"gmsh:physical": tags, "gmsh:geometrical": tags}
    gmsh = meshio.Mesh(pts, blocks, cell_data=data, field_data=m.field_data)
    meshio.write(folder / "inverted.msh", gmsh, file_format="gmsh22", binary=False)
    return folder


@pytest.mark.parametrize(
    "name, expected",
    [
        ("mixed.vtu", "mixed.vtu: mixed cell types (164 tetra, 1 hexahedron); hyperfem needs a purely tetrahedral"),
        ("hex.vtu", "hex.vtu: unsupported cell type hexahedron (1 hexahedron); hyperfem solves on tetrahedra"),
        ("surface.vtu", "surface.vtu: no tetrahedra (132 triangle); convert imports volume meshes of tetrahedra"),
        ("inverted.vtu", "inverted.vtu: 7 of 164 tetrahedra are inverted (negative orientation: vertices in mirrored "
                         "order); rerun with --reorient to fix their vertex order"),
        ("degenerate.vtu", "degenerate.vtu: 1 of 165 tetrahedra have no volume (degenerate; the first is cell 164)"),
    ],
)
def test_convert_refuses(name, expected, bad_meshes, tmp_path):
    target = tmp_path / "out.msh"
    message = _one_error(hyperfem("convert", str(bad_meshes / name), str(target)))
    assert message == f"{bad_meshes}/{expected}" or message.startswith(f"{bad_meshes}/{expected}"), message
    assert not target.exists()


def test_convert_reorients_on_request(bad_meshes, tmp_path):
    target = tmp_path / "fixed.msh"
    result = hyperfem("convert", str(bad_meshes / "inverted.vtu"), str(target), "--reorient")
    assert result.returncode == 0, result.stderr
    assert "hyperfem: warning: reoriented 7 inverted tetrahedra" in result.stderr
    quality = hyperfem("mesh-quality", str(target))
    assert "orientation: 0 inverted, 0 degenerate of 164 cells" in quality.stdout


def test_inverted_cells_in_a_run_are_a_warning(bad_meshes, tmp_path):
    """DOLFINx keeps the vertex order and integrates |det J|: the run warns and gives the usual answer."""
    path = tmp_path / "inverted.toml"
    text = BASE.replace(str(MESH), str(bad_meshes / "inverted.msh"))
    path.write_text(text + "[output]\nprobes = [[4.5, 1.5, 1.5]]\n")
    result = hyperfem("run", str(path), "--output", str(tmp_path / "out"))
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if line.startswith("hyperfem: warning: ")]
    assert len(warnings) == 1 and "7 of 164 cells are inverted (negative orientation); harmless here" in warnings[0]
    summary = json.loads((tmp_path / "out" / "inverted.json").read_text())
    np.testing.assert_allclose(summary["probe_displacement"][0], [0.135077318161, -0.852854731738, 0.003404957717],
                               rtol=1e-6)


# -- two ranks: one line, nobody hangs --------------------------------------------------------------
@pytest.mark.parametrize("name", ["syntax", "missing_group"])
def test_bad_case_file_on_two_ranks(name, tmp_path):
    path = _case(tmp_path, name)
    message = _one_error(hyperfem("run", str(path), "--output", str(tmp_path / "out"), ranks=2, timeout=180))
    assert CASES[name][1] in message


def test_failed_step_on_two_ranks(tmp_path):
    path = tmp_path / "heavy.toml"
    path.write_text(BASE.replace("-5.0e3", "-5.0e7") + "\n[stepping]\nmin_increment = 0.25\nincrement = 0.5\n"
                    "max_increment = 0.5\n")
    message = _one_error(hyperfem("run", str(path), "--output", str(tmp_path / "out"), ranks=2, timeout=180))
    assert "stepping failed: reached t = 0 of 1" in message


def test_convert_refuses_on_two_ranks(bad_meshes, tmp_path):
    result = hyperfem("convert", str(bad_meshes / "mixed.vtu"), str(tmp_path / "x.msh"), ranks=2, timeout=180)
    message = _one_error(result)
    assert "mixed cell types" in message


@pytest.mark.parametrize(
    "times, expected",
    [
        ("[-1, 7]", "output.times[0]: -1 is outside the run's load-factor span [0, 1] (stepping.end)"),
        ("[0.5, 7]", "output.times[1]: 7 is outside the run's load-factor span [0, 1] (stepping.end)"),
    ],
)
def test_output_times_outside_the_run(times, expected, tmp_path):
    """Times no step reaches are refused with the key path (before: exit 0 and a .bp holding t = 0 only)."""
    path = tmp_path / "case.toml"
    path.write_text(BASE + f"\n[output]\ntimes = {times}\n")
    message = _one_error(hyperfem("run", str(path), "--output", str(tmp_path / "out")))
    assert message == f"{path}: {expected}; no frame would be written there"


def test_output_every_longer_than_the_run_writes_the_final_state(tmp_path):
    """every = 5 on a ramp to 1 in 2 steps: the .bp holds t = 0 and the final state, and a warning says so."""
    from mpi4py import MPI  # noqa: F401

    from hyperfem.io import vtx_steps

    path = tmp_path / "case.toml"
    path.write_text(BASE + "\n[stepping]\nincrement = 0.5\nmax_increment = 0.5\n[output]\nevery = 5\n"
                    "progress = false\n")
    result = hyperfem("run", str(path), "--output", str(tmp_path / "out"))
    assert result.returncode == 0, result.stderr
    assert ("hyperfem: warning: output.every: 5 is longer than the run's load-factor span [0, 1] (stepping.end); "
            "the field file gets the initial and the final state only") in result.stderr
    assert vtx_steps(tmp_path / "out" / "case.bp") == 2  # before: 1 (t = 0 only)
    summary = json.loads((tmp_path / "out" / "case.json").read_text())
    assert summary["steps"] == 2


def test_run_refuses_a_folder_with_a_previous_run(tmp_path):
    """A second run into the same folder is refused unless --overwrite (before: silently overwritten)."""
    path = tmp_path / "case.toml"
    path.write_text(BASE + "\n[output]\nprogress = false\nfields = []\n")
    out = tmp_path / "out"
    assert hyperfem("run", str(path), "--output", str(out)).returncode == 0
    message = _one_error(hyperfem("run", str(path), "--output", str(out)))
    assert message == (f"run: {out} holds a previous run (case.json); give --overwrite to replace it, --restart to "
                       "continue it, or another --output")
    again = hyperfem("run", str(path), "--output", str(out), "--overwrite")
    assert again.returncode == 0, again.stderr
    assert f"overwriting the previous run in {out} (case.json)" in again.stdout


def test_run_refuses_a_previous_run_on_two_ranks(tmp_path):
    path = tmp_path / "case.toml"
    path.write_text(BASE + "\n[output]\nprogress = false\nfields = []\n")
    out = tmp_path / "out"
    assert hyperfem("run", str(path), "--output", str(out)).returncode == 0
    message = _one_error(hyperfem("run", str(path), "--output", str(out), ranks=2, timeout=180))
    assert message.startswith(f"run: {out} holds a previous run (case.json)")
