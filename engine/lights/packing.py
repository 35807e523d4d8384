"""Lights as flat arrays for the compiled direct-light kernels (engine/directlight.py).

Each light kind writes its parameters into one float64 row of P slots (pack(row) on its
class); the slot names below are the only contract between the kinds and the kernels.
Emissive triangles (one MeshLight at most) travel as their own arrays."""
from __future__ import annotations

import numpy as np

# Kind codes seen by the kernels.
CODE_POINT, CODE_SPOT, CODE_AREA, CODE_SUN, CODE_MESH, CODE_WORLD = range(6)

# Slots of a light's parameter row.
POS, DIR, U, V, DU, DV, RGB = 0, 3, 6, 9, 12, 15, 18   # 3 each
RADIUS, SIZE_X, SIZE_Y, AREA_, COS_HALF = 21, 22, 23, 24, 25
SPREAD_ON, TAN_H, SPREAD_NORM, IS_DISK, SPREAD_RECT = 26, 27, 28, 29, 30
SPOT_COS_HALF, SPOT_WIDTH, SPOT_FRAME = 31, 32, 33  # frame: 9 slots, row-major
P = 42


def pack_lights(lights):
    """(codes (L,) int64, params (L,P) float64, mesh arrays) for a list of Light; the mesh
    arrays (v0, e1, e2, ng, L, area/prob, cdf, round32, tilt32) are empty without
    emissive meshes."""
    codes = np.zeros(len(lights), np.int64)
    params = np.zeros((len(lights), P))
    mesh = None
    for i, light in enumerate(lights):
        codes[i] = light.pack(params[i])
        if codes[i] == CODE_MESH:
            mesh = light
    if mesh is None:
        z3 = np.zeros((0, 3))
        return codes, params, (z3, z3, z3, z3, z3, np.zeros(0), np.zeros(0),
                               np.zeros((0, 3, 3)), np.zeros(0))
    c = np.ascontiguousarray
    return codes, params, (c(mesh.v0), c(mesh.e1), c(mesh.e2), c(mesh.tri_ng), c(mesh.tri_L),
                           c(mesh.tri_area / mesh.prob), c(mesh.cdf), c(mesh.round32),
                           c(np.asarray(mesh.tilt32, np.float64)))
