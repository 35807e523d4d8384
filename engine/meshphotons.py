"""Which triangle of a mesh light each of its photons left.

emit_mesh (lights/emission.py) picks a photon's triangle from the light's triangle CDF at
the photon's emission number 0 (emission.emit_uniform: a SplitMix64 number of the key
and the photon's slot). Code after the photon pass that needs that triangle (Light
Linking's emitter rows, Clamp Indirect's per-triangle radiance) recomputes the same pick
here, so there is one copy of it outside the kernel.
"""
from __future__ import annotations

import numpy as np


def emitted_triangles(light, key, slot) -> np.ndarray:
    """(M,) int64 the rows of mesh light `light`'s triangles (lights/mesh.py MeshLight:
    its `cdf`) its photons in `slot` (M,) int left under emission key `key` (uint64):
    emit_mesh's choice, the triangle CDF at the photon's emission number 0
    (photonkernels.uniforms: the same SplitMix64 number; emission.pick is searchsorted's
    right side)."""
    from .lights.emission import EMIT_BOUNCE
    from .photonkernels import uniforms
    slot = np.ascontiguousarray(slot, np.int64)
    u = np.empty(len(slot))
    uniforms(np.uint64(key), slot, EMIT_BOUNCE, 0, u)
    cdf = np.asarray(light.cdf)
    return np.minimum(np.searchsorted(cdf, u, side="right"), len(cdf) - 1)
