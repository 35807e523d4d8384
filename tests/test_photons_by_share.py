"""The global shot's photons follow the indirect share (docs/performance.md
"worldcolour44"): a pilot shot measures the share (render.global_photon_count), and below
render.PHOTONS_SHARE_FULL the shot is settings.photons x share / PHOTONS_SHARE_FULL,
never under PHOTONS_LEAST of it (render.photons_for_share). Checked: the count's bounds
and monotony; a sunlit lawn (share ~1-2 %) shoots PHOTONS_LEAST of its photons and keeps
its Indirect pass's mean; a wall lit by its ground (share ~20 %) keeps every photon and
its film bit for bit (the pilot's own random stream touches nothing else); a lamp-lit
scene runs no pilot."""
import importlib
import math

import numpy as np
import pytest

from engine import RenderSettings

from test_share_sizing import _glow_yard, _lawn

render_mod = importlib.import_module("engine.render")  # (engine.render is also a function)


def test_photons_for_share_within_bounds():
    pfs, full, least = (render_mod.photons_for_share, render_mod.PHOTONS_SHARE_FULL,
                        render_mod.PHOTONS_LEAST)
    n = 400_000
    for share in (None, float("nan"), full, 0.5, 1.0):
        assert pfs(n, share) == n
    assert pfs(n, 0.0) == math.ceil(least * n) and pfs(n, 1e-6) == math.ceil(least * n)
    assert pfs(n, 0.8 * full) == math.ceil(n * (0.8 * full) / full)  # in proportion
    shares = np.linspace(0.0, 0.2, 41)
    counts = [pfs(n, s) for s in shares]
    assert all(a <= b for a, b in zip(counts, counts[1:]))  # monotone in the share


def test_a_small_share_shoots_fewer_photons_and_keeps_the_indirect_mean(monkeypatch):
    """The lawn (10k photons) over 4 seeds with the pilot's count and with every photon (PHOTONS_SHARE_FULL
    0: no pilot): PHOTONS_LEAST of the photons, the Indirect pass's mean the same within
    3 standard errors of the paired differences + 2 % (other photons: the maps' noise
    differs, the estimates' blur a little: radius x 1.41)."""
    def indirect(film):
        return float(np.asarray(film.passes()["indirect"], np.float64)[..., :3].mean())
    fewer, every = [], []
    for seed in range(1, 5):
        monkeypatch.setattr(render_mod, "PHOTONS_SHARE_FULL", 0.1)
        f = _lawn(seed=seed, spp=2, photons=10_000)
        share = f.stats["pilot_share"]
        assert 0.0 < share < 0.1 * render_mod.PHOTONS_LEAST, share
        assert f.stats["photons_emitted"] == math.ceil(10_000 * render_mod.PHOTONS_LEAST)
        assert f.stats["pilot_photons"] == int(10_000 * render_mod.PILOT_FRACTION)
        fewer.append(indirect(f))
        monkeypatch.setattr(render_mod, "PHOTONS_SHARE_FULL", 0.0)
        f = _lawn(seed=seed, spp=2, photons=10_000)
        assert f.stats["photons_emitted"] == 10_000 and "pilot_share" not in f.stats
        every.append(indirect(f))
    d = np.array(fewer) - np.array(every)
    assert min(every) > 0.0
    assert abs(d.mean()) < 3 * d.std(ddof=1) / math.sqrt(len(d)) + 0.02 * np.mean(every), (
        fewer, every)


def test_a_large_share_keeps_every_photon_and_the_film(monkeypatch):
    scene = _glow_yard()
    st = RenderSettings(photons=20_000, caustic_photons=5_000, spp=2, seed=4, workers=1)
    piloted = scene.render(st)
    assert piloted.stats["pilot_share"] > render_mod.PHOTONS_SHARE_FULL
    assert piloted.stats["photons_emitted"] == 20_000
    monkeypatch.setattr(render_mod, "PHOTONS_SHARE_FULL", 0.0)
    plain = scene.render(st)
    assert "pilot_share" not in plain.stats
    for k in ("direct", "indirect", "caustic", "specular"):
        np.testing.assert_array_equal(getattr(piloted, k), getattr(plain, k))


def test_no_pilot_without_a_light_at_infinity():
    """A lamp-lit scene (no world, no sun) shoots settings.photons without a pilot (the
    pilot's cost is spared where rooms lit by lamps have large shares)."""
    from engine.api import PaperScene
    from engine.scene import Material
    s = PaperScene(width=16, height=12, background=(0.0, 0.0, 0.0))
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), size=10.0, material="grey", name="ground")
    s.add_box((0, 0, 0.5), (1.0, 1.0, 1.0), "grey", name="box")
    s.add_point_light((1.0, -1.0, 3.0), power=500.0)
    s.set_camera((2.5, -4.0, 3.0), (0, 0, 0.4), view_angle=45)
    film = s.render(RenderSettings(photons=5_000, caustic_photons=0, spp=1, seed=1,
                                   workers=1))
    assert film.stats["indirect_share"] < render_mod.PHOTONS_SHARE_FULL  # (small, yet)
    assert "pilot_share" not in film.stats and film.stats["photons_emitted"] == 5_000
