"""One linear-solver configuration for every solve in hyperfem.

Newton's tangent solves (through SNES), the boundary-increment predictor, the
initial acceleration of a dynamic run, fibre projections and the Laplace fibre
rule all get their KSP from here: the options (:data:`DIRECT` by default), a
unique options prefix (:func:`unique_prefix`; nothing is left in PETSc's
global options database), and an optional near-nullspace hook, so a scalable
iterative method plugs in at this one place.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from petsc4py import PETSc

__all__ = ["DIRECT", "LinearSolver", "unique_prefix"]

DIRECT: dict[str, object] = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
"""Sparse direct solve with MUMPS (both install routes ship it)."""

_counter = itertools.count()


def unique_prefix(kind: str) -> str:
    """A fresh PETSc options prefix ``hyperfem_<kind>_<n>_``."""
    return f"hyperfem_{kind}_{next(_counter)}_"


@dataclass(frozen=True)
class LinearSolver:
    """A linear-solver configuration.

    Attributes:
        options: PETSc KSP/PC options (keys without prefix).
        near_nullspace: Optional ``hook(A)`` called on every operator before
            the solver is set up (e.g. to attach rigid-body modes for AMG).
    """

    options: Mapping[str, object] = field(default_factory=lambda: dict(DIRECT))
    near_nullspace: Callable[[PETSc.Mat], None] | None = None

    def ksp(self, comm, A: PETSc.Mat | None = None, kind: str = "linear") -> PETSc.KSP:
        """A KSP configured from :attr:`options` under a unique prefix (operators set if ``A`` is given).

        The options are pushed for ``setFromOptions`` and removed again.
        """
        prefix = unique_prefix(kind)
        ksp = PETSc.KSP().create(comm)
        ksp.setOptionsPrefix(prefix)
        opts = PETSc.Options()
        for key, value in self.options.items():
            opts[f"{prefix}{key}"] = value
        try:
            ksp.setFromOptions()
        finally:
            for key in self.options:
                opts.delValue(f"{prefix}{key}")
        if A is not None:
            self.set_operators(ksp, A)
        return ksp

    def set_operators(self, ksp: PETSc.KSP, A: PETSc.Mat, P: PETSc.Mat | None = None) -> None:
        """Set the operators of ``ksp``, applying the near-nullspace hook first."""
        if self.near_nullspace is not None:
            self.near_nullspace(A)
        ksp.setOperators(A, A if P is None else P)

    def solve(self, comm, A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, kind: str = "linear") -> int:
        """One solve ``A x = b`` with a throw-away KSP; returns the KSP converged reason."""
        ksp = self.ksp(comm, A, kind)
        try:
            ksp.solve(b, x)
            return int(ksp.getConvergedReason())
        finally:
            ksp.destroy()
