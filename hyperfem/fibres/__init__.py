"""Fibre-direction fields: constant, callable, Laplace rule, or read from a mesh file."""

from hyperfem.fibres.fields import (
    REPRESENTATIONS,
    constant_fibres,
    fibre_space,
    fibres_from_callable,
    fibres_from_expression,
    normalize_fibres,
)
from hyperfem.fibres.laplace import laplace_fibres, laplace_potential
from hyperfem.fibres.meshfile import fibres_from_file

__all__ = [
    "REPRESENTATIONS",
    "constant_fibres",
    "fibre_space",
    "fibres_from_callable",
    "fibres_from_expression",
    "fibres_from_file",
    "laplace_fibres",
    "laplace_potential",
    "normalize_fibres",
]
