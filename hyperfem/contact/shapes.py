"""Triangulated tool shapes: a sphere (a ball-ended probe) for :class:`~hyperfem.contact.ToolContact`."""

from __future__ import annotations

import numpy as np

__all__ = ["icosphere"]


def icosphere(level: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The unit sphere triangulated: the icosahedron, each triangle split in four ``level`` times, on the sphere.

    Args:
        level: Subdivisions (0: 20 triangles; each level multiplies them by 4).

    Returns:
        Points ``(k, 3)`` and triangles ``(f, 3)``, outward oriented.
    """
    t = (1.0 + 5.0**0.5) / 2.0
    points = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
              (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    v = [np.array(p, dtype=float) / np.linalg.norm(p) for p in points]
    middle: dict[tuple[int, int], int] = {}

    def mid(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in middle:
            m = v[a] + v[b]
            v.append(m / np.linalg.norm(m))
            middle[key] = len(v) - 1
        return middle[key]

    for _ in range(level):
        middle.clear()
        split = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            split += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = split
    return np.array(v), np.array(faces)
