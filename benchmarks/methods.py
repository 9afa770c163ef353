"""Seed 003's method comparison (§5.7.3-5.7.6) on the bend and twist cantilever: I-FEM, SI-FEM, L-FEM,
FVM (explicit, lumped), SE-FEM (explicit forces, consistent mass: seed 003's own "SI-FEM") and COR.

For each case and method (``demos/methods.py`` builds them) one fixed-step run
to ``--t-end`` with the seed's steps (``--dt`` for the cheap methods,
``--dt-implicit`` for I-FEM) records the wall time per step and per simulated
second, the test-point trajectory, the kinetic energy and the volume gain.
A stability ladder then runs every method to ``--sweep-t-end`` with steps
``--sweep-dts`` (ascending; the first failure ends the ladder): a run is
unstable when a step fails (Newton, non-finite or inverted state), the test
point leaves the beam's length, or the kinetic energy exceeds 10 times the
largest kinetic energy of the I-FEM run. The explicit schemes run unchecked
there (``check_step=False``) so their true limit can be set against the
estimate ``h_min/c``.

COR is also run against the Neo-Hookean SI-FEM on a large prescribed rotation
(``--rotation-case``, bc-bend: the free end turned by pi/2 in the first second).

The last JSON line states the seed's qualitative findings as numbers:
I-FEM slowest per step but with the largest stable step, COR's stiffness
(its test-point motion and, under the large rotation, its stored energy over
the Neo-Hookean SI-FEM ones), and FVM against
L-FEM (and SE-FEM against SI-FEM, the pair that seed 003's definitions make
algebraically equal) as trajectory, kinetic-energy and volume-gain differences.

    PYTHONPATH=. python benchmarks/methods.py          # ~4 min serial on meshes/beam_h2.msh
    PYTHONPATH=. python benchmarks/methods.py --smoke  # seconds; writes under output/ only

Timings on a shared machine are indicative only.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"


def _demo():
    spec = importlib.util.spec_from_file_location("demo_methods", ROOT / "demos" / "methods.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


demo = _demo()
COMPONENT = {"bend": 1, "twist": 2, "bc-bend": 2, "bc-twist": 1}  # the test point's main direction of motion


def parse(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mesh", type=Path, default=ROOT / "meshes" / "beam_h2.msh")
    p.add_argument("--cases", nargs="+", default=["bend", "twist"], choices=demo.CASES)
    p.add_argument("--methods", nargs="+", default=None, choices=list(demo.METHODS))
    p.add_argument("--t-end", type=float, default=2.0, help="simulated time of the main runs (s)")
    p.add_argument("--dt", type=float, default=1e-3, help="step of SI-FEM, L-FEM, FVM, SE-FEM, COR (s)")
    p.add_argument("--dt-implicit", type=float, default=1e-2, help="step of I-FEM (s)")
    p.add_argument("--sweep-t-end", type=float, default=1.28, help="simulated time of the stability ladder (s)")
    p.add_argument(
        "--sweep-dts", type=float, nargs="*", default=[0.005, 0.01, 0.02, 0.04, 0.08, 0.16, 0.32, 0.64],
        help="steps of the ladder (each should divide --sweep-t-end)",
    )
    p.add_argument("--rotation-case", default="bc-bend", choices=["bc-bend", "bc-twist", "none"],
                   help="large-rotation case for COR vs the Neo-Hookean SI-FEM")
    p.add_argument("--rotation-t-end", type=float, default=1.0, help="simulated time of the rotation case (s)")
    p.add_argument("--output", type=Path, default=None, help="jsonl (default benchmarks/results/methods.jsonl)")
    p.add_argument("--plot", type=Path, default=None, help="png (default benchmarks/results/methods.png)")
    p.add_argument("--smoke", action="store_true", help="tiny horizon and ladder; output under output/")
    args = p.parse_args(argv)
    if args.smoke:
        args.t_end, args.dt, args.dt_implicit = 0.05, 5e-3, 0.025
        args.sweep_t_end, args.sweep_dts = 0.05, [0.01, 0.05]
        args.rotation_t_end = 0.05
        out = ROOT / "output" / "methods_smoke"
        args.output = args.output or out / "methods.jsonl"
        args.plot = args.plot or out / "methods.png"
    args.output = args.output or RESULTS / "methods.jsonl"
    args.plot = args.plot or RESULTS / "methods.png"
    return args


def trajectory(run: dict, every: float = 0.02) -> dict:
    """The recorded rows thinned to ``every`` seconds (for the jsonl)."""
    rows = run["rows"]
    keep, last = [], -math.inf
    for r in rows:
        if r["time"] >= last + every - 1e-12 or r is rows[-1]:
            keep.append(r)
            last = r["time"]
    return {
        "time": [r["time"] for r in keep],
        "test_point": [r["x"] for r in keep],
        "kinetic_energy": [r["kinetic_energy"] for r in keep],
        "volume_gain": [r["volume_gain"] for r in keep],
    }


def on_common_times(a: dict, b: dict, key):
    """Values of ``key(row)`` of two runs at the times both recorded (rows every 0.01 s)."""
    tb = {round(r["time"], 9): r for r in b["rows"]}
    pairs = [(key(r), key(tb[round(r["time"], 9)])) for r in a["rows"] if round(r["time"], 9) in tb]
    if not pairs:
        return np.zeros((0,)), np.zeros((0,))
    x, y = zip(*pairs, strict=True)
    return np.array(x), np.array(y)


def compare(a: dict, b: dict) -> dict:
    """Differences of run ``a`` from run ``b``: trajectory (relative to b's motion), K and volume gain."""
    xa, xb = on_common_times(a, b, lambda r: np.array(r["x"]))
    origin = np.array(demo.TEST_POINT)
    motion = float(np.linalg.norm(xb - origin, axis=1).max()) if len(xb) else float("nan")
    ka, kb = on_common_times(a, b, lambda r: r["kinetic_energy"])
    va, vb = on_common_times(a, b, lambda r: r["volume_gain"])
    return {
        "trajectory_max_diff_rel": float(np.linalg.norm(xa - xb, axis=1).max() / motion) if len(xa) else None,
        "kinetic_energy_max_ratio": float(ka.max() / kb.max()) if len(ka) else None,
        "kinetic_energy_max_diff_rel": float(np.abs(ka - kb).max() / kb.max()) if len(ka) else None,
        "volume_gain_range_ratio": float((va.max() - va.min()) / (vb.max() - vb.min())) if len(va) else None,
    }


def stable(run: dict, energy_cap: float) -> bool:
    return run["completed"] and max(r["kinetic_energy"] for r in run["rows"]) <= energy_cap


def main(argv=None) -> dict:
    args = parse(argv)
    comm = MPI.COMM_WORLD
    domain = hf.read_mesh(args.mesh, comm)
    methods = args.methods or demo.available_methods()
    lines: list[dict] = []

    def emit(line: dict) -> None:
        lines.append(line)
        if comm.rank == 0:
            print(json.dumps(line, default=float), flush=True)

    runs: dict[tuple[str, str], dict] = {}
    for case in args.cases:
        for method in methods:
            dt = args.dt_implicit if method in demo.IMPLICIT else args.dt
            run = demo.run_method(method, case, domain, dt=dt, t_end=args.t_end)
            runs[case, method] = run
            summary = {k: v for k, v in run.items() if k != "rows"}
            emit({"kind": "run", **summary, **demo.extremes(run), "trajectory": trajectory(run)})

    ladders: dict[tuple[str, str], dict] = {}
    for case in args.cases:
        reference = runs.get((case, "I-FEM")) or next(runs[case, m] for m in methods)
        cap = 10.0 * max(r["kinetic_energy"] for r in reference["rows"])
        for method in methods:
            tried, largest = [], None
            for dt in sorted(args.sweep_dts):
                run = demo.run_method(method, case, domain, dt=dt, t_end=args.sweep_t_end, check_step=False)
                ok = stable(run, cap)
                k_max = max(r["kinetic_energy"] for r in run["rows"])
                why = run["failure"] or ("" if ok else f"kinetic energy {k_max:.3g} J > cap {cap:.3g} J")
                tried.append(
                    {
                        "dt": dt,
                        "stable": ok,
                        "why": why,
                        "wall_per_step": run["wall_per_step"],
                        "residual_left_max": run["residual_left_max"],
                    }
                )
                if not ok:
                    break
                largest = dt
            ladder = {
                "kind": "stability",
                "case": case,
                "method": method,
                "t_end": args.sweep_t_end,
                "largest_stable_dt": largest,
                "tried": tried,
                "dt_crit_estimate": runs[case, method]["dt_crit"],
                "dt_spectral": runs[case, method]["dt_spectral"],
            }
            ladders[case, method] = ladder
            emit(ladder)

    rotation: dict = {}
    if args.rotation_case != "none" and "COR" in methods:
        for method in ("COR", "SI-FEM"):
            run = demo.run_method(method, args.rotation_case, domain, dt=args.dt, t_end=args.rotation_t_end)
            rotation[method] = run
            summary = {k: v for k, v in run.items() if k != "rows"}
            emit({"kind": "rotation", **summary, **demo.extremes(run), "trajectory": trajectory(run)})

    checks: dict = {"kind": "checks", "mesh": str(args.mesh), "ranks": comm.size, "t_end": args.t_end}
    if rotation:
        cor, nh = demo.extremes(rotation["COR"]), demo.extremes(rotation["SI-FEM"])
        checks[args.rotation_case] = {
            "cor_over_neo_hookean_max_elastic_energy": cor["max_elastic_energy"] / nh["max_elastic_energy"],
            "cor_over_neo_hookean_max_kinetic_energy": cor["max_kinetic_energy"] / nh["max_kinetic_energy"],
            "cor_vs_si_fem": compare(rotation["COR"], rotation["SI-FEM"]),
            "min_J": {"COR": cor["min_J"], "SI-FEM": nh["min_J"]},
            "volume_gain_range": {
                "COR": [cor["volume_gain_min"], cor["volume_gain_max"]],
                "SI-FEM": [nh["volume_gain_min"], nh["volume_gain_max"]],
            },
        }
    for case in args.cases:
        c: dict = {}
        per_step = {m: runs[case, m]["wall_per_step"] for m in methods}
        median = {m: runs[case, m]["wall_per_step_median"] for m in methods}
        per_second = {m: runs[case, m]["wall_per_simulated_second"] for m in methods}
        c["wall_per_step_ms"] = {m: 1e3 * v for m, v in per_step.items()}
        c["wall_per_step_median_ms"] = {m: 1e3 * v for m, v in median.items()}
        c["wall_per_simulated_second_s"] = per_second
        c["largest_stable_dt"] = {m: ladders[case, m]["largest_stable_dt"] for m in methods}
        c["explicit_dt_estimate_vs_spectral"] = {
            m: [runs[case, m]["dt_crit"], runs[case, m]["dt_spectral"]] for m in methods if m in demo.EXPLICIT
        }
        if "I-FEM" in methods and len(methods) > 1:
            others = [m for m in methods if m != "I-FEM"]
            slowest_other = max(others, key=lambda m: per_step[m])
            c["ifem_slowest_per_step"] = all(per_step["I-FEM"] > per_step[m] for m in others)
            c["ifem_slowest_per_step_median"] = all(median["I-FEM"] > median[m] for m in others)
            c["ifem_per_step_over_next_slowest"] = {slowest_other: per_step["I-FEM"] / per_step[slowest_other]}
            c["ifem_per_step_over_fvm"] = per_step["I-FEM"] / per_step["FVM"] if "FVM" in methods else None
            dts = c["largest_stable_dt"]
            c["ifem_largest_stable_dt"] = all((dts["I-FEM"] or 0) >= (dts[m] or 0) for m in others)
        if "COR" in methods and "SI-FEM" in methods:
            cor, nh = demo.extremes(runs[case, "COR"]), demo.extremes(runs[case, "SI-FEM"])
            k = COMPONENT[case]
            c["cor_over_neo_hookean_max_displacement"] = cor["max_displacement"] / nh["max_displacement"]
            c["cor_over_neo_hookean_final_component"] = cor["final_displacement"][k] / nh["final_displacement"][k]
            c["cor_vs_si_fem"] = compare(runs[case, "COR"], runs[case, "SI-FEM"])
        pairs = (("FVM", "L-FEM"), ("SE-FEM", "SI-FEM"), ("FVM", "SE-FEM"), ("L-FEM", "SI-FEM"), ("I-FEM", "SI-FEM"))
        for a, b in pairs:
            if a in methods and b in methods:
                c[f"{a}_vs_{b}"] = compare(runs[case, a], runs[case, b])
        c["volume_gain_range"] = {
            m: [demo.extremes(runs[case, m])["volume_gain_min"], demo.extremes(runs[case, m])["volume_gain_max"]]
            for m in methods
        }
        c["max_kinetic_energy"] = {m: demo.extremes(runs[case, m])["max_kinetic_energy"] for m in methods}
        checks[case] = c
    emit(checks)

    if comm.rank == 0:
        args.output.parent.mkdir(parents=True, exist_ok=True)
        with args.output.open("w") as fh:
            for line in lines:
                fh.write(json.dumps(line, default=float) + "\n")
        plot(args, runs, ladders, methods)
    return checks


def plot(args, runs, ladders, methods) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = args.cases
    fig, axes = plt.subplots(len(cases), 5, figsize=(24, 4.6 * len(cases)), squeeze=False)
    colours = dict(zip(demo.METHODS, plt.rcParams["axes.prop_cycle"].by_key()["color"], strict=False))
    styles = {"FVM": "--", "SE-FEM": ":"}
    for row, case in enumerate(cases):
        ax_x, ax_k, ax_v, ax_cost, ax_dt = axes[row]
        k = COMPONENT[case]
        for m in methods:
            run = runs[case, m]
            t = [r["time"] for r in run["rows"]]
            label = f"{m} (dt={run['dt']:g})"
            kw = {"color": colours[m], "ls": styles.get(m, "-"), "label": label}
            ax_x.plot(t, [r["x"][k] - demo.TEST_POINT[k] for r in run["rows"]], **kw)
            ax_k.plot(t, [r["kinetic_energy"] for r in run["rows"]], **kw)
            ax_v.plot(t, [r["volume_gain"] for r in run["rows"]], **kw)
        ax_x.set(title=f"{case}: test point u_{'xyz'[k]} (m)", xlabel="t (s)")
        ax_k.set(title=f"{case}: kinetic energy (J)", xlabel="t (s)")
        ax_v.set(title=f"{case}: volume gain", xlabel="t (s)")
        ax_x.legend(fontsize=8)
        x = np.arange(len(methods))
        per_step = [1e3 * runs[case, m]["wall_per_step"] for m in methods]
        per_second = [runs[case, m]["wall_per_simulated_second"] for m in methods]
        ax_cost.bar(x - 0.2, per_step, 0.4, label="ms per step")
        ax_cost.bar(x + 0.2, per_second, 0.4, label="s per simulated s")
        ax_cost.set(yscale="log", title=f"{case}: wall time (indicative)", xticks=x, xticklabels=methods)
        ax_cost.legend(fontsize=8)
        largest = [ladders[case, m]["largest_stable_dt"] or 0.0 for m in methods]
        ax_dt.bar(x, largest, 0.6, color=[colours[m] for m in methods])
        for m in methods:
            estimate = runs[case, m]["dt_crit"]
            if estimate:
                i = methods.index(m)
                ax_dt.plot([i - 0.3, i + 0.3], [estimate] * 2, "k-", lw=2)
        ax_dt.set(
            yscale="log",
            title=f"{case}: largest stable dt (top {max(args.sweep_dts):g}) | h_min/c",
            xticks=x,
            xticklabels=methods,
        )
    fig.tight_layout()
    args.plot.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.plot, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main()
