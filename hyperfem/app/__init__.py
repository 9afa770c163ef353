"""The ``hyperfem`` command and its TOML case files.

* :mod:`~hyperfem.app.casefile` — the case schema, validation, ``--set`` overrides (:func:`load_case`);
* :mod:`~hyperfem.app.plan` — the case as a plan of calls to the library (:func:`plan`), made of the
  nodes of :mod:`~hyperfem.app.calls`;
* :mod:`~hyperfem.app.build` — that plan called: the objects of the run (:func:`build`);
* :mod:`~hyperfem.app.script` — the same plan printed as a Python program (:func:`script`, ``--print-python``);
* :mod:`~hyperfem.app.main` — the argument parser and the subcommands;
* :mod:`~hyperfem.app.program` — running any hyperfem program (the command, the demos) from the command line:
  one-line errors, argument types.

>>> from hyperfem.app import build, load_case
>>> run = build(load_case("cases/bend.toml", ["mesh.file=../meshes/beam_h2.msh", "problem.degree=1"]))
>>> summary = run.simulation.run()
"""

from hyperfem.app.build import Built, build, check_groups, check_mesh
from hyperfem.app.casefile import Case, CaseFileError, load_case
from hyperfem.app.plan import plan
from hyperfem.app.script import script

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
