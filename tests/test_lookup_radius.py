"""The global search radius (engine/render.py lookup_radius, camera_radius, kth_radius):
the k-NN distance measured where the estimates are made (the pre-pass' lookup points; the
camera's diffuse hits without final gathering), not at the stored photons, so a crowd of
photons away from the lookups (a lamp in a narrow gap, docs/accuracy.md "night43") does
not shrink it."""
import importlib
import math
import os
import sys
from types import SimpleNamespace

import numpy as np
import pytest

# The module (engine.render is also the package's render function).
R = importlib.import_module("engine.render")
VI = importlib.import_module("engine.visualimportance")


class Shot(SimpleNamespace):
    """The part of a photons.Photons shot lookup_radius reads: position (N,3), len()."""

    def __len__(self):
        return len(self.position)


def _grid(n: int, size: float) -> np.ndarray:
    """(n*n, 3) points on an even n x n grid over [0, size]^2 at z = 0 (cell centres)."""
    c = (np.arange(n) + 0.5) * size / n
    x, y = np.meshgrid(c, c)
    return np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)


def test_crowd_away_from_the_lookups_leaves_the_radius(monkeypatch):
    """Photons spread evenly over a 2 m square (density rho = 2,500 / m^2) plus 40,000
    piled into a 5 cm corner patch: over the photons the median k-NN distance is the
    pile's (auto_radius, main's rule, shrinks ~10x); at lookups spread over the square it
    is the even photons' sqrt(k / (pi rho)), so the radius is twice that (within 10 %)."""
    k = 32
    even = _grid(100, 2.0)
    rng = np.random.default_rng(1)
    pile = np.concatenate([rng.random((40_000, 2)) * 0.05, np.zeros((40_000, 1))], axis=1)
    shot = Shot(position=np.concatenate([even, pile]).astype(np.float32))
    lookups = _grid(40, 2.0)
    monkeypatch.setattr(VI, "lookup_points", lambda ctx: lookups)
    ctx = SimpleNamespace(geo=SimpleNamespace(extent=100.0), lookups=None)
    want = 2.0 * math.sqrt(k / (math.pi * len(even) / 4.0))
    got = R.lookup_radius(ctx, shot, k)
    assert abs(got / want - 1) < 0.10, (got, want)
    photons = R.auto_radius(4.0, len(shot), k, 100.0, shot.position)
    assert photons < 0.2 * got, (photons, got)


def test_no_lookups_or_too_few_photons_fall_back(monkeypatch):
    """None (global_search_radius then takes auto_radius) without lookups or with at most
    k photons; never more than 0.1 x the scene's extent."""
    shot = Shot(position=_grid(20, 1.0).astype(np.float32))
    ctx = SimpleNamespace(geo=SimpleNamespace(extent=100.0), lookups=None)
    monkeypatch.setattr(VI, "lookup_points", lambda ctx: np.zeros((0, 3)))
    assert R.lookup_radius(ctx, shot, 8) is None
    monkeypatch.setattr(VI, "lookup_points", lambda ctx: _grid(4, 1.0))
    assert R.lookup_radius(ctx, shot, len(shot)) is None
    small = SimpleNamespace(geo=SimpleNamespace(extent=0.5), lookups=None)
    assert R.lookup_radius(small, shot, 300) == 0.05


def test_visual_importances_lookups_are_read_not_traced_again(monkeypatch):
    """ctx.lookups (visual importance's pre-pass points, global_emitters) are the points
    measured at; nothing is traced then. An empty set falls back (None)."""
    k = 16
    even = _grid(60, 1.0)
    shot = Shot(position=even.astype(np.float32))

    def traced(ctx):
        raise AssertionError("lookup_points traced again")
    monkeypatch.setattr(VI, "lookup_points", traced)
    ctx = SimpleNamespace(geo=SimpleNamespace(extent=100.0), lookups=_grid(10, 1.0))
    want = 2.0 * math.sqrt(k / (math.pi * len(even)))
    assert abs(R.lookup_radius(ctx, shot, k) / want - 1) < 0.1
    ctx.lookups = np.zeros((0, 3))
    assert R.lookup_radius(ctx, shot, k) is None


def test_the_radius_follows_the_lookups_density_not_the_photons():
    """kth_radius: points over a sparse half of a square (density 900 / m^2 against
    8,100 on the other half) give that half's 2 sqrt(k / (pi rho)); points on the dense
    half that half's; the median over both halves' points lies between."""
    k = 24
    sparse = _grid(30, 1.0)
    dense = _grid(90, 1.0) + [1.0, 0.0, 0.0]
    photons = np.concatenate([sparse, dense])
    inner = _grid(8, 0.6) + [0.2, 0.2, 0.0]  # away from the halves' border
    for points, rho in ((inner, 900.0), (inner + [1.0, 0.0, 0.0], 8100.0)):
        got = R.kth_radius(points, photons, k, 100.0)
        assert abs(got / (2.0 * math.sqrt(k / (math.pi * rho))) - 1) < 0.1, (got, rho)
    both = R.kth_radius(np.concatenate([inner, inner + [1.0, 0.0, 0.0]]), photons, k, 100.0)
    assert 2.0 * math.sqrt(k / (math.pi * 8100.0)) < both < 2.0 * math.sqrt(k / (math.pi * 900.0))
    assert R.kth_radius(np.zeros((0, 3)), photons, k, 100.0) is None


def test_without_final_gathering_the_radius_is_measured_at_the_camera_hits(monkeypatch):
    """camera_radius: the k-NN distance at the pre-pass' diffuse camera hits
    (visualimportance.diffuse_camera_hits), not at the photons: a pile of photons away
    from the hits leaves it at the even photons' 2 sqrt(k / (pi rho))."""
    k = 32
    even = _grid(100, 2.0)
    rng = np.random.default_rng(2)
    pile = np.concatenate([rng.random((40_000, 2)) * 0.05, np.zeros((40_000, 1))], axis=1)
    positions = np.concatenate([even, pile]).astype(np.float32)
    hits = _grid(40, 2.0)
    monkeypatch.setattr(VI, "diffuse_camera_hits",
                        lambda ctx, rays, rng: (hits, np.tile([0.0, 0.0, 1.0], (len(hits), 1)),
                                                np.zeros(len(hits))))
    ctx = SimpleNamespace(geo=SimpleNamespace(extent=100.0), settings=SimpleNamespace(seed=0))
    want = 2.0 * math.sqrt(k / (math.pi * len(even) / 4.0))
    assert abs(R.camera_radius(ctx, positions, k) / want - 1) < 0.10
    assert R.camera_radius(ctx, positions[:k], k) is None


def _spy_camera_radius(monkeypatch) -> list:
    """R.camera_radius replaced by itself keeping its answers: the list they go into."""
    plain, asked = R.camera_radius, []

    def spy(ctx, positions, k):
        asked.append(plain(ctx, positions, k))
        return asked[-1]
    monkeypatch.setattr(R, "camera_radius", spy)
    return asked


def test_a_render_without_final_gathering_reads_the_global_map_at_the_camera_radius(
        monkeypatch):
    """The global map's radius (Film.stats radius_global) is camera_radius's answer when
    final gathering is off (below the 0.1 x extent cap: measured, not capped)."""
    from engine import RenderSettings
    from engine.api import PaperScene, box_mesh
    from engine.scene import Material
    s = PaperScene(width=4, height=4)
    s.add_material(Material("wall", (0.6,) * 3))
    v, f = box_mesh((0, 0, 0), 2.0)
    s.add_triangles(v, f, "wall", name="room")
    s.add_point_light((0.0, 0.0, 0.5), power=100.0)
    s.set_camera((0, -0.9, -0.2), (0, 1, 0.3), view_angle=70)
    asked = _spy_camera_radius(monkeypatch)
    # No gather ray reads a map: the pre-pass' gather rays are not traced (mem45).
    monkeypatch.setattr(VI, "lookup_points", lambda *a, **kw: pytest.fail("traced"))
    film = s.render(RenderSettings(photons=20_000, caustic_photons=0, spp=1, seed=1,
                                   workers=1, final_gather=False, k_nearest=16))
    assert len(asked) == 1 and 0 < asked[0] < 0.1 * 2.0 * math.sqrt(3.0)
    assert film.stats["radius_global"] == asked[0]


def _portal_room_with_rug():
    """tests/test_portal.py's room lit through a roof pane by a world (portals: the glow
    shot is aimed), with a rough metal rug on its floor (a glow off a rough specular
    layer)."""
    sys.path.insert(0, os.path.dirname(__file__))
    from test_portal import _room
    from engine.scene import Material
    s = _room()
    s.add_material(Material("brushed", (0.6, 0.6, 0.6), metallic=0.5, roughness=0.5))
    s.add_plane((0, 0, 0.01), (0, 0, 1), 2.0, "brushed", name="rug")
    return s


def test_without_final_gathering_the_glow_share_is_capped_at_the_camera_radius(
        monkeypatch):
    """Without final gathering a glow shot's share is capped by the global map's radius
    at the camera's hits (camera_radius, measured once and reused by the maps), not by
    the pre-pass' gather rays (lookup_radius: 4,096 x 4 rays and a tree over the whole
    shot, which no estimate reads then; fast46)."""
    from engine import RenderSettings
    asked = _spy_camera_radius(monkeypatch)
    monkeypatch.setattr(R, "lookup_radius", lambda *a, **kw: pytest.fail("gather rays"))
    caps = []
    plain_share = R.glow_share
    monkeypatch.setattr(R, "glow_share", lambda ctx, shot, radius: (
        caps.append(radius), plain_share(ctx, shot, radius))[1])
    film = _portal_room_with_rug().render(RenderSettings(
        photons=20_000, caustic_photons=0, spp=1, seed=1, workers=1, final_gather=False))
    st = film.stats
    assert st.get("glow_photons_emitted", 0) > 0  # (a glow shot was traced)
    assert len(asked) == 1 and asked[0] is not None and asked[0] > 0
    assert caps == [asked[0]] and st["radius_global"] == asked[0]


def test_the_maps_build_no_tree_where_the_passed_radius_covers_the_shot(monkeypatch):
    """_build_maps: where the photon pass' global radius was measured over every photon
    of the shot (pre_radius's count == len(shot)) the gather chain builds no Morton tree
    over the shot and the spacing is that radius; measured elsewhere (count 0: at the
    lookups) it builds one, for the shot's own spacing (fast46)."""
    from engine import RenderSettings
    from engine.render import prepare_context
    ctx = prepare_context(_portal_room_with_rug(), RenderSettings(
        photons=8_000, caustic_photons=0, spp=1, seed=1, workers=1))
    try:
        shots = R.shoot_photons(ctx, {})
        shot, caustic = shots[0], shots[-1]
        built = []
        plain = R.KthTree

        def counted(*a, **kw):
            built.append(len(a[0]))
            return plain(*a, **kw)
        monkeypatch.setattr(R, "KthTree", counted)
        out = R._build_maps(ctx, shot, caustic, True, lambda: False,
                            pre_radius=(0.25, len(shot)))
        assert [n for n in built if n == len(shot)] == []
        assert out["radius_spacing"] == 0.25 and out["gather_short"] == 0.25
        built.clear()
        out = R._build_maps(ctx, shot, caustic, True, lambda: False,
                            pre_radius=(0.25, 0))
        assert [n for n in built if n == len(shot)] == [len(shot)]
        assert out["radius_spacing"] > 0 and out["gather_short"] == 0.25
    finally:
        ctx.accel.close()
