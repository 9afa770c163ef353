"""Material laws: form compilation and tangent assembly of every law of issue 21 against neo-Hookean, and the
accuracy of the principal-stretch energies where stretches coincide.

The laws: neo-Hookean, Ogden-3 (Ogden's 1972 exponents and a set without an even
one), Hencky, SVK in stretches, Yeoh, a five-term reduced polynomial, Gent,
Arruda-Boyce, Veronda-Westmann, HGO, Weiss, Fung, and a viscoelastic neo-Hookean
(the incremental potential of a step: two Prony terms, the history frozen at the
quadrature points). Prints one JSON object per line:

* ``"kind": "compile"``: the residual and the tangent form of each law on the
  6x6x6 unit cube (P1, quadrature degree 2), compiled into a fresh JIT cache
  with DOLFINx's default flags (or ``--cflags``): wall and CPU seconds of
  ``dolfinx.fem.form`` (FFCx code generation and the C compiler; the CPU time
  counts the compiler process too, and is what to compare on a busy machine),
  FFCx's share, and the generated C size in characters;
* ``"kind": "assemble"``: the median wall and CPU time of one tangent assembly
  there (1296 tetrahedra);
* ``"kind": "accuracy"``: the spectral machinery against exact invariant
  expressions: the Ogden sum with even exponents (2, 4, -2), whose stretch sums
  are ``tr Cbar``, ``tr Cbar^2``, ``tr Cbar^-1``, evaluated through
  ``eigenvalue_power_sum`` (the path Ogden uses) and ``eigenvalue_sum``
  (``ufl.diff`` derivatives, the path of Hencky); the largest stress error over
  the shear modulus and the largest tangent error over the largest tangent
  entry, at exact coincident stretches (identity, uniaxial, equibiaxial, each
  also rotated), three distinct stretches, and random states near the branch
  thresholds.

    python benchmarks/materials_principal.py [--output benchmarks/results/materials_principal.jsonl]
    python benchmarks/materials_principal.py --laws ogden3_treloar --cflags="-O0 -g0" --no-accuracy
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402, I001  (before dolfinx/petsc4py)

import ffcx.compiler  # noqa: E402
import ffcx.options  # noqa: E402
import numpy as np  # noqa: E402
import ufl  # noqa: E402
from dolfinx import fem  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402

from hyperfem.kinematics import right_cauchy_green  # noqa: E402
from hyperfem.materials import LameParameters, neo_hookean  # noqa: E402
from hyperfem.materials.ogden import OgdenParameters, ogden  # noqa: E402
from hyperfem.materials import (  # noqa: E402
    ArrudaBoyceParameters,
    FungOrthotropicParameters,
    GentParameters,
    HolzapfelGasserOgdenParameters,
    VerondaWestmannParameters,
    WeissParameters,
    YeohParameters,
    arruda_boyce,
    fung_orthotropic,
    gent,
    holzapfel_gasser_ogden,
    veronda_westmann,
    weiss,
    yeoh,
)
from hyperfem.materials.neo_hookean import neo_hookean_isochoric  # noqa: E402
from hyperfem.materials.principal_stretches import (  # noqa: E402
    eigenvalue_power_sum,
    eigenvalue_sum,
    hencky,
    saint_venant_kirchhoff_principal,
    spectral_invariants,
)
from hyperfem.materials.prony import PronySeries  # noqa: E402
from hyperfem.materials.viscoelastic import Viscoelastic  # noqa: E402
from hyperfem.materials.yeoh import ReducedPolynomialParameters, reduced_polynomial  # noqa: E402
from hyperfem.problem import SplitEnergy  # noqa: E402

LAME = LameParameters(mu=1.0, lmbda=10.0)
TRELOAR = OgdenParameters(mu=(0.63, 0.0012, -0.01), alpha=(1.3, 5.0, -2.0), K=10.0)  # Ogden 1972, MPa
GENERAL = OgdenParameters(mu=(0.63, 0.0012, -0.01), alpha=(1.3, 5.0, -2.5), K=10.0)  # no even exponent
A0, A1 = ufl.as_vector((1.0, 0.0, 0.0)), ufl.as_vector((0.0, 0.6, 0.8))  # fibre directions (constants)
LAWS = {
    "neo_hookean": lambda F: neo_hookean(F, LAME),
    "ogden3_treloar": lambda F: ogden(F, TRELOAR),
    "ogden3_general": lambda F: ogden(F, GENERAL),
    "hencky": lambda F: hencky(F, LAME),
    "saint_venant_kirchhoff_principal": lambda F: saint_venant_kirchhoff_principal(F, LAME),
    "yeoh": lambda F: yeoh(F, YeohParameters(c10=0.5, c20=-0.04, c30=0.006, K=10.0)),
    "reduced_polynomial": lambda F: reduced_polynomial(
        F, ReducedPolynomialParameters(coefficients=(0.5, -0.04, 0.006, -1e-4, 2e-6), K=10.0)
    ),
    "gent": lambda F: gent(F, GentParameters(mu=1.1, Jm=10.0, K=10.0)),
    "arruda_boyce": lambda F: arruda_boyce(F, ArrudaBoyceParameters(mu=0.9, lambda_m=2.5, K=10.0)),
    "veronda_westmann": lambda F: veronda_westmann(F, VerondaWestmannParameters(c1=0.3, c2=0.8, K=10.0)),
    "holzapfel_gasser_ogden": lambda F: holzapfel_gasser_ogden(
        F, A0, A1, HolzapfelGasserOgdenParameters(mu=1.0, k1=2.0, k2=0.8, kappa=0.1, K=10.0)
    ),
    "weiss": lambda F: weiss(
        F, A0, WeissParameters(c1=1.0, c2=0.2, c3=0.05, c4=20.0, c5=10.0, lambda_star=1.1, K=10.0)
    ),
    "fung_orthotropic": lambda F: fung_orthotropic(
        F, A0, ufl.as_vector((0.0, 1.0, 0.0)),
        FungOrthotropicParameters(c=1.0, b1=2.0, b2=1.5, b3=1.0, b4=0.5, b5=0.3, b6=0.4, b7=1.2, b8=0.9, b9=0.8,
                                  K=10.0),
    ),
    # the incremental potential of a step (history frozen: Q_i, S_n at the quadrature points of degree 2)
    "viscoelastic_neo_hookean": lambda F: Viscoelastic(
        SplitEnergy(lambda G: neo_hookean_isochoric(G, 1.0), 10.0), PronySeries(g=(0.3, 0.2), tau=(0.1, 1.0)),
        quadrature_degree=2,
    )(F),
}
EVEN = ((1.0, 2.0), (0.3, 4.0), (-0.2, -2.0))  # (mu_p, alpha_p)


def _cpu_seconds() -> float:
    """CPU time of this process and its finished children (the C compiler): robust to a busy machine."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def timing_rows(names: list[str], cflags: list[str] | None, repeats: int) -> list[dict]:
    mesh = dmesh.create_unit_cube(MPI.COMM_WORLD, 6, 6, 6)
    V = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
    u = fem.Function(V)
    u.interpolate(lambda x: 0.1 * np.array([x[0] * x[1], np.sin(x[2]), x[0] ** 2]))
    F = ufl.Identity(3) + ufl.grad(u)
    rows = []
    for name in names:
        Pi = LAWS[name](F) * ufl.dx(metadata={"quadrature_degree": 2})
        R = ufl.derivative(Pi, u, ufl.TestFunction(V))
        K = ufl.derivative(R, u, ufl.TrialFunction(V))
        compiled = None
        for form_name, form in (("residual", R), ("tangent", K)):
            t0 = time.perf_counter()
            code, _ = ffcx.compiler.compile_ufl_objects([form], options=ffcx.options.get_options())
            ffcx_s = time.perf_counter() - t0
            jit = {"cache_dir": tempfile.mkdtemp(prefix="hyperfem_bench_"), "timeout": 3600}
            if cflags is not None:
                jit["cffi_extra_compile_args"] = cflags
            t0, c0 = time.perf_counter(), _cpu_seconds()
            compiled = fem.form(form, jit_options=jit)
            rows.append(
                {
                    "kind": "compile",
                    "law": name,
                    "form": form_name,
                    "seconds": time.perf_counter() - t0,
                    "cpu_seconds": _cpu_seconds() - c0,
                    "ffcx_seconds": ffcx_s,
                    "c_chars": sum(len(c) for c in code),
                    "cflags": cflags or "default",
                }
            )
        A = fem.assemble_matrix(compiled)
        times, cpu = [], []
        for _ in range(repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            A = fem.assemble_matrix(compiled)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        values = A.data
        rows.append(
            {
                "kind": "assemble",
                "law": name,
                "cells": mesh.topology.index_map(3).size_global,
                "seconds": statistics.median(times),
                "cpu_seconds": statistics.median(cpu),
                "finite": bool(np.all(np.isfinite(values))),
            }
        )
    return rows


def _states(rng: np.random.Generator) -> dict[str, list[np.ndarray]]:
    def rotation() -> np.ndarray:
        Q, R = np.linalg.qr(rng.standard_normal((3, 3)))
        Q = Q @ np.diag(np.sign(np.diag(R)))
        return Q if np.linalg.det(Q) > 0 else Q @ np.diag([-1.0, 1.0, 1.0])

    def rotated(D: np.ndarray, n: int = 5) -> list[np.ndarray]:
        return [D] + [rotation() @ D @ rotation().T for _ in range(n)]

    def near(spread: float, n: int = 20) -> list[np.ndarray]:
        out = []
        for _ in range(n):
            v = rng.standard_normal(3)
            v = (v - v.mean()) / np.linalg.norm(v - v.mean())
            out.append(rotation() @ np.diag(np.exp(spread * v)) @ rotation().T)
        return out

    def near_double(stretch: float, gap: float, n: int = 10) -> list[np.ndarray]:
        s = stretch**-0.5
        return [rotation() @ np.diag([stretch, s, s * (1.0 + gap)]) @ rotation().T for _ in range(n)]

    return {
        "identity": rotated(np.eye(3)),
        "dilatation 1.3": rotated(1.3 * np.eye(3)),
        "uniaxial 1.5": rotated(np.diag([1.5, 1.5**-0.5, 1.5**-0.5])),
        "uniaxial 5": rotated(np.diag([5.0, 5.0**-0.5, 5.0**-0.5])),
        "equibiaxial 2": rotated(np.diag([2.0, 2.0, 0.25])),
        "distinct": rotated(np.diag([1.3, 0.8, 1.1])),
        "near identity (1e-6..1e-2)": [F for s in (1e-6, 1e-4, 3e-4, 6e-4, 1e-3, 2e-3, 1e-2) for F in near(s)],
        "near double (1e-6..1e-2)": [
            F for lam in (0.5, 2.0) for g in (1e-6, 1e-4, 5e-4, 1e-3, 3e-3, 1e-2) for F in near_double(lam, g)
        ],
    }


def accuracy_rows() -> list[dict]:
    mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    Fc = fem.Constant(mesh, np.eye(3))
    F = ufl.variable(Fc)
    J = ufl.det(F)
    inv = spectral_invariants(right_cauchy_green(F)).scaled(J ** (-2.0 / 3.0))
    Cb = J ** (-2.0 / 3.0) * right_cauchy_green(F)
    exact_sums = {2.0: ufl.tr(Cb), 4.0: ufl.tr(Cb * Cb), -2.0: ufl.tr(ufl.inv(Cb))}
    energies = {
        "exact": sum(m / a * (exact_sums[a] - 3.0) for m, a in EVEN),
        "power": eigenvalue_power_sum(inv, [m / a for m, a in EVEN], [a / 2 for _, a in EVEN]),
        "generic": eigenvalue_sum(inv, lambda c: sum(m / a * (c ** (a / 2) - 1.0) for m, a in EVEN)),
    }
    idx2 = [(i, j) for i in range(3) for j in range(3)]
    entries = []
    for psi in energies.values():
        P = ufl.diff(psi, F)
        A = ufl.diff(P, F)
        entries += [psi] + [P[i, j] for i, j in idx2] + [A[i, j, k, m] for i, j in idx2 for k, m in idx2]
    expr = fem.Expression(ufl.as_vector(entries), np.full((1, 3), 0.25))
    cells = np.array([0], dtype=np.int32)
    mu0 = 0.5 * sum(m * a for m, a in EVEN)

    def evaluate(Fv: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        Fc.value[:] = Fv
        v = expr.eval(mesh, cells).reshape(3, 91)
        return {name: (v[k, 1:10], v[k, 10:]) for k, name in enumerate(energies)}

    rows = []
    for state, Fs in _states(np.random.default_rng(2024)).items():
        for path in ("power", "generic"):
            stress = tangent = 0.0
            finite = True
            for Fv in Fs:
                values = evaluate(Fv)
                P, A = values[path]
                P0, A0 = values["exact"]
                finite &= bool(np.all(np.isfinite(P)) and np.all(np.isfinite(A)))
                stress = max(stress, float(np.max(np.abs(P - P0))) / mu0)
                tangent = max(tangent, float(np.max(np.abs(A - A0) / np.max(np.abs(A0)))))
            rows.append(
                {
                    "kind": "accuracy",
                    "path": path,
                    "state": state,
                    "samples": len(Fs),
                    "stress_error_over_mu": stress,
                    "tangent_rel_error": tangent,
                    "finite": finite,
                }
            )
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--laws", nargs="*", default=list(LAWS), choices=list(LAWS))
    p.add_argument("--cflags", default=None, help="C compiler flags, e.g. '-O0 -g0' (default: DOLFINx's)")
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--no-accuracy", action="store_true")
    p.add_argument("--output", type=Path, default=None, help="append the JSON lines to this file")
    args = p.parse_args()
    rows = timing_rows(args.laws, None if args.cflags is None else args.cflags.split(), args.repeats)
    if not args.no_accuracy:
        rows += accuracy_rows()
    if MPI.COMM_WORLD.rank == 0:
        lines = [json.dumps(r) for r in rows]
        print("\n".join(lines), flush=True)
        if args.output is not None:
            with args.output.open("a") as f:
                f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
