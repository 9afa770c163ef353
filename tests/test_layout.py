"""One room per concept (issue 18): the moved modules are gone, errors are all exported, validation is at the bottom."""

from __future__ import annotations

import ast
import importlib.util
import inspect
import re
from pathlib import Path

import pytest

import hyperfem.errors

PACKAGE = Path(hyperfem.errors.__file__).resolve().parent

MOVED = {
    "hyperfem.app.meshconvert": "hyperfem.mesh.convert",
    "hyperfem.app.abaqus": "hyperfem.mesh.abaqus",
    "hyperfem.app.meshcheck": "hyperfem.mesh.orientation",
    "hyperfem.problem.validation": "hyperfem.validation",
    "hyperfem.dynamics.motion": "hyperfem.loading.motion",
    "hyperfem.app.functions": "hyperfem.loading.profiles",
    "hyperfem.activation": "hyperfem.loading.activation",
}


@pytest.mark.parametrize("old, new", sorted(MOVED.items()))
def test_moved_module_is_gone_and_its_new_room_imports(old, new):
    """No shim is left at the old path; the new module imports."""
    assert importlib.util.find_spec(old) is None, f"{old} should have moved to {new}"
    importlib.import_module(new)


def test_every_error_class_is_exported():
    """``hyperfem.errors.__all__`` lists every exception class the module defines (SolverError was missing)."""
    defined = {
        name
        for name, obj in vars(hyperfem.errors).items()
        if inspect.isclass(obj) and issubclass(obj, BaseException) and obj.__module__ == hyperfem.errors.__name__
    }
    assert "SolverError" in defined
    assert defined == set(hyperfem.errors.__all__)


def _hyperfem_imports(path: Path) -> list[tuple[str, list[str]]]:
    tree = ast.parse(path.read_text())
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("hyperfem"):
            out.append((node.module, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            out.extend((a.name, []) for a in node.names if a.name.startswith("hyperfem"))
    return out


def test_validation_sits_at_the_bottom():
    """``hyperfem.validation`` imports nothing of hyperfem but its errors (every layer may use it)."""
    modules = {module for module, _ in _hyperfem_imports(PACKAGE / "validation.py")}
    assert modules == {"hyperfem.errors"}


def _imports_io(module: str, names: list[str]) -> bool:
    return module == "hyperfem.io" or module.startswith("hyperfem.io.") or (module == "hyperfem" and "io" in names)


def test_solver_does_not_import_io():
    """solver/ sits below the output layer: its inversion measure comes from ``hyperfem.problem.inversion``.

    ``QuadratureMinimum`` lived in ``hyperfem.io.probes``, so the Newton solver
    and its step filters imported the input/output package.
    """
    offending = [
        (path.name, module)
        for path in sorted((PACKAGE / "solver").glob("*.py"))
        for module, names in _hyperfem_imports(path)
        if _imports_io(module, names)
    ]
    assert offending == []


def test_plots_import_no_private_name():
    """plots.py takes the public ``flatten_row`` (it imported ``outputs._flatten``)."""
    private = [(m, n) for m, names in _hyperfem_imports(PACKAGE / "simulation" / "plots.py") for n in names
               if n.startswith("_")]
    assert private == []
    from hyperfem.io.results import flatten_row

    assert flatten_row({"t": 0.5, "u": [[1, 2]], "name": "x"}) == {"t": 0.5, "u_0_0": 1.0, "u_0_1": 2.0, "name": "x"}


CASE = f"""name = "loading"
[mesh]
file = "{Path(__file__).resolve().parent.parent / 'meshes' / 'beam_h2.msh'}"
[problem]
degree = 1
[[material]]
law = "neo_hookean"
E = 1.0e6
nu = 0.3
[[bc]]
type = "clamp"
boundary = "clamped"
[[bc]]
type = "rotation"
boundary = "free_end"
axis = [1.0, 0.0, 0.0]
center = [5.0, 0.0, 0.0]
angle = 0.2
profile = {{ type = "table", times = [0.0, 1.0], values = [0.0, 1.0] }}
[[load]]
type = "dead_traction"
boundary = "free_end"
value = {{ matrix = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]] }}
profile = {{ type = "ramp", t1 = 1.0 }}
[[load]]
type = "body_force"
value = [0.0, 0.0, -1.0]
profile = "steady"
"""


def test_printed_script_takes_profiles_motions_and_fields_from_loading(tmp_path):
    """``--print-python`` imports Table, Ramp, Steady, Scaled, rotating_surface, AffineField from hyperfem.loading.

    The command builds exactly those statements (``build`` evaluates them), so a
    name missing from the import lines fails here, not in a user's script.
    """
    from mpi4py import MPI

    from hyperfem.app import build, load_case, script

    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))
    path = folder / "loading.toml"
    if MPI.COMM_WORLD.rank == 0:
        path.write_text(CASE)
    MPI.COMM_WORLD.Barrier()
    case = load_case(path, output=folder / "out")
    text = script(case)
    assert "from hyperfem.loading import AffineField, Ramp, Scaled, Steady, Table, rotating_surface" in text
    assert "hyperfem.app.functions" not in text and "dyn." not in text
    compile(text, "loading.py", "exec")
    built = build(case)
    bc = built.variables["bcs"][1]
    assert bc.boundary == "free_end" and bc.value.angle(0.5) == pytest.approx(0.1)


def test_readme_table_names_every_folder_of_the_package():
    """"Where things live" lists every subpackage of hyperfem/, and no folder that does not exist."""
    root = Path(__file__).resolve().parent.parent
    readme = (root / "README.md").read_text()
    folders = sorted(p.parent.name for p in (root / "hyperfem").glob("*/__init__.py"))
    assert [f for f in folders if f"`hyperfem/{f}/`" not in readme] == []
    named = set(re.findall(r"`hyperfem/([a-z_]+)/`", readme))
    assert sorted(named - set(folders)) == []
    assert not (root / "hyperfem" / "cli.py").exists()  # the command-line runner lives in app/program.py
