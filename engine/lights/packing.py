"""Lights as flat arrays for the compiled direct-light kernels (engine/directlight.py).

Each light kind writes its parameters into one float64 row of P slots (pack(row) on its
class); the slot names below are the only contract between the kinds and the kernels.
Emissive triangles (one MeshLight at most) and the world's environment map travel as
their own arrays."""
from __future__ import annotations

import numpy as np

# Kind codes seen by the kernels.
CODE_POINT, CODE_SPOT, CODE_AREA, CODE_SUN, CODE_MESH, CODE_WORLD = range(6)

# Slots of a light's parameter row.
POS, DIR, U, V, DU, DV, RGB = 0, 3, 6, 9, 12, 15, 18   # 3 each
RADIUS, SIZE_X, SIZE_Y, AREA_, COS_HALF = 21, 22, 23, 24, 25
SPREAD_ON, TAN_H, SPREAD_NORM, IS_DISK, SPREAD_RECT = 26, 27, 28, 29, 30
SPOT_COS_HALF, SPOT_WIDTH, SPOT_FRAME = 31, 32, 33  # frame: 9 slots, row-major
ENV_FRAME = SPOT_FRAME      # world: the environment's rotation (world -> texture), 9 slots
ENV_ON, ENV_INTERP = 42, 43  # world: 1 with an environment map; its interpolation code
SPHERE = 44                 # point / spot: 1 for a sphere (Soft Falloff off), 0 a facing disk
# world: Cycles light portals (engine/lights/world.py, lightportal34): how many (0: none,
# the shadow rays as before), the portal strategy's share bounds, 1 when the portals are
# sampled by the environment map seen through them (lights/portalmap.py, portalenv35; 0:
# uniform in their solid angle), the share rule (world.PORTAL_RULE_*), then MAX_PORTALS
# portals of PORTAL_STRIDE slots: corner s, edges ex, ey (re-centred world space, m), the
# unit normal into the room and 1 for a round portal (the ellipse inscribed in the
# rectangle, portals36), else 0.
PORTAL_N, PORTAL_LO, PORTAL_HI, PORTAL_MAP, PORTAL_RULE, PORTAL0 = 45, 46, 47, 48, 49, 50
PORTAL_STRIDE = 13
PORTAL_ROUND = 12  # (within a portal's slots)
MAX_PORTALS = 4
P = PORTAL0 + PORTAL_STRIDE * MAX_PORTALS
# point / spot with an IES profile (ies38): the packed profile (engine/ies.py
# IESProfile.packed: the world -> lamp matrix, then the table) from slot IES on; the rows
# are that much wider only when a light has one (a row without one holds zeros there:
# ies.HEADER + 0 horizontal angles, no profile).
IES = P


def pack_lights(lights):
    """(codes (L,) int64, params (L,P) float64, arrays) for a list of Light; `arrays` are
    the emissive triangles' (v0, e1, e2, ng, L, area, their light tree's tree_f and
    tree_i (MeshLight.triangle_tree), round32, tilt32, sides (T,) int64: the sides shadow
    rays sample, MeshLight.sides), empty
    without emissive meshes, then the world's environment map (radiance texels (H,W,3)
    float32, the texels its lookup reads and their scale (Environment.stored, (H,W,3)
    float32, and Environment.scale, (3,) float64) and its cosine-weighted
    distributions: row cdfs (K,Hc+1), column cdfs (K,Hc,Wc+1), cell probabilities
    (K,Hc,Wc), per-row prefix sums (H,W+1), cell sums (Hc,Wc):
    environment.build_cosine_distributions), one black texel without one; then the
    world's light portal tables (lights/portalmap.py: f (K,N,N), sat (K,N+1,N+1) float64;
    (1,1,1) and (1,2,2) zeros without an environment map and portals)."""
    codes = np.zeros(len(lights), np.int64)
    extra = max([len(light.ies) for light in lights if getattr(light, "ies", None) is not None],
                default=0)
    params = np.zeros((len(lights), P + extra))
    mesh = None
    env = None
    portal_tables = None
    for i, light in enumerate(lights):
        codes[i] = light.pack(params[i])
        if codes[i] == CODE_MESH:
            mesh = light
        elif codes[i] == CODE_WORLD and getattr(light, "environment", None) is not None:
            env = light.environment
            portal_tables = light.portal_tables
    if env is None:
        none = np.zeros((1, 1, 3), np.float32)
        env_arrays = (none, none, np.ones(3), np.array([[0.0, 1.0]]),
                      np.array([[[0.0, 1.0]]]), np.zeros((1, 1, 1)), np.zeros((1, 2)),
                      np.zeros((1, 1)))
    else:
        env_arrays = (env.pixels, env.stored, env.scale, *env.cosine_distributions)
    if portal_tables is None:
        portal_tables = (np.zeros((1, 1, 1)), np.zeros((1, 2, 2)))
    env_arrays = (*env_arrays, *portal_tables)
    c = np.ascontiguousarray
    if mesh is None:
        z3 = np.zeros((0, 3))
        from .selection import NF, NI
        return codes, params, (z3, z3, z3, z3, z3, np.zeros(0), np.zeros((0, NF)),
                               np.zeros((0, NI), np.int64), np.zeros((0, 3, 3)), np.zeros(0),
                               np.zeros(0, np.int64), *env_arrays)
    tree_f, tree_i, _ = mesh.triangle_tree()
    return codes, params, (c(mesh.v0), c(mesh.e1), c(mesh.e2), c(mesh.tri_ng), c(mesh.tri_L),
                           c(np.asarray(mesh.tri_area, np.float64)), tree_f, tree_i,
                           c(mesh.round32), c(np.asarray(mesh.tilt32, np.float64)),
                           mesh.sides(), *env_arrays)
