r"""External loads by physical-group name.

Conservative (dead) loads enter the total potential energy,

.. math::
    \Pi(u) = \int_\Omega \psi(F)\,dX - \int_\Omega b\cdot u\,dX - \sum_k \int_{\Gamma_k} t_k\cdot u\,dA,

non-conservative (follower) loads add a residual term whose tangent UFL
derives with ``ufl.derivative``:

* :class:`FollowerTraction` — :math:`-\int_\Gamma t(x)\cdot v\,dA` with
  :math:`x = X + u` the current position; force per unit *reference* area.
* :class:`FollowerPressure` — :math:`+\int_\Gamma p\,J F^{-T}N\cdot v\,dA`
  (Nanson's formula); positive ``p`` pushes against the outward normal.

Every load is multiplied by ``profile(s)`` with ``s`` the load factor or time.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import ufl
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.kinematics import cofactor
from hyperfem.loading.profiles import linear_profile
from hyperfem.problem.quadrature import load_quadrature_degree
from hyperfem.validation import check_callable, check_finite_scalar, check_finite_vector, check_name

if TYPE_CHECKING:
    from hyperfem.mesh.domain import Domain

__all__ = ["BodyForce", "DeadTraction", "FollowerPressure", "FollowerTraction", "Load", "LoadTerms", "load_terms"]


@dataclass(frozen=True)
class DeadTraction:
    """Traction of fixed direction and magnitude per unit reference area.

    Attributes:
        boundary: Physical-group name.
        value: Constant vector, or a callable ``value(X) -> UFL vector`` of the
            reference coordinates.
        profile: Scaling with the load factor/time.
    """

    boundary: str
    value: Sequence[float] | Callable
    profile: Callable[[float], float] = linear_profile

    def __post_init__(self) -> None:
        _check_load(self, self.boundary)


@dataclass(frozen=True)
class FollowerTraction:
    """Traction that depends on the *current* position ``x = X + u``.

    Attributes:
        boundary: Physical-group name.
        value: Callable ``value(x) -> UFL vector`` of the current coordinates,
            or a constant vector. Force per unit reference area.
        profile: Scaling with the load factor/time.
    """

    boundary: str
    value: Sequence[float] | Callable
    profile: Callable[[float], float] = linear_profile

    def __post_init__(self) -> None:
        _check_load(self, self.boundary)


@dataclass(frozen=True)
class FollowerPressure:
    """Pressure acting normal to the deformed surface (Nanson's formula).

    Attributes:
        boundary: Physical-group name.
        value: Pressure (force per unit *current* area); positive compresses.
        profile: Scaling with the load factor/time.
    """

    boundary: str
    value: float
    profile: Callable[[float], float] = linear_profile

    def __post_init__(self) -> None:
        _check_load(self, self.boundary)


@dataclass(frozen=True)
class BodyForce:
    """Body force per unit reference volume.

    Attributes:
        value: Constant vector or callable ``value(X) -> UFL vector``.
        region: Physical-group name of the region, ``None`` for everywhere.
        profile: Scaling with the load factor/time.
    """

    value: Sequence[float] | Callable
    region: str | None = None
    profile: Callable[[float], float] = linear_profile

    def __post_init__(self) -> None:
        _check_load(self, self.region)


Load = DeadTraction | FollowerTraction | FollowerPressure | BodyForce


def _check_load(load: Load, name: str | None) -> None:
    """Validate a load on construction: group name, finite value(s), callable profile."""
    kind = type(load).__name__
    body = isinstance(load, BodyForce)
    check_name(name, "region" if body else "boundary", kind, optional=body)
    where = f"{kind} on {name!r}" if name is not None else kind
    if isinstance(load, FollowerPressure):
        check_finite_scalar(load.value, where, "pressure value")
    elif not callable(load.value):
        check_finite_vector(load.value, where)
    check_callable(load.profile, where, "profile")


LOAD_DEGREE_CAP_OFFSET = 4
"""Non-polynomial load integrands get at most the volume degree plus this."""


def _vector(
    value: Sequence[float] | Callable[..., Any], x: ufl.core.expr.Expr, gdim: int, what: str
) -> ufl.core.expr.Expr:
    if callable(value):
        return value(x)
    vals = [float(v) for v in value]
    if len(vals) != gdim:
        raise ParameterError(f"{what}: expected {gdim} components, got {len(vals)}")
    return ufl.as_vector(vals)


@dataclass
class LoadTerms:
    """The UFL terms of a set of loads.

    Attributes:
        scales: One ``(Constant, load)`` per load; the constant holds ``load.profile(s)``.
        external: Work of the dead loads (UFL scalar form), or ``None``.
        follower: Residual of the follower loads (UFL form linear in ``v``), or ``None``.
        parts: One ``(load, form)`` per load (work or residual term; for diagnostics).
    """

    scales: list[tuple[fem.Constant, Load]] = field(default_factory=list)
    external: ufl.Form | None = None
    follower: ufl.Form | None = None
    parts: list[tuple[Load, ufl.Form]] = field(default_factory=list)

    def set(self, s: float) -> None:
        """Set every load magnitude for load factor/time ``s``."""
        for c, load in self.scales:
            c.value = float(load.profile(s))  # type: ignore[assignment]  # dolfinx: any array-like


def load_terms(
    loads: Sequence[Load],
    domain: Domain,
    u: ufl.core.expr.Expr,
    v: ufl.core.expr.Expr,
    F: ufl.core.expr.Expr,
    metadata: dict[str, Any],
    where: str = "problem",
) -> LoadTerms:
    """Build the external-work and follower-residual terms of ``loads``.

    Each term gets its own quadrature degree
    (:func:`~hyperfem.problem.quadrature.load_quadrature_degree`): exact where
    the integrand is polynomial, never below the volume rule of ``metadata``.

    Args:
        loads: Sequence of loads.
        domain: The :class:`~hyperfem.mesh.Domain` (names → measures).
        u: Displacement (UFL; may be a block of a mixed function).
        v: Displacement test function (UFL; may be a block).
        F: Deformation gradient (UFL).
        metadata: Measure metadata of the volume rule (quadrature degree).
        where: Name used in error messages.
    """
    mesh = domain.mesh
    gdim = domain.gdim
    X = ufl.SpatialCoordinate(mesh)
    terms = LoadTerms()
    external, follower = [], []
    volume_degree = int(metadata["quadrature_degree"])
    cap = volume_degree + LOAD_DEGREE_CAP_OFFSET

    def md(integrand: ufl.core.expr.Expr) -> dict[str, Any]:
        return {**metadata, "quadrature_degree": load_quadrature_degree(integrand, volume_degree, cap)}

    for load in loads:
        c = fem.Constant(mesh, 0.0)
        terms.scales.append((c, load))
        if isinstance(load, DeadTraction):
            t = _vector(load.value, X, gdim, f"DeadTraction on {load.boundary!r}")
            w = ufl.dot(t, u)
            external.append(c * w * domain.ds(load.boundary, metadata=md(w)))
            terms.parts.append((load, external[-1]))
        elif isinstance(load, BodyForce):
            b = _vector(load.value, X, gdim, "BodyForce")
            w = ufl.dot(b, u)
            external.append(c * w * domain.dx(load.region, metadata=md(w)))
            terms.parts.append((load, external[-1]))
        elif isinstance(load, FollowerTraction):
            t = _vector(load.value, X + u, gdim, f"FollowerTraction on {load.boundary!r}")
            r = ufl.dot(t, v)
            follower.append(-c * r * domain.ds(load.boundary, metadata=md(r)))
            terms.parts.append((load, follower[-1]))
        elif isinstance(load, FollowerPressure):
            N = ufl.FacetNormal(mesh)
            p = float(load.value)
            r = ufl.dot(cofactor(F) * N, v)  # J F^{-T} N (Nanson), polynomial in u
            follower.append(c * p * r * domain.ds(load.boundary, metadata=md(r)))
            terms.parts.append((load, follower[-1]))
        else:
            raise ParameterError(f"{where}: unknown load type {type(load).__name__}")
    terms.external = sum(external) if external else None
    terms.follower = sum(follower) if follower else None
    return terms
