"""The strain energy a problem is given, checked at construction: a scalar of F, on regions that cover the mesh.

Every check raises :class:`~hyperfem.errors.ParameterError` with a one-line
message naming the object (``where``), before any form is compiled or
assembled; :func:`check_region_coverage` is collective, the others are
deterministic functions of their arguments, so every MPI rank raises the same
error. The generic checks (finite numbers, names, callables) are in
:mod:`hyperfem.validation`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import ufl

from hyperfem.errors import HyperfemError, ParameterError
from hyperfem.problem.protocol import EnergyProtocol
from hyperfem.validation import check_callable, is_real

if TYPE_CHECKING:
    from hyperfem.mesh.domain import Domain

__all__ = ["as_energy", "check_energy_callable", "check_region_coverage", "scalar_energy"]


def scalar_energy(psi: Callable, F: ufl.core.expr.Expr, where: str) -> ufl.core.expr.Expr:
    """Evaluate the strain-energy density ``psi(F)`` and check that it is a UFL scalar.

    Raises:
        ParameterError: If ``psi`` is not callable, fails on ``F`` with a UFL
            error (``ValueError``/``TypeError``), or returns something that is
            not a scalar (e.g. ``lambda F: F``).
    """
    check_callable(psi, where, "the energy psi(F)")
    try:
        value = psi(F)
    except HyperfemError:
        raise
    except (ValueError, TypeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ParameterError(f"{where}: evaluating the energy psi(F) failed: {first}") from exc
    if is_real(value):
        return ufl.as_ufl(float(value))
    if not isinstance(value, ufl.core.expr.Expr):
        raise ParameterError(
            f"{where}: the energy psi(F) must return a UFL scalar expression, got {type(value).__name__}"
        )
    if value.ufl_shape != () or value.ufl_free_indices:
        raise ParameterError(
            f"{where}: the energy psi(F) must be a scalar, got a UFL expression of shape {value.ufl_shape}"
            + (f" with free indices {value.ufl_free_indices}" if value.ufl_free_indices else "")
        )
    return value


def _symbolic_deformation_gradient(gdim: int) -> ufl.core.expr.Expr:
    import basix.ufl

    cell = {2: "triangle", 3: "tetrahedron"}[gdim]
    element = basix.ufl.element("Lagrange", cell, 1, shape=(gdim,))
    mesh = ufl.Mesh(element)
    u = ufl.Coefficient(ufl.FunctionSpace(mesh, element))
    return ufl.variable(ufl.Identity(gdim) + ufl.grad(u))


def check_energy_callable(psi: Callable, where: str) -> None:
    """Check, without a mesh, that ``psi`` maps a deformation gradient to a scalar.

    ``psi`` is evaluated on a symbolic :math:`F` of dimension 3 and 2; if it
    evaluates on either, the result must be a scalar. An energy that needs a
    real mesh (and fails on both) is left to the problem to check.
    """
    check_callable(psi, where, "the energy psi(F)")
    for gdim in (3, 2):
        try:
            value = psi(_symbolic_deformation_gradient(gdim))
        except Exception:  # noqa: BLE001 - may need a real mesh; the problem checks again
            continue
        if is_real(value):
            return
        # Boundary: the user's psi may return anything, not only a UFL expression.
        shape = getattr(value, "ufl_shape", None)
        if shape != () or getattr(value, "ufl_free_indices", ()):
            raise ParameterError(
                f"{where}: the energy psi(F) must be a scalar, got "
                + (f"a UFL expression of shape {shape}" if shape is not None else type(value).__name__)
            )
        return


class _UserEnergy:
    """A user's energy ``psi(F)`` seen through :class:`~hyperfem.problem.protocol.EnergyProtocol`.

    Every extra the callable lacks takes its neutral value: not invertible
    (unless a known law), no state hooks or updaters, ``bind`` a no-op, no
    tangent correction, no fields on quadrature points. Extras are read when
    asked for (``bind`` may set them).

    Boundary: ``psi`` is a user-supplied callable, so each extra is read with
    ``getattr`` here, and nowhere else in the library.
    """

    def __init__(self, psi: Callable):
        self.psi = psi

    @property
    def invertible(self) -> bool:
        from hyperfem.materials.invertibility import is_invertible

        return is_invertible(self.psi)

    @property
    def state_hooks(self) -> tuple:
        return tuple(getattr(self.psi, "state_hooks", ()))  # optional extra of a user callable

    @property
    def updaters(self) -> tuple:
        return tuple(getattr(self.psi, "updaters", ()))  # optional extra of a user callable

    @property
    def quadrature_rule_degree(self) -> int | None:
        return getattr(self.psi, "quadrature_rule_degree", None)  # optional extra of a user callable

    def __call__(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        return self.psi(F)

    def bind(self, F: ufl.core.expr.Expr, quadrature_degree: int) -> None:
        bind = getattr(self.psi, "bind", None)  # optional extra of a user callable
        if callable(bind):
            bind(F, quadrature_degree)

    def tangent_correction(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr | None:
        correction = getattr(self.psi, "tangent_correction", None)  # optional extra of a user callable
        return correction(F) if callable(correction) else None


def as_energy(psi: Callable) -> EnergyProtocol:
    """``psi`` as an :class:`~hyperfem.problem.protocol.EnergyProtocol`, its missing extras neutral.

    An energy that declares every extra is returned as it is; any other
    callable ``psi(F)`` is wrapped (calling the wrapper calls ``psi``).
    """
    if isinstance(psi, EnergyProtocol):
        return psi
    return _UserEnergy(psi)


def check_region_coverage(domain: Domain, regions: Sequence[str], where: str) -> None:
    """Every cell must belong to one of the material ``regions`` (names of cell groups).

    Cells outside every region carry no energy: their dofs make the tangent
    singular, which SNES reports far from the cause. Collective.
    """
    import numpy as np
    from mpi4py import MPI

    tdim = domain.tdim
    n_local = domain.mesh.topology.index_map(tdim).size_local
    covered = np.zeros(n_local, dtype=bool)
    for name in regions:
        cells = domain.cells(name)
        covered[cells[cells < n_local]] = True
    missing = domain.comm.allreduce(int(n_local - covered.sum()), op=MPI.SUM)
    if missing:
        total = domain.comm.allreduce(n_local, op=MPI.SUM)
        available = ", ".join(sorted(domain.cell_groups)) or "none"
        raise ParameterError(
            f"{where}: {missing} of {total} cells lie outside every material region "
            f"(given: {', '.join(regions)}; cell groups of {domain.source}: {available})"
        )
