"""``hyperfem fit``: a law's parameters fitted to homogeneous test data.

.. code-block:: text

    hyperfem fit DATA.csv --law LAW [--terms N] [--modes uniaxial,equibiaxial,pure_shear]
                 [--bulk-modulus K] [--volumetric log] [--weighting relative|absolute] [--fix NAME=VALUE,...]
                 [--json] [--png FIT.png]
    hyperfem fit RELAX.csv --law prony [--terms N | --tau 0.1,1 [--fit-tau]] [--ramp-time T] [--json] [--png]

DATA.csv has the columns ``mode,stretch,nominal_stress_MPa`` (the format of
:func:`hyperfem.materials.fitting.read_curves`; rows of mode ``relaxation``, with a
column ``time_s``, are left to ``--law prony``, and said so). The command prints the
parameters, the rms and relative errors per mode, Drucker's stability over the
data range and a ``[[material]]`` table (moduli in Pa) to paste into a case file;
``--json`` prints ``{"law", "parameters", "rms_MPa", "stable", ...}`` instead.

``--law prony`` fits a Prony series to relaxation data instead
(:mod:`hyperfem.materials.prony_fit`): RELAX.csv has the columns ``time_s`` and
``nominal_stress_MPa`` (the stress at a held strain) or ``relaxation_modulus``
(:math:`g(t)`, 1 at 0), or is a file of DATA.csv's format with a ``time_s``
column, of which it takes the rows of mode ``relaxation`` (one held stretch); it
prints :math:`g_i, \tau_i`, the rms and a ``[material.viscoelastic]`` table.
Every rank fits (each on its own, ``MPI.COMM_SELF``: the same numbers); rank 0
prints and draws.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from mpi4py import MPI

from hyperfem.app.program import positive_float, positive_int

__all__ = ["add_fit_parser", "fit_command"]

PA_PER_MPA = 1e6
"""The case-file table is in Pa (consistent with meshes in m); the data are in MPa."""


def add_fit_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``hyperfem fit`` to the subcommands."""
    from hyperfem.materials.fitting import FIT_LAWS
    from hyperfem.materials.homogeneous import MODES
    from hyperfem.materials.volumetric import VOLUMETRIC_LAWS

    f = sub.add_parser(
        "fit",
        help="fit a law's parameters to homogeneous test data, or a Prony series to relaxation data (CSV)",
        description="Least-squares fit of a hyperelastic law to homogeneous test data: the response is the law's own "
        "UFL energy (incompressible unless --bulk-modulus is given or the data have volumetric points; the laws of two "
        "elastic constants, hencky, saint_venant_kirchhoff, linear_elastic, fixed_corotated, ..., are always "
        "compressible: mu and the bulk modulus from two modes or volumetric data, the lateral stretch solved from free "
        "faces). Prints the "
        "parameters, the rms and relative errors per mode, Drucker stability over the data range and a "
        "[[material]] table (Pa) to paste into a case file. --law prony fits a Prony series (g_i, tau_i) to "
        "relaxation data instead and prints a [material.viscoelastic] table.",
        epilog="DATA.csv: a header with the columns mode,stretch,nominal_stress_MPa (others ignored); mode one of "
        f"{', '.join(MODES)}; stretch the stretch along the load (volumetric: J^(1/3)); nominal_stress_MPa the "
        "first Piola-Kirchhoff stress P11 in MPa (force per undeformed area); holzapfel_gasser_ogden needs a column "
        "fibre_angle_deg (the two fibre families at +-angle to the load in the 1-2 plane; each mode and angle a "
        "curve), weiss and fung_orthotropic too (one family / the material axes a1, a2 at 0 or 90 only; "
        "fung_orthotropic needs --fix b7=..,b8=..,b9=..: these tests do not strain its shear terms); "
        "muscle and arap are not fitted. "
        "Example: hyperfem fit "
        "hyperfem/materials/data/treloar1944.csv --law ogden --terms 3 --png fit.png. --law prony: relaxation data, "
        "columns time_s (s from the start of the loading) and nominal_stress_MPa (the stress at a held strain) or "
        "relaxation_modulus (g(t) = G(t)/G(0)); the strain ramps linearly over --ramp-time, then is held. One file may "
        "hold both: rows of mode relaxation (stretch: the uniaxial stretch held, one per file; time_s; "
        "nominal_stress_MPa) are fitted by --law prony and left out by the hyperelastic laws.",
    )
    f.add_argument("data", type=Path, help="CSV file of test data (columns mode,stretch,nominal_stress_MPa; "
                   "--law prony: time_s and nominal_stress_MPa or relaxation_modulus)")
    f.add_argument("--law", required=True, metavar="LAW", help=f"the law: {', '.join(FIT_LAWS)}")
    f.add_argument("--terms", type=positive_int, default=None, metavar="N",
                   help="number of terms of ogden and reduced_polynomial (default 3)")
    f.add_argument("--modes", default=None, metavar="MODE,...",
                   help="the modes to fit, comma-separated (default: every mode of the data)")
    f.add_argument("--bulk-modulus", type=positive_float, default=None, metavar="K",
                   help="fixed bulk modulus in MPa: a compressible fit (default: incompressible, or K fitted to "
                   "volumetric data; the two-constant laws always fit K unless it is given)")
    f.add_argument("--volumetric", choices=tuple(VOLUMETRIC_LAWS), default="log",
                   help="the volumetric energy U(J) of a compressible fit and of the table (default log)")
    f.add_argument("--weighting", choices=("relative", "absolute"), default="relative",
                   help="residuals relative to each data stress (default) or absolute")
    f.add_argument("--tau", type=_times, default=None, metavar="T1,T2,...",
                   help="prony: the relaxation times in s, comma-separated (default: --terms times fitted)")
    f.add_argument("--fit-tau", action="store_true", help="prony: refine the --tau times too")
    f.add_argument("--ramp-time", type=_ramp, default=None, metavar="T",
                   help="prony: duration in s of the linear ramp of strain before the hold (default 0: a step)")
    f.add_argument("--fix", type=_fixed, default=None, metavar="NAME=VALUE[,NAME=VALUE]",
                   help="hold these parameters at the given values (moduli in MPa), fit the others; e.g. "
                   "--fix c2=0.1; fung_orthotropic needs its shear constants: --fix b7=2,b8=2,b9=2 (the table and "
                   "--json list them as fixed)")
    f.add_argument("--json", action="store_true", help="print the result as JSON")
    f.add_argument("--png", type=Path, default=None, metavar="FIT.png", help="draw data and fit per mode to this PNG")


def _times(text: str) -> list[float]:
    """``--tau``: comma-separated relaxation times > 0."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated times in s, got {text!r}") from None
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected relaxation times > 0, got {text!r}")
    return values


def _fixed(text: str) -> dict[str, float]:
    """``--fix``: comma-separated NAME=VALUE pairs."""
    out: dict[str, float] = {}
    for item in (i.strip() for i in text.split(",")):
        name, sep, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not sep or not name.strip() or not math.isfinite(number):
            raise argparse.ArgumentTypeError(f"expected NAME=VALUE[,NAME=VALUE] with finite values, got {text!r}")
        out[name.strip()] = number
    return out


def _ramp(text: str) -> float:
    """``--ramp-time``: a finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a time in s, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"expected a time >= 0, got {text!r}")
    return value


def _plot(args: argparse.Namespace, draw: Any) -> None:
    """Rank 0 draws; a failure is raised on every rank."""
    from hyperfem.errors import HyperfemError, OutputError

    comm = MPI.COMM_WORLD
    failure = None
    if comm.rank == 0:
        try:
            if not args.png.parent.is_dir():
                raise OutputError(f"fit: no folder {args.png.parent} for the PNG")
            draw()
        except HyperfemError as exc:
            failure = (type(exc), str(exc))
    failure = comm.bcast(failure, root=0)
    if failure is not None:
        raise failure[0](failure[1])


def _prony_command(args: argparse.Namespace) -> dict[str, Any]:
    """``hyperfem fit RELAX.csv --law prony``."""
    from hyperfem.errors import ParameterError
    from hyperfem.materials.prony_fit import fit_prony, plot_relaxation, read_relaxation

    elastic = [name for name, value in (("--modes", args.modes), ("--bulk-modulus", args.bulk_modulus),
                                        ("--volumetric", None if args.volumetric == "log" else args.volumetric),
                                        ("--fix", args.fix))
               if value is not None]
    if elastic:
        raise ParameterError(f"fit: {elastic[0]} is an option of the hyperelastic laws, not of prony")
    curve = read_relaxation(args.data, args.ramp_time or 0.0)
    result = fit_prony(curve, terms=args.terms, tau=args.tau, fit_tau=True if args.fit_tau else None,
                       weighting=args.weighting)
    summary = result.to_json()
    if args.png is not None:
        summary["png"] = str(args.png)
        _plot(args, lambda: plot_relaxation(result, args.png, title=f"{result.label} fitted to {args.data.name}"))
    if MPI.COMM_WORLD.rank == 0:
        if args.json:
            print(json.dumps(summary, indent=2), flush=True)
        else:
            lines = [f"{args.data}: {curve.time.size} relaxation points ({curve.kind}, ramp {curve.ramp_time:g} s)",
                     result.summary(), "", "# paste under the [[material]] of a split law in a case file:",
                     result.case_table().rstrip("\n")]
            if args.png is not None:
                lines.append(f"wrote {args.png}")
            print("\n".join(lines), flush=True)
    return summary


def fit_command(args: argparse.Namespace) -> dict[str, Any]:
    """Run ``hyperfem fit``; returns the JSON summary."""
    from hyperfem.app.spec import LAWS
    from hyperfem.errors import ParameterError
    from hyperfem.materials.fitting import RELAXATION_MODE, fit, plot_fits, read_curves, relaxation_rows

    if args.law == "prony":
        return _prony_command(args)
    relaxation = [name for name, value in (("--tau", args.tau), ("--fit-tau", args.fit_tau or None),
                                           ("--ramp-time", args.ramp_time)) if value is not None]
    if relaxation:
        raise ParameterError(f"fit: {relaxation[0]} is an option of --law prony (relaxation data), not of {args.law}")
    comm = MPI.COMM_WORLD
    curves = read_curves(args.data)
    modes = None if args.modes is None else [m.strip() for m in args.modes.split(",") if m.strip()]
    result = fit(
        args.law,
        curves,
        terms=args.terms,
        modes=modes,
        bulk_modulus=args.bulk_modulus,
        volumetric=args.volumetric,
        weighting=args.weighting,
        fixed=args.fix,
    )
    summary = result.to_json()
    left_out = relaxation_rows(args.data)
    if left_out:
        summary["relaxation_rows_left_out"] = left_out
    if args.png is not None:
        summary["png"] = str(args.png)
        _plot(args, lambda: plot_fits([result], args.png, title=f"{result.label} fitted to {args.data.name}"))
    if comm.rank == 0:
        if args.json:
            print(json.dumps(summary, indent=2), flush=True)
        else:
            counts = ", ".join(f"{m} {c.stretch.size}" for m, c in result.data.items())
            lines = [f"{args.data}: {sum(c.stretch.size for c in result.data.values())} points ({counts})",
                     result.summary(), "", "# paste into a case file:"]
            if left_out:
                lines.insert(1, f"{left_out} rows of mode {RELAXATION_MODE} left out: fit them with "
                                f"hyperfem fit {args.data} --law prony [--ramp-time T]")
            if result.law not in LAWS:
                lines.append(f'# (case files do not read law = "{result.law}" yet)')
            lines.append(result.case_table(stress_factor=PA_PER_MPA).rstrip("\n"))
            if args.png is not None:
                lines.append(f"wrote {args.png}")
            print("\n".join(lines), flush=True)
    return summary
