"""Pixel filter (engine/pixelfilter.py): camera rays drawn from the filter's distribution,
as Cycles samples its Blackman-Harris / Gaussian / box filter by importance.

Analytic checks: the table's samples follow the filter; a sharp emissive edge seen by an
orthographic camera gives, per pixel, the filter's mass beyond the edge; a sub-pixel
bright line keeps its total (the filter is normalised) and spreads as the filter's
weights; the width is honoured. tests/blender/test_pixel_filter_cycles.py compares the
same profiles with Cycles."""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.api import PaperScene
from engine.pixelfilter import (PIXEL_FILTERS, filter_radius, filter_table, filter_weight,
                                lookup_filter)
from engine.scene import Camera, Material

W, H = 32, 16


def _cdf(kind, width, x):
    """The filter's CDF at offsets x (pixels from the centre), integrated directly from
    filter_weight on a fine grid (independent of the table's construction)."""
    r = filter_radius(kind, width)
    grid = np.linspace(-r, r, 200_001)
    f = filter_weight(kind, width, grid)
    c = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]))])
    return np.interp(x, grid, c / c[-1], left=0.0, right=1.0)


@pytest.mark.parametrize("kind,width", [("blackman_harris", 1.5), ("blackman_harris", 3.0),
                                        ("gaussian", 1.5), ("gaussian", 0.7)])
def test_table_samples_follow_the_filter(kind, width):
    t = filter_table(kind, width)
    r = filter_radius(kind, width)
    assert t.shape == (1024,) and np.all(np.diff(t) >= 0)
    np.testing.assert_allclose([t[0], t[-1]], [0.5 - r, 0.5 + r], atol=1e-9)
    np.testing.assert_allclose(t + t[::-1], 1.0, atol=1e-12)  # symmetric about the centre
    u = (np.arange(200_000) + 0.5) / 200_000
    x = np.sort(lookup_filter(t, u) - 0.5)
    # Kolmogorov distance between the samples and the filter's own CDF
    assert np.abs(_cdf(kind, width, x) - u).max() < 2e-3


def test_blackman_harris_at_blender_default_is_narrower_than_its_support():
    """Blender's default (1.5 px): support +-1.5 px, yet the standard deviation is only
    0.42 px (the box's is 0.29): a soft but not blurry image."""
    x = lookup_filter(filter_table("blackman_harris", 1.5),
                      (np.arange(100_000) + 0.5) / 100_000) - 0.5
    assert 0.40 < x.std() < 0.43
    assert np.abs(x).max() <= 1.5 + 1e-9


def test_box_and_zero_width():
    assert filter_table("box", 1.5).shape == (0,)  # identity: plain jitter, unchanged rays
    u = np.array([0.0, 0.3, 0.99])
    np.testing.assert_array_equal(lookup_filter(filter_table("box", 7.0), u), u)
    np.testing.assert_array_equal(lookup_filter(filter_table("blackman_harris", 0.0), u), 0.5)


@pytest.mark.parametrize("bad", [dict(pixel_filter="lanczos"), dict(pixel_filter=3),
                                 dict(filter_width=-1.0), dict(filter_width=float("nan")),
                                 dict(filter_width=1e4), dict(filter_width="wide"),
                                 dict(filter_width=True)])
def test_bad_settings_are_refused_by_name(bad):
    name = next(iter(bad))
    with pytest.raises(ValueError, match=name):
        RenderSettings(**bad)
    assert set(PIXEL_FILTERS) == {"box", "gaussian", "blackman_harris"}
    assert RenderSettings(pixel_filter="Blackman_Harris").pixel_filter == "blackman_harris"


def _strip_scene(x0, x1, radiance=1.0):
    """An emissive strip x0 <= x <= x1 (pixel units across the image; tall enough to fill
    it) on black, seen straight down by an orthographic camera one world unit per pixel."""
    s = PaperScene(width=W, height=H)
    s.add_material(Material("glow", base_color=(0, 0, 0), emission=(radiance,) * 3))
    verts = np.array([[x0 - W / 2, -H, 0], [x1 - W / 2, -H, 0], [x1 - W / 2, H, 0],
                      [x0 - W / 2, H, 0]], float)
    s.add_triangles(verts, np.array([[0, 1, 2], [0, 2, 3]]), "glow", name="strip")
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO", ortho_scale=W)
    return s


def _profile(scene, spp=256, **kw):
    st = RenderSettings(spp=spp, photon_mapping=False, seed=3, **kw)
    img = render(scene, st).combined
    return img[..., 0].mean(axis=0).astype(np.float64)  # mean over the rows, per column


def _expected(kind, width, x0, x1):
    c = np.arange(W) + 0.5
    return _cdf(kind, width, x1 - c) - _cdf(kind, width, x0 - c)


@pytest.mark.parametrize("kind,width", [("blackman_harris", 1.5), ("blackman_harris", 3.0),
                                        ("gaussian", 1.5), ("box", 1.0)])
def test_edge_profile_is_the_filter_mass_beyond_the_edge(kind, width):
    """A step edge at x = 16.3 px: pixel i sees the fraction of its filter that lies on
    the bright side. 256 stratified samples per pixel, 16 rows: error < 0.012."""
    x0, x1 = 16.3, W + 8.0
    got = _profile(_strip_scene(x0, x1), pixel_filter=kind, filter_width=width)
    want = _expected(kind, width, x0, x1)
    np.testing.assert_allclose(got, want, atol=0.012)
    if kind != "box":  # really wider than the box: light leaks past the edge pixel
        assert got[15] > 0.012  # the box leaves pixel 15 black


def test_sub_pixel_line_takes_the_filter_shape():
    """A line 0.2 px wide over a pixel centre: its light spreads as the filter's weights
    and the width is honoured (3 columns at 1.5 px, 5 at 3 px). Its total
    over the columns is 0.2 x the sum of the filter's weights at the pixel centres around
    it: 1.03 for Blackman-Harris 1.5 px (its shifted copies are not a partition of unity,
    in Cycles as here); the box keeps exactly 0.2 in its own pixel."""
    x0, x1 = 15.4, 15.6  # centred on pixel 15
    prof = {}
    for width in (1.5, 3.0):
        got = _profile(_strip_scene(x0, x1), spp=1024, pixel_filter="blackman_harris",
                       filter_width=width)
        want = _expected("blackman_harris", width, x0, x1)
        np.testing.assert_allclose(got, want, atol=0.004)
        np.testing.assert_allclose(got.sum(), want.sum(), rtol=0.01)
        assert abs(want.sum() / 0.2 - 1) < 0.04
        prof[width] = got
    lit = {w: np.nonzero(p > 1e-3)[0].tolist() for w, p in prof.items()}
    assert lit == {1.5: [14, 15, 16], 3.0: [13, 14, 15, 16, 17]}, lit
    box = _profile(_strip_scene(x0, x1), spp=256, pixel_filter="box")
    np.testing.assert_allclose(box[15], 0.2, atol=0.01)  # the box keeps it in its pixel
    assert box.sum() == pytest.approx(box[15], abs=1e-9)
