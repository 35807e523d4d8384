"""Memory per triangle (issue 16): Embree's compact BVH answers exactly as the default
one, and the effect analysis walks large objects a piece at a time with the same answers
as over all their triangles at once (docs/performance.md, "Memory per triangle")."""
import numpy as np
import pytest

from engine import accel as accel_mod
from engine import casterspheres, effects
from engine.accel import Accel
from engine.rayoffset import ulp32
from engine.scene import Material, Mesh, Scene
from engine.geometry import prepare

pytestmark = pytest.mark.skipif(accel_mod._LIBRARY is None,
                                reason="Embree's C library is not reachable from embreex")


def _bumpy_grid(n=60, seed=0):
    rng = np.random.default_rng(seed)
    xs = np.linspace(-1, 1, n + 1)
    X, Y = np.meshgrid(xs, xs)
    V = np.stack([X.ravel(), Y.ravel(), 0.05 * rng.standard_normal(X.size)], 1)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    F = np.concatenate([np.stack([i, i + 1, i + n + 2], 1), np.stack([i, i + n + 2, i + n + 1], 1)])
    return V, F


def _rays(count=20000, seed=1):
    rng = np.random.default_rng(seed)
    o = np.column_stack([rng.uniform(-1.2, 1.2, count), rng.uniform(-1.2, 1.2, count),
                         np.full(count, 1.0)])
    d = np.column_stack([rng.normal(0, 0.5, count), rng.normal(0, 0.5, count), -np.ones(count)])
    return o, d / np.linalg.norm(d, axis=1)[:, None]


def test_compact_bvh_gives_the_same_hits(monkeypatch):
    V, F = _bumpy_grid()
    o, d = _rays()
    tmax = np.random.default_rng(2).uniform(0.5, 2.0, len(o))
    monkeypatch.setattr(accel_mod, "COMPACT_TRIANGLES", 1 << 40)
    default = Accel(V, F)
    monkeypatch.setattr(accel_mod, "COMPACT_TRIANGLES", 1)
    compact = Accel(V, F, should_cancel=lambda: False)
    assert not default.compact and compact.compact
    lib, offset, ctypes = accel_mod._LIBRARY
    ptr = ctypes.c_void_p.from_address(id(compact._scene) + offset).value
    assert lib.rtcGetSceneFlags(ptr) == accel_mod.SCENE_FLAG_ROBUST | accel_mod.SCENE_FLAG_COMPACT
    a, b = default.intersect(o, d), compact.intersect(o, d)
    assert (a[1] >= 0).sum() > len(o) // 2
    # The same triangle for every ray and the same occlusion. Distances and barycentrics
    # are equal to float32 rounding only: the compact layout keeps vertex indices and
    # forms the edges during traversal, and Embree's two layouts round differently on
    # some CPUs (bitwise on an AVX-512 machine; on an AMD EPYC without AVX-512, t differs
    # by up to 1.3e-6 relative and u, v by up to 2.1e-5 on 24-52 % of the rays).
    t_a, prim_a, u_a, v_a = a
    t_b, prim_b, u_b, v_b = b
    np.testing.assert_array_equal(prim_a, prim_b)
    np.testing.assert_allclose(t_a, t_b, rtol=1e-5, atol=0)
    np.testing.assert_allclose(u_a, u_b, rtol=0, atol=1e-4)
    np.testing.assert_allclose(v_a, v_b, rtol=0, atol=1e-4)
    np.testing.assert_array_equal(default.occluded(o, d, tmax), compact.occluded(o, d, tmax))


def test_large_meshes_get_the_compact_bvh():
    V, F = _bumpy_grid(n=8)
    assert not Accel(V, F).compact  # small: the faster default BVH
    assert accel_mod.COMPACT_TRIANGLES <= 1 << 20  # a 1M-triangle scene is compact


def _geometry(V, F):
    scene = Scene()
    scene.add_material(Material("default"))
    scene.add_mesh(Mesh("grid", V, F))
    return prepare(scene)[0]


def _spheres_at_once(geo, mask):
    """effects._object_spheres over all corners at once (the way it was written before)."""
    ids = np.unique(geo.object_id[mask])
    out = []
    for oid in ids:
        sel = np.nonzero(mask & (geo.object_id == oid))[0]
        pts = np.concatenate([geo.v0[sel], geo.v0[sel] + geo.e1[sel], geo.v0[sel] + geo.e2[sel]])
        c = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
        r = float(np.linalg.norm(pts - c, axis=1).max()) * 1.001 + 16.0 * float(
            ulp32(np.abs(pts).max()))
        out.append((c, r))
    return out


@pytest.mark.parametrize("piece", [7, 1 << 16])
def test_effect_analysis_in_pieces_matches_all_at_once(monkeypatch, piece):
    monkeypatch.setattr(casterspheres, "PIECE_TRIANGLES", piece)
    V, F = _bumpy_grid(n=12)
    geo = _geometry(V, F)
    mask = np.ones(geo.count, bool)
    mask[::5] = False
    ids, centers, radii, names = effects._object_spheres(geo, mask)
    (c, r), = _spheres_at_once(geo, mask)
    np.testing.assert_array_equal(centers[0], c)
    assert radii[0] == r and names == ["grid"]
    assert not effects._single_flat_surface(geo, mask)
    flat = V.copy()
    flat[:, 2] = 0.25
    geo = _geometry(flat, F)
    assert effects._single_flat_surface(geo, mask)
    tilted = flat.copy()
    tilted[-1, 2] += 1e-3  # one corner off the plane, in the last piece
    assert not effects._single_flat_surface(_geometry(tilted, F), np.ones(len(F), bool))
