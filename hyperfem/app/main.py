"""The ``hyperfem`` command.

.. code-block:: text

    hyperfem run CASE.toml [--output DIR] [--set KEY=VALUE ...] [--print-python] [--overwrite] [--restart]
    hyperfem check CASE.toml [--set KEY=VALUE ...]
    hyperfem schema
    hyperfem demo [NAME [ARGS ...]]
    hyperfem mesh beam [--size H] [--order N] [-o OUT.msh]
    hyperfem mesh fusiform [--size H] [--order N] [--belly-length L ...] [-o OUT.msh]
    hyperfem mesh-quality MESH.msh [--png OUT.png] [--threshold Q]
    hyperfem plot OUTPUT_FOLDER
    hyperfem render CASE.toml [--checkpoint PATH] [-o OUT.png] [--scalars NAME] [--set KEY=VALUE ...]
    hyperfem convert IN OUT.msh [--reorient] [--tags NAME] [--names TAG=NAME,...]
    hyperfem fit DATA.csv --law LAW [--terms N] [--modes MODE,...] [--fix NAME=VALUE,...] [--json]
                 [--png FIT.png] (hyperfem.app.fit)
    hyperfem fit RELAX.csv --law prony [--terms N | --tau T1,T2 [--fit-tau]] [--ramp-time T] [--json] [--png FIT.png]
    hyperfem --version

Every command runs under ``mpiexec -n N`` (mesh generation and conversion on
rank 0; the others wait for its outcome). Every hyperfem error — a bad case
file, a missing mesh, a failed step — is one line ``hyperfem: error: ...`` on
rank 0 and exit status 1 on every rank (:func:`hyperfem.app.program.run`); bad
arguments are argparse's one line and status 2. Warnings are one line
``hyperfem: warning: ...``.
"""

from __future__ import annotations

import argparse
import runpy
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TextIO, TypeVar

from mpi4py import MPI

from hyperfem.app.fit import add_fit_parser, fit_command
from hyperfem.app.program import ArgumentParser, positive_float, positive_int, run, unit_interval
from hyperfem.errors import HyperfemError, ParameterError

__all__ = ["DEMOS", "main", "make_parser", "dispatch"]

DEMOS = Path(__file__).resolve().parent.parent.parent / "demos"
"""The demo scripts of the source tree (``hyperfem demo`` runs them)."""

EPILOG = """\
examples:
  hyperfem run cases/bend.toml
  mpiexec -n 2 hyperfem run cases/twist.toml --set problem.degree=1 --output out/twist
  hyperfem run cases/bend.toml --print-python > bend.py
  hyperfem demo bend --degree 1
  hyperfem mesh beam --size 2 -o beam_h2.msh
  hyperfem mesh-quality beam_h2.msh --png quality.png
  hyperfem convert part.inp part.msh
  hyperfem render cases/bend.toml --scalars von_mises -o bend.png
"""


ALLOW_LARGE_HELP = (
    "mesh even if the estimated memory (cells ~ volume / (0.2 h^3), ~1 kB each) exceeds what this machine has "
    "available (also: HYPERFEM_ALLOW_LARGE=1)"
)


def _version() -> str:
    import dolfinx

    from hyperfem import __version__

    mpi = MPI.Get_library_version().splitlines()[0].strip()
    return f"hyperfem {__version__} (DOLFINx {dolfinx.__version__}, {mpi})"


def _demos() -> list[str]:
    if not DEMOS.is_dir():
        return []
    return sorted(p.stem for p in DEMOS.glob("*.py") if not p.stem.startswith("_"))


# -- parser --------------------------------------------------------------------------------------
def make_parser() -> ArgumentParser:
    """The argument parser of every subcommand (help and errors on rank 0)."""
    p = ArgumentParser(
        prog="hyperfem",
        description="Large-deformation hyperelastic solids with FEniCSx: run case files, demos and mesh tools.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="store_true", help="print the hyperfem, DOLFINx and MPI versions")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    _add_run_parser(sub)
    _add_check_parser(sub)
    _add_schema_parser(sub)
    _add_demo_parser(sub)
    _add_mesh_parser(sub)
    _add_plot_parser(sub)
    _add_render_parser(sub)
    _add_quality_parser(sub)
    _add_convert_parser(sub)
    add_fit_parser(sub)
    return p


def _add_run_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem run``: run a TOML case file."""
    r = sub.add_parser(
        "run",
        help="run a TOML case file",
        description="Check a TOML case file, build its problem and run it; the summary, CSV, convergence log, "
        "ParaView fields and checkpoints go to the output folder. Keys of a case file: hyperfem schema; "
        "examples: cases/*.toml.",
        epilog="Inverted (negatively oriented) cells in the mesh draw a warning (they do not change the result); "
        "cells without volume are an error.",
    )
    r.add_argument("case", type=Path, help="the .toml case file")
    r.add_argument("--output", "-o", type=Path, default=None, help="output folder (replaces [output] directory)")
    r.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a case entry, e.g. --set stepping.dt=0.01 --set material[0].E=2e6 (repeatable)",
    )
    r.add_argument(
        "--restart",
        nargs="?",
        const="latest",
        default=None,
        metavar="CHECKPOINT",
        help="continue from a checkpoint of this case (default: the newest in OUTPUT/NAME.checkpoint)",
    )
    r.add_argument("--print-python", action="store_true", help="print the equivalent Python script and exit")
    r.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the results of a previous run in the output folder (without it such a folder is refused)",
    )


def _add_check_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem check``: check a case file and its mesh without solving."""
    c = sub.add_parser(
        "check",
        help="check a case file and its mesh without solving",
        description="Check the case file (schema, values, conflicts), read its mesh and check every group name.",
    )
    c.add_argument("case", type=Path, help="the .toml case file")
    c.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help="as for run")


def _add_schema_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem schema``: print the keys of a case file (a commented case file, or a JSON Schema)."""
    s = sub.add_parser(
        "schema",
        help="print the keys of a case file",
        description="Print every section and key of a TOML case file as a commented case file (a valid one): type, "
        "range or choices, default, and the class or keyword each feeds.",
        epilog="For editors: hyperfem schema --json > hyperfem-case.schema.json, then '#:schema "
        "./hyperfem-case.schema.json' as the first line of a case file (taplo, VS Code 'Even Better TOML').",
    )
    s.add_argument("--json", action="store_true", help="print a JSON Schema (draft 2020-12) of case files instead")


def _add_demo_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem demo``: run one of the demos."""
    names = _demos()
    d = sub.add_parser(
        "demo",
        help="run one of the demos",
        description="Run a demo script of demos/ with its own arguments (hyperfem demo NAME --help shows them). "
        f"Demos: {', '.join(names) or 'none found'}.",
    )
    d.add_argument("name", nargs="?", default=None, help="demo name (without one: list them)")
    d.add_argument("args", nargs=argparse.REMAINDER, help="arguments passed to the demo")


def _add_mesh_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem mesh`` with its generators ``beam`` and ``fusiform``."""
    m = sub.add_parser(
        "mesh",
        help="generate a gmsh mesh",
        description="Generate a mesh with gmsh and write it (rank 0). Sizes whose estimated memory exceeds what the "
        "machine has available are refused with the estimate, unless --allow-large or HYPERFEM_ALLOW_LARGE=1.",
    )
    msub = m.add_subparsers(dest="generator", metavar="GENERATOR")
    _add_beam_parser(msub)
    _add_fusiform_parser(msub)


def _add_beam_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem mesh beam``: the cantilever beam of seed 003."""
    beam = sub.add_parser(
        "beam",
        help="the 10 x 4 x 4 m cantilever beam of seed 003",
        description="The cantilever beam, groups beam, clamped, free_end, surface.",
    )
    beam.add_argument("--size", "--h", dest="size", type=positive_float, default=1.0, help="element size h (m)")
    beam.add_argument("--order", type=int, choices=(1, 2), default=1, help="geometric order")
    _add_generator_output(beam, "beam")


def _add_generator_output(parser: argparse.ArgumentParser, name: str) -> None:
    """``-o/--output`` and ``--allow-large`` of a mesh generator's command."""
    parser.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help=f"output .msh (default: {name}_h<SIZE>.msh in the current folder; the path written is printed)",
    )
    parser.add_argument("--allow-large", action="store_true", help=ALLOW_LARGE_HELP)


def _add_fusiform_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem mesh fusiform``: the fusiform muscle of seed 000."""
    fus = sub.add_parser(
        "fusiform",
        help="the fusiform muscle with tendons of seed 000",
        description="The spindle muscle: regions muscle, tendon_proximal, tendon_distal; boundaries origin, "
        "insertion, lateral.",
    )
    fus.add_argument("--size", "--h", dest="size", type=positive_float, default=0.004, help="element size h (m)")
    fus.add_argument("--order", type=int, choices=(1, 2), default=1, help="geometric order")
    fus.add_argument("--belly-length", type=positive_float, default=None, help="belly length L (m)")
    fus.add_argument("--belly-radius", type=positive_float, default=None, help="largest radius R (m)")
    fus.add_argument("--tendon-radius", type=positive_float, default=None, help="tendon radius (m), below R")
    fus.add_argument("--tendon-length", type=positive_float, default=None, help="length of each tendon (m)")
    fus.add_argument("--sections", type=positive_int, default=None, help="lofted cross-sections (odd, >= 3)")
    _add_generator_output(fus, "fusiform")


def _add_plot_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem plot``: PNG plots of a run's output folder."""
    pl = sub.add_parser(
        "plot",
        help="plots of a run's output folder as PNG",
        description="Load-displacement, Newton convergence (semilog residuals per step) and, for a dynamic run, "
        "the time series of the test point, energies and volume, from the files a run left in its output folder.",
    )
    pl.add_argument("folder", type=Path, help="the output folder of a run")


def _add_render_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem render``: a PNG of the deformed body from a checkpoint."""
    rd = sub.add_parser(
        "render",
        help="a PNG of the deformed body from a run's checkpoint (needs pyvista)",
        description="Build the case, load the state of one of its checkpoints (the last one by default: the end "
        "of a completed run) and draw the deformed body offscreen to PNG, as [output] render does during a run. "
        "The checkpoint may come from a run on any number of ranks. Needs the optional extra: "
        "pip install 'hyperfem[render]'.",
    )
    rd.add_argument("case", type=Path, help="the .toml case file of the run")
    rd.add_argument(
        "--checkpoint",
        type=Path,
        default=None,
        help="the run's output folder, its checkpoint folder or one step folder (default: the newest checkpoint "
        "in the case's output folder)",
    )
    rd.add_argument("--output", "-o", type=Path, default=None, help="the PNG (default OUTPUT/NAME.png)")
    rd.add_argument(
        "--scalars",
        default=None,
        help="what colours the surface: displacement, von_mises, J, fibre_stretch, activation "
        "(default: [output] render's, else displacement)",
    )
    rd.add_argument("--scale", type=positive_float, default=None, help="displacement magnification")
    rd.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help="as for run")


def _add_quality_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem mesh-quality``: shape-quality measures of a mesh."""
    q = sub.add_parser(
        "mesh-quality",
        help="shape-quality measures of a mesh (seed 003, section 5.6)",
        description="Radius ratio, inradius/edge, minimum dihedral sine and volume-length measure of every cell "
        "(1 = regular): min, percentiles, mean and max; optionally histograms as PNG.",
    )
    q.add_argument("mesh", type=Path, help="gmsh .msh file")
    q.add_argument("--png", type=Path, default=None, help="write histograms of the measures to this PNG")
    q.add_argument("--threshold", type=unit_interval, default=None, help="warn below this quality (default 0.1)")


def _add_convert_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem convert``: import a tetrahedral mesh as a gmsh file."""
    v = sub.add_parser(
        "convert",
        help="import a tetrahedral mesh (meshio) as a gmsh file",
        description="Read a tetrahedral mesh (.vtu, .inp, .mesh, .msh, .xdmf, ... via meshio) with its cell and "
        "facet tags (or cell/point sets) and write the gmsh 2.2 .msh that hyperfem reads, one physical group per "
        "tag. Refuses surface meshes, mixed or non-tetrahedral cells and degenerate cells; inverted cells unless "
        "--reorient.",
    )
    v.add_argument("input", type=Path, help="input mesh")
    v.add_argument("output", type=Path, help="output .msh")
    v.add_argument("--reorient", action="store_true", help="fix inverted tetrahedra by swapping two vertices")
    v.add_argument("--tags", default=None, help="integer cell-data array with the group tags (default: detect)")
    v.add_argument(
        "--names",
        default=None,
        metavar="TAG=NAME,...",
        help="names of tagged groups, e.g. --names 1=beam,2=clamped (region:TAG=NAME or boundary:TAG=NAME where a "
        "tag is both; default: the file's names, else region_TAG / boundary_TAG)",
    )

# -- commands ---------------------------------------------------------------------------------------
def _say(text: str) -> None:
    if MPI.COMM_WORLD.rank == 0:
        print(text, flush=True)


_T = TypeVar("_T")


def _on_rank0(action: Callable[[], _T]) -> _T:
    """Run ``action()`` on rank 0; every rank returns its result or raises the same hyperfem error."""
    comm = MPI.COMM_WORLD
    result, failure = None, None
    if comm.rank == 0:
        try:
            result = action()
        except HyperfemError as exc:
            failure = (type(exc).__name__, str(exc))
        except Exception:
            comm.bcast(("unexpected", ""), root=0)
            raise
    failure = comm.bcast(failure, root=0)
    if failure is not None:
        kind, message = failure
        if kind == "unexpected":
            raise RuntimeError("rank 0 failed (see its traceback)")
        from hyperfem import errors

        raise getattr(errors, kind, HyperfemError)(message)
    return comm.bcast(result, root=0)


def _run(args: argparse.Namespace) -> dict[str, Any] | None:
    from hyperfem.app.build import build
    from hyperfem.app.casefile import load_case
    from hyperfem.app.plan import checkpoint_folder
    from hyperfem.app.script import script
    from hyperfem.simulation import format_summary

    case = load_case(args.case, args.overrides, output=args.output)
    restart = None
    if args.restart is not None:
        restart = checkpoint_folder(case) if args.restart == "latest" else Path(args.restart)
    if args.print_python:
        _say(script(case, restart))
        return None
    if restart is None:
        _refuse_previous_run(case.output.directory, overwrite=args.overwrite)
    built = build(case, MPI.COMM_WORLD, echo=True)
    summary = built.simulation.run(restart=restart)
    lines = [format_summary(summary)]
    for name, reaction in summary.get("reactions", {}).items():
        about = f" about the {reaction['about']}" if reaction.get("about") else ""
        lines.append(
            f"  reaction on {name}: force {_vector(reaction['force'])} N, "
            f"moment {_vector(reaction['moment'])} N m{about}"
        )
    _say("\n".join(lines))
    return summary


def _refuse_previous_run(folder: Path, *, overwrite: bool) -> None:
    """Refuse an output folder that holds a previous run's summary, unless ``overwrite`` (then say so)."""
    from hyperfem.errors import OutputError
    from hyperfem.io.results import previous_summaries

    found = previous_summaries(folder, MPI.COMM_WORLD)
    if not found:
        return
    names = ", ".join(p.name for p in found)
    if not overwrite:
        raise OutputError(
            f"run: {folder} holds a previous run ({names}); give --overwrite to replace it, --restart to continue "
            "it, or another --output"
        )
    _say(f"overwriting the previous run in {folder} ({names})")


def _vector(values: Sequence[float]) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in values) + ")"


def _check(args: argparse.Namespace) -> None:
    from hyperfem.app.build import build_domain, check_mesh
    from hyperfem.app.casefile import load_case
    from hyperfem.app.plan import plan

    case = load_case(args.case, args.overrides)
    statements = plan(case)  # the script can be written
    domain = build_domain(case, MPI.COMM_WORLD)
    check_mesh(case, domain, echo=True)
    _say(
        f"{args.case}: ok ({case.name}: {len(case.materials)} material(s), {len(case.bcs)} condition(s), "
        f"{len(case.loads)} load(s), {'dynamic' if case.dynamic else 'quasi-static'}; {len(statements)} statements)"
    )


def _schema(args: argparse.Namespace) -> None:
    from hyperfem.app.reference import dumps, json_schema, reference

    _say(dumps(json_schema()) if getattr(args, "json", False) else reference().rstrip("\n"))


def _demo(args: argparse.Namespace) -> None:
    names = _demos()
    if args.name is None:
        _say(f"demos: {', '.join(names)}\nrun one with: hyperfem demo NAME [ARGS ...] (NAME --help: its options)")
        return
    name = args.name.replace("-", "_")
    if name not in names:
        from hyperfem.app.schema import suggestion

        where = f"in {DEMOS}" if names else f"({DEMOS} not found: the demos ship with the source tree)"
        raise ParameterError(
            f"demo: unknown demo {args.name!r}{suggestion(name, names)}; demos {where}: {', '.join(names)}"
        )
    path = DEMOS / f"{name}.py"
    saved = sys.argv
    sys.argv = [str(path), *args.args]
    try:
        runpy.run_path(str(path), run_name="__main__")
    finally:
        sys.argv = saved


def _mesh(args: argparse.Namespace) -> None:
    from hyperfem.mesh.convert import describe_msh

    if args.generator is None:
        raise ParameterError("mesh: name a generator: hyperfem mesh beam ... or hyperfem mesh fusiform ...")
    out = args.output or Path(f"{args.generator}_h{args.size:g}.msh").resolve()  # say where the default went
    allow_large = True if args.allow_large else None  # None: HYPERFEM_ALLOW_LARGE decides

    def write() -> str:
        if args.generator == "beam":
            from hyperfem.mesh.beam import write_beam_mesh

            write_beam_mesh(out, h=args.size, order=args.order, allow_large=allow_large)
        else:
            from hyperfem.mesh.fusiform import FusiformGeometry, write_fusiform_mesh

            given = {
                k: getattr(args, k)
                for k in ("belly_length", "belly_radius", "tendon_radius", "tendon_length", "sections")
                if getattr(args, k) is not None
            }
            write_fusiform_mesh(
                out, h=args.size, geometry=FusiformGeometry(**given), order=args.order, allow_large=allow_large
            )
        return "wrote " + describe_msh(out)

    _say(_on_rank0(write))


def _plot(args: argparse.Namespace) -> None:
    from hyperfem.errors import OutputError
    from hyperfem.simulation.plots import plot_run

    def plot() -> list[str]:
        if not args.folder.is_dir():
            raise OutputError(f"plot: {args.folder} is not a folder (give the output folder of a run)")
        return [str(p) for p in plot_run(args.folder) if p is not None]

    for path in _on_rank0(plot):
        _say(f"wrote {path}")


def _quality(args: argparse.Namespace) -> None:
    from hyperfem.app.report import quality_table, warn
    from hyperfem.mesh.io import read_mesh
    from hyperfem.mesh.orientation import domain_orientation
    from hyperfem.mesh.quality import POOR_QUALITY, mesh_quality

    domain = read_mesh(args.mesh, MPI.COMM_WORLD)
    quality = mesh_quality(domain)
    regions = ", ".join(sorted(domain.cell_groups)) or "none"
    boundaries = ", ".join(sorted(domain.facet_groups)) or "none"
    _say(f"{args.mesh}: {quality.num_cells} {quality.cell_type} cells; regions: {regions}; boundaries: {boundaries}")
    _say(quality_table(quality))
    counts = domain_orientation(domain)
    if counts is not None:
        _say(f"orientation: {counts.inverted} inverted, {counts.degenerate} degenerate of {counts.cells} cells")
        if counts.inverted:
            warn(
                f"{args.mesh}: {counts.inverted} inverted cells (harmless to hyperfem; "
                "hyperfem convert --reorient fixes them)"
            )
    threshold = POOR_QUALITY if args.threshold is None else args.threshold
    poor = quality.poor_measures(threshold) if threshold > 0 else []
    if poor:
        warn(f"{args.mesh}: cells below quality {threshold:g} in: {', '.join(poor)}")
    if args.png is not None:
        from hyperfem.io.results import ensure_output_dir

        ensure_output_dir(args.png.parent, MPI.COMM_WORLD)
        quality.histogram_png(args.png)
        _say(f"wrote {args.png}")


def _render_picture(args: argparse.Namespace) -> None:
    import dataclasses

    from hyperfem.app.build import build
    from hyperfem.app.casefile import load_case
    from hyperfem.app.plan import checkpoint_folder
    from hyperfem.app.spec import RenderSpec
    from hyperfem.io.checkpoint import resolve_checkpoint
    from hyperfem.simulation.checkpoint import load_checkpoint
    from hyperfem.app.casefile import CaseFileError
    from hyperfem.simulation import Simulation
    from hyperfem.simulation.render import Render, require_pyvista

    case = load_case(args.case, args.overrides)
    options = dict(case.output.render.options) if case.output.render is not None else {}
    options.pop("every", None)
    for key in ("scalars", "scale"):
        if getattr(args, key) is not None:
            options[key] = getattr(args, key)
    spec = RenderSpec(tuple(options.items()))
    # the case as its run built it, without writing anything but the picture
    output = dataclasses.replace(case.output, render=spec, checkpoint_every=None)
    case = dataclasses.replace(case, output=output)
    source = args.checkpoint if args.checkpoint is not None else checkpoint_folder(case)
    if (source / f"{case.name}.checkpoint").is_dir():  # the run's output folder
        source = source / f"{case.name}.checkpoint"
    source = resolve_checkpoint(source, MPI.COMM_WORLD, action="draw the state of")  # before building anything
    require_pyvista(MPI.COMM_WORLD)
    built = build(case, MPI.COMM_WORLD)
    simulation = built.simulation
    if not isinstance(simulation, Simulation):
        raise CaseFileError("render: a buckling analysis has no checkpoints to draw (its modes are in NAME_modes.bp)")
    meta = load_checkpoint(simulation, source)
    (render,) = [o for o in built.outputs if isinstance(o, Render)]
    target = args.output if args.output is not None else case.output.directory / f"{case.name}.png"
    render.path = Path(target)
    render.start(simulation)
    render.draw(simulation, target)
    state = "completed run" if meta.get("completed") else "checkpoint"
    _say(f"wrote {target}: {case.name} at t = {float(meta['time']):g}, step {meta['step']} ({state}, {meta['path']})")


def _convert(args: argparse.Namespace) -> None:
    from hyperfem.mesh.convert import convert
    from hyperfem.app.report import warn

    def work() -> tuple[str, list[str], list[str]]:
        report = convert(args.input, args.output, reorient=args.reorient, tags=args.tags, names=args.names)
        return report.summary(), report.notes, report.warnings

    line, notes, cautions = _on_rank0(work)
    for note in notes:
        _say(f"note: {note}")
    for text in cautions:
        warn(text)
    _say(line)


COMMANDS = {
    "run": _run,
    "check": _check,
    "schema": _schema,
    "demo": _demo,
    "mesh": _mesh,
    "mesh-quality": _quality,
    "plot": _plot,
    "render": _render_picture,
    "convert": _convert,
    "fit": fit_command,
}


def dispatch(argv: list[str] | None = None) -> dict[str, Any] | None:
    """Parse ``argv`` and run the command (errors propagate; :func:`main` turns them into one line)."""
    parser = make_parser()
    args = parser.parse_args(argv)
    if args.version:
        _say(_version())
        return None
    if args.command is None:
        parser.print_help()
        return None
    return COMMANDS[args.command](args)


def _one_line_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    if MPI.COMM_WORLD.rank == 0:
        print(f"hyperfem: warning: {message}", file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``hyperfem`` console script."""
    warnings.showwarning = _one_line_warning
    run(lambda: dispatch(argv))


if __name__ == "__main__":
    main()
