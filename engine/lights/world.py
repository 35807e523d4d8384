"""World: a non-black background as a uniform environment of radiance `background`
(when the scene lets the background light it), sampled by the cosine hemisphere."""
from __future__ import annotations

import math

import numpy as np

from ..sampling import uniform_sphere
from . import packing as pk
from .base import InfiniteLight

WORLD = "WORLD"


class WorldLight(InfiniteLight):
    kind = WORLD
    declared = False

    @classmethod
    def from_background(cls, scene, common):
        """The world light of the scene, or None (black background, or not a light)."""
        bg = np.asarray(scene.background, np.float64)
        if not (scene.background_is_light and np.any(bg > 0)):
            return None
        radius = common["scene_radius"]
        return cls("world", radiance=bg,
                   photon_flux=bg * math.pi * radius ** 2 * 4.0 * math.pi,
                   radius=0.0, cos_half_angle=1.0, **common)

    def pack(self, row) -> int:
        """Write the kernel parameters (engine/lights/packing.py); returns the kind code."""
        row[pk.RGB:pk.RGB + 3] = self.radiance
        return pk.CODE_WORLD

    def _directions(self, n, u1, u2):
        return uniform_sphere(u1, u2)
