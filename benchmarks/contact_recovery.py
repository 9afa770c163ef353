"""How the surgery demo's Newton directions are recovered after a failed Krylov solve (issue 19/20).

Runs ``demos/surgery.py``'s indentation and drag (``--n`` as there) and counts, per Newton
direction that ``NewtonSolver._recover_direction`` had to mend: the Krylov reason of the
first solve, whether the contact tangent was exact, the reason after the recovery, and
which recovery it took (``project``: the barrier's Hessian projected and the tangent solved
again; ``rebuild``: the lagged preconditioner rebuilt on the current tangent; ``fallback``:
one MUMPS solve), with the seconds each took and PETSc's event totals.

    python benchmarks/contact_recovery.py --n 16 [--json out.jsonl]
    mpiexec -n 2 python benchmarks/contact_recovery.py --n 24

Measured (quiet 2-core machine; ``results/contact_recovery_s33.jsonl``), before -> after the
rebuild of a failed lagged preconditioner (commit a7d409f), same 16 steps and end force to
1e-10:

* ``--n 16`` (15k unknowns, CG + GAMG lagged by 2), serial, two interleaved pairs:
  104.6 / 91.5 s -> 97.0 / 86.3 s; MUMPS fallbacks 42 -> 8 (36 rebuilds, 0.14 s each
  against 0.35 s per fallback); 34 of the 42 fallbacks had been
  ``KSP_DIVERGED_INDEFINITE_PC`` on a projected (positive semi-definite) tangent.
* ``--n 24`` (47.8k unknowns), 2 ranks: 351 -> 291 s; fallbacks 60 -> 13 (52 rebuilds,
  0.28 s each against 1.45 s per fallback); ``MatLUFactorNum`` 87 -> 29 s.
* the demo itself, ``mpiexec -n 2 python demos/surgery.py --n 30`` (90.8k unknowns):
  14 min 51 s (stop 31) -> 10 min 14 s (a7d409f) -> 9 min 45 s (db287dc, the lifts too), the same 19
  steps and printed results.

The predictor's lifts failed on the same lagged hierarchy (12 of the 54 MUMPS solves at ``--n 16``
before); rebuilt the same way (``BoundaryPredictor._solve``): ``--n 16`` serial 65.4 s, 12 steps
instead of 16, no LU lift (5 rebuilt), 10 Newton fallbacks; the end force differs by 1.7 % in x
(another step sequence, on which the lagged friction depends; ``snes_lag_preconditioner 1`` gives
the same 12 steps and force to 1e-9).

The remaining fallbacks are tangents that are indefinite themselves
(``KSP_DIVERGED_INDEFINITE_MAT`` after the projection: strongly compressed cells under
the probe). The ``project`` recoveries (an exact barrier tangent that stopped CG or did
not descend, about 120 at ``--n 24``, 0.34 s each) are the next cost.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import collections  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

import hyperfem as hf  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "demos"))
import surgery  # noqa: E402

EVENTS = ("PCSetUp", "KSPSolve", "SNESJacobianEval", "SNESFunctionEval", "SNESLineSearch", "MatLUFactorNum")


class CountingSolver(hf.NewtonSolver):
    """A :class:`~hyperfem.NewtonSolver` that tallies what each recovered direction needed."""

    reasons: collections.Counter = collections.Counter()
    seconds: collections.Counter = collections.Counter()
    last: "CountingSolver | None" = None

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        CountingSolver.last = self

    def _recover_direction(self, x, y):
        ksp = self.snes.getKSP()
        before = int(ksp.getConvergedReason())
        exact = bool(self.external) and self.external.exact_tangents()
        fallbacks, rebuilds = self.direct_fallbacks, self.preconditioner_rebuilds
        start = time.perf_counter()
        ok = super()._recover_direction(x, y)
        seconds = time.perf_counter() - start
        if before < 0 or exact:
            kind = ("fallback" if self.direct_fallbacks > fallbacks
                    else "rebuild" if self.preconditioner_rebuilds > rebuilds else "project")
            after = int(ksp.getConvergedReason())
            CountingSolver.reasons[f"first {before}, exact {exact}, after {after}: {kind}"] += 1
            CountingSolver.seconds[kind] += seconds
        return ok


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=16)
    p.add_argument("--json", type=Path, default=None, help="append the result as a JSON line")
    p.add_argument(
        "--lag", type=int, default=None,
        help="snes_lag_preconditioner of the P1 iterative path instead of the default (2 before stop 39)",
    )
    args = p.parse_args()
    if args.lag is not None:  # the demo chooses its linear solver itself: change the default it reads
        from hyperfem.solver import linear

        linear.SYMMETRIC_ITERATIVE["snes_lag_preconditioner"] = args.lag
    comm = MPI.COMM_WORLD
    PETSc.Log.begin()
    hf.NewtonSolver = CountingSolver  # the demo builds its solver through hf
    start = time.perf_counter()
    result = surgery.surgery(comm, args.n, 0.1, 0.4, 8, 5e-3, 0.3)
    elapsed = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    solver = CountingSolver.last
    events = {name: PETSc.Log.Event(name).getPerfInfo() for name in EVENTS}
    row = {
        "n": args.n, "ranks": comm.size, "lag": args.lag, "time": elapsed, "steps": result["steps"],
        "direct_fallbacks": solver.direct_fallbacks, "preconditioner_rebuilds": solver.preconditioner_rebuilds,
        "lift_fallbacks": solver._boundary_predictor.direct_fallbacks,
        "lift_rebuilds": solver._boundary_predictor.preconditioner_rebuilds,
        "early_rebuilds": solver._lag.early_rebuilds,
        "force_end": result["force"][-1], "min_distance": result["min_distance"],
        "intersecting": result["intersecting"], "recoveries": dict(CountingSolver.reasons),
        "recovery_seconds": dict(CountingSolver.seconds),
        "events": {name: {"count": e["count"], "time": e["time"]} for name, e in events.items()},
    }
    if comm.rank == 0:
        print(json.dumps(row))
        if args.json is not None:
            with args.json.open("a") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
