"""Orientation of the cells of an input mesh: see :mod:`hyperfem.mesh.orientation` (re-exported here)."""

from __future__ import annotations

from hyperfem.mesh.orientation import (
    DEGENERATE_TOLERANCE,
    Orientation,
    check_cell_volumes,
    domain_orientation,
    orientation,
    signed_volumes,
)

__all__ = [
    "DEGENERATE_TOLERANCE",
    "Orientation",
    "check_cell_volumes",
    "domain_orientation",
    "orientation",
    "signed_volumes",
]
