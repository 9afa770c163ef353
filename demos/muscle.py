# %% [markdown]
# # Contraction of a fusiform muscle
#
# A spindle-shaped muscle belly with a tendon at each end, after the muscle
# model of seed 000 (supplement §2, an excerpt of Teran et al.): a
# transversely isotropic, nearly incompressible solid whose fibres can
# actively contract. The strain energy per unit reference volume is
#
# $$
# W = c_1(\bar I_1 - 3) + c_2(\bar I_2 - 3) + \frac{K}{2}(\ln J)^2
#     + T_\max\,\big[\alpha A(\bar\lambda) + B(\bar\lambda)\big],
# \qquad \bar\lambda = J^{-1/3}\sqrt{a_0\cdot C a_0},
# $$
#
# where $A' = f_\text{act}$ and $B' = f_\text{pas}$ are the active
# (piecewise quadratic, peak at the optimal fibre length) and passive
# (exponential, zero in compression) force–length curves, so that the fibre
# stress is $\bar\lambda\,\partial_{\bar\lambda}F_2 = T_\max(\alpha f_\text{act} +
# f_\text{pas})\bar\lambda$. Muscle uses $c_1 = 30$ kPa, $c_2 = 10$ kPa,
# $T_\max = 80$ kPa; the tendons are passive ($\alpha = 0$) with $c_1 = 60$ kPa.
# The seed's bulk moduli (60/80 kPa) make the tissue almost as compressible as
# cork ($\nu \approx 0.04$) although the text calls it incompressible; we
# scale them by `--bulk-factor` (default 50, $\nu \approx 0.49$) and use the
# three-field (Hu–Washizu) formulation: $P_2$ displacement, $P_1$ pressure $p$
# and $P_1$ volume ratio $\theta$, which does not lock,
#
# $$
# \Pi(u, p, \theta) = \int_\Omega \Big[W_\text{iso}(F) + \frac{K}{2}(\ln\theta)^2
#     + p\,(J - \theta)\Big]dX - W_\text{ext}(u),
# $$
#
# where $\theta$ is the $L^2$ projection of $J$ and $p$ that of $K\ln\theta/\theta$.
# After every converged step we also record the volume consistency
# $\eta = \|J - \theta\|/|\Omega|^{1/2}$ (small when $J$ is resolved by $\theta$).
#
# Fibres follow the Laplace rule: $\phi$ solves $\Delta\phi = 0$ with
# $\phi = 0$ on `origin` and $\phi = 1$ on `insertion`, and
# $a_0 = \nabla\phi/|\nabla\phi|$.
#
# Two experiments ramp the activation $\alpha = s$ of the belly with the load
# factor $s \in [0, 1]$:
#
# * **(a) isometric** — both tendon ends clamped; we report the reaction
#   force at `insertion` and the maximum radial bulge;
# * **(b) free** — `origin` clamped, `insertion` loaded by a small dead
#   traction along the axis; we report the shortening.
#
# Run with `python demos/muscle.py` or `mpiexec -n 2 python demos/muscle.py`
# (same numbers).

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.loading import Activation  # noqa: E402
from hyperfem.fibres import laplace_fibres  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_float, positive_int  # noqa: E402
from hyperfem.io.results import ensure_output_dir, note_overwrite, write_json  # noqa: E402
from hyperfem.kinematics import deformation_gradient  # noqa: E402
from hyperfem.cases.muscle import muscle_materials  # noqa: E402
from hyperfem.materials.muscle import fibre_stretch  # noqa: E402
from hyperfem.mesh.fusiform import FusiformGeometry, fusiform_mesh  # noqa: E402
from hyperfem.problem import solid_problem  # noqa: E402
from hyperfem.simulation import (  # noqa: E402
    VTX,
    BoundaryAverage,
    CellVTX,
    JSONSummary,
    Progress,
    Quantity,
    RadialBulge,
    Reaction,
    Simulation,
    cauchy_stress,
)



def parse(argv=None) -> argparse.Namespace:
    p = ArgumentParser(description="Isometric and free contraction of a fusiform muscle")
    where = p.add_mutually_exclusive_group()
    # h = 5 mm meshes this geometry with one sliver (radius ratio 0.056, below the 0.1 warning); 4.5 mm: min 0.34
    where.add_argument("--h", type=positive_float, default=0.0045, help="element size of the generated mesh (m)")
    where.add_argument("--mesh", type=Path, default=None, help="read this fusiform .msh instead of generating one")
    p.add_argument("--steps", type=positive_int, default=4, help="activation load steps (>= 1)")
    p.add_argument("--bulk-factor", type=positive_float, default=50.0, help="multiplier of the seed bulk moduli")
    p.add_argument("--formulation", choices=("mixed", "displacement"), default="mixed")
    p.add_argument("--traction", type=float, default=2.0e3, help="dead traction at insertion in (b), Pa")
    p.add_argument("--fibres", choices=("DG0", "P1", "quadrature"), default="DG0", help="fibre representation")
    p.add_argument("--output", type=Path, default=Path("output"), help="output folder")
    return p.parse_args(argv)


# %% [markdown]
# ## Model
# Regions and boundaries are the gmsh physical groups of the mesh; every
# region gets its own parameters and activation.


# %%
def build_materials(domain, a0, args, activation):
    """Belly and tendons (`hyperfem.cases.muscle`), with the seed bulk moduli times `--bulk-factor`."""
    return muscle_materials(a0, activation, bulk_factor=args.bulk_factor)


# %% [markdown]
# ## Measures
# After every converged step the run records the reaction at `insertion`, the
# residual of the stored energy tested with the unit axial field on that face,
# $R_z = \partial_u \Pi_\text{int}[e_z\chi_\text{insertion}]$ (the force the
# support exerts on the muscle; positive = the muscle pulls on it); the radial
# bulge $\max_X\big(|x_\perp + u_\perp| - |x_\perp|\big)$ over the displacement
# nodes; and the mean axial displacement of `insertion`. Cell-wise output: the
# fibre stretch, the activation and the Cauchy stress $\sigma = J^{-1} P F^T$
# per region, from $P = \partial W/\partial F$ at fixed pressure. Each experiment is a
# `Simulation` that records the passive state (row 0) and every activation step.


# %%
def run_experiment(kind, domain, a0, a0_out, args):
    activation = Activation(domain.mesh, value=lambda s: min(max(s, 0.0), 1.0), name="muscle activation")
    materials = build_materials(domain, a0, args, activation)
    if kind == "isometric":
        bcs, loads = [hf.Clamp("origin"), hf.Clamp("insertion")], []
    else:
        bcs = [hf.Clamp("origin")]
        loads = [hf.DeadTraction("insertion", (0.0, 0.0, args.traction), profile=lambda s: 1.0)]
    problem = solid_problem(
        domain, materials, formulation=args.formulation, bcs=bcs, loads=loads, updaters=[activation]
    )
    solver = hf.NewtonSolver(problem, petsc_options={"snes_linesearch_type": "bt"})
    insertion = BoundaryAverage("insertion", 2, name="insertion_uz")
    outputs = [
        Quantity("activation", lambda: activation.value),
        Reaction("insertion"),
        RadialBulge(axis=(0.0, 0.0, 1.0)),
        insertion,
        Progress(
            lambda row: f"  ({kind}) alpha={row['activation']:.3f}  Rz={row['reaction_insertion'][2]:.5g} N  "
            f"bulge={1e3 * row['max_radial_bulge']:.4f} mm  uz(insertion)={1e3 * row['insertion_uz']:.4f} mm  "
            f"newton={row['newton_iterations']}"
        ),
    ]
    if args.output is not None:
        # Output is evaluated at cell midpoints: quadrature-point fibres cannot be, so
        # the cell fields then use the same Laplace fibres in DG0.
        out_materials = materials if a0_out is a0 else build_materials(domain, a0_out, args, activation)
        cells = {
            "fibre_stretch": fibre_stretch(deformation_gradient(problem.displacement()), a0_out),
            "activation": {"muscle": activation.expr},
            "cauchy_stress": cauchy_stress(problem, out_materials),
        }
        outputs += [
            VTX(args.output / f"muscle_{kind}_u.bp"),
            CellVTX(args.output / f"muscle_{kind}_cells.bp", cells),
            JSONSummary(args.output / f"muscle_{kind}.json"),
        ]
    stepping = hf.LoadStepping(
        initial_increment=1.0 / args.steps, max_increment=1.0 / args.steps, min_increment=1.0 / (64 * args.steps)
    )
    # The passive state at s = 0 (traction only) is solved first: it is row 0.
    sim = Simulation(problem, solver, stepping, outputs, name=f"muscle {kind}", solve_initial=True)
    sim.run()
    return {
        "steps": sim.rows,
        "cutbacks": sum(st.rejected for st in sim.steps),
        "insertion_area": insertion.area,
        "dofs": sim.dofs,
    }


# %%
def main(argv=None) -> dict:
    args = parse(argv)
    comm = MPI.COMM_WORLD
    start = time.perf_counter()
    if args.output is not None:
        ensure_output_dir(args.output, comm)  # collective: every rank fails together, before any work
        note_overwrite(output_files(args.output), comm)
    geometry = FusiformGeometry()
    domain = hf.read_mesh(args.mesh, comm) if args.mesh else fusiform_mesh(h=args.h, geometry=geometry, comm=comm)
    quad = 4 if args.formulation == "mixed" else 1
    a0 = laplace_fibres(domain, "origin", "insertion", representation=args.fibres, quadrature_degree=quad)
    a0_out = a0 if args.fibres != "quadrature" else laplace_fibres(domain, "origin", "insertion")
    iso = run_experiment("isometric", domain, a0, a0_out, args)
    free = run_experiment("free", domain, a0, a0_out, args)
    forces = [row["reaction_insertion"][2] for row in iso["steps"]]
    summary = {
        "ranks": comm.size,
        "cells": domain.mesh.topology.index_map(3).size_global,
        "formulation": args.formulation,
        "h": args.h,
        "bulk_factor": args.bulk_factor,
        "isometric": iso,
        "free": free,
        "activations": [row["activation"] for row in iso["steps"]],
        "isometric_reaction": forces,
        "isometric_bulge": iso["steps"][-1]["max_radial_bulge"],
        "free_shortening": free["steps"][0]["insertion_uz"] - free["steps"][-1]["insertion_uz"],
        "free_shortening_ratio": (free["steps"][0]["insertion_uz"] - free["steps"][-1]["insertion_uz"])
        / geometry.total_length,
        "newton_iterations": [row["newton_iterations"] for row in iso["steps"] + free["steps"]],
        "wall_time": time.perf_counter() - start,
    }
    if args.output is not None:
        write_json(args.output / "muscle.json", summary, comm)
    if comm.rank == 0:
        print(
            f"isometric: Rz = {forces[-1]:.5g} N at alpha = 1, bulge = {1e3 * summary['isometric_bulge']:.4f} mm; "
            f"free: shortening = {1e3 * summary['free_shortening']:.4f} mm "
            f"({100 * summary['free_shortening_ratio']:.2f} %); {summary['wall_time']:.1f} s",
            flush=True,
        )
        if args.output is not None:
            print(f"output: {', '.join(str(p) for p in output_files(args.output))}", flush=True)
    return summary


def output_files(folder: Path) -> list[Path]:
    """What a run writes into ``folder``: the summary, then per experiment its JSON and ParaView files."""
    files = [folder / "muscle.json"]
    for kind in ("isometric", "free"):
        files += [folder / f"muscle_{kind}.json", folder / f"muscle_{kind}_u.bp", folder / f"muscle_{kind}_cells.bp"]
    return files


# %%
if __name__ == "__main__":
    from hyperfem.app.program import run

    run(main)
