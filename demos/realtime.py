# %% [markdown]
# # Real-time stepping: the end of a soft beam dragged along a circle
#
# Seed 000 sets the budget of an interactive simulation: a time step must take
# less than the frame time, $1/30$ s. Here the cantilever of seed 003 (the
# 10 × 4 × 4 m beam, compressible Neo-Hookean, $E = 10^6$ Pa, $\nu = 0.3$,
# $\rho = 1000$ kg/m³, viscous damping $c = 0.0004\ \mathrm{s^{-1}}$) is
# clamped at $x = -5$ while its free end — the physical group `free_end` of
# the gmsh mesh — is dragged rigidly along a circle in the $y$–$z$ plane,
#
# $$
# u(X, t) = r(t)\,\bigl(0,\ \sin\omega t,\ 1 - \cos\omega t\bigr)\quad\text{on } \Gamma_\text{free},
# \qquad r(t) = R\,s\bigl(\min(t/T, 1)\bigr),\ s(\xi) = 3\xi^2 - 2\xi^3 ,
# $$
#
# (the radius grows smoothly over the first period $T = 2\pi/\omega$, so the
# drag starts from rest), as a user's cursor would drag it.
#
# Each frame is one backward-Euler step (seed 000, eq. 2.15): the minimiser of
# the incremental potential
#
# $$
# \Pi_\Delta(u) = \frac{1}{2\Delta t^2}\int_\Omega \rho\,|u - u_n - \Delta t\,v_n|^2\,dX
#   + \frac{c}{2\Delta t}\int_\Omega \rho\,|u - u_n|^2\,dX + \Pi(u),
# $$
#
# approximated by at most `--budget` Newton iterations from the warm start
# $u_n + \Delta t\,v_n$ (with the new boundary values). The
# `RealtimeStepper` compiles the forms once, assembles the constant inertia
# part once, reuses the sparsity, the KSP and its preconditioner, and reports
# for every step the residual it leaves, $\|r\|/\|r_0\|$ — a real-time step is
# allowed to be inexact, but never silently.
#
# The frame loop is the demo's own, not a `Simulation`: the frame clock drives
# the steps, and no file is written between frames (the module docstring of
# `hyperfem.dynamics.realtime` says why).
#
# Run with `python demos/realtime.py` or `mpiexec -n 2 python demos/realtime.py --h 0.6`;
# `--config` picks the linear solver: the default `cg-icc-modified` keeps the
# tangent and its ICC(0) factors over steps (modified Newton) until a step
# misses `--rtol`; `cg-icc` is Newton with a fresh tangent per iteration.

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import math  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402

import numpy as np  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem import dynamics as dyn  # noqa: E402
from hyperfem.cases.cantilever_dynamics import CantileverDynamics  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_float, positive_int, run  # noqa: E402
from hyperfem.dynamics.realtime import CONFIGS, RealtimeStepper  # noqa: E402
from hyperfem.io import PointProbe, ensure_output_dir, write_json  # noqa: E402
from hyperfem.mesh.beam import LENGTH  # noqa: E402

GRAB_POINT = (LENGTH / 2, 0.0, 0.0)
"""Centre of the dragged face: it moves exactly along the path."""


# %% [markdown]
# ## The path
# A prescribed displacement per component, each a constant value scaled by
# its own time profile: moving the boundary costs one vector update per step
# (no re-interpolation of a callable over the mesh).


# %%
@dataclass(frozen=True)
class CirclePath:
    """The displacement :math:`r(t)(0, \\sin\\omega t, 1 - \\cos\\omega t)` with a smooth radius ramp."""

    radius: float = 1.0
    period: float = 2.0

    def __call__(self, t: float) -> tuple[float, float, float]:
        xi = min(max(t / self.period, 0.0), 1.0)
        r = self.radius * xi * xi * (3.0 - 2.0 * xi)
        w = 2.0 * math.pi / self.period
        return (0.0, r * math.sin(w * t), r * (1.0 - math.cos(w * t)))


def dragged_surface(boundary: str, path) -> list[hf.PrescribedDisplacement]:
    """Prescribe the rigid translation ``path(t)`` (3 components) of the named surface."""
    return [
        hf.PrescribedDisplacement(boundary, (1.0,), components=[i], profile=lambda t, i=i: path(t)[i])
        for i in range(3)
    ]


def parse(argv=None):
    p = ArgumentParser(description="Real-time stepping: a beam's end dragged along a circle (seed 000)")
    where = p.add_mutually_exclusive_group()  # a --mesh given is always read (a missing file is an error)
    where.add_argument("--mesh", type=Path, default=None, help="gmsh beam mesh (physical groups clamped, free_end)")
    where.add_argument("--h", type=positive_float, default=1.0, help="element size of the generated beam (m)")
    p.add_argument("--steps", type=positive_int, default=60, help="time steps (frames)")
    p.add_argument("--dt", type=positive_float, default=1.0 / 30.0, help="time step = frame time (s)")
    p.add_argument("--budget", type=positive_int, default=6, help="Newton iterations per step")
    p.add_argument("--config", choices=sorted(CONFIGS), default="cg-icc-modified", help="linear solver configuration")
    p.add_argument("--rtol", type=positive_float, default=1e-4, help="a step stops at |r| <= rtol |r0|")
    p.add_argument("--radius", type=positive_float, default=1.0, help="radius of the circle (m)")
    p.add_argument("--period", type=positive_float, default=2.0, help="period of the circle (s)")
    p.add_argument("--output", type=Path, default=None, help="write the summary JSON into this folder")
    p.add_argument("--quiet", action="store_true")
    return p.parse_args(argv)


# %% [markdown]
# ## Model and stepper


# %%
def main(argv=None) -> dict:
    args = parse(argv)
    comm = MPI.COMM_WORLD
    out = ensure_output_dir(args.output, comm) if args.output is not None else None
    spec = CantileverDynamics()
    domain = hf.read_mesh(args.mesh, comm) if args.mesh else hf.beam_mesh(h=args.h, comm=comm)
    path = CirclePath(args.radius, args.period)
    base = hf.HyperelasticProblem(
        domain,
        lambda F: hf.materials.neo_hookean(F, spec.lame),
        bcs=[hf.Clamp("clamped"), *dragged_surface("free_end", path)],
    )
    problem = dyn.IncrementalProblem(
        base, dyn.BackwardEuler(), dyn.MassDensity(spec.rho), dyn.viscous_damping(spec.damping)
    )
    stepper = RealtimeStepper(problem, args.dt, args.budget, config=args.config, rtol=args.rtol)
    probe = PointProbe(domain.mesh, [GRAB_POINT])

    # %% [markdown]
    # ## The frame loop
    # One `step()` per frame; every tenth frame rank 0 prints the step's wall
    # time, Newton iterations and the residual left.

    # %%
    for _ in range(args.steps):
        rec = stepper.step()
        if comm.rank == 0 and not args.quiet and rec.step % 10 == 0:
            print(
                f"t = {rec.time:.3f} s  its = {rec.iterations}  |r|/|r0| = {rec.relative_residual:.2e}  "
                f"step {1e3 * rec.wall_time:.1f} ms",
                flush=True,
            )
    stats = stepper.summary(skip=1)  # the first step sets up the preconditioner
    grab = probe(problem.u)[0]
    target = np.array(path(problem.t_n))
    tets = domain.mesh.topology.index_map(3).size_global
    summary = {
        "tets": int(tets),
        "unknowns": int(problem.V.dofmap.index_map.size_global * problem.V.dofmap.index_map_bs),
        "ranks": comm.size,
        "config": args.config,
        "budget": args.budget,
        "time": problem.t_n,
        **stats.as_dict(),
        "grab_displacement": grab.tolist(),
        "grab_error": float(np.linalg.norm(grab - target)),
        "kinetic_energy": problem.kinetic_energy(),
        "elastic_energy": problem.elastic_energy(),
    }
    if comm.rank == 0 and not args.quiet:
        print(
            f"{tets} tets, {comm.size} rank(s), {args.config}, budget {args.budget}: "
            f"{stats.steps_per_second:.1f} steps/s sustained ({100 * stats.realtime_fraction:.0f} % of steps "
            f"within {1e3 * args.dt:.1f} ms; assembly {1e3 * stats.assembly_time:.1f} ms, solve "
            f"{1e3 * stats.solve_time:.1f} ms, other {1e3 * stats.other_time:.1f} ms per step)\n"
            f"residual left |r|/|r0|: median {stats.relative_residual_median:.2e}, "
            f"max {stats.relative_residual_max:.2e}; {stats.unconverged} of {stats.steps} steps ended on the budget",
            flush=True,
        )
    if out is not None:
        write_json(out / "realtime.json", summary, comm)
    if comm.rank == 0 and not args.quiet:
        where = out / "realtime.json" if out is not None else "none (give --output DIR for a JSON summary)"
        print(f"output: {where}", flush=True)
    return summary


# %%
if __name__ == "__main__":
    run(main)
