"""Cycles' Light Paths > Clamping (engine/sampleclamp.py): per-sample contributions held to
3 x the UI value (R + G + B), direct at Cycles' bounce 0, indirect after it; off (0) keeps
every bit."""
import math

import numpy as np
import pytest

from engine import RenderSettings, sampleclamp
from engine.api import cornell_box
from engine.cli import build_parser
from engine.scene import Camera, Material
from engine.api import PaperScene
from helpers import top_down_plane

DIRECT_ONLY = dict(photon_mapping=False, max_depth=0)


def _sun_plane(rho=0.6, E=3.0, theta_deg=30.0, res=16):
    s = top_down_plane(rho, res=res)
    th = math.radians(theta_deg)
    s.add_sun(direction=(math.sin(th), 0, -math.cos(th)), strength=E)
    return s, rho * E * math.cos(th) / math.pi


def test_settings_take_cycles_ui_values_and_reject_bad_ones():
    s = RenderSettings(clamp_direct=2, clamp_indirect=10)
    assert (s.clamp_direct, s.clamp_indirect) == (2.0, 10.0)
    assert sampleclamp.limits(s) == (6.0, 30.0)  # Cycles: 3 x the UI value
    assert sampleclamp.limits(RenderSettings()) == (np.inf, np.inf)  # 0 = off
    assert not sampleclamp.enabled(RenderSettings())
    for bad in (-1.0, 2e8, True, "10", float("nan"), None):
        with pytest.raises(ValueError, match="clamp_indirect"):
            RenderSettings(clamp_indirect=bad)
    args = build_parser().parse_args(["render", "scene.toml", "-o", "x.png",
                                      "--clamp-direct", "0", "--clamp-indirect", "10"])
    assert (args.clamp_direct, args.clamp_indirect) == (0.0, 10.0)
    with pytest.raises(SystemExit):
        build_parser().parse_args(["render", "scene.toml", "-o", "x.png",
                                   "--clamp-indirect", "-3"])


def test_clamp_scales_colour_keeps_hue_and_zeroes_non_finite():
    rgb = np.array([[1.0, 2.0, 3.0], [0.1, 0.1, 0.1], [np.inf, 0.0, 0.0], [np.nan, 1, 1]])
    tp = np.array([[2.0, 2.0, 2.0], [1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 1.0, 1.0]])
    out = sampleclamp.clamp(rgb, tp, None, 6.0)
    # Row 0: contribution (2, 4, 6), sum 12 > 6: halved, hue kept.
    assert np.allclose(out[0] * tp[0], [1.0, 2.0, 3.0])
    assert np.array_equal(out[1], rgb[1])
    assert np.array_equal(out[2:], np.zeros((2, 3)))
    # A limit per row.
    out = sampleclamp.clamp(np.array([[2.0, 2.0, 2.0], [2.0, 2.0, 2.0]]), None, None,
                            np.array([12.0, 3.0]))
    assert np.array_equal(out[0], [2.0, 2.0, 2.0]) and np.allclose(out[1], [1.0, 1.0, 1.0])
    # Nothing over: the very array back (bits kept).
    fine = rgb[:2].copy()
    assert sampleclamp.clamp(fine, tp[:2], None, 100.0) is fine


def test_sun_lit_plane_direct_radiance_is_clamped_exactly():
    """A white plane under a sun: every sample's direct radiance is R (grey); Clamp Direct
    c < R gives exactly c per channel (3R scaled to 3c), above R nothing changes (bits);
    Clamp Indirect does not touch direct light."""
    s, R = _sun_plane()
    off = s.render(RenderSettings(spp=2, **DIRECT_ONLY)).combined
    assert np.allclose(off, R, rtol=1e-6)
    above = s.render(RenderSettings(spp=2, clamp_direct=1.01 * R, **DIRECT_ONLY)).combined
    assert np.array_equal(above, off)
    c = 0.4 * R
    low = s.render(RenderSettings(spp=2, clamp_direct=c, **DIRECT_ONLY)).combined
    assert np.allclose(low, c, rtol=1e-6)
    ind = s.render(RenderSettings(spp=2, clamp_indirect=c, **DIRECT_ONLY)).combined
    assert np.array_equal(ind, off)


def test_world_seen_directly_and_through_a_mirror_is_direct_light():
    """Cycles clamps an emitter or the world met by the camera ray, or by the first hit's
    scattered ray, as direct (film_write_background: bounce - 1 <= 0): a constant world
    seen past a mirror is held by Clamp Direct, not by Clamp Indirect."""
    W = 2.0
    s = PaperScene(width=8, height=8, background=(W, W, W))
    s.add_material(Material("mirror", (1.0, 1.0, 1.0), metallic=1.0, roughness=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 2.0, "mirror", name="mirror")
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO", ortho_scale=4.0)
    base = dict(spp=1, photon_mapping=False)
    off = s.render(RenderSettings(**base))
    seen, mirrored = off.emission, off.specular
    assert seen.max() == pytest.approx(W, rel=1e-6)
    assert mirrored.max() > 0.5 * W  # the mirror's middle shows the world
    d = s.render(RenderSettings(clamp_direct=0.25 * W, **base))
    assert np.allclose(d.emission[seen > 0], 0.25 * W, rtol=1e-6)
    assert np.all(d.specular <= 0.25 * W * (1 + 1e-6))
    assert np.array_equal(d.specular > 0, mirrored > 0)
    i = s.render(RenderSettings(clamp_indirect=0.25 * W, **base))
    assert np.array_equal(i.emission, seen) and np.array_equal(i.specular, mirrored)


@pytest.fixture(scope="module")
def box_renders():
    scene = cornell_box(24, 18)
    base = dict(workers=1, spp=4, photons=3000, caustic_photons=2000, seed=3)
    return {k: scene.render(RenderSettings(**base, **kw)) for k, kw in (
        ("off", {}), ("high", dict(clamp_direct=1e8, clamp_indirect=1e8)),
        ("ind", dict(clamp_indirect=0.001)), ("dir", dict(clamp_direct=0.02)))}


def test_a_clamp_above_every_sample_changes_no_bit(box_renders):
    off, high = box_renders["off"], box_renders["high"]
    for name, img in off.passes().items():
        assert np.array_equal(img, high.passes()[name]), name


def test_clamp_indirect_holds_every_pixel_of_the_photon_estimates(box_renders):
    """Each sample's caustic estimate (taken at a stride of samples and weighed up) is at
    most 3c, so the pixel's mean is too; the direct and emission passes (Cycles' bounce 0)
    are untouched."""
    off, ind = box_renders["off"], box_renders["ind"]
    c3 = 3 * 0.001
    assert np.array_equal(ind.direct, off.direct) and np.array_equal(ind.emission, off.emission)
    caustic = ind.caustic.sum(axis=2)
    assert caustic.max() <= c3 * (1 + 1e-5)
    assert off.caustic.sum(axis=2).max() > c3  # the clamp had work to do
    assert ind.indirect.sum() < off.indirect.sum()
    assert np.all(ind.indirect.sum(axis=2) <= off.indirect.sum(axis=2) * (1 + 1e-6) + 1e-7)


def test_clamp_direct_holds_every_pixel_of_the_direct_light(box_renders):
    off, d = box_renders["off"], box_renders["dir"]
    assert d.direct.sum(axis=2).max() <= 3 * 0.02 * (1 + 1e-5)
    assert off.direct.sum(axis=2).max() > 3 * 0.02
    assert np.array_equal(d.caustic, off.caustic) and np.array_equal(d.indirect, off.indirect)
