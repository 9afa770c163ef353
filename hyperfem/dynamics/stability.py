r"""Stable step of explicit time integration: element size over wave speed.

Central differences (symplectic Euler) with a lumped mass are stable for a
linear problem when :math:`\Delta t \le 2/\omega_\max`, with
:math:`\omega_\max^2` the largest eigenvalue of :math:`M_L^{-1}K`. Bounding
:math:`\omega_\max` element by element gives the familiar
Courant–Friedrichs–Lewy estimate

.. math::
    \Delta t_\text{crit} = \min_\text{cells} \frac{h_K}{c},\qquad
    c = \sqrt{\frac{\lambda + 2\mu}{\rho}},

with :math:`c` the dilatational (P-) wave speed. The element size used here
is the **diameter of the inscribed sphere** of the simplex,

.. math::
    h_K = 2 r_K = \frac{2\,d\,|K|}{|\partial K|}
    \quad(\text{tetrahedron: } 6V/A,\ \text{triangle: } 4A/P,\ \text{interval: } L),

the smallest size that enters every linear simplex's highest mode. On a
uniform interval mesh (seed 000's 1D bar) :math:`h/c` *is*
:math:`2/\omega_\max` of the lumped P1 bar; on tetrahedra it is conservative:
the linearised limit :math:`2/\omega_\max` at the reference state
(:meth:`~hyperfem.dynamics.explicit.ExplicitDynamics.spectral_time_step`,
lumped P1, :math:`\nu = 0.3`) is 1.60 :math:`h_\min/c` on a
``create_box`` 8 × 2 × 2 beam, 2.05 on ``meshes/beam_h2.msh`` and 2.81 on
``meshes/beam_h1.msh`` (whose worst cell sets :math:`h_\min`).

A consistent mass lowers the limit: by exactly :math:`1/\sqrt 3` on the 1D
bar, by a factor 0.49–0.56 on the meshes above. :class:`StableStep` carries a
``mass_factor`` for it (:data:`CONSISTENT_MASS_FACTOR` :math:`= 1/\sqrt 3`;
with it the estimate is at or below the measured limits: 1.0 of the 1D limit, 1.35–2.65 of those above).
:data:`DEFAULT_SAFETY` multiplies the estimate because large deformation
and stiffening materials raise the tangent stiffness above the reference
:math:`\lambda + 2\mu`.

The sizes are computed vectorized over the owned cells from the vertex
coordinates; the minimum is reduced over ``mesh.comm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from dolfinx import mesh as dmesh

from hyperfem.errors import ParameterError
from hyperfem.materials.parameters import LameParameters
from hyperfem.validation import check_positive

if TYPE_CHECKING:
    from hyperfem.mesh.domain import Domain

__all__ = [
    "CONSISTENT_MASS_FACTOR",
    "DEFAULT_SAFETY",
    "StableStep",
    "inscribed_diameters",
    "stable_time_step",
    "wave_speed",
]

DEFAULT_SAFETY = 0.9
r"""Factor on :math:`h_\min/c`: the largest step an explicit run accepts is ``0.9 * dt_crit``."""

CONSISTENT_MASS_FACTOR = 1.0 / math.sqrt(3.0)
r"""Ratio of the consistent- to the lumped-mass limit of the P1 bar, :math:`1/\sqrt 3`."""

_SIMPLICES = {"interval": 1, "triangle": 2, "tetrahedron": 3}


def wave_speed(params: LameParameters, rho: float) -> float:
    r"""Dilatational wave speed :math:`c = \sqrt{(\lambda + 2\mu)/\rho}` of the reference configuration.

    Args:
        params: Lamé parameters.
        rho: Mass density (> 0).

    Raises:
        ParameterError: If ``rho`` is not a positive finite number.
    """
    check_positive("rho", rho, "wave_speed")
    return math.sqrt((params.lmbda + 2.0 * params.mu) / float(rho))


def _measure(edges: np.ndarray) -> np.ndarray:
    """k-dimensional measure of simplices spanned by ``edges`` of shape ``(n, k, gdim)`` (Gram determinant)."""
    k = edges.shape[1]
    if k == 0:
        return np.ones(edges.shape[0])
    gram = np.einsum("nig,njg->nij", edges, edges)
    return np.sqrt(np.clip(np.linalg.det(gram), 0.0, None)) / math.factorial(k)


def inscribed_diameters(mesh: dmesh.Mesh) -> np.ndarray:
    r"""Inscribed-sphere diameter :math:`2\,d\,|K|/|\partial K|` of every owned cell (affine simplices).

    Only the vertices of each cell are used (a curved higher-order geometry
    is measured by its straight-sided simplex).

    Args:
        mesh: A DOLFINx mesh of intervals, triangles or tetrahedra.

    Returns:
        Array of length ``number of owned cells``.

    Raises:
        ParameterError: For non-simplex cells.
    """
    name = mesh.topology.cell_name()
    if name not in _SIMPLICES:
        raise ParameterError(f"inscribed_diameters: needs simplex cells (interval, triangle, tetrahedron), got {name}")
    tdim = _SIMPLICES[name]
    n = mesh.topology.index_map(tdim).size_local
    nodes = mesh.geometry.dofmaps[0][:n, : tdim + 1]  # vertices come first
    X = mesh.geometry.x[nodes][:, :, : mesh.geometry.dim]  # (n, tdim + 1, gdim)
    volume = _measure(X[:, 1:] - X[:, :1])
    surface = np.zeros(n)
    for k in range(tdim + 1):  # the facet opposite vertex k
        facet = np.delete(X, k, axis=1)
        surface += _measure(facet[:, 1:] - facet[:, :1])
    return 2.0 * tdim * volume / surface


@dataclass(frozen=True)
class StableStep:
    r"""The explicit step estimate of a mesh and material.

    Attributes:
        h_min: Smallest inscribed-sphere diameter over all cells.
        wave_speed: :math:`c = \sqrt{(\lambda + 2\mu)/\rho}`.
        safety: Factor applied to :attr:`dt_crit` for :attr:`dt_max`.
        location: Centroid of the smallest cell (reference coordinates).
        mass_factor: 1 for the lumped mass, :data:`CONSISTENT_MASS_FACTOR` for the consistent one.
    """

    h_min: float
    wave_speed: float
    safety: float = DEFAULT_SAFETY
    location: tuple[float, ...] = ()
    mass_factor: float = 1.0

    @property
    def dt_crit(self) -> float:
        r""":math:`\Delta t_\text{crit} = f_M\,h_\min / c` (:math:`f_M` the :attr:`mass_factor`)."""
        return self.mass_factor * self.h_min / self.wave_speed

    @property
    def dt_max(self) -> float:
        r"""The largest accepted step, ``safety * dt_crit``."""
        return self.safety * self.dt_crit

    def check(self, dt: float, where: str = "explicit step") -> None:
        """Raise unless ``dt <= dt_max``.

        Raises:
            ParameterError: With Δt, Δt_crit, the safety factor and the size and place of the smallest cell.
        """
        if not dt <= self.dt_max * (1.0 + 1e-12):
            at = ", ".join(f"{c:.3g}" for c in self.location)
            mass = "" if self.mass_factor == 1.0 else f"{self.mass_factor:.3g} x "
            raise ParameterError(
                f"{where}: dt = {dt:.4g} s exceeds the stable step {self.safety:g} x dt_crit = {self.dt_max:.4g} s "
                f"(dt_crit = {mass}h_min/c = {self.h_min:.4g} m / {self.wave_speed:.4g} m/s = {self.dt_crit:.4g} s, "
                f"smallest cell at ({at}))"
            )


def stable_time_step(
    domain: Domain | dmesh.Mesh,
    params: LameParameters,
    rho: float,
    safety: float = DEFAULT_SAFETY,
    *,
    lumped: bool = True,
) -> StableStep:
    r"""Estimate :math:`\Delta t_\text{crit} = \min_K h_K / c` for ``domain`` (see the module docstring).

    Args:
        domain: A :class:`~hyperfem.mesh.Domain` (or anything with ``.mesh``) of simplices.
        params: Lamé parameters of the stiffest material.
        rho: The smallest mass density.
        safety: Factor in (0, 1] for :attr:`StableStep.dt_max`.
        lumped: Whether the mass is lumped (else :data:`CONSISTENT_MASS_FACTOR` applies).

    Returns:
        The :class:`StableStep` (the same on every rank).

    Raises:
        ParameterError: Bad ``rho`` or ``safety``, non-simplex cells, or an empty mesh.
    """
    if not (isinstance(safety, (int, float)) and 0.0 < safety <= 1.0):
        raise ParameterError(f"stable_time_step: safety must lie in (0, 1], got {safety!r}")
    c = wave_speed(params, rho)
    mesh = domain if isinstance(domain, dmesh.Mesh) else domain.mesh
    h = inscribed_diameters(mesh)
    comm = mesh.comm
    if h.size:
        i = int(np.argmin(h))
        tdim = mesh.topology.dim
        nodes = mesh.geometry.dofmaps[0][i, : tdim + 1]
        local = (float(h[i]), tuple(float(x) for x in mesh.geometry.x[nodes].mean(axis=0)[: mesh.geometry.dim]))
    else:
        local = (math.inf, ())
    h_min, where = min(comm.allgather(local), key=lambda item: item[0])
    if not math.isfinite(h_min) or h_min <= 0:
        raise ParameterError(f"stable_time_step: the mesh has no cells of positive size (h_min = {h_min})")
    factor = 1.0 if lumped else CONSISTENT_MASS_FACTOR
    return StableStep(h_min=h_min, wave_speed=c, safety=float(safety), location=where, mass_factor=factor)
