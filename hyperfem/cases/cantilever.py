r"""Erleben's cantilever beam (seed 003, §5.7).

A 10 × 4 × 4 m beam, :math:`x \in [-5, 5]`, clamped at :math:`x = -5`, loaded on
the free end :math:`x = +5`; compressible Neo-Hookean with
:math:`E = 10\cdot 10^5` Pa, :math:`\nu = 0.3`, :math:`\rho = 1000` kg/m³.

* *bend*: dead traction :math:`t = (0, -5, 0)` kPa;
* *twist*: :math:`t = 5\,\text{kPa}\,(0, z, -y)` with :math:`y, z` the *current*
  coordinates of the surface point — a follower load. We take it per unit
  reference area (the seed integrates over the current surface; for this
  nearly rigid end section the difference is the area change of the end
  face, well below 1 % here).

The test point is :math:`(4.5, 1.5, 1.5)`.

Mesh convergence
----------------
:data:`MESH_CONVERGENCE` lists the test-point displacement of both cases on the
gmsh beams of element size :math:`h` (``beam_mesh(h)``; ``meshes/beam_h1.msh``
and ``beam_h2.msh`` are the same generator's output) for P1 and P2
displacements, serial, with the default solver. P1 tetrahedra lock in
bending: on :math:`h = 1` the bend deflection is 17 % short, while P2 on the
same mesh is within 0.3 % of the finest entry (:data:`REFERENCE`, taken as
converged). :func:`convergence_note` turns a computed displacement into that
one-line statement; the demos print it.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import ufl

from hyperfem.materials.parameters import LameParameters
from hyperfem.problem.loads import DeadTraction, FollowerTraction

__all__ = [
    "BEND_TRACTION",
    "MESH_CONVERGENCE",
    "REFERENCE",
    "TEST_POINT",
    "TWIST_MAGNITUDE",
    "CantileverSpec",
    "bend_load",
    "convergence_note",
    "mesh_size_of",
    "twist_load",
]

TEST_POINT = (4.5, 1.5, 1.5)
BEND_TRACTION = (0.0, -5.0e3, 0.0)  # Pa
TWIST_MAGNITUDE = 5.0e3  # Pa per metre of lever arm


@dataclass(frozen=True)
class CantileverSpec:
    """Material data of the cantilever experiments (SI units).

    Attributes:
        E: Young's modulus (Pa).
        nu: Poisson's ratio.
        rho: Mass density (kg/m³).
        damping: Viscous damping coefficient c (1/s).
    """

    E: float = 10.0e5
    nu: float = 0.3
    rho: float = 1000.0
    damping: float = 0.0004

    @property
    def lame(self) -> LameParameters:
        """Lamé parameters from (E, ν)."""
        return LameParameters.from_youngs(self.E, self.nu)


def bend_load(scale: float = 1.0, profile: Callable[[float], float] | None = None) -> DeadTraction:
    """Dead traction ``scale * (0, -5, 0) kPa`` on ``free_end``."""
    t = tuple(scale * c for c in BEND_TRACTION)
    return DeadTraction("free_end", t) if profile is None else DeadTraction("free_end", t, profile)


def twist_load(scale: float = 1.0, profile: Callable[[float], float] | None = None) -> FollowerTraction:
    """Follower traction ``scale * 5 kPa * (0, z, -y)`` (current y, z) on ``free_end``."""

    def traction(x: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        return scale * TWIST_MAGNITUDE * ufl.as_vector((0.0, x[2], -x[1]))

    return FollowerTraction("free_end", traction) if profile is None else FollowerTraction(
        "free_end", traction, profile
    )


MESH_CONVERGENCE: dict[tuple[str, float, int], tuple[float, float, float]] = {
    # (case, element size h in m, displacement degree): test-point displacement (m).
    # Serial runs of demos/bend.py and demos/twist.py (--h or the committed meshes).
    # Update a row by rerunning e.g. `python demos/twist.py --h 0.5 --degree 1`.
    ("bend", 1.0, 1): (0.1662, -1.0631, 0.0037),
    ("bend", 1.0, 2): (0.1848, -1.2736, -0.0016),
    ("bend", 0.5, 1): (0.1801, -1.2095, -0.0022),
    ("bend", 0.5, 2): (0.1848, -1.2775, -0.0017),
    # P1 twist: with the exactly integrated follower load (issue 7); the one-point
    # rule gave (0.0009, 0.1410, -0.1586) and (0.0006, 0.1800, -0.2050).
    ("twist", 1.0, 1): (0.0009, 0.1447, -0.1633),
    ("twist", 1.0, 2): (0.0000, 0.2019, -0.2339),
    ("twist", 0.5, 1): (0.0007, 0.1813, -0.2066),
    ("twist", 0.5, 2): (0.0000, 0.2028, -0.2350),
}
"""Test-point displacement per (case, h, degree) on the gmsh beam."""

REFERENCE: dict[str, tuple[float, int]] = {"bend": (0.5, 2), "twist": (0.5, 2)}
"""The (h, degree) row of :data:`MESH_CONVERGENCE` taken as the converged answer of each case."""

_HEADLINE = {"bend": (1, "deflection u_y")}  # case -> (component, name) quoted in the note


def _fmt(x: float, spec: str = "g") -> str:
    return format(x, spec)  # ASCII only: the note is printed to any terminal


def mesh_size_of(mesh: str | Path | None) -> float | None:
    """Element size ``h`` of a committed beam mesh named ``beam_h<h>.msh``, else ``None``."""
    if mesh is None:
        return None
    m = re.fullmatch(r"beam_h(\d+(?:\.\d+)?)\.msh", Path(mesh).name)
    return float(m.group(1)) if m else None


def convergence_note(
    case: str, degree: int, h: float | None = None, displacement: Sequence[float] | np.ndarray | None = None
) -> str:
    """One line saying how far a cantilever result is from the converged answer.

    The relative distance of the test-point displacement to the
    :data:`REFERENCE` row of :data:`MESH_CONVERGENCE`: of the deflection
    :math:`u_y` for the bend, of the vector :math:`|u - u_\text{ref}| / |u_\text{ref}|`
    for the twist, e.g. ``"P2, h = 1: 0.3 % from the converged
    deflection u_y = -1.2775 m (h = 0.5, P2; ...)"``.

    Args:
        case: ``"bend"`` or ``"twist"``.
        degree: Displacement degree of the result.
        h: Element size of the beam mesh (``None`` for another mesh).
        displacement: The computed test-point displacement; by default the
            table entry of ``(case, h, degree)``.
    """
    if case not in REFERENCE:
        return f"{case}: no mesh-convergence reference (known cases: {', '.join(REFERENCE)})"
    href, pref = REFERENCE[case]
    ref = np.asarray(MESH_CONVERGENCE[(case, href, pref)])
    label = f"P{degree}" + (f", h = {_fmt(h)}" if h is not None else ", this mesh")
    if displacement is None:
        row = MESH_CONVERGENCE.get((case, float(h), int(degree))) if h is not None else None
        if row is None:
            return f"{label}: no entry in the mesh-convergence table of hyperfem/cases/cantilever.py"
        displacement = row
    u = np.asarray(displacement, dtype=float).reshape(-1)[:3]
    if case in _HEADLINE:
        k, name = _HEADLINE[case]
        error = abs(float(u[k] - ref[k]) / float(ref[k]))
        converged = f"the converged {name} = {_fmt(ref[k], '.4f')} m"
    else:
        error = float(np.linalg.norm(u - ref) / np.linalg.norm(ref))
        converged = "the converged test-point displacement (" + ", ".join(_fmt(c, ".4f") for c in ref) + ") m"
    where = f"h = {_fmt(href)}, P{pref}; mesh-convergence table in hyperfem/cases/cantilever.py"
    if h is not None and (float(h), int(degree)) == (href, pref):
        return f"{label}: this is the reference mesh of {converged} ({where})"
    advice = "; refine (--h) or raise the degree (--degree 2) for a converged answer" if error > 0.02 else ""
    return f"{label}: {100 * error:.1f} % from {converged} ({where}){advice}"
