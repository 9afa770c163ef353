"""Stability of equilibrium states: eigenvalues of the tangent and linearised buckling.

* :mod:`~hyperfem.stability.pencil` — the tangent and a metric as a matrix
  pencil (Dirichlet conditions out of the spectrum; the mixed problem's
  displacement-reduced tangent);
* :mod:`~hyperfem.stability.eigensolver` — SLEPc Krylov–Schur with
  shift-and-invert (MUMPS) on a pencil;
* :mod:`~hyperfem.stability.spectrum` — :func:`lowest_eigenvalues`,
  :class:`TangentEigensolver`, :class:`TangentSpectrum` (stable or not);
* :mod:`~hyperfem.stability.buckling` — :func:`buckling_analysis`,
  :class:`BucklingResult`, :func:`write_buckling_modes`.
"""

from hyperfem.stability.pencil import METRICS, TangentPencil, negative_pivots
from hyperfem.stability.spectrum import TangentEigensolver, TangentSpectrum, lowest_eigenvalues

__all__ = [
    "METRICS",
    "TangentEigensolver",
    "TangentPencil",
    "TangentSpectrum",
    "lowest_eigenvalues",
    "negative_pivots",
]
