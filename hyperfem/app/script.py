"""The plan of a case printed as a runnable Python program (``hyperfem run --print-python``).

:func:`script` writes the statements of :func:`hyperfem.app.plan.plan` with
:func:`hyperfem.app.calls.source`, under the import lines their functions need
(:func:`hyperfem.app.calls.imports`, ``from m import a`` lines of one module
merged). Running the printed program builds the objects ``hyperfem run`` calls
and gives the same result.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

from hyperfem.app.calls import imports as node_imports
from hyperfem.app.calls import source
from hyperfem.app.plan import Statement, plan
from hyperfem.app.spec import Case

__all__ = ["imports", "script", "statement_source"]

BASE_IMPORTS = ("from mpi4py import MPI", "import hyperfem as hf")


def statement_source(statement: Statement, indent: str = "") -> str:
    """The statement as source lines (``target = value``, or a list with one entry per line)."""
    head = "" if statement.target is None else f"{statement.target} = "
    lines = [f"{indent}# {statement.comment}"] if statement.comment else []
    if statement.items is None:
        lines.append(_indent(f"{head}{source(statement.value)}", indent))
    elif not statement.items:
        lines.append(f"{indent}{head}[]")
    else:
        lines.append(f"{indent}{head}[")
        for key, node in statement.items:
            lines.append(_indent(f"{source(node)},  # {key}", indent + "    "))
        lines.append(f"{indent}]")
    return "\n".join(lines)


def _indent(text: str, indent: str) -> str:
    return "\n".join(indent + line for line in text.splitlines())


def _nodes(statements: Iterable[Statement]) -> list[object]:
    out: list[object] = []
    for s in statements:
        out.extend([s.value] if s.items is None else [node for _, node in s.items])
    return out


def imports(statements: Sequence[Statement], extra: Sequence[str] = ()) -> list[str]:
    """The import lines of ``statements`` (``from m import a`` lines of one module merged), in order."""
    lines = [*BASE_IMPORTS, *(line for node in _nodes(statements) for line in node_imports(node)), *extra]
    plain: list[str] = []
    names: dict[str, list[str]] = {}
    for line in lines:
        if line.startswith("from ") and " import " in line and " as " not in line:
            module, _, items = line[5:].partition(" import ")
            bucket = names.setdefault(module, [])
            for item in (s.strip() for s in items.split(",")):
                if item not in bucket:
                    bucket.append(item)
        elif line not in plain:
            plain.append(line)
    merged = [f"from {m} import {', '.join(sorted(items, key=_order))}" for m, items in names.items()]
    return list(dict.fromkeys([*plain, *merged]))


def _order(name: str) -> tuple[int, str]:
    """isort's order by type: CONSTANTS, Classes, functions."""
    kind = 0 if name.isupper() and len(name) > 1 else (1 if name[:1].isupper() else 2)
    return kind, name


def _sorted_imports(lines: list[str]) -> list[str]:
    def group(line: str) -> int:
        if line.startswith(("from pathlib", "import math")):
            return 0
        if "mpi4py" in line:
            return 1
        return 2

    def key(line: str) -> tuple[int, str]:
        return (0, line) if line.startswith("import ") else (1, line.split(" import ")[0])

    blocks = [sorted((ln for ln in lines if group(ln) == g), key=key) for g in range(3)]
    return ["\n".join(b) for b in blocks if b]


FOOTER = """    summary = simulation.run({restart})
    if comm.rank == 0:
        print(format_summary(summary), flush=True)
    return summary


if __name__ == "__main__":
    from hyperfem.app.program import run

    run(main)
"""


def _docstring_text(text: str) -> str:
    """``text`` safe inside a triple-quoted docstring (no backslashes, no closing quotes)."""
    return text.replace("\\", "/").replace('"' * 3, "'" * 3)


def script(case: Case, restart: str | Path | None = None) -> str:
    """A runnable script that builds and runs ``case`` exactly as ``hyperfem run`` does.

    Args:
        case: The case.
        restart: The checkpoint ``hyperfem run --restart`` continues from, if any.
    """
    statements = plan(case)
    lines = imports(statements, ["from hyperfem.simulation import format_summary"])
    header = "\n\n".join(_sorted_imports(lines))
    what = _docstring_text(case.description or f"the run {case.name!r}")
    doc = (
        f'"""{case.name}: {what}\n\n'
        f"The Python equivalent of {_docstring_text(str(case.source))} (``hyperfem run --print-python``):\n"
        "running it (``python this.py`` or ``mpiexec -n 2 python this.py``) builds the same\n"
        'objects as ``hyperfem run`` and gives the same result.\n"""\n'
    )
    body = "\n".join(statement_source(s, "    ") for s in statements)
    footer = FOOTER.replace("{restart}", "" if restart is None else f"restart={source(Path(restart))}")
    return f"{doc}\n{header}\n\n\ndef main() -> dict:\n    comm = MPI.COMM_WORLD\n{body}\n{footer}"
