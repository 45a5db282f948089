"""The panoramic camera: which objects are seen from a point, and how large they look.

An object is hidden when the line of sight to its centre passes within the radius of an object
whose centre is nearer, or when its surface is farther than ``view_range``; walls never hide
anything (the room is convex).  The observation has one entry per object type: the largest
apparent (angular) size ``2 * atan(radius / distance)`` among the visible objects of that type
(0 if none is visible); the distance is to the centre.
"""

from __future__ import annotations

import numpy as np

from .geometry import TOL

__all__ = ["Camera"]


class Camera:
    """The robot's camera in a room of disc-shaped objects (types, centres, radii)."""

    def __init__(self, types, centers, radii, n_types: int, view_range: float, reach: float):
        self.types, self.centers, self.radii = types, centers, radii
        self.n_types, self.view_range, self.reach = int(n_types), float(view_range), float(reach)
        self._key = None
        self._val = None

    def view(self, x: float, y: float):
        """Visibility mask, apparent sizes and centre distances of all objects from ``(x, y)``.

        The last view is cached: a step observes and then asks which actions are executable.
        """
        key = (float(x), float(y))
        if key == self._key:
            return self._val
        C, R = self.centers, self.radii
        D = C - np.array(key)
        dist = np.maximum(np.hypot(D[:, 0], D[:, 1]), 1e-12)
        U = D / dist[:, None]
        t = U @ D.T  # t[i, j]: position of object j's centre along the line of sight to object i
        perp2 = dist[None, :] ** 2 - t**2
        occ = (t > 0) & (dist[None, :] < dist[:, None]) & (perp2 < R[None, :] ** 2)
        np.fill_diagonal(occ, False)
        visible = ~occ.any(axis=1) & (dist - R <= self.view_range)
        apparent = 2.0 * np.arctan(R / np.maximum(dist, R))
        self._key, self._val = key, (visible, apparent, dist)
        return self._val

    def observe(self, x: float, y: float) -> np.ndarray:
        """Noise-free observation from ``(x, y)``: ``(n_types,)`` apparent sizes in radians."""
        visible, apparent, _ = self.view(x, y)
        obs = np.zeros(self.n_types)
        np.maximum.at(obs, self.types[visible], apparent[visible])
        return obs

    def approachable(self, x: float, y: float) -> np.ndarray:
        """Boolean mask of the objects seen from ``(x, y)`` that are not within reach."""
        visible, _, dist = self.view(x, y)
        return visible & (dist - self.radii > self.reach + TOL)

    def approach_target(self, x: float, y: float, type_index: int) -> int | None:
        """The nearest (by centre distance) approachable object of a type, or None."""
        cand = self.approachable(x, y) & (self.types == type_index)
        if not cand.any():
            return None
        idx = np.flatnonzero(cand)
        return int(idx[np.argmin(self.view(x, y)[2][idx])])
