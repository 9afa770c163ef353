# %% [markdown]
# # Dynamic cantilever: the eight experiments of seed 003, §5.7
#
# The 10 × 4 × 4 m beam, $x \in [-5, 5]$, clamped at $x = -5$, is set in
# motion by tractions on its free end or by prescribed motions of its end caps
# and followed for 3 s. The material is the compressible Neo-Hookean solid
#
# $$
# \psi(F) = \frac{\mu}{2}(\operatorname{tr} C - 3) - \mu \ln J + \frac{\lambda}{2}(\ln J)^2,
# $$
#
# with $E = 10^6$ Pa, $\nu = 0.3$, density $\rho = 1000$ kg/m³ and a viscous body
# force $c\,\rho\,\dot u$, $c = 0.0004\ \mathrm{s}^{-1}$. Balance of momentum,
#
# $$
# \int_\Omega \rho\,\ddot u\cdot w\,dX + \int_\Omega c\rho\,\dot u\cdot w\,dX
#   + \int_\Omega P(F) : \nabla w\,dX = \int_{\Gamma} t\cdot w\,dA ,
# $$
#
# is discretised in time by Newmark's average-acceleration rule
# ($\beta = 1/4$, $\gamma = 1/2$, seed 003 eq. 2.21). Its step is the minimiser of
# an *incremental potential*
#
# $$
# \Pi_\Delta(u) = \frac{1}{2\beta\Delta t^2}\int_\Omega\rho\,|u - u^\text{pred}|^2\,dX
#   + \frac{c\gamma}{2\beta\Delta t}\int_\Omega\rho\,|u - \hat u|^2\,dX + \Pi(u),
# \qquad u^\text{pred} = u_n + \Delta t\,v_n + \Delta t^2(\tfrac12 - \beta)\,a_n ,
# $$
#
# so the same line-searched Newton solver as for the static problems applies
# (follower loads add a residual term). Backward Euler (seed 000 eq. 2.15,
# $\Pi_\Delta = \frac{\rho}{2\Delta t^2}\|u - u_n - \Delta t v_n\|^2 + \Pi$) and
# generalized-$\alpha$ are available with `--scheme`.
#
# The step size is controlled by step doubling (seed 003 §5.7.7): one step of
# $\Delta t$ and two of $\Delta t/2$; if the nodal positions differ by more than
# `--tol` the step is halved, otherwise the two-half-step result is kept, and
# after four accepted steps without a reduction $\Delta t$ is doubled. Failed
# Newton solves and inverted elements also halve the step. The end of the
# ramps ($t = 1$ s) is a must-hit time.
#
# Run with `python demos/dynamics.py --case bend` or
# `mpiexec -n 2 python demos/dynamics.py --case twist`.

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.cases.cantilever_dynamics import CASES, TEST_POINT, CantileverDynamics, cantilever_problem  # noqa: E402
from hyperfem.app.program import (  # noqa: E402
    ArgumentParser,
    nonnegative_float,
    positive_float,
    positive_int,
    run,
    unit_interval,
)
from hyperfem.io import ensure_output_dir  # noqa: E402
from hyperfem.io.results import note_overwrite  # noqa: E402
from hyperfem.simulation import VTX, CSVLog, Derived, JSONSummary, Progress, Recorder, Simulation  # noqa: E402

SCHEMES = {
    "newmark": lambda a: dyn.Newmark(),
    "backward-euler": lambda a: dyn.BackwardEuler(),
    "generalized-alpha": lambda a: dyn.GeneralizedAlpha(a.rho_inf),
    "quasi-static": lambda a: dyn.QuasiStatic(),
}


def parse(argv=None):
    p = ArgumentParser(description="Dynamic cantilever experiments (seed 003, §5.7)")
    p.add_argument("--case", choices=CASES, default="bend")
    p.add_argument("--t-end", type=positive_float, default=3.0, help="simulated time (s)")
    p.add_argument("--dt", type=positive_float, default=0.02, help="initial time step (s)")
    p.add_argument("--dt-max", type=positive_float, default=None, help="largest time step (s)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--h", type=positive_float, default=1.0, help="element size of the generated beam mesh (m)")
    where.add_argument("--mesh", type=Path, default=None, help="read this gmsh beam mesh instead of generating one")
    p.add_argument("--degree", type=positive_int, default=1, help="displacement degree")
    p.add_argument("--scheme", choices=sorted(SCHEMES), default="newmark")
    p.add_argument("--rho-inf", type=unit_interval, default=0.8, help="generalized-alpha spectral radius in [0, 1]")
    p.add_argument("--lumped", action="store_true", help="lumped (vertex-rule) mass, P1 only")
    p.add_argument("--fixed", action="store_true", help="fixed step (cutback only), no step doubling")
    p.add_argument("--tol", type=positive_float, default=1e-3, help="step-doubling tolerance on nodal positions (m)")
    p.add_argument("--output-every", type=nonnegative_float, default=0.1, help="VTX output interval (s), 0 for none")
    p.add_argument("--output", type=Path, default=Path("output") / "dynamics", help="output folder")
    p.add_argument("--no-vtx", action="store_true", help="skip the VTX time series")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    if args.dt_max is not None and args.dt_max < args.dt:
        p.error(f"argument --dt-max: must be >= --dt ({args.dt:g}), got {args.dt_max:g}")
    if args.lumped and args.degree != 1:
        p.error("argument --lumped: the lumped mass needs --degree 1")
    return args


# %% [markdown]
# ## Model
# `cantilever_problem` builds the hyperelastic problem of the case with time as
# its load factor: loads carry time profiles (`Steady`, `Ramp`) and the
# prescribed motions are `PrescribedDisplacement`s whose value is re-evaluated
# at each time, e.g. the rigid rotation of the free end about an axis through
# the centre of the face,
#
# $$
# u(X, t) = R(\theta(t)\,\hat a)(X - c) + c - X .
# $$
#
# `IncrementalProblem` adds the inertia and damping terms of the chosen scheme.


# %%
def main(argv=None) -> dict:
    args = parse(argv)
    comm = MPI.COMM_WORLD
    out = ensure_output_dir(args.output / args.case, comm)  # fail on every rank before any work
    spec = CantileverDynamics()
    domain = hf.read_mesh(args.mesh, comm) if args.mesh else hf.beam_mesh(h=args.h, comm=comm)
    base, must_hit = cantilever_problem(args.case, domain, spec, degree=args.degree)
    scheme = SCHEMES[args.scheme](args)
    problem = dyn.IncrementalProblem(
        base, scheme, dyn.MassDensity(spec.rho, lumped=args.lumped), dyn.viscous_damping(spec.damping)
    )
    # snes_stol: a Newton update below 1e-10 |u| ends the solve (very short steps cannot
    # reach a small absolute residual: their inertia term is scaled by 1/dt^2).
    options = {"snes_rtol": 1e-8, "snes_atol": 1e-8, "snes_stol": 1e-10, "snes_max_it": 25}
    solver = hf.NewtonSolver(problem, options)
    problem.initial_acceleration()

    # %% [markdown]
    # ## Output
    # After every accepted step the diagnostics (energies, volume, min J, the
    # test-point position) go to one CSV line and the summary to JSON; the
    # displacement and velocity go to a VTX (ADIOS2) time series at the output
    # times, which are must-hit times.

    # %%
    diagnostics = dyn.Diagnostics(problem, [TEST_POINT])
    n_out = int(round(args.t_end / args.output_every)) if args.output_every > 0 else 0
    output_times = [k * args.output_every for k in range(1, n_out + 1)]

    def line(row: dict) -> str:
        return (
            f"t = {row['time']:.4f} s  dt = {row['dt']:.4g} s  its = {row['newton_iterations']}  "
            f"K = {row['kinetic_energy']:.4g} J  Psi = {row['elastic_energy']:.4g} J  "
            f"minJ = {row['min_J']:.3f}  x_p = ({row['p0_x']:.3f}, {row['p0_y']:.3f}, {row['p0_z']:.3f}) m"
        )

    files = [out / "diagnostics.csv", out / "summary.json"] + ([] if args.no_vtx else [out / "displacement.bp"])
    note_overwrite(files, comm)  # the default folder is reused: say what a second run replaces
    outputs = [
        Recorder(diagnostics),
        Derived("final_test_point", lambda s: [diagnostics.rows[-1][f"p0_{a}"] for a in "xyz"]),
        CSVLog(out / "diagnostics.csv"),
        JSONSummary(out / "summary.json", rows=False),
    ]
    if not args.no_vtx:
        outputs.append(VTX(out / "displacement.bp", times=output_times))
    if not args.quiet:
        outputs.append(Progress(line, every=10, initial=False))

    # %% [markdown]
    # ## Time stepping

    # %%
    stepping = dyn.TimeStepping(
        dt=args.dt,
        t_end=args.t_end,
        dt_max=args.dt_max,
        dt_min=args.dt / 2**12,
        adaptive=not args.fixed,
        tolerance=args.tol,
        must_hit=[*must_hit, *output_times],
    )
    info = {
        "case": args.case,
        "scheme": scheme.name,
        "h": args.h,
        "lumped": args.lumped,
        "adaptive": not args.fixed,
        "tolerance": args.tol,
    }
    sim = Simulation(problem, solver, stepping, outputs, name=f"dynamics {args.case}", info=info)
    try:
        sim.run()
    except hf.ConvergenceError as exc:  # what was computed is written; report and return it
        if comm.rank == 0:
            print(f"stopped: {exc}", flush=True)
    summary = sim.summary(rows=False)
    if comm.rank == 0 and not args.quiet:
        print(summary_table(summary, diagnostics.rows, scheme.name, files), flush=True)
    return summary


def summary_table(summary: dict, rows: list[dict], scheme: str, files: list[Path]) -> str:
    """A few lines on the run (the whole summary is in ``summary.json``)."""
    first, last = rows[0], rows[-1]
    total0, total = first["total_energy"], last["total_energy"]
    scale = max(abs(r["kinetic_energy"]) + abs(r["elastic_energy"]) for r in (first, last)) or 1.0
    state = "completed" if summary["completed"] else f"stopped at t = {summary['time']:g} s"
    lines = [
        f"{summary['name']}: {summary['dofs']} dofs, {summary['cells']} cells, {summary['ranks']} rank(s), {scheme}",
        f"  {state}: {summary['steps']} time steps ({summary['rejected']} rejected), "
        f"{summary['total_newton_iterations']} Newton iterations, {summary['wall_time']:.2f} s",
        f"  {'':<10}{'t [s]':>10}{'K [J]':>12}{'Psi [J]':>12}{'total [J]':>12}{'min J':>8}   test point x_p [m]",
    ]
    for label, row in (("start", first), ("end", last)):
        point = ", ".join(f"{row[f'p0_{a}']:.4f}" for a in "xyz")
        lines.append(
            f"  {label:<10}{row['time']:>10.4g}{row['kinetic_energy']:>12.4g}{row['elastic_energy']:>12.4g}"
            f"{row['total_energy']:>12.4g}{row['min_J']:>8.3f}   ({point})"
        )
    lines.append(f"  energy drift (total = kinetic + elastic - external work): {(total - total0) / scale:+.2e} "
                 "of K + Psi")
    lines.append(f"  output: {', '.join(f'{p} (ParaView)' if p.suffix == '.bp' else str(p) for p in files)}")
    return "\n".join(lines)


# %% [markdown]
# Plot the motion curve and the energies with
# `python demos/plot_dynamics.py output/dynamics/bend/diagnostics.csv`.

# %%
if __name__ == "__main__":
    run(main)
