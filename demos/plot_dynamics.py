# %% [markdown]
# # Plot a dynamics run
#
# Reads the diagnostics CSV written by `demos/dynamics.py` and renders, one
# above the other, the motion curve of the test point $(4.5, 1.5, 1.5)$ (its
# current coordinates $x_p(t)$), the kinetic, elastic and total energy, and the
# volume ratio with $\min J$. Several CSV files are overlaid (e.g. schemes or
# cases). The plot is `hyperfem.simulation.plots.dynamics_time_series`, which
# also reads a run that is still going or was killed (the CSV is written
# after every step).
#
# `python demos/plot_dynamics.py output/dynamics/bend/diagnostics.csv -o bend.png`

# %%
from pathlib import Path

from mpi4py import MPI  # noqa: F401 - before dolfinx (imported by the plots module)

from hyperfem.app.program import ArgumentParser
from hyperfem.simulation.plots import dynamics_time_series, read_rows


def read(path: Path) -> dict[str, list[float]]:
    """The numeric columns of a diagnostics CSV (text columns such as the SNES reason are left out)."""
    rows = read_rows(path)
    return {k: [r[k] for r in rows] for k in rows[0]}


def main(argv=None) -> Path:
    p = ArgumentParser(description="Plot motion curve and energies of dynamics runs")
    p.add_argument("csv", type=Path, nargs="+", help="diagnostics.csv file(s)")
    p.add_argument("-o", "--output", type=Path, default=None, help="PNG file (default: next to the first CSV)")
    args = p.parse_args(argv)
    out = dynamics_time_series(args.csv, output=args.output)
    print(f"wrote {out}", flush=True)
    return out


# %%
if __name__ == "__main__":
    from hyperfem.app.program import run

    run(main)  # a missing or empty CSV: one line "hyperfem: error: ..." and exit status 1
