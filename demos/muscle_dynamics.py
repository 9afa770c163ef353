# %% [markdown]
# # A fusiform muscle contracting with inertia
#
# The spindle-shaped muscle of `demos/muscle.py` (seed 000, supplement §2) hangs
# from its `origin`, which is clamped, with a small dead traction $t_0$ pulling
# its `insertion` along the axis. At $t = 0$ it is at rest in passive
# equilibrium. The belly is then activated,
#
# $$
# \alpha(t) = \min(t / T_a, 1),
# $$
#
# and contracts in a few tens of milliseconds, fast enough for its own mass
# to matter: the insertion overshoots the quasi-static shortening and rings
# about it. The tissue is the transversely isotropic, nearly incompressible
# muscle solid of `hyperfem.cases.muscle` (fibres by the Laplace rule from
# `origin` to `insertion`, tendons passive), with density
# $\rho = 1060$ kg/m³.
#
# **Balance of momentum.** With the three-field (Hu–Washizu) energy
#
# $$
# \Pi(u, p, \theta; t) = \int_\Omega \Big[W_\text{iso}(F; \alpha(t)) + U(\theta)
#     + p\,(\det F - \theta)\Big]dX - \int_{\Gamma_\text{ins}} t_0\cdot u\,dA ,
# $$
#
# $P_2$ displacement and $P_1$ pressure $p$ and volume ratio $\theta$, the
# motion satisfies $\int_\Omega \rho\,\ddot u\cdot w\,dX + \partial_u\Pi[w] = 0$
# together with $\partial_p\Pi = \partial_\theta\Pi = 0$ (pressure and volume are
# constraint fields, without inertia).
#
# **Backward Euler** (seed 000, eq. 2.15) makes each step the stationary point of
# an incremental potential,
#
# $$
# \Pi_\Delta(u, p, \theta) = \frac{1}{2\Delta t^2}\int_\Omega \rho\,
#     |u - u_n - \Delta t\,v_n|^2\,dX + \Pi(u, p, \theta; t_{n+1}),
# \qquad v_{n+1} = \frac{u_{n+1} - u_n}{\Delta t},
# $$
#
# solved by the same line-searched Newton method as the static problems
# (`dyn.IncrementalProblem` over the three-field problem). Backward Euler is
# first order and damps the ringing numerically (`--scheme newmark` conserves
# energy instead).
#
# **Quasi-static reference.** The same time loop without inertia
# (`dyn.QuasiStatic()`) gives the equilibrium at each activation; the
# difference is the effect of inertia.
#
# Run with `python demos/muscle_dynamics.py` or
# `mpiexec -n 2 python demos/muscle_dynamics.py` (same numbers).

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402

import numpy as np  # noqa: E402
from dolfinx import fem  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.loading import Activation  # noqa: E402
from hyperfem.cases.muscle import MUSCLE_DENSITY, muscle_problem  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_float, run  # noqa: E402
from hyperfem.fibres import laplace_fibres  # noqa: E402
from hyperfem.io import ensure_output_dir, write_json  # noqa: E402
from hyperfem.io.results import note_overwrite  # noqa: E402
from hyperfem.mesh.fusiform import FusiformGeometry, fusiform_mesh  # noqa: E402
from hyperfem.simulation import VTX, CSVLog, Quantity, Recorder, Simulation  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
MESH = ROOT / "meshes" / "fusiform_h8mm.msh"  # committed: 268 cells

SCHEMES = {
    "backward-euler": dyn.BackwardEuler,
    "newmark": dyn.Newmark,
    "generalized-alpha": dyn.GeneralizedAlpha,
}


def parse(argv=None):
    p = ArgumentParser(description="A fusiform muscle contracting with inertia (three-field, backward Euler)")
    where = p.add_mutually_exclusive_group()  # a --mesh given is always read (a missing file is an error)
    where.add_argument("--mesh", type=Path, default=MESH, help="fusiform .msh (default: the committed h = 8 mm mesh)")
    where.add_argument(
        "--h", type=positive_float, default=None, help="generate a mesh of this element size (m) instead"
    )
    p.add_argument("--rho", type=positive_float, default=MUSCLE_DENSITY, help="density (kg/m^3)")
    p.add_argument("--ramp", type=positive_float, default=0.02, help="activation ramp time T_a (s)")
    p.add_argument("--dt", type=positive_float, default=0.002, help="time step (s)")
    p.add_argument("--t-end", type=positive_float, default=0.08, help="simulated time (s)")
    p.add_argument("--traction", type=float, default=2.0e3, help="dead axial traction at insertion (Pa)")
    p.add_argument("--bulk-factor", type=positive_float, default=50.0, help="multiplier of the seed bulk moduli")
    p.add_argument("--scheme", choices=sorted(SCHEMES), default="backward-euler")
    p.add_argument("--output", type=Path, default=Path("output") / "muscle_dynamics", help="output folder")
    p.add_argument("--no-vtx", action="store_true", help="skip the VTX time series")
    p.add_argument("--quiet", action="store_true")
    return p.parse_args(argv)


# %% [markdown]
# ## Model
# One builder serves the dynamic and the quasi-static run: fibres, activation
# schedule, the three-field problem of the free experiment, and its passive
# equilibrium under the traction at $t = 0$ (the start of the motion).


# %%
def build(domain, a0, args):
    activation = Activation(domain.mesh, value=lambda t: min(max(t / args.ramp, 0.0), 1.0), name="muscle activation")
    base = muscle_problem(domain, a0, activation, "free", traction=args.traction, bulk_factor=args.bulk_factor)
    hf.NewtonSolver(base).solve(raise_on_failure=True)  # passive equilibrium, alpha(0) = 0
    return base, activation


class InsertionMotion:
    r"""Mean axial displacement of the insertion face, $\int_{\Gamma_\text{ins}} u_z\,dA / |\Gamma_\text{ins}|$."""

    def __init__(self, problem, domain):
        ds = domain.ds("insertion")
        self.comm = domain.comm
        self.area = self.comm.allreduce(fem.assemble_scalar(fem.form(1.0 * ds)))
        self._form = fem.form(problem.displacement()[2] * ds)

    def __call__(self) -> float:
        return self.comm.allreduce(fem.assemble_scalar(self._form)) / self.area


# %% [markdown]
# ## Time integration
# `IncrementalProblem` adds the inertia of the displacement block to the
# three-field problem; `initial_acceleration` solves $M a_0 = -R(u_0)$ on the
# displacement space ($a_0 \approx 0$ at equilibrium). Steps land on the end
# of the ramp. A `Simulation` takes the steps; its outputs observe every
# accepted state: the diagnostics (energies, volume, min J), the activation
# and the insertion's motion become the columns of its rows, which the
# dynamic run also writes as CSV, with the fields as a VTX time series. The
# quasi-static run repeats it with `QuasiStatic()` and no files.


# %%
def integrate(domain, a0, args, scheme, out=None, vtx=True):
    """One run; with ``out`` it writes ``diagnostics.csv`` (and ``displacement.bp`` with ``vtx``) there."""
    base, activation = build(domain, a0, args)
    problem = dyn.IncrementalProblem(base, scheme, dyn.MassDensity(args.rho) if scheme.dynamic else None)
    problem.initial_acceleration()
    diagnostics = dyn.Diagnostics(problem)
    outputs = [
        Recorder(diagnostics),
        Quantity("activation", lambda: activation.value),
        Quantity("insertion_uz", InsertionMotion(problem, domain)),
    ]
    if out is not None:
        outputs.append(CSVLog(out / "diagnostics.csv"))
        if vtx:
            outputs.append(VTX(out / "displacement.bp"))  # displacement, pressure, velocity
    stepping = dyn.TimeStepping(dt=args.dt, t_end=args.t_end, must_hit=[args.ramp], dt_min=args.dt / 64)
    sim = Simulation(problem, hf.NewtonSolver(problem), stepping, outputs, name=f"muscle ({scheme.name})")
    sim.run()
    return sim.rows, diagnostics, problem


# %% [markdown]
# ## Results
# The shortening $s(t) = \bar u_z(0) - \bar u_z(t)$; its peak against the
# quasi-static value at full activation (the overshoot), the half-periods of
# the ringing (between successive extrema of $s$ after the ramp), and the
# largest distance of the dynamic from the quasi-static trajectory.


# %%
def extrema_times(t: np.ndarray, s: np.ndarray, after: float) -> list[float]:
    """Times of the interior local extrema of ``s`` with ``t > after`` (parabola through three samples)."""
    out = []
    for i in range(1, len(s) - 1):
        if t[i] <= after or (s[i] - s[i - 1]) * (s[i + 1] - s[i]) > 0:
            continue
        h = t[i + 1] - t[i]
        curvature = s[i + 1] - 2 * s[i] + s[i - 1]
        out.append(t[i] + (0.5 * h * (s[i - 1] - s[i + 1]) / curvature if curvature else 0.0))
    return out


def main(argv=None) -> dict:
    args = parse(argv)
    comm = MPI.COMM_WORLD
    start = time.perf_counter()
    out = ensure_output_dir(args.output, comm)  # collective: fail on every rank before any work
    files = [out / "diagnostics.csv", out / "muscle_dynamics.json", *([] if args.no_vtx else [out / "displacement.bp"])]
    note_overwrite(files, comm)
    domain = (
        fusiform_mesh(h=args.h, geometry=FusiformGeometry(), comm=comm) if args.h else hf.read_mesh(args.mesh, comm)
    )
    a0 = laplace_fibres(domain, "origin", "insertion")
    scheme = SCHEMES[args.scheme]()
    dynamic, diagnostics, problem = integrate(domain, a0, args, scheme, out, vtx=not args.no_vtx)
    static, _, _ = integrate(domain, a0, args, dyn.QuasiStatic())
    t = np.array([r["time"] for r in dynamic])
    s = dynamic[0]["insertion_uz"] - np.array([r["insertion_uz"] for r in dynamic])
    # The same steps unless one run had to cut back: compare at the dynamic times.
    t_qs = np.array([r["time"] for r in static])
    s_qs = np.interp(t, t_qs, static[0]["insertion_uz"] - np.array([r["insertion_uz"] for r in static]))
    peak = int(np.argmax(s))
    full = int(np.searchsorted(t, args.ramp - 1e-9 * args.ramp))  # first step at full activation
    turns = extrema_times(t, s, args.ramp)
    summary = {
        "ranks": comm.size,
        "cells": domain.mesh.topology.index_map(domain.tdim).size_global,
        "dofs": problem.u.function_space.dofmap.index_map.size_global * problem.u.function_space.dofmap.index_map_bs,
        "scheme": scheme.name,
        "rho": args.rho,
        "ramp": args.ramp,
        "dt": args.dt,
        "times": t.tolist(),
        "activation": [r["activation"] for r in dynamic],
        "shortening": s.tolist(),
        "shortening_quasistatic": s_qs.tolist(),
        "quasistatic_shortening": float(s_qs[full]),
        "peak_shortening": float(s[peak]),
        "peak_time": float(t[peak]),
        "overshoot": float(s[peak] / s_qs[full] - 1.0),
        "half_periods": np.diff(turns).tolist(),
        "max_deviation_from_quasistatic": float(np.abs(s - s_qs).max()),
        "kinetic_energy": [r["kinetic_energy"] for r in dynamic],
        "newton_iterations": [r["newton_iterations"] for r in dynamic[1:]],
        "min_J": diagnostics.summary()["min_J"],
        "wall_time": time.perf_counter() - start,
    }
    write_json(out / "muscle_dynamics.json", summary, comm)
    if comm.rank == 0 and not args.quiet:
        for k in range(0, len(t), max(1, len(t) // 20)):
            print(
                f"t = {1e3 * t[k]:6.1f} ms  alpha = {dynamic[k]['activation']:.3f}  shortening = {1e3 * s[k]:7.4f} mm "
                f"(quasi-static {1e3 * s_qs[k]:7.4f} mm)  K = {dynamic[k]['kinetic_energy']:.3e} J",
                flush=True,
            )
        half = summary["half_periods"]
        print(
            f"{scheme.name}: peak shortening {1e3 * s[peak]:.4f} mm at t = {1e3 * t[peak]:.1f} ms, "
            f"{100 * summary['overshoot']:.1f} % above the quasi-static {1e3 * s_qs[full]:.4f} mm; "
            + (f"half-period {1e3 * np.mean(half):.1f} ms; " if half else "")
            + f"{summary['wall_time']:.1f} s",
            flush=True,
        )
    if comm.rank == 0 and not args.quiet:
        print(f"output: {', '.join(f'{p} (ParaView)' if p.suffix == '.bp' else str(p) for p in files)}", flush=True)
    return summary


# %%
if __name__ == "__main__":
    run(main)
