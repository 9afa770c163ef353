"""Cost of a checkpoint: write, read on the same ranks (by global index), read on another rank count (by dof key).

Prints one JSON line per size: unknowns, bytes on disk, seconds to write, to read
back on the ranks that wrote (each rank its own file) and, on rank 0 alone, to
read the same checkpoint on one rank (every rank file, dofs found by key). The
one-rank state is written again and read back on all ranks: the largest
difference from the original values must be 0 (values are copied, not
interpolated), as must that of the same-ranks read.

    mpiexec -n 2 python benchmarks/checkpoint_io.py --sizes 10 20 40
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np
from dolfinx import fem, mesh

from hyperfem.io.checkpoint import read_functions, write_checkpoint


def _field(comm, n: int, degree: int) -> fem.Function:
    domain = mesh.create_box(comm, [np.zeros(3), np.array([2.0, 1.0, 1.0])], [2 * n, n, n])
    u = fem.Function(fem.functionspace(domain, ("Lagrange", degree, (3,))))
    u.interpolate(lambda x: np.vstack([np.sin(x[0]), x[1] * x[2], np.cos(x[2])]))
    return u


def _max_difference(a: fem.Function, b: fem.Function, comm) -> float:
    n = a.function_space.dofmap.index_map.size_local * a.function_space.dofmap.index_map_bs
    return comm.allreduce(float(np.abs(a.x.array[:n] - b.x.array[:n]).max(initial=0.0)), op=MPI.MAX)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 30])
    p.add_argument("--degree", type=int, default=1)
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    for n in args.sizes:
        folder = Path(comm.bcast(tempfile.mkdtemp(prefix="hf-ckpt-") if comm.rank == 0 else None, root=0))
        u = _field(comm, n, args.degree)
        comm.Barrier()
        t0 = time.perf_counter()
        step = write_checkpoint(folder, 1, {"u": u}, {}, comm)
        comm.Barrier()
        t_write = time.perf_counter() - t0
        v = fem.Function(u.function_space)
        comm.Barrier()
        t0 = time.perf_counter()
        read_functions(step, {"u": v}, comm)
        comm.Barrier()
        t_same = time.perf_counter() - t0
        same_error = _max_difference(u, v, comm)
        other = {}
        if comm.size > 1:
            if comm.rank == 0:  # the same checkpoint on one rank: by key; then written again from there
                w1 = _field(MPI.COMM_SELF, n, args.degree)
                r1 = fem.Function(w1.function_space)
                t0 = time.perf_counter()
                read_functions(step, {"u": r1}, MPI.COMM_SELF)
                other["read_one_rank_s"] = time.perf_counter() - t0
                write_checkpoint(folder / "one", 1, {"u": r1}, {}, MPI.COMM_SELF)
            comm.Barrier()
            back = fem.Function(u.function_space)
            read_functions(folder / "one", {"u": back}, comm)  # one rank's file on all ranks: by key
            other["round_trip_error"] = _max_difference(u, back, comm)
        comm.Barrier()
        if comm.rank == 0:
            size = sum(f.stat().st_size for f in step.iterdir())
            row = {
                "ranks": comm.size,
                "degree": args.degree,
                "unknowns": u.function_space.dofmap.index_map.size_global * 3,
                "bytes": size,
                "bytes_per_unknown": size / (u.function_space.dofmap.index_map.size_global * 3),
                "write_s": t_write,
                "read_same_ranks_s": t_same,
                "same_ranks_error": same_error,
                **other,
            }
            print(json.dumps(row), flush=True)
            shutil.rmtree(folder, ignore_errors=True)
        comm.Barrier()


if __name__ == "__main__":
    main()
