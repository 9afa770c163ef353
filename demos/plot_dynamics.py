# %% [markdown]
# # Plot a dynamics run
#
# Reads the diagnostics CSV written by `demos/dynamics.py` and renders, one
# above the other, the motion curve of the test point $(4.5, 1.5, 1.5)$ (its
# current coordinates $x_p(t)$), the kinetic, elastic and total energy, and the
# volume ratio with $\min J$. Several CSV files are overlaid (e.g. schemes or
# cases).
#
# `python demos/plot_dynamics.py output/dynamics/bend/diagnostics.csv -o bend.png`

# %%
import argparse
import csv
from pathlib import Path


def _number(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def read(path: Path) -> dict[str, list[float]]:
    """The numeric columns of a diagnostics CSV (text columns such as the SNES reason are left out)."""
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    columns = {k: [_number(r[k]) for r in rows] for k in rows[0]}
    return {k: v for k, v in columns.items() if all(x is not None for x in v)}


def main(argv=None) -> Path:
    p = argparse.ArgumentParser(description="Plot motion curve and energies of dynamics runs")
    p.add_argument("csv", type=Path, nargs="+", help="diagnostics.csv file(s)")
    p.add_argument("-o", "--output", type=Path, default=None, help="PNG file (default: next to the first CSV)")
    args = p.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(7, 9), sharex=True)
    for path in args.csv:
        d = read(path)
        label = path.parent.name
        t = d["time"]
        for comp, style in zip("xyz", ("-", "--", ":"), strict=True):
            if f"p0_{comp}" in d:
                axes[0].plot(t, d[f"p0_{comp}"], style, label=f"{label}: {comp}")
        axes[1].plot(t, d["kinetic_energy"], label=f"{label}: kinetic")
        axes[1].plot(t, d["elastic_energy"], label=f"{label}: elastic")
        axes[1].plot(t, d["total_energy"], "k--", lw=1, label=f"{label}: total")
        axes[2].plot(t, d["volume_ratio"], label=f"{label}: V/V0")
        axes[2].plot(t, d["min_J"], ":", label=f"{label}: min J")
    axes[0].set_ylabel("test point position (m)")
    axes[1].set_ylabel("energy (J)")
    axes[2].set_ylabel("volume ratio, min J")
    axes[2].set_xlabel("time (s)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    out = args.output or args.csv[0].with_suffix(".png")
    fig.savefig(out, dpi=120)
    plt.close(fig)
    print(out)
    return out


# %%
if __name__ == "__main__":
    main()
