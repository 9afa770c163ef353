r"""The fusiform muscle of seed 000 (supplement §2): regions, materials and the two experiments.

The spindle of :func:`~hyperfem.mesh.fusiform_mesh` (or the committed
``meshes/fusiform_h8mm.msh``) has a contractile belly ``muscle`` between two
passive tendons ``tendon_proximal`` and ``tendon_distal``; its end faces are
``origin`` (:math:`z = -L/2 - L_t`) and ``insertion``. The belly is the
transversely isotropic muscle energy of
:func:`~hyperfem.materials.muscle.muscle_isochoric` with activation
:math:`\alpha`, the tendons the same law with :math:`\alpha = 0` and the
tendon parameters. The seed's bulk moduli (60/80 kPa) make the tissue almost
as compressible as cork (:math:`\nu \approx 0.04`) although the text calls it
incompressible; they are scaled by ``bulk_factor`` (default 50,
:math:`\nu \approx 0.49`).

Experiments (:data:`EXPERIMENTS`):

* ``"isometric"`` — both tendon ends clamped;
* ``"free"`` — ``origin`` clamped, ``insertion`` loaded by a dead axial
  traction (a small weight that keeps the tendon taut).
"""

from __future__ import annotations

from collections.abc import Iterable

from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.loading.activation import Activation
from hyperfem.materials.muscle import MuscleParameters, muscle_isochoric
from hyperfem.mesh.domain import Domain
from hyperfem.problem import (
    Clamp,
    DeadTraction,
    HyperelasticProblem,
    MixedHyperelasticProblem,
    SplitEnergy,
    solid_problem,
)
from hyperfem.problem.protocol import Updater

__all__ = ["EXPERIMENTS", "MUSCLE_DENSITY", "TENDONS", "muscle_materials", "muscle_problem"]

TENDONS = ("tendon_proximal", "tendon_distal")
"""Names of the passive regions."""

EXPERIMENTS = ("isometric", "free")
"""Boundary conditions of :func:`muscle_problem`."""

MUSCLE_DENSITY = 1060.0
"""Mass density of skeletal muscle, kg/m³ (1.06 g/cm³, Mendez & Keys 1960); used for the tendons too."""


def muscle_materials(
    a0: fem.Function, activation: Activation, bulk_factor: float = 50.0
) -> dict[str, SplitEnergy]:
    """Split energies of belly and tendons.

    Args:
        a0: Unit fibre field (e.g. :func:`~hyperfem.fibres.laplace_fibres`).
        activation: The belly's :class:`~hyperfem.loading.Activation`.
        bulk_factor: Multiplier of the seed bulk moduli.

    Returns:
        Region name → :class:`~hyperfem.problem.SplitEnergy`.
    """
    mp = MuscleParameters.muscle(K=MuscleParameters.muscle().K * bulk_factor)
    tp = MuscleParameters.tendon(K=MuscleParameters.tendon().K * bulk_factor)
    materials = {"muscle": SplitEnergy(lambda F: muscle_isochoric(F, a0, activation.expr, mp), mp.K)}
    for name in TENDONS:
        materials[name] = SplitEnergy(lambda F: muscle_isochoric(F, a0, 0.0, tp), tp.K)
    return materials


def muscle_problem(
    domain: Domain,
    a0: fem.Function,
    activation: Activation,
    experiment: str = "free",
    *,
    traction: float = 2.0e3,
    bulk_factor: float = 50.0,
    formulation: str = "mixed",
    updaters: Iterable[Updater] = (),
) -> HyperelasticProblem | MixedHyperelasticProblem:
    r"""The problem of one experiment; the activation is updated by ``set_time``.

    Args:
        domain: The fusiform mesh.
        a0: Unit fibre field.
        activation: The belly's :class:`~hyperfem.loading.Activation`
            (its schedule :math:`\alpha(t)` is evaluated at the problem time).
        experiment: One of :data:`EXPERIMENTS`.
        traction: Dead axial traction on ``insertion`` in the free experiment
            (Pa, constant in time).
        bulk_factor: Multiplier of the seed bulk moduli.
        formulation: ``"mixed"`` (three-field :math:`u, p, \theta`) or ``"displacement"``.
        updaters: Further updaters (the activation is always one).
    """
    if experiment not in EXPERIMENTS:
        raise ParameterError(f"muscle_problem: unknown experiment {experiment!r} (use {', '.join(EXPERIMENTS)})")
    if experiment == "isometric":
        bcs, loads = [Clamp("origin"), Clamp("insertion")], []
    else:
        bcs = [Clamp("origin")]
        loads = [DeadTraction("insertion", (0.0, 0.0, traction), profile=lambda t: 1.0)]
    return solid_problem(
        domain,
        muscle_materials(a0, activation, bulk_factor),
        formulation=formulation,
        bcs=bcs,
        loads=loads,
        updaters=[activation, *updaters],
    )
