# %% [markdown]
# # Time-integration methods compared on the cantilever (seed 003, §5.7)
#
# Seed 003 compares five ways of stepping the beam of `dynamics.py` (10 × 4 × 4 m,
# clamped at $x = -5$, $E = 10^6$ Pa, $\nu = 0.3$, $\rho = 1000$ kg/m³, viscous
# damping $c\rho\dot u$ with $c = 0.0004\ \mathrm{s^{-1}}$) in the *bend* and
# *twist* experiments. All solve the semi-discrete balance of momentum
#
# $$
# M\ddot u + C\dot u + f_\text{int}(u) = f_\text{ext}(t),\qquad C = cM ,
# $$
#
# and differ in how much of it is implicit:
#
# | method | step | mass | work per step |
# |---|---|---|---|
# | **I-FEM** | backward Euler, $R_\Delta(u_{n+1}) = 0$ by Newton | consistent | Newton iterations |
# | **SI-FEM** | backward Euler, *one* Newton iteration from $u_n + \Delta t\,v_n$ | consistent | 1 tangent + 1 solve |
# | **L-FEM** | as SI-FEM | lumped | 1 tangent + 1 solve |
# | **FVM** | central differences, $a_n = M_L^{-1}(f_\text{ext} - f_\text{int}(u_n) - Cv)$ | lumped | 1 residual |
# | **SE-FEM** | as FVM (elastic force explicit) | consistent | 1 residual + 1 CG mass solve |
# | **COR** | corotational linear $\psi_\text{lin}(R_n^T F)$, SI-FEM step | consistent | 1 tangent + 1 solve |
#
# SI-FEM and L-FEM here are the *linearly implicit* backward Euler of the
# task this demo answers (`hyperfem.dynamics.semi_implicit`); seed 003 itself
# calls "SI-FEM" the scheme with the elastic forces explicit and a
# consistent-mass velocity solve (its §5.5: "the coefficient matrix of the
# velocity update is the mass matrix"), which is **SE-FEM** in this table, and
# its L-FEM is then the lumped version of that, i.e. exactly the FVM (seed 003
# eq. 3.97; `tests/test_explicit.py` checks that the FVM node force is the
# assembled FEM force). COR needs `hyperfem.materials.corotational_linear` and is
# skipped without it; its energy is quadratic within a step (the rotation
# $R_n$ is that of the step's start), so its single iteration solves the
# backward-Euler step exactly.
#
# The explicit schemes are checked against the stable step
# $\Delta t_\text{crit} = \min_K h_K / c$, $c = \sqrt{(\lambda + 2\mu)/\rho}$,
# $h_K$ the inscribed-sphere diameter (`hyperfem.dynamics.stability`).
#
# Run with `python demos/methods.py --case bend` (or `--case twist`,
# `--methods FVM L-FEM`); `benchmarks/methods.py` runs the full comparison.

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import importlib.util  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.cases.cantilever import bend_load, twist_load  # noqa: E402
from hyperfem.cases.cantilever_dynamics import TEST_POINT, CantileverDynamics, cantilever_problem  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_float, run  # noqa: E402
from hyperfem.io import ensure_output_dir, write_json  # noqa: E402
from hyperfem.io.results import note_overwrite  # noqa: E402
from hyperfem.mesh.beam import LENGTH  # noqa: E402
from hyperfem.simulation import CSVLog, Output, Recorder, Simulation  # noqa: E402

END_ROTATION = {"bc-bend": ((0.0, 1.0, 0.0), math.pi / 2), "bc-twist": ((1.0, 0.0, 0.0), 2 * math.pi)}
"""Axis and final angle of the free end's prescribed rotation (as in ``cantilever_problem``)."""

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_MESH = ROOT / "meshes" / "beam_h2.msh"

METHODS = {
    "I-FEM": "backward Euler, Newton to convergence, consistent mass",
    "SI-FEM": "backward Euler, one Newton iteration per step, consistent mass",
    "L-FEM": "backward Euler, one Newton iteration per step, lumped mass",
    "FVM": "explicit central differences, lumped mass (no solve)",
    "SE-FEM": "explicit elastic forces, consistent-mass solve (seed 003's own SI-FEM)",
    "COR": "corotational linear elasticity, one backward-Euler iteration, consistent mass",
}
IMPLICIT = ("I-FEM",)
EXPLICIT = ("FVM", "SE-FEM")
CASES = ("bend", "twist", "bc-bend", "bc-twist")
"""Seed 003's study is bend and twist; the prescribed rotations bc-bend/bc-twist test large rotations (COR)."""
NEWTON_OPTIONS = {"snes_rtol": 1e-8, "snes_atol": 1e-8, "snes_stol": 1e-10, "snes_max_it": 25}
"""I-FEM's Newton tolerances (those of demos/dynamics.py)."""


def corotational_available() -> bool:
    """Whether ``hyperfem.materials.corotational_linear`` (the COR energy) is installed."""
    return importlib.util.find_spec("hyperfem.materials.corotational_linear") is not None


def available_methods() -> list[str]:
    """The methods this installation can run (COR only with its material)."""
    return [m for m in METHODS if m != "COR" or corotational_available()]


class BlowUp(Exception):
    """The run left the physical range (test point beyond one beam length, or non-finite)."""


# %% [markdown]
# ## Building a method
# The body is `cantilever_problem(case)` (compressible Neo-Hookean); COR swaps
# the material for the corotational linear energy with its step-rotation
# updater, keeping the loads and the clamp.


# %%
def body(method: str, case: str, domain, spec: CantileverDynamics):
    """The hyperelastic problem of ``case`` with the material of ``method``, and its must-hit times."""
    if case not in CASES:
        raise hf.ParameterError(f"methods demo: unknown case {case!r} (choose from {', '.join(CASES)})")
    if method != "COR":
        return cantilever_problem(case, domain, spec)
    from hyperfem.materials.corotational_linear import corotational_linear

    psi, updater = corotational_linear(spec.lame)
    bcs, loads, must_hit = [hf.Clamp("clamped")], [], []
    steady = dyn.Steady()  # on from t = 0, as in cantilever_problem (the default profile ramps with t)
    if case == "bend":
        loads.append(bend_load(profile=steady))
    elif case == "twist":
        loads.append(twist_load(profile=steady))
    else:
        axis, angle = END_ROTATION[case]
        ramp = dyn.Ramp(spec.ramp_time, final=angle)
        bcs.append(dyn.rotating_surface("free_end", axis, ramp, (LENGTH / 2, 0.0, 0.0)))
        must_hit.append(spec.ramp_time)
    problem = hf.HyperelasticProblem(domain, psi, bcs=bcs, loads=loads, updaters=[updater])
    return problem, must_hit


def build(method: str, case: str, domain, spec: CantileverDynamics | None = None, *, check_step: bool = True):
    """``(stepper, solver, stage, must_hit)`` of one method: the object that holds the state (the
    ``Simulation``'s problem, which the diagnostics observe), its Newton solver (``None`` for the
    explicit schemes), the ``Simulation``'s stage class (``None``: its default) and the case's must-hit times."""
    if method not in METHODS:
        raise hf.ParameterError(f"methods demo: unknown method {method!r} (choose from {', '.join(METHODS)})")
    if method == "COR" and not corotational_available():
        raise hf.ParameterError(
            "methods demo: COR needs hyperfem.materials.corotational_linear, which is not installed"
        )
    spec = CantileverDynamics() if spec is None else spec
    base, must_hit = body(method, case, domain, spec)
    damping = dyn.viscous_damping(spec.damping)
    lumped = method in ("L-FEM", "FVM")
    density = dyn.MassDensity(spec.rho, lumped=lumped)
    if method in EXPLICIT:
        explicit = dyn.ExplicitDynamics(base, density, damping, lame=spec.lame, check_step=check_step)
        explicit.initial_acceleration()
        return explicit, None, dyn.ExplicitStage, must_hit
    problem = dyn.IncrementalProblem(base, dyn.BackwardEuler(), density, damping)
    problem.initial_acceleration()
    if method in IMPLICIT:
        return problem, hf.NewtonSolver(problem, NEWTON_OPTIONS), None, must_hit  # None: the default DynamicStage
    return problem, dyn.semi_implicit_solver(problem), dyn.SemiImplicitStage, must_hit


# %% [markdown]
# ## One run
# Every method is a `Simulation` of its state, solver and stage with fixed
# steps (no step doubling, no cutback: a failed step ends the run). Its outputs
# record the seed's diagnostics every `output_every` seconds: the test point
# $(4.5, 1.5, 1.5)$, the kinetic energy and the volume gain
# $\int\det F\,dX/|\Omega| - 1$ (with `csv_file`, also into a CSV file), and stop
# a run whose test point leaves the physical range. The wall time per step
# counts the step only (not the outputs).


# %%
class BlowUpWatch(Output):
    """Raise :class:`BlowUp` when a recorded test point is not finite or has moved more than a beam length."""

    def write(self, sim, step) -> None:
        row = sim.rows[-1]
        if "p0_x" not in row:  # a step between the recorded ones
            return
        moved = float(np.linalg.norm(np.subtract([row["p0_x"], row["p0_y"], row["p0_z"]], TEST_POINT)))
        if not (math.isfinite(moved) and moved < LENGTH):
            raise BlowUp(f"test point moved {moved:.3g} m at t = {row['time']:.4g} s")


def summary_row(row: dict) -> dict:
    """The row of a run's summary from a diagnostics row."""
    return {
        "time": row["time"],
        "x": [row["p0_x"], row["p0_y"], row["p0_z"]],
        "kinetic_energy": row["kinetic_energy"],
        "elastic_energy": row["elastic_energy"],
        "volume_gain": row["volume_ratio"] - 1.0,
        "min_J": row["min_J"],
    }


def run_method(
    method: str,
    case: str,
    domain,
    *,
    dt: float,
    t_end: float,
    spec: CantileverDynamics | None = None,
    check_step: bool = True,
    output_every: float = 0.01,
    csv_file: Path | None = None,
) -> dict:
    r"""Run one method on one case; returns the summary and the recorded rows.

    Keys: ``method, case, dt, t_end, completed, failure, steps, newton_iterations_per_step,
    wall_per_step`` (mean), ``wall_per_step_median, wall_per_simulated_second`` (mean step / dt),
    ``residual_left_max`` (SI methods: the largest relative residual left by a step),
    ``dt_crit`` and ``dt_spectral`` (explicit: the estimate and the linearised limit
    :math:`2/\omega_\max` at the start), ``rows`` (time, test point, kinetic and elastic
    energy, volume gain, min J). With ``csv_file`` the recorded rows (all diagnostics) go to that file.
    """
    stepper, solver, stage, must_hit = build(method, case, domain, spec, check_step=check_step)
    sharp = stepper.spectral_time_step() if method in EXPLICIT else None
    diagnostics = dyn.Diagnostics(stepper, [TEST_POINT])
    every = max(1, round(output_every / dt))
    outputs = [Recorder(diagnostics, every=every), BlowUpWatch()]
    if csv_file is not None:
        outputs.insert(1, CSVLog(csv_file, every=every))
    must_hit = [t for t in must_hit if t < t_end]
    stepping = dyn.TimeStepping(dt=dt, t_end=t_end, dt_min=dt, must_hit=must_hit, reject_inversion=True)
    sim = Simulation(stepper, solver, stepping, outputs, stage=stage, name=f"{method} {case}")
    failure = ""
    start = time.perf_counter()
    try:
        sim.run()
    except BlowUp as exc:
        failure = f"blow-up: {exc}"
    except hf.ConvergenceError as exc:
        failure = f"step failed: {exc}"
    wall = time.perf_counter() - start
    history = sim.steps
    rows = [summary_row(row) for row in diagnostics.rows]
    residual_left = [dyn.linearization_residual(r)[1] for r in history] if method in ("SI-FEM", "L-FEM", "COR") else []
    comm = domain.comm
    step_wall = comm.allreduce(sum(r.wall_time for r in history), op=MPI.MAX)
    median = comm.allreduce(float(np.median([r.wall_time for r in history])) if history else math.nan, op=MPI.MAX)
    steps = len(history)
    summary = {
        "method": method,
        "case": case,
        "dt": dt,
        "t_end": t_end,
        "completed": not failure,
        "failure": failure,
        "time_reached": float(history[-1].time) if history else 0.0,
        "steps": steps,
        "newton_iterations_per_step": (sum(r.iterations for r in history) / steps) if steps else 0.0,
        "wall_per_step": step_wall / steps if steps else float("nan"),
        "wall_per_step_median": median,
        "wall_per_simulated_second": step_wall / steps / dt if steps else float("nan"),
        "wall_total": wall,
        "residual_left_max": max(residual_left) if residual_left else None,
        "dt_crit": getattr(getattr(stepper, "stable_step", None), "dt_crit", None),
        "dt_spectral": sharp,
        "ranks": comm.size,
        "rows": rows,
    }
    return summary


def extremes(summary: dict) -> dict:
    """Headline numbers of a run: test-point displacement range, kinetic-energy and volume-gain extremes."""
    rows = summary["rows"]
    x = np.array([r["x"] for r in rows]) - np.array(TEST_POINT)
    return {
        "max_displacement": float(np.linalg.norm(x, axis=1).max()),
        "final_displacement": x[-1].tolist(),
        "max_kinetic_energy": max(r["kinetic_energy"] for r in rows),
        "max_elastic_energy": max(r["elastic_energy"] for r in rows),
        "volume_gain_min": min(r["volume_gain"] for r in rows),
        "volume_gain_max": max(r["volume_gain"] for r in rows),
        "min_J": min(r["min_J"] for r in rows),
    }


def parse(argv=None):
    p = ArgumentParser(description="Time-integration methods on the cantilever (seed 003, §5.7)")
    p.add_argument("--case", choices=CASES, default="bend")
    p.add_argument("--methods", nargs="+", choices=list(METHODS), default=None, help="default: all available")
    p.add_argument("--mesh", type=Path, default=DEFAULT_MESH, help="gmsh beam mesh")
    p.add_argument("--dt", type=positive_float, default=1e-3, help="step of SI-FEM, L-FEM, FVM, SE-FEM, COR (s)")
    p.add_argument("--dt-implicit", type=positive_float, default=1e-2, help="step of I-FEM (s)")
    p.add_argument("--t-end", type=positive_float, default=1.0, help="simulated time (s)")
    p.add_argument("--output", type=Path, default=Path("output") / "methods", help="output folder")
    p.add_argument("--quiet", action="store_true")
    return p.parse_args(argv)


# %% [markdown]
# ## Running the comparison
# Every method's recorded rows (all the diagnostics columns, every `output_every`
# seconds) go to `<output>/<case>_<method>.csv`, the summaries to
# `<output>/<case>.json`; rank 0 prints one line per method.


# %%
def main(argv=None) -> dict:
    args = parse(argv)
    comm = MPI.COMM_WORLD
    out = ensure_output_dir(args.output, comm)
    domain = hf.read_mesh(args.mesh, comm)
    methods = args.methods or available_methods()
    files = [out / f"{args.case}_{method}.csv" for method in methods] + [out / f"{args.case}.json"]
    note_overwrite(files, comm)
    results = {}
    for method in methods:
        dt = args.dt_implicit if method in IMPLICIT else args.dt
        csv_file = out / f"{args.case}_{method}.csv"
        summary = run_method(method, args.case, domain, dt=dt, t_end=args.t_end, csv_file=csv_file)
        results[method] = {**{k: v for k, v in summary.items() if k != "rows"}, **extremes(summary)}
        if comm.rank == 0 and not args.quiet:
            r = results[method]
            d = r["final_displacement"]
            print(
                f"{method:7s} dt = {dt:<7.3g} steps {r['steps']:5d}  {1e3 * r['wall_per_step']:8.2f} ms/step "
                f"{r['wall_per_simulated_second']:8.2f} s per simulated s  u_p(t_end) = ({d[0]:.3f}, {d[1]:.3f}, "
                f"{d[2]:.3f})  K_max = {r['max_kinetic_energy']:.4g} J  volume gain [{r['volume_gain_min']:.2e}, "
                f"{r['volume_gain_max']:.2e}]" + ("" if r["completed"] else f"  FAILED: {r['failure']}"),
                flush=True,
            )
    summary = {"case": args.case, "mesh": str(args.mesh), "ranks": comm.size, "methods": results}
    write_json(out / f"{args.case}.json", summary, comm)
    if comm.rank == 0 and not args.quiet:
        print(f"output: {', '.join(str(p) for p in files)}", flush=True)
    return summary


# %%
if __name__ == "__main__":
    run(main)
