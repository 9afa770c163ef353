"""Loading: how a run is driven in load factor or time.

* :mod:`~hyperfem.loading.profiles` — time profiles ``f(s)`` that scale loads
  and prescribed displacements (:func:`linear_profile`, :class:`Steady`,
  :class:`Ramp`, :class:`Table`, :class:`Scaled`);
* :mod:`~hyperfem.loading.motion` — prescribed rigid motions of a surface
  (:func:`rotating_surface`, :class:`RigidRotation`, :func:`rotation_matrix`)
  and translation paths of an obstacle (:class:`Waypoints`);
* :mod:`~hyperfem.loading.fields` — vector fields of the coordinates for loads
  (:class:`AffineField`);
* :mod:`~hyperfem.loading.activation` — muscle activation per region
  (:class:`Activation`: constant, α(t), spatial field).

>>> from mpi4py import MPI
>>> import hyperfem as hf
>>> from hyperfem.loading import Ramp, rotating_surface
>>> twist = rotating_surface("free_end", (1, 0, 0), Ramp(1.0, final=0.5), center=(5.0, 0.5, 0.5))
"""

from hyperfem.loading.activation import Activation
from hyperfem.loading.fields import AffineField
from hyperfem.loading.motion import RigidRotation, Waypoints, rotating_surface, rotation_matrix
from hyperfem.loading.profiles import Ramp, Scaled, Steady, Table, linear_profile

__all__ = [
    "Activation",
    "AffineField",
    "Ramp",
    "RigidRotation",
    "Scaled",
    "Steady",
    "Table",
    "Waypoints",
    "linear_profile",
    "rotating_surface",
    "rotation_matrix",
]
