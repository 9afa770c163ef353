# %% [markdown]
# # Euler buckling of a Neo-Hookean column
#
# A slender column $b \times h \times L = 1 \times 1.5 \times 20$ of compressible
# Neo-Hookean rubber ($E = 1$, $\nu = 0.3$; the units are immaterial) is clamped
# at its base and pressed down at its free top by a dead traction $-\sigma\,e_z$.
# Euler's clamped–free load about the weak axis,
#
# $$
# P_\text{cr} = \frac{\pi^2 E I}{4L^2},\qquad I = \frac{h b^3}{12}
# \quad\Longrightarrow\quad
# \sigma_E = \frac{\pi^2 E b^2}{48 L^2},
# $$
#
# is the load at $t = 1$. A straight column is an equilibrium at every load;
# it stops being a *stable* one where the second variation of
# $\Pi(u) = \int_\Omega \psi(F)\,dX - t\int_\text{top}\sigma_E\,e_z\cdot u\,dA$
# first has a zero eigenvalue. The **linearised buckling analysis** takes the
# tangent at the unloaded state, $K_0$, and at the state $u_1$ one linear
# step away under the load $t = 1$, $K_1$, and solves
#
# $$
# K_0\,\phi = \mu\,(K_0 - K_1)\,\phi,\qquad t_\text{cr} = \mu ,
# $$
#
# with SLEPc (Krylov–Schur, shift-and-invert, MUMPS), the clamped dofs removed
# from the spectrum as infinite eigenvalues (`hyperfem.stability`). The first
# mode bends about the weak axis; the second about the strong one, at
# $(h/b)^2 = 2.25$ times the load.
#
# A second route: the **lowest eigenvalue of the tangent** along the loaded
# path (Newton at each load, `TangentEigensolver` with the mass matrix as
# metric) falls to zero at the critical load; a secant through two loads
# near it extrapolates $t_\text{cr}$.
#
# Measured with the defaults (P2 tetrahedra, $1\times1\times10$ and
# $2\times2\times20$ boxes): $t_\text{cr} = 1.0175$ and $1.0064$, converging to
# $1.0034$ (P3 hexahedra, `tests/test_stability.py`): the continuum column
# sits 0.3 % above the beam formula, since the clamp stops the Poisson
# contraction of the base (0.05 % below it with $\nu = 0$). Second mode
# $2.2625$. The lowest eigenvalue extrapolates to $1.0076$ on the fine mesh.
# The modes go to `buckling.png` (deformed outlines, with Euler's
# $1 - \cos(\pi z/2L)$) and `buckling_modes.bp`, the numbers to `buckling.json`.
#
# Run with `python demos/buckling.py` or `mpiexec -n 2 python demos/buckling.py`.

# %%
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # threaded BLAS slows MUMPS ~10x
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

import hyperfem as hf  # noqa: E402
from hyperfem.app.program import ArgumentParser, positive_int, run  # noqa: E402
from hyperfem.cases.column import ColumnSpec, column_domain  # noqa: E402
from hyperfem.io import ensure_output_dir  # noqa: E402
from hyperfem.materials.neo_hookean import neo_hookean  # noqa: E402
from hyperfem.stability import TangentEigensolver  # noqa: E402
from hyperfem.stability.buckling import buckling_analysis, write_buckling_modes  # noqa: E402

COLUMN = ColumnSpec(width=1.0, depth=1.5, length=20.0, E=1.0, nu=0.3)
PATH_LOADS = (0.9, 0.95)  # where the lowest eigenvalue of the tangent is computed


def parse(argv=None):
    p = ArgumentParser(description="Euler buckling of a Neo-Hookean column: linearised buckling and tangent spectrum")
    p.add_argument("--divisions", type=positive_int, default=2,
                   help="boxes across the width of the finest mesh (n x n x 10n; each coarser mesh halves it)")
    p.add_argument("--meshes", type=positive_int, default=2, help="number of meshes, coarsest first")
    p.add_argument("--degree", type=positive_int, default=2, help="displacement degree")
    p.add_argument("--output", type=Path, default=Path("output"), help="output folder (buckling.png, .json, .bp)")
    return p.parse_args(argv)


# %% [markdown]
# ## The column under a dead load, and its buckling analysis


# %%
def column_problem(comm, n: int, degree: int) -> hf.HyperelasticProblem:
    """The column on n x n x 10n boxes, clamped at z = 0, Euler's load on the top at t = 1."""
    return hf.HyperelasticProblem(
        column_domain(COLUMN, (n, n, 10 * n), comm),
        lambda F: neo_hookean(F, COLUMN.lame),
        bcs=[hf.Clamp("bottom")],
        loads=[hf.DeadTraction("top", (0.0, 0.0, -COLUMN.euler_traction))],
        degree=degree,
    )


def lowest_along_path(problem) -> dict:
    """Lowest eigenvalue of the tangent at equilibria below the critical load, and its zero by a secant."""
    solver = hf.NewtonSolver(problem)
    eigensolver = TangentEigensolver(problem, 1)
    lowest = []
    for t in PATH_LOADS:
        problem.set_time(t)
        solver.solve(raise_on_failure=True)
        spectrum = eigensolver.solve()
        lowest.append(spectrum.lowest)
    (t_a, t_b), (l_a, l_b) = PATH_LOADS, lowest
    eigensolver.destroy()
    return {"loads": list(PATH_LOADS), "lowest": lowest, "zero": t_b + l_b * (t_b - t_a) / (l_a - l_b)}


# %% [markdown]
# ## The first two modes, as deformed outlines


# %%
def outlines(mode, axis: int, comm) -> list[np.ndarray] | None:
    """On rank 0: the two edges of the column in the bending plane (columns X_axis, z, u_axis, u_z), by z."""
    V = mode.function_space
    owned = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:owned]
    u = mode.x.array.reshape(-1, 3)[:owned]
    gathered = comm.gather(np.hstack([X, u]), root=0)
    if comm.rank != 0:
        return None
    data = np.vstack(gathered)
    other = 1 - axis
    side = (COLUMN.width, COLUMN.depth)[axis]
    edges = []
    for c in (0.0, side):
        on = np.isclose(data[:, axis], c) & np.isclose(data[:, other], 0.0)
        edge = data[on][np.argsort(data[on][:, 2])]
        edges.append(edge[:, [axis, 2, 3 + axis, 5]])
    return edges


def plot(modes: list, load_factors: list[float], path: Path, comm) -> None:
    shapes = [outlines(mode, axis, comm) for mode, axis in zip(modes, (0, 1), strict=False)]
    if comm.rank != 0:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    L = COLUMN.length
    scale = 0.15 * L
    fig, axes = plt.subplots(1, len(shapes), figsize=(2.8 * len(shapes), 6.0), sharey=True)
    axes = np.atleast_1d(axes)
    for k, (ax, edges, t_cr) in enumerate(zip(axes, shapes, load_factors, strict=False)):
        label = "xz" if k == 0 else "yz"
        z = np.linspace(0.0, L, 101)
        euler = scale * (1.0 - np.cos(np.pi * z / (2.0 * L)))
        for j, edge in enumerate(edges):
            X, Z, u, w = edge.T
            ax.plot(X, Z, color="0.7", lw=1)
            ax.plot(X + scale * u, Z + scale * w, "C0", lw=2, label="FE mode" if j == 0 else None)
            ax.plot(X[0] + euler, z, "k--", lw=1, label=r"Euler $1-\cos(\pi z/2L)$" if j == 0 else None)
        ax.set_aspect("equal")
        ax.set_xlabel(label[0])
        ax.set_title(f"mode {k + 1}: $t_{{cr}}$ = {t_cr:.4f}")
    axes[0].set_ylabel("z")
    axes[0].legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# %%
def main(argv=None):
    args = parse(argv)
    comm = MPI.COMM_WORLD
    ensure_output_dir(args.output, comm)
    sizes = [max(1, args.divisions // 2**k) for k in reversed(range(args.meshes))]
    meshes = []
    for n in sizes:
        problem = column_problem(comm, n, args.degree)
        result = buckling_analysis(problem, 2)
        meshes.append({
            "divisions": [n, n, 10 * n],
            "dofs": problem.V.dofmap.index_map.size_global * 3,
            "load_factors": list(result.load_factors),
            "error": result.critical_load_factor - 1.0,
        })
    path = lowest_along_path(problem)
    write_buckling_modes(result, args.output / "buckling_modes.bp", comm)
    plot(list(result.modes), list(result.load_factors), args.output / "buckling.png", comm)
    summary = {
        "ranks": comm.size,
        "degree": args.degree,
        "euler_traction": COLUMN.euler_traction,
        "critical_load_factor": result.critical_load_factor,
        "second_load_factor": result.load_factors[1],
        "mode_ratio_beam_theory": COLUMN.mode_ratio,
        "meshes": meshes,
        "lowest_eigenvalue_path": path,
    }
    if comm.rank == 0:
        (args.output / "buckling.json").write_text(json.dumps(summary, indent=2))
        errors = ", ".join(f"{100 * m['error']:+.2f} %" for m in meshes)
        print(
            f"buckling: t_cr / Euler = {result.critical_load_factor:.4f} ({errors} on {len(meshes)} meshes); "
            f"second mode {result.load_factors[1]:.4f} (beam theory {COLUMN.mode_ratio:.4f}); "
            f"zero of the lowest tangent eigenvalue {path['zero']:.4f}; "
            f"output: {args.output / 'buckling.png'}, {args.output / 'buckling.json'}"
        )
    comm.Barrier()
    return summary


if __name__ == "__main__":
    run(main)
