"""The ``hyperfem`` command and its TOML case files.

* :mod:`~hyperfem.app.casefile` — the case schema, validation, ``--set`` overrides (:func:`load_case`);
* :mod:`~hyperfem.app.python_equivalent` — the case as Python statements (:func:`script`);
* :mod:`~hyperfem.app.build` — those statements evaluated: the objects of the run (:func:`build`);
* :mod:`~hyperfem.app.main` — the argument parser and the subcommands.

>>> from hyperfem.app import build, load_case
>>> run = build(load_case("cases/bend.toml", ["mesh.file=../meshes/beam_h2.msh", "problem.degree=1"]))
>>> summary = run.simulation.run()
"""

from hyperfem.app.build import Built, build, check_groups, check_mesh
from hyperfem.app.casefile import Case, CaseFileError, load_case
from hyperfem.app.python_equivalent import plan, script

__all__ = [
    "Built",
    "Case",
    "CaseFileError",
    "build",
    "check_groups",
    "check_mesh",
    "load_case",
    "plan",
    "script",
]
