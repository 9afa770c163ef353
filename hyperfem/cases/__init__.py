"""Reference set-ups from the seed documents, shared by demos, tests and benchmarks."""

from hyperfem.cases.cantilever import (
    BEND_TRACTION,
    MESH_CONVERGENCE,
    REFERENCE,
    TEST_POINT,
    TWIST_MAGNITUDE,
    CantileverSpec,
    bend_load,
    convergence_note,
    mesh_size_of,
    twist_load,
)

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
