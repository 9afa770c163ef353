# %% [markdown]
# # Gluing: a two-material bar from two non-matching meshes
#
# Seed 003 §6.2 glues FEM objects together. Here a bar is two unit cubes of
# different rubbers, meshed independently (element sizes 0.5 and 0.34, so the
# facets where they meet do not match), stacked with a small gap and glued
# across it by ``TieContact``: every node of each face is tied to its place on
# the other face's triangles, a two-pass penalty tie (``hyperfem.contact.tie``).
# The bar is pulled by $\delta$ at its top, its bottom held along the bar, with
# rollers on $x = 0$ and $y = 0$.
#
# With Poisson's ratio 0 (Neo-Hookean with $\lambda_L = 0$) a cube in uniaxial
# tension keeps its width, so the glued faces stay compatible and each cube is
# stretched uniformly. The two cubes then carry the same nominal stress,
#
# $$
# P = \mu_1\Bigl(\lambda_1 - \frac{1}{\lambda_1}\Bigr) = \mu_2\Bigl(\lambda_2 - \frac{1}{\lambda_2}\Bigr),
# \qquad \lambda_1 + \lambda_2 = 2 + \delta ,
# $$
#
# (the tie keeps the gap), which is solved for the two stretches and compared
# with the computed reaction and tie force.
#
# Run with `python demos/glued_bar.py` or `mpiexec -n 2 python demos/glued_bar.py`
# (needs the contact extra: `pip install 'hyperfem[contact]'`).

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # threaded BLAS slows MUMPS ~10x
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
import math  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_float, run  # noqa: E402
from hyperfem.contact import TieContact  # noqa: E402
from hyperfem.io import ensure_output_dir  # noqa: E402
from hyperfem.simulation import Recorder, Simulation  # noqa: E402
from hyperfem.simulation.measures import Reaction  # noqa: E402

GAP = 5e-4


def parse(argv=None):
    p = ArgumentParser(description="Gluing: a two-material bar from two non-matching meshes (TieContact)")
    p.add_argument("--stiff", type=positive_float, default=10.0, help="Young's modulus of the lower cube")
    p.add_argument("--soft", type=positive_float, default=1.0, help="Young's modulus of the upper cube")
    p.add_argument("--pull", type=positive_float, default=0.5, help="how far the top is pulled")
    p.add_argument("--output", type=Path, default=Path("output"), help="output folder (glued_bar.json)")
    return p.parse_args(argv)


# %% [markdown]
# ## The closed form: two nonlinear springs in series


# %%
def series_stress(mu1: float, mu2: float, total: float) -> tuple[float, float, float]:
    """The common nominal stress and the two stretches with lambda_1 + lambda_2 = total (bisection on lambda_1)."""

    def stress(mu: float, stretch: float) -> float:
        return mu * (stretch - 1.0 / stretch)

    def stretch_for(mu: float, p: float) -> float:  # mu (s - 1/s) = p  =>  s = (p/mu + sqrt((p/mu)^2 + 4)) / 2
        q = p / mu
        return 0.5 * (q + math.sqrt(q * q + 4.0))

    low, high = 1.0, total - 1.0
    for _ in range(200):
        l1 = 0.5 * (low + high)
        if l1 + stretch_for(mu2, stress(mu1, l1)) > total:
            high = l1
        else:
            low = l1
    l1 = 0.5 * (low + high)
    p = stress(mu1, l1)
    return p, l1, stretch_for(mu2, p)


# %% [markdown]
# ## The bar


# %%
def glued_bar(comm, stiff: float, soft: float, pull: float) -> dict:
    domain = hf.mesh.stacked_blocks_mesh(0.5, 0.34, GAP, comm=comm)
    lower = hf.materials.LameParameters.from_youngs(E=stiff, nu=0.0)
    upper = hf.materials.LameParameters.from_youngs(E=soft, nu=0.0)
    materials = {  # region name -> psi(F)
        "lower": lambda F: hf.materials.neo_hookean(F, lower),
        "upper": lambda F: hf.materials.neo_hookean(F, upper),
    }
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("lower_bottom", [0.0], components=[2]),
        hf.PrescribedDisplacement("upper_top", [pull], components=[2]),
    ]
    problem = hf.HyperelasticProblem(domain, materials, bcs=bcs)
    tie = TieContact("upper_bottom", "lower_top", name="glue").bind(problem)
    solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10, "snes_atol": 1e-7}, external_energies=[tie])
    outputs = [Recorder(tie), Reaction("upper_top")]
    summary = Simulation(problem, solver, hf.StepPolicy(increment=0.25), outputs, name="glued_bar").run()
    last = summary["rows"][-1]
    p, l1, l2 = series_stress(lower.mu, upper.mu, 2.0 + pull)
    reaction = float(last["reaction_upper_top"][2])
    return {
        "completed": bool(summary["completed"]),
        "steps": len(summary["rows"]) - 1,
        "reaction": reaction,
        "tie_force": float(last["glue_force"][2]),
        "closed_form": p,
        "relative_error": abs(reaction - p) / p,
        "stretches": [l1, l2],
        "max_gap": float(last["glue_max_gap"]),
    }


# %%
def main(argv=None):
    args = parse(argv)
    comm = MPI.COMM_WORLD
    ensure_output_dir(args.output, comm)
    result = glued_bar(comm, args.stiff, args.soft, args.pull)
    if comm.rank == 0:
        (args.output / "glued_bar.json").write_text(json.dumps(result, indent=2))
        print(
            f"glued bar (E = {args.stiff:g} | {args.soft:g}, pulled {args.pull:g}): reaction {result['reaction']:.8g}, "
            f"closed form {result['closed_form']:.8g} ({result['relative_error']:.1e}), tie force "
            f"{result['tie_force']:.8g}, stretches {result['stretches'][0]:.6f} | {result['stretches'][1]:.6f}, "
            f"largest gap {result['max_gap']:.1e} m"
        )
    comm.Barrier()
    return result


if __name__ == "__main__":
    run(main)
