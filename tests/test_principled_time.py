"""Guards for issue 14's Principled scene at equal time (docs/accuracy_time.md): the
causes of its time and noise that were found and cut, each checked here without Blender.

1. The gather map's visibility test on curved surfaces: the chord between two points of a
   ball runs inside the ball, so every candidate of a lookup on a ball was hidden; each
   lookup then tried all its candidates (100-200 us instead of ~3) and answered
   "boundary", which regathered from every such point. 89 % of the scene's camera time.
2. Which specular lobes count as caustic casters (engine/effects.py): the fixed roughness
   limit became a lobe-width limit that widens with the light's size seen from the
   object, and the effect report says which objects it admitted and why."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.scene import Material

from engine.accel import Accel
from engine.api import sphere_mesh
from engine.photonmap import GatherMap
from engine.photons import Photons


def _points_on_mesh(v, f, n, rng):
    """n points uniform by area on triangles (v, f), with the triangles' outward normals."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    cross = np.cross(b - a, c - a)
    area = np.linalg.norm(cross, axis=1)
    tri = rng.choice(len(f), n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    p = (1 - s)[:, None] * a[tri] + (s * (1 - r2))[:, None] * b[tri] + (s * r2)[:, None] * c[tri]
    normal = cross[tri] / area[tri, None]
    centre = v.mean(axis=0)
    normal *= np.sign(np.einsum("ij,ij->i", normal, p - centre))[:, None]  # outward
    return p, normal


def test_gather_lookup_on_a_ball_finds_its_nearest_facing_point():
    """On a lone ball nothing hides one surface point from another nearby on the same
    side: a lookup with the visibility test answers as one without it (no boundary
    flags from a chord running inside the ball)."""
    rng = np.random.default_rng(14)
    v, f, _, _ = sphere_mesh((0.3, -0.2, 0.5), 0.5)
    pos, nrm = _points_on_mesh(v, f, 40_000, rng)
    d = -nrm + 0.3 * rng.normal(size=nrm.shape)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ph = Photons(pos.astype(np.float32), np.full((len(pos), 3), 1e-4, np.float32),
                 d.astype(np.float32), nrm.astype(np.float32), np.zeros(len(pos), np.uint8))
    accel = Accel(v, f)
    g = GatherMap(ph, 0.3, 32, 4, "knn_simpson", max_points=5000, accel=accel)
    q, nq = _points_on_mesh(v, f, 3000, rng)
    E, B = g.lookup(q, nq)
    g.accel = None
    E_free, B_free = g.lookup(q, nq)
    same = np.all(E == E_free, axis=1) & (B == B_free)
    assert same.mean() > 0.99, f"{(~same).sum()} of {len(q)} lookups lost their candidate"
    assert (~B).mean() > 0.9  # and those candidates are real estimates, not boundaries


def test_gather_lookup_still_hides_a_point_behind_a_wall():
    """The lift is zero between equal normals: a floor point beside a thin wall never
    takes the brighter floor's gather point behind it, though that one is nearer (the
    coplanar ground under a room's wall, docs/stability.md)."""
    rng = np.random.default_rng(3)
    n = 20_000
    xy = rng.random((n, 2))
    xy = xy[(xy[:, 0] < 0.46) | (xy[:, 0] > 0.52)]
    m = len(xy)
    power = np.where(xy[:, 0] > 0.5, 100.0, 1.0)[:, None].repeat(3, axis=1)
    up = np.tile([0.0, 0.0, 1.0], (m, 1))
    ph = Photons(np.c_[xy, np.zeros(m)].astype(np.float32), power.astype(np.float32),
                 -up.astype(np.float32), up.astype(np.float32), np.zeros(m, np.uint8))
    wall_v = np.array([[0.5, -1, -0.5], [0.5, 2, -0.5], [0.5, 2, 1], [0.5, -1, 1]], float)
    g = GatherMap(ph, 0.2, 32, 4, "knn_simpson", max_points=2000,
                  accel=Accel(wall_v, np.array([[0, 1, 2], [0, 2, 3]])))
    q = np.c_[np.full(500, 0.499), 0.1 + 0.8 * rng.random(500), np.zeros(500)]
    E, _ = g.lookup(q, up[:500])
    bright = g.E[g.position[:, 0] > 0.5].mean()
    assert E.max() < 0.1 * bright  # the dim side's light (or none), never the bright side's
    g.accel = None
    assert g.lookup(q, up[:500])[0].max() > 0.5 * bright  # without the wall: the bright one


def _ball_scene(big_light: bool, roughness: float):
    """A Principled ball of `roughness` on a diffuse floor, lit by a 4 m area light 3 m
    above it (it spans ~43 degrees from the ball) or by a point light."""
    s = PaperScene(width=16, height=16)
    s.add_material(Material("floor", (0.7, 0.7, 0.7), specular=0.0))
    s.add_material(Material("ball", (0.8, 0.6, 0.2), metallic=1.0, roughness=roughness))
    s.add_plane((0, 0, 0), (0, 0, 1), 8, "floor", name="floor")
    s.add_sphere((0, 0, 0.5), 0.5, "ball", name="ball", segments=24)
    if big_light:
        s.add_rect_area_light((0, 0, 3.5), (4.0, 4.0), power=500, direction=(0, 0, -1))
    else:
        s.add_point_light((0, 0, 3.5), power=500)
    s.set_camera((0, -5, 2), (0, 0, 0.5), view_angle=40)
    return s


@pytest.mark.parametrize("big_light,roughness,caster", [
    (False, 0.25, True),   # within the fixed 10 degrees (2 x 0.25^2 = 7 deg)
    (False, 0.4, False),   # 18 deg: wider than a point light, no caster
    (True, 0.4, True),     # 18 deg, but the light spans 43 deg from the ball
    (True, 0.7, False),    # 56 deg: wider than that light too
])
def test_a_lobe_focuses_up_to_the_light_s_size(big_light, roughness, caster):
    from engine.render import prepare_context
    ctx = prepare_context(_ball_scene(big_light, roughness),
                          RenderSettings(photons=2000, workers=1))
    ctx.accel.close()
    assert (ctx.plan.casters == ["ball"]) == caster
    assert ("ball" in ctx.plan.rough_specular) == (not caster)
    line = next(r for r in ctx.plan.report() if r.startswith("caustics:"))
    widened = big_light and caster
    assert ("'ball' (lobe 18 deg within the light's 4" in line) == widened, line
    if not caster:
        assert "too wide to focus" in line or "too rough to focus" in line, line


def test_light_angular_radius_per_kind():
    from engine.effects import light_angular_radius
    from engine.render import prepare_context
    ctx = prepare_context(_ball_scene(True, 0.4), RenderSettings(photons=2000, workers=1))
    ctx.accel.close()
    area = ctx.lights[0]
    p = np.asarray(area.pos, float) - np.array([0.0, 0.0, 3.0])  # 3 m below its centre
    assert light_angular_radius(area, p) == pytest.approx(math.atan(2 * math.sqrt(2) / 3))
