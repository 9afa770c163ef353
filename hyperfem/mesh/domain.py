"""A mesh together with its named physical groups.

:class:`Domain` is what every other part of hyperfem receives: the DOLFINx
mesh, its cell and facet tags, and the mapping from physical-group *names* to
tags. Boundary conditions, loads and material regions refer to names only;
unknown names raise :class:`~hyperfem.errors.UnknownGroupError` listing the
names that exist.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import ufl
from mpi4py import MPI
from dolfinx import mesh as dmesh

from hyperfem.errors import ParameterError, UnknownGroupError

__all__ = ["Domain"]


@dataclass
class Domain:
    """Mesh, tags and physical-group names.

    Attributes:
        mesh: The DOLFINx mesh.
        cell_tags: Cell markers (may be ``None`` when the mesh has no regions).
        facet_tags: Facet markers (may be ``None``).
        cell_groups: Region name → tag.
        facet_groups: Boundary name → tag.
        source: Where the mesh came from (file path or generator), for messages.
    """

    mesh: dmesh.Mesh
    cell_tags: dmesh.MeshTags | None = None
    facet_tags: dmesh.MeshTags | None = None
    cell_groups: dict[str, int] = field(default_factory=dict)
    facet_groups: dict[str, int] = field(default_factory=dict)
    source: str = "<memory>"

    @property
    def comm(self) -> MPI.Comm:
        """The mesh communicator."""
        return self.mesh.comm

    @property
    def gdim(self) -> int:
        """Geometric dimension."""
        return self.mesh.geometry.dim

    @property
    def tdim(self) -> int:
        """Topological dimension."""
        return self.mesh.topology.dim

    def _lookup(self, name: str, groups: Mapping[str, int], kind: str) -> int:
        if name not in groups:
            available = ", ".join(sorted(groups)) or "none"
            raise UnknownGroupError(
                f"{self.source}: no {kind} physical group named {name!r} (available: {available})"
            )
        return groups[name]

    def facet_tag(self, name: str) -> int:
        """Tag of the boundary group ``name``."""
        return self._lookup(name, self.facet_groups, "boundary (facet)")

    def cell_tag(self, name: str) -> int:
        """Tag of the region group ``name``."""
        return self._lookup(name, self.cell_groups, "region (cell)")

    def facets(self, name: str) -> np.ndarray:
        """Local indices of the facets in boundary group ``name``."""
        tag = self.facet_tag(name)
        assert self.facet_tags is not None
        return self.facet_tags.find(tag)

    def cells(self, name: str) -> np.ndarray:
        """Local indices of the cells in region group ``name``."""
        tag = self.cell_tag(name)
        assert self.cell_tags is not None
        return self.cell_tags.find(tag)

    def ds(self, name: str, **kwargs: Any) -> ufl.Measure:
        """Surface measure restricted to boundary group ``name``."""
        tag = self.facet_tag(name)
        return ufl.Measure("ds", domain=self.mesh, subdomain_data=self.facet_tags, **kwargs)(tag)

    def dx(self, name: str | None = None, **kwargs: Any) -> ufl.Measure:
        """Volume measure, restricted to region ``name`` if given."""
        if name is None:
            return ufl.Measure("dx", domain=self.mesh, **kwargs)
        tag = self.cell_tag(name)
        return ufl.Measure("dx", domain=self.mesh, subdomain_data=self.cell_tags, **kwargs)(tag)

    @classmethod
    def from_locators(
        cls,
        mesh: dmesh.Mesh,
        facets: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None = None,
        source: str = "<memory>",
    ) -> Domain:
        """Name boundary facets of a built-in mesh with geometric locator functions.

        Useful for analytic tests on ``dolfinx.mesh.create_box`` meshes. The
        whole mesh is region ``"domain"`` (tag 1).

        Args:
            mesh: A DOLFINx mesh.
            facets: Boundary name → ``marker(x) -> bool array`` (as for
                :func:`dolfinx.mesh.locate_entities_boundary`).
            source: Label used in error messages.
        """
        tdim = mesh.topology.dim
        fdim = tdim - 1
        mesh.topology.create_connectivity(fdim, tdim)
        facets = dict(facets or {})
        for name, locator in facets.items():
            if not (isinstance(name, str) and name) or not callable(locator):
                raise ParameterError(
                    f"Domain.from_locators: need boundary name (str) -> marker(x) callable, got {name!r}: {locator!r}"
                )
        indices, values, groups = [], [], {}
        for tag, (name, locator) in enumerate(facets.items(), start=1):
            found = dmesh.locate_entities_boundary(mesh, fdim, locator)
            indices.append(found)
            values.append(np.full_like(found, tag))
            groups[name] = tag
        idx = np.concatenate(indices) if indices else np.zeros(0, dtype=np.int32)
        val = np.concatenate(values) if values else np.zeros(0, dtype=np.int32)
        order = np.argsort(idx)
        facet_tags = dmesh.meshtags(mesh, fdim, idx[order].astype(np.int32), val[order].astype(np.int32))
        ncells = mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts
        cell_tags = dmesh.meshtags(
            mesh, tdim, np.arange(ncells, dtype=np.int32), np.ones(ncells, dtype=np.int32)
        )
        return cls(mesh, cell_tags, facet_tags, {"domain": 1}, groups, source)
