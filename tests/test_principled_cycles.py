"""Issue 14's Principled scene against Cycles: brightness per object within 2 %.

The scene (tools/accuracy_scenes.py, "principled_spheres", 160x120) is what a new Blender
user builds: a row of Principled balls (dielectrics at roughness 0, 0.25, 0.5 and 1, clear
glass, two metals, a clear-coated and a sheen ball) on a rough Principled floor, one area
light and a dim grey world. The reference (tests/references/principled_spheres.npz and
.json, made by `.venv/bin/python tools/make_principled_reference.py`; this file never
renders Cycles) stores Cycles' image, per-pixel object labels (pixels an object covers
fully) and each object's mean RGB. Our engine renders the scene through the add-on at its
default settings; each object's mean brightness (mean of R, G, B over its pixels) must be
within 2 % of Cycles' (test_object_brightness_matches_cycles: what a user gets, one seed,
where the glass ball's ~3 % seed-to-seed scatter makes 2 % a draw), and the same, every
object, by renders whose own noise is below a third of that
(test_object_brightness_converged: the balls' rows at 768 spp over 8 seeds, with the
standard error measured). The reference's own noise is in the .json (a second Cycles render at
256 spp strays up to 3 % on the gold ball, 1 % on the glass: the 2048-spp reference's own
error is a third of that, see reference_noise). Equal-time and equal-FLIP
comparisons of the same scene: docs/accuracy_time.md (bench/bench_accuracy.py)."""
import json
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REF = os.path.join(ROOT, "tests", "references", "principled_spheres")
NAME = "principled_spheres"
TOLERANCE = 0.02

pytestmark = pytest.mark.blender

with open(REF + ".json") as f:
    META = json.load(f)

# Objects measured outside the 2 % at default settings, with the measured cause.
KNOWN_MISSES = {
    "Glass": ("noise, not a bias: tested by test_object_brightness_converged (2026-12-01, "
              "the balls' rows at 768 spp over seeds 0-7: 1.0033 +- 0.0043 s.e. of Cycles, "
              "per seed 0.986-1.018). A default render (128 spp, one gather ray from the "
              "indirect share) reads 1.048 at the test's seed; the ball's mean scatters by "
              "~3 % (s.d.) from seed to seed there (0.995-0.997 mean over seeds 0-31), as "
              "~7 camera samples a render land on the area light's sub-pixel images in and "
              "through the ball (its 8 brightest pixels: ~17 % of its light in 6 % of its "
              "pixels), so one render is within 2 % at about half the seeds; "
              "docs/accuracy_time_principled_spheres.md, ninth round."),
}


@pytest.fixture(scope="module")
def reference():
    with np.load(REF + ".npz") as z:
        return z["image"].astype(np.float32), z["labels"]


@pytest.fixture(scope="module")
def ours():
    """Our render at default settings: ((H, W, 3) float32, seconds)."""
    pytest.importorskip("bpy")
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import accuracy_scenes
    img, seconds = accuracy_scenes.render_ours(NAME)
    return img, seconds


# The converged check: the 2 % asked of every object, by renders whose own noise is well
# below it. One default render cannot show 2 % on every ball: ~7 of the Glass ball's camera
# samples land on the area light's sub-pixel images in and through it, so its mean
# scatters by ~3 % from seed to seed at 128 spp (the metal balls by ~2 %). Here the balls'
# rows (the box round every ball's labelled pixels, full-label for each ball, and the
# floor's pixels between and beside them) are rendered at CONVERGED_SPP with each of
# CONVERGED_SEEDS (other photon maps and camera streams), everything else at the default
# settings; per object the mean over the seeds must lie within TOLERANCE of Cycles with
# a standard error (the seeds' scatter / sqrt(K)) below TOLERANCE / 3.
CONVERGED_SEEDS = tuple(range(8))
CONVERGED_SPP = 768


def ball_rows(labels):
    """(x0, y0, x1, y1): the box round every labelled pixel but the floor's."""
    floor = META["objects"].index("Floor") + 1
    ys, xs = np.nonzero((labels > 0) & (labels != floor))
    return int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1


@pytest.fixture(scope="module")
def converged(reference):
    """{object: (ours / Cycles per seed (K,), pixels)} over the balls' rows."""
    pytest.importorskip("bpy")
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import accuracy_scenes
    from engine.render import render
    from engine.settings import RenderSettings
    ref_image, labels = reference
    x0, y0, x1, y1 = region = ball_rows(labels)
    pm_scene, kwargs = accuracy_scenes.export_ours(NAME)
    rows = labels[y0:y1, x0:x1]
    masks = {n: rows == i + 1 for i, n in enumerate(META["objects"])}
    want = {n: float(ref_image[y0:y1, x0:x1][m].mean()) for n, m in masks.items()}
    ratios = {n: [] for n in masks}
    for seed in CONVERGED_SEEDS:
        film = render(pm_scene, RenderSettings(**dict(kwargs, seed=seed, spp=CONVERGED_SPP)),
                      region=region)
        image = np.asarray(film.combined, np.float64)
        assert image.shape == (y1 - y0, x1 - x0, 3) and np.isfinite(image).all()
        for n, m in masks.items():
            ratios[n].append(float(image[m].mean()) / want[n])
    return {n: (np.array(r), int(masks[n].sum())) for n, r in ratios.items()}


def test_reference_is_stored(reference):
    """Small, finite, labelled: every object covers enough whole pixels for a mean, and
    the stored means are those of the stored image."""
    image, labels = reference
    assert image.shape == (META["height"], META["width"], 3)
    assert labels.shape == image.shape[:2] and labels.dtype == np.uint8
    assert np.isfinite(image).all() and (image >= 0).all()
    assert META["cycles_samples"] >= 1024
    assert os.path.getsize(REF + ".npz") < 150_000
    for i, name in enumerate(META["objects"]):
        mask = labels == i + 1
        assert mask.sum() == META["pixels"][name] >= 100, name
        np.testing.assert_allclose(image[mask].mean(axis=0), META["means"][name], rtol=1e-4)
        assert reference_noise(name) < TOLERANCE / 2, name


def reference_noise(name):
    """Estimated standard error of the reference's mean over object `name`: a Cycles
    render at n spp (another seed) strays from the N-spp reference by d, with
    d^2 ~ s^2 (1/n + 1/N), so the reference's own error is d sqrt(q / (1 + q)), q = n/N."""
    q = META["cycles_low_samples"] / META["cycles_samples"]
    return abs(META["cycles_low_ratio"][name] - 1) * (q / (1 + q)) ** 0.5


# One default render at 160x120: ~30 s on an idle 2-core machine (670 s at load 20), so slow.
@pytest.mark.slow
@pytest.mark.parametrize("name", META["objects"])
def test_object_brightness_matches_cycles(ours, reference, name):
    image, labels = ours
    _, ref_labels = reference
    assert image.shape == (META["height"], META["width"], 3)
    assert np.isfinite(image).all()
    mask = ref_labels == META["objects"].index(name) + 1
    got = image[mask].mean(axis=0)
    want = np.array(META["means"][name])
    ratio = float(got.mean() / want.mean())
    info = (f"{name}: ours/Cycles brightness {ratio:.4f} (RGB {np.round(got / want, 3)}) "
            f"over {int(mask.sum())} px")
    print(info)
    if name in KNOWN_MISSES and abs(ratio - 1) > TOLERANCE:
        pytest.xfail(KNOWN_MISSES[name] + " | " + info)
    assert abs(ratio - 1) <= TOLERANCE, info


# 8 region renders of 146x13 px at 768 spp: 93 CPU s (measured at load 6-7; ~50 s wall on an
# idle 2-core machine), 8 x 512 spp 70 CPU s left the Glass ball's s.e. at 0.0051 of 0.0067.
@pytest.mark.slow
@pytest.mark.parametrize("name", META["objects"])
def test_object_brightness_converged(converged, name):
    """Every object, no known misses: its mean over CONVERGED_SEEDS within 2 % of Cycles,
    measured with a standard error below a third of that. The balls' means are over their
    whole labels; the floor's over its pixels in the balls' rows (near the contacts and
    under the glass ball's focus: the hardest part of it), the whole floor being the
    default test's (its scatter by seed: 1.0010-1.0015 over seeds 0-3 even at 16 spp)."""
    ratios, pixels = converged[name]
    mean = float(ratios.mean())
    se = float(ratios.std(ddof=1) / np.sqrt(len(ratios)))
    info = (f"{name}: ours/Cycles {mean:.4f} +- {se:.4f} (s.e.) over seeds "
            f"{CONVERGED_SEEDS[0]}-{CONVERGED_SEEDS[-1]} at {CONVERGED_SPP} spp, {pixels} px;"
            f" per seed {np.round(ratios, 3)}")
    print(info)
    assert pixels >= 100, info
    assert se < TOLERANCE / 3, "too noisy to test 2 %: " + info
    assert abs(mean - 1) <= TOLERANCE, info


# Two default renders through the exported scene (seeds 0 and 1): ~16 CPU s idle.
@pytest.mark.slow
def test_flip_at_equal_time_no_worse_than_cycles(reference):
    """Issue 14: at equal time our HDR-FLIP is no worse than Cycles'. Equal time is fixed
    by a measurement, not timed here: Cycles' samples in our default render's CPU time on
    one machine (docs/accuracy_time.md: 177 spp), rounded up to cycles_equal_time's 192 spp
    (Cycles' FLIP at seeds 1, 2 stored in the reference's .json by
    tools/make_principled_reference.py). Our mean FLIP over seeds 0 and 1 at the default
    settings (the whole image, against the same 2048-spp reference) must not exceed
    Cycles' mean."""
    pytest.importorskip("bpy")
    pytest.importorskip("flip_evaluator")
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import accuracy_scenes
    from engine.render import render
    from engine.settings import RenderSettings
    ref_image, _ = reference
    cycles = META["cycles_equal_time"]
    assert cycles["samples"] >= 177 and len(cycles["flip"]) == 2
    pm_scene, kwargs = accuracy_scenes.export_ours(NAME)
    flips = []
    for seed in (0, 1):
        film = render(pm_scene, RenderSettings(**dict(kwargs, seed=seed)))
        image = np.asarray(film.combined, np.float32)
        assert image.shape == ref_image.shape and np.isfinite(image).all()
        flips.append(accuracy_scenes.flip(image, ref_image))
    info = (f"HDR-FLIP ours {np.round(flips, 5)} (seeds 0, 1) against Cycles at "
            f"{cycles['samples']} spp {cycles['flip']} (seeds {cycles['seeds']})")
    print(info)
    assert np.mean(flips) <= np.mean(cycles["flip"]), info
