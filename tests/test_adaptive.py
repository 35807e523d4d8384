"""Adaptive sampling (engine/adaptive.py, Cycles' Noise Threshold): off by default and then
the plain camera pass; on, unbiased against fixed spp, fewer samples where the image is
smooth, the same image for any thread count, min samples and spp respected."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.adaptive import (Schedule, auto_min_samples, class_a, dilate_unconverged,
                             pixel_error, schedule_warnings)
from engine.api import cornell_box
from engine.integrator import CAUSTIC_SAMPLES_PER_PIXEL, SECONDARY_SAMPLES_PER_PIXEL
from engine.progressive import pass_settings

# A Lambert box lit by an area light under its ceiling (no glass: the noise is the light's
# and the gather's), small enough for a few renders a test.
W, H = 32, 24
BASE = dict(photons=6000, caustic_photons=2000, spp=64)


@pytest.fixture(scope="module")
def box():
    return cornell_box(W, H, glass_sphere=False)


def test_cycles_auto_min_samples_and_schedule():
    # Cycles' comment in Integrator::get_adaptive_sampling: 0.1 -> 32, 0.01 -> 64,
    # 0.001 -> 128; never fewer than 4.
    assert [auto_min_samples(t) for t in (0.1, 0.01, 0.001)] == [32, 64, 128]
    assert auto_min_samples(1.0) == 16
    assert Schedule(0.01, 0, 128).min_effective == 64
    assert Schedule(0.01, 2, 128).min_effective == 4
    assert Schedule(0.01, 500, 128).min_effective == 128
    # Cycles' need_filter: after 0-based sample s > min_samples with s % 16 == 15 (the
    # first at (min + 1) | 15): rounds of 80, then 16 samples, the last one capped at spp.
    assert Schedule(0.01, 0, 128).rounds() == [(0, 80, True), (80, 96, True),
                                               (96, 112, True), (112, 128, False)]
    assert Schedule(0.1, 0, 100).rounds() == [(0, 48, True), (48, 64, True), (64, 80, True),
                                              (80, 96, True), (96, 100, False)]
    assert Schedule(0.01, 0, 16).rounds() == [(0, 16, False)]  # min samples >= spp


def test_a_threshold_that_can_stop_no_pixel_is_said():
    """A new-user trial set Noise Threshold 0.05 at 32 samples: the automatic Min Samples
    (40) put the first check after sample 48, so nothing changed, silently. Said now, with
    what would make it act; not said where a check comes before Max Samples."""
    (w,) = schedule_warnings(0.05, 0, 32)
    assert "no effect at Max Samples 32" in w and "automatic for this threshold: 40" in w
    assert "above 48 or lower Min Samples" in w
    (w,) = schedule_warnings(0.05, 3, 8)  # Min Samples at its floor: only Max Samples helps
    assert "above 16" in w and "lower Min Samples" not in w
    for t, m, spp in ((0.05, 0, 64), (0.05, 8, 32), (0.0, 0, 16), (0.01, 0, 81)):
        assert schedule_warnings(t, m, spp) == [], (t, m, spp)
        assert t == 0.0 or any(c for _, _, c in Schedule(t, m, spp).rounds())
    for t, m, spp in ((0.05, 0, 32), (0.01, 0, 80), (0.1, 20, 32)):
        assert not any(c for _, _, c in Schedule(t, m, spp).rounds())
        assert schedule_warnings(t, m, spp)


def test_the_warning_comes_with_the_render(box):
    from engine.render import render
    told = []
    film = render(box, RenderSettings(seed=1, photons=2000, caustic_photons=500, spp=8,
                                      adaptive_threshold=0.05), on_warning=told.append)
    assert sum("Noise Threshold 0.05 has no effect" in w for w in film.warnings) == 1
    assert sum("Noise Threshold 0.05 has no effect" in w for w in told) == 1
    assert (film.sample_count == 8).all()


def test_halves_split_the_estimate_taking_samples():
    """Half A takes half of the samples, and half of those that take the strided caustic
    and secondary estimates (else a pixel lit by caustics could never converge)."""
    spp = 128
    strides = [-(-spp // k) for k in (CAUSTIC_SAMPLES_PER_PIXEL, SECONDARY_SAMPLES_PER_PIXEL)]
    sub = np.arange(80)
    counts = []
    for r in range(4):
        a = class_a(sub if r == 0 else np.arange(16), r, strides)
        counts.append(a)
        assert abs(int(a.sum()) - len(a) / 2) <= 1
    caustic_a = sum(int(a[::strides[0]].sum()) for a in counts)
    caustic_n = sum(len(a[::strides[0]]) for a in counts)
    assert abs(caustic_a - caustic_n / 2) <= 1
    secondary = [bool(a[0]) for a in counts]  # each round's first sample takes it
    assert secondary.count(True) == 2


def test_pixel_error_and_dilation_follow_cycles():
    full = np.array([[2.0, 2.0, 2.0], [0.2, 0.2, 0.2]])  # sums over 4 samples
    half = np.array([[1.0, 1.0, 1.0], [0.06, 0.06, 0.06]])  # sums over 2 of them
    err = pixel_error(full, np.array([4, 4]), half, np.array([2, 2]))
    # pixel 0: I = 0.5 each, A = 0.5: no error; pixel 1: I = 0.05, A = 0.03,
    # (3 x 0.02) / (1e-4 + sqrt(0.15))
    assert err[0] == 0.0
    assert err[1] == pytest.approx(0.06 / (1e-4 + math.sqrt(0.15)))
    # bright: divided by the intensity itself (R+G+B >= 1)
    e = pixel_error(np.array([[3.0, 3.0, 3.0]]), np.array([1]), np.array([[1.0, 1.0, 1.0]]),
                    np.array([1]))
    assert e[0] == pytest.approx(6.0 / (1e-4 + 9.0))
    conv = np.ones((5, 5), bool)
    conv[2, 2] = False
    out = dilate_unconverged(conv)
    assert (~out).sum() == 9 and not out[1:4, 1:4].any()


def test_settings_validation():
    assert RenderSettings().adaptive_threshold == 0.0
    assert RenderSettings().adaptive_min_samples == 0
    for bad in (-0.01, 1.5, float("nan"), True, "0.01", None):
        with pytest.raises(ValueError, match="adaptive_threshold"):
            RenderSettings(adaptive_threshold=bad)
    for bad in (-1, 2.5, 70000):
        with pytest.raises(ValueError, match="adaptive_min_samples"):
            RenderSettings(adaptive_min_samples=bad)
    # progressive passes take all their samples (a warning says so)
    assert pass_settings(RenderSettings(adaptive_threshold=0.01), 1).adaptive_threshold == 0


def test_off_is_the_plain_pass(box):
    a = box.render(RenderSettings(seed=3, **BASE))
    b = box.render(RenderSettings(seed=3, adaptive_threshold=0.0, adaptive_min_samples=9,
                                  **BASE))
    assert a.sample_count is None and "adaptive_mean_spp" not in a.stats
    np.testing.assert_array_equal(a.combined, b.combined)


def test_threads_min_samples_and_savings(box):
    st = dict(seed=4, adaptive_threshold=0.02, adaptive_min_samples=8, **BASE)
    one = box.render(RenderSettings(workers=1, **st))
    two = box.render(RenderSettings(workers=2, **st))
    np.testing.assert_array_equal(one.combined, two.combined)
    np.testing.assert_array_equal(one.sample_count, two.sample_count)
    n = one.sample_count
    assert n.shape == (H, W)
    assert n.min() >= 16 and n.max() <= BASE["spp"]  # first check after 16 samples
    assert one.stats["adaptive_mean_spp"] == pytest.approx(n.mean())
    assert one.stats["adaptive_mean_spp"] < BASE["spp"]
    # Min Samples = spp: every pixel takes spp samples
    full = box.render(RenderSettings(seed=4, adaptive_threshold=0.02,
                                     adaptive_min_samples=BASE["spp"], **{
                                         k: v for k, v in BASE.items()}))
    assert (full.sample_count == BASE["spp"]).all()
    # a threshold every pixel meets: all stop at the first check past Min Samples 20
    loose = box.render(RenderSettings(seed=4, adaptive_threshold=1.0, adaptive_min_samples=20,
                                      **BASE))
    assert (loose.sample_count == 32).all()


def test_unbiased_and_smooth_regions_stop_first(box):
    """The mean image over seeds matches fixed spp within the seeds' noise; the pixels that
    stopped at the first check are the ones whose fixed-spp value varies least from seed
    to seed (relative to their brightness)."""
    seeds = range(4)
    fixed = np.array([box.render(RenderSettings(seed=s, **BASE)).combined for s in seeds])
    films = [box.render(RenderSettings(seed=s, adaptive_threshold=0.02,
                                       adaptive_min_samples=8, **BASE)) for s in seeds]
    adapt = np.array([f.combined for f in films])
    # whole-image and per-quadrant means (noise: the seeds' spread)
    for ys, xs in ((slice(None), slice(None)), (slice(0, H // 2), slice(0, W // 2)),
                   (slice(H // 2, H), slice(W // 2, W)), (slice(0, H // 2), slice(W // 2, W)),
                   (slice(H // 2, H), slice(0, W // 2))):
        f = fixed[:, ys, xs].mean(axis=(1, 2, 3))
        a = adapt[:, ys, xs].mean(axis=(1, 2, 3))
        se = math.sqrt(f.var(ddof=1) / len(f) + a.var(ddof=1) / len(a))
        assert abs(a.mean() - f.mean()) <= max(4 * se, 0.005 * f.mean()), (ys, xs)
    count = np.array([f.sample_count for f in films]).mean(axis=0)
    lum = fixed.mean(axis=(0, 3))
    rel = fixed.std(axis=0, ddof=1).mean(axis=2) / np.maximum(lum, 1e-3)
    early, late = count <= np.percentile(count, 25), count >= np.percentile(count, 75)
    assert early.any() and late.any() and count[early].mean() < count[late].mean()
    assert rel[early].mean() < rel[late].mean()
