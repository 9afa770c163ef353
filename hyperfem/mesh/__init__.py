"""Meshes: reading gmsh files, named groups, geometry generators, and the checks made on them.

:mod:`~hyperfem.mesh.budget` (the size guard), :mod:`~hyperfem.mesh.orientation`
(inverted and degenerate cells), :mod:`~hyperfem.mesh.convert` (``hyperfem convert``:
other formats → gmsh, via meshio) and :mod:`~hyperfem.mesh.abaqus` (Abaqus ``.inp``
sets and surfaces for it) are submodules.
"""

from hyperfem.mesh.beam import BEAM_GROUPS, beam_mesh, write_beam_mesh
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.io import read_mesh

__all__ = ["BEAM_GROUPS", "Domain", "beam_mesh", "read_mesh", "write_beam_mesh"]

from hyperfem.mesh.fusiform import FUSIFORM_GROUPS, FusiformGeometry, fusiform_mesh, write_fusiform_mesh  # noqa: E402

__all__ += ["FUSIFORM_GROUPS", "FusiformGeometry", "fusiform_mesh", "write_fusiform_mesh"]

from hyperfem.mesh.quality import MeshQuality, MeshQualityWarning, mesh_quality, quality_report  # noqa: E402

__all__ += ["MeshQuality", "MeshQualityWarning", "mesh_quality", "quality_report"]

from hyperfem.mesh.blocks import BLOCKS_GROUPS, stacked_blocks_mesh, write_stacked_blocks_mesh  # noqa: E402

__all__ += ["BLOCKS_GROUPS", "stacked_blocks_mesh", "write_stacked_blocks_mesh"]

from hyperfem.mesh.shell import SHELL_GROUPS, spherical_shell_mesh, write_spherical_shell_mesh  # noqa: E402

__all__ += ["SHELL_GROUPS", "spherical_shell_mesh", "write_spherical_shell_mesh"]
