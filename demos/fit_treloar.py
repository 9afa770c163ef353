# %% [markdown]
# # Rubber laws fitted to Treloar's data
#
# L. R. G. Treloar's 1944 measurements on a vulcanised natural rubber (8 % sulphur)
# in uniaxial tension (to $\lambda = 7.6$), equibiaxial tension and pure shear are
# the classic test of a hyperelastic law: a law fitted to one mode need not predict
# the others. Here six laws are fitted to all three modes together,
# `hf.materials.fit(law, data)`: neo-Hookean, Mooney–Rivlin, Yeoh, Arruda–Boyce,
# Gent and Ogden with three terms.
#
# **The response is the law's own energy.** For an incompressible material the
# homogeneous state of each mode is known, $F = \operatorname{diag}(\lambda_1,
# \lambda_2, \lambda_3)$ with $\lambda_1\lambda_2\lambda_3 = 1$
# (uniaxial $\lambda, \lambda^{-1/2}, \lambda^{-1/2}$; equibiaxial
# $\lambda, \lambda, \lambda^{-2}$; pure shear $\lambda, 1, \lambda^{-1}$), and the
# pressure $p$ of $P = \partial\bar\psi/\partial F - pF^{-T}$ follows from the
# traction-free face $P_{33} = 0$:
#
# $$
# P_{11} = \frac{\partial\bar\psi}{\partial F_{11}} - \frac{\lambda_3}{\lambda_1}\,
#          \frac{\partial\bar\psi}{\partial F_{33}} .
# $$
#
# $\partial\bar\psi/\partial F$ is `ufl.diff` of the law's `*_isochoric` energy,
# compiled once per law into a `dolfinx.fem.Expression` whose parameters are
# `fem.Constant`s, so the optimiser (Levenberg–Marquardt, residuals relative to
# each measured stress) never recompiles
# (`hyperfem.materials.homogeneous`). After the fit, Drucker's condition
# $d\tau : d\varepsilon > 0$ is checked along each mode over the data range.
#
# **Then a finite-element run:** a unit cube on rollers pulled to Treloar's largest
# uniaxial stretch with the fitted law, nearly incompressible ($K = 10^4\mu_0$),
# reproduces the homogeneous response of the same compressible law at every data
# stretch (its homogeneous state lies in the P1 space), and so the fitted curve and
# the data.
#
# Run with `python demos/fit_treloar.py` or `mpiexec -n 2 python demos/fit_treloar.py`;
# `hyperfem fit DATA.csv --law ogden` does one fit from the command line.

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_float, positive_int, run  # noqa: E402
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube  # noqa: E402
from hyperfem.io import ensure_output_dir  # noqa: E402
from hyperfem.materials.fitting import FitResult, fit, plot_fits, treloar_data  # noqa: E402
from hyperfem.simulation import Simulation  # noqa: E402
from hyperfem.simulation.measures import Reaction  # noqa: E402

LAWS = (("neo_hookean", None), ("mooney_rivlin", None), ("yeoh", None), ("arruda_boyce", None), ("gent", None),
        ("ogden", 3))
"""The laws fitted (name, terms)."""

OGDEN_1972 = {"mu_1": 0.63, "mu_2": 0.0012, "mu_3": -0.01, "alpha_1": 1.3, "alpha_2": 5.0, "alpha_3": -2.0}
"""Ogden's (1972) three-term fit to these data, MPa (6.3, 0.012, -0.1 kgf/cm^2)."""


def parse(argv=None):
    p = ArgumentParser(description="Rubber laws fitted to Treloar's 1944 data, and a finite-element check")
    p.add_argument("--fe-law", default="yeoh", choices=[law for law, _ in LAWS],
                   help="the fitted law of the finite-element run (default yeoh)")
    p.add_argument("--cells", type=positive_int, default=1, help="unit cube of N x N x N boxes (default 1)")
    p.add_argument("--bulk-ratio", type=positive_float, default=1e4,
                   help="K / mu0 of the finite-element material (default 1e4)")
    p.add_argument("--increment", type=positive_float, default=0.05,
                   help="load-factor increment of the finite-element run (default 0.05)")
    p.add_argument("--output", type=Path, default=Path("output"),
                   help="output folder (fit_treloar.png, fit_treloar.json)")
    return p.parse_args(argv)


# %% [markdown]
# ## The fits
#
# Each law from its default start (Ogden: three starts of the exponents, the best
# kept); the moduli come out in MPa, the data's unit. The published parameters of
# Ogden (1972) are evaluated with the same response (`max_iterations=0`) for
# comparison.


# %%
def fit_all(data: dict) -> list[FitResult]:
    return [fit(law, data, terms=terms) for law, terms in LAWS]


def rms_table(results: list[FitResult], extra: dict[str, FitResult]) -> str:
    modes = list(results[0].errors)
    head = f"{'law':<28}" + "".join(f"{m + ' [MPa]':>20}" for m in modes) + "   Drucker"
    lines = [head, "-" * len(head)]
    rows = [(r.label, r) for r in results] + list(extra.items())
    for label, r in rows:
        cells = "".join(f"{r.errors[m].rms:>11.4f} ({r.errors[m].relative_rms:5.1%})" for m in modes)
        stable = "stable" if r.stable else "lost: " + ", ".join(f"{s.mode} {s.stretch:.3g}" for s in r.stability_lost)
        lines.append(f"{label:<28}{cells}   {stable}")
    return "\n".join(lines)


# %% [markdown]
# ## The finite-element check
#
# Rollers on $x = 0$, $y = 0$, $z = 0$ and $u_x = \lambda_\text{max} - 1$ on $x = 1$;
# the steps land on every uniaxial data stretch (`must_hit`). The reaction on
# $x = 1$ is the nominal stress (unit face). It must equal the homogeneous
# response of the same compressible law (`FitResult.nominal_stress(...,
# bulk_modulus=K)`, lateral stretch solved) to the Newton tolerance; that differs
# from the incompressible fit by the volume change, $\ln J \approx \sigma_m/K$,
# which at $\lambda = 7.6$ (Cauchy stress ~15 $\mu_0$ per unit $P$) is 4 % with
# $K = 1000\mu_0$ and 0.4 % with $10^4\mu_0$.


# %%
def finite_element_uniaxial(result: FitResult, stretches: np.ndarray, K: float, cells: int, increment: float,
                            comm) -> dict:
    top = float(stretches.max())
    times = [(s - 1.0) / (top - 1.0) for s in stretches if s > 1.0]
    problem = hf.HyperelasticProblem(unit_cube(cells, comm), lambda F: result.energy(F, bulk_modulus=K),
                                     bcs=uniaxial_rollers(top))
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10, "snes_atol": 1e-10})
    policy = hf.StepPolicy(increment=increment, must_hit=times)
    summary = Simulation(problem, solver, policy, [Reaction("x1")], name="fit_treloar_fe").run()
    rows = summary["rows"]
    lam = np.array([1.0 + float(r["time"]) * (top - 1.0) for r in rows])
    stress = np.array([float(r["reaction_x1"][0]) for r in rows])
    on_data = np.array([np.argmin(np.abs(lam - s)) for s in stretches])
    return {"completed": bool(summary["completed"]), "steps": len(rows) - 1, "stretch": lam[on_data],
            "stress": stress[on_data]}


# %%
def main(argv=None):
    args = parse(argv)
    comm = MPI.COMM_WORLD
    ensure_output_dir(args.output, comm)
    data = treloar_data()
    start = time.perf_counter()
    results = fit_all(data)
    fitting = time.perf_counter() - start
    ogden_1972 = fit("ogden", data, initial=OGDEN_1972, max_iterations=0)
    chosen = next(r for r in results if r.law == args.fe_law)
    uniaxial = data["uniaxial"]
    mu0 = chosen.bulk_modulus / hf.materials.fitting.BULK_RATIO
    K = args.bulk_ratio * mu0
    fe = finite_element_uniaxial(chosen, uniaxial.stretch, K, args.cells, args.increment, comm)
    homogeneous = chosen.nominal_stress("uniaxial", uniaxial.stretch, bulk_modulus=K)
    loaded = uniaxial.stretch > 1.0
    fe_vs_homogeneous = float(np.max(np.abs(fe["stress"] - homogeneous)[loaded] / homogeneous[loaded]))
    model = chosen.model["uniaxial"]
    fe_vs_fit = float(np.max(np.abs(fe["stress"] - model)[loaded] / model[loaded]))
    fe_rms = float(np.sqrt(np.mean((fe["stress"] - uniaxial.stress) ** 2)))
    summary = {
        "laws": {r.label: r.to_json() for r in results},
        "ogden_1972": ogden_1972.to_json(),
        "fe": {"law": chosen.label, "completed": fe["completed"], "steps": fe["steps"],
               "bulk_modulus_MPa": K, "max_relative_to_homogeneous": fe_vs_homogeneous,
               "max_relative_to_fit": fe_vs_fit, "rms_to_data_MPa": fe_rms,
               "fit_rms_MPa": chosen.errors["uniaxial"].rms},
        "fit_seconds": fitting,
    }
    if comm.rank == 0:
        plot = plot_fits(results, args.output / "fit_treloar.png", title="Treloar (1944): six laws fitted to "
                         "uniaxial, equibiaxial and pure shear together")
        (args.output / "fit_treloar.json").write_text(json.dumps(summary, indent=2))
        print(rms_table(results, {"ogden 1972 (published)": ogden_1972}))
        ogden = next(r for r in results if r.law == "ogden")
        print("\nOgden, fitted:    mu = (" + ", ".join(f"{ogden.parameters[f'mu_{p}']:.4g}" for p in (1, 2, 3))
              + ") MPa, alpha = (" + ", ".join(f"{ogden.parameters[f'alpha_{p}']:.4g}" for p in (1, 2, 3)) + ")")
        print("Ogden 1972:       mu = (0.63, 0.0012, -0.01) MPa, alpha = (1.3, 5, -2)")
        print(f"\nfinite elements ({chosen.label}, K = {args.bulk_ratio:g} mu0, {args.cells}^3 cube, {fe['steps']} "
              f"steps): uniaxial stress within {fe_vs_homogeneous:.1e} of the homogeneous response of the same law, "
              f"{fe_vs_fit:.1e} of the incompressible fit; rms {fe_rms:.4f} MPa to the data (the fit: "
              f"{chosen.errors['uniaxial'].rms:.4f} MPa)")
        print(f"fits: {fitting:.1f} s; output: {plot}, {args.output / 'fit_treloar.json'}")
    comm.Barrier()
    return summary


if __name__ == "__main__":
    run(main)
