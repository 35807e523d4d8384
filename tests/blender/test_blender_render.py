"""Rendering through bpy.ops.render.render with the Photon Mapping engine."""
import time

import numpy as np
import pytest

from blender_helpers import (cheap, luminance, open_blend, project, read_layers, read_rgba,
                      render_exr)

pytestmark = pytest.mark.blender

PASSES = ("Combined", "Direct", "Indirect", "Caustic", "Specular", "Emission", "Photon Hits",
          "Depth", "Normal")


def test_passes_and_film_transparent(bpy_addon, tmp_path):
    bpy = bpy_addon
    scene = open_blend(bpy, "figure3_sphere.blend")
    cheap(scene, pct=25)
    scene.render.film_transparent = True
    vl = scene.view_layers[0]
    vl.use_pass_z = vl.use_pass_normal = True
    layers = read_layers(render_exr(bpy, scene, tmp_path / "f3.exr", multilayer=True))
    for name in PASSES:
        assert name in layers, f"missing pass {name}: {sorted(layers)}"
        assert layers[name].shape[:2] == (60, 80)
        assert np.all(np.isfinite(layers[name])), name
    comb = layers["Combined"]
    effects = sum(layers[n] for n in ("Direct", "Indirect", "Caustic", "Specular", "Emission"))
    np.testing.assert_allclose(effects, comb[..., :3], rtol=1e-4, atol=1e-5)
    alpha, depth = comb[..., 3], layers["Depth"][..., 0]
    assert alpha[0].max() == 0.0          # top row: background, transparent
    assert alpha[-1].min() == 1.0         # bottom row: floor
    assert np.all(depth[0] >= 1e9) and np.all(depth[-1] < 20)
    n = layers["Normal"][-1, 40]          # floor below the sphere faces up
    np.testing.assert_allclose(n, (0, 0, 1), atol=1e-3)
    assert comb[..., :3].max() > 0.1
    assert layers["Direct"].mean() > 0 and layers["Indirect"].mean() > 0


def test_resolution_percentage_and_border(bpy_addon, tmp_path):
    bpy = bpy_addon
    from addon import engine
    scene = open_blend(bpy, "figure3_sphere.blend")
    cheap(scene, pct=50, spp=1, photons=5000, caustic_photons=2000)
    r = scene.render
    r.use_border = True
    r.border_min_x, r.border_max_x = 0.25, 0.75
    r.border_min_y, r.border_max_y = 0.0, 0.5      # bottom half (Blender: y up)
    r.use_crop_to_border = False
    img = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "border.exr"))
    assert engine.last_render["region"] == (40, 60, 120, 120)
    assert (engine.last_render["width"], engine.last_render["height"]) == (80, 60)
    assert img.shape == (120, 160, 4)
    inside = img[60:, 40:120]
    assert inside[..., 3].min() == 1.0 and inside[..., :3].max() > 0.05
    assert img[:60].max() == 0.0 and img[:, :40].max() == 0.0 and img[:, 120:].max() == 0.0
    r.use_crop_to_border = True
    img2 = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "crop.exr"))
    assert img2.shape == (60, 80, 4)
    r.use_border = False


def test_border_covers_the_pixels_cycles_renders(open_ground, tmp_path):
    """Render Region: the rows and columns we fill are the ones Cycles fills. Blender
    multiplies the border (float32) by the size in float32 and truncates; in double
    0.9 x 120 is 107.99999 -> 107, one row short of Blender's 108 (new-user trial,
    newuser29: a region of 0.4..0.9 rendered rows 13..71 where Cycles renders 12..71)."""
    import bpy
    from addon import engine
    scene = open_ground
    cheap(scene, width=160, height=120, pct=100, spp=1, photons=2000, caustic_photons=0)
    r = scene.render
    r.use_border, r.use_crop_to_border = True, False
    r.border_min_x, r.border_max_x = 0.35, 0.7
    r.border_min_y, r.border_max_y = 0.45, 0.9
    try:
        ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))
        assert engine.last_render["region"] is not None
        scene.render.engine = "CYCLES"
        scene.cycles.samples, scene.cycles.use_denoising = 1, False
        theirs = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))
    finally:
        scene.render.engine = "PHOTONMAP"
        r.use_border = False
    filled = lambda img: (np.nonzero(img[..., 3].max(axis=1) > 0)[0],
                          np.nonzero(img[..., 3].max(axis=0) > 0)[0])
    (rows_c, cols_c), (rows_o, cols_o) = filled(theirs), filled(ours)
    assert (rows_c[0], rows_c[-1], cols_c[0], cols_c[-1]) == (12, 65, 56, 111)  # Blender's
    assert (rows_o[0], rows_o[-1], cols_o[0], cols_o[-1]) == (12, 65, 56, 111)
    assert engine.last_render["region"] == (56, 12, 112, 66)


def _caustic_contrast(bpy, scene, img):
    lum = luminance(img[..., :3])
    r0, c0 = project(bpy, scene, (0, 0, 0))
    spot = lum[r0 - 1:r0 + 2, c0 - 1:c0 + 2].mean()
    ring = []
    for x in (-0.45, 0.45):  # inside the sphere's shadow, outside the focus
        r1, c1 = project(bpy, scene, (x, 0, 0))
        ring.append(lum[r1 - 1:r1 + 2, c1 - 1:c1 + 2].mean())
    return spot, max(ring)


def test_caustic_fast(bpy_addon, tmp_path):
    """The glass ball's caustic shows: its focus (3 x 3 pixels) well above the ball's
    shadow beside it, in the Combined and Caustic passes. One 4-spp render's spot / ring
    spreads 2.8-7.5 over seeds 0-5 (s51; s50's main 3.0-5.5, the same means: spot 2.06 /
    2.04, ring 0.45 / 0.46), so one seed against 5x failed by the draw; seeds 0-3 averaged
    read ~4.4x, and the bound 3x stays far from a missing caustic (spot ~ ring, 1x)."""
    bpy = bpy_addon
    spots, rings, caustics = [], [], []
    for seed in range(4):
        scene = open_blend(bpy, "figure8_caustic.blend")
        cheap(scene, pct=50, spp=4, photons=50_000, caustic_photons=50_000)
        scene.photonmap.seed = seed
        layers = read_layers(render_exr(bpy, scene, tmp_path / f"f8_{seed}.exr",
                                        multilayer=True))
        spot, ring = _caustic_contrast(bpy, scene, layers["Combined"])
        r0, c0 = project(bpy, scene, (0, 0, 0))
        spots.append(spot)
        rings.append(ring)
        caustics.append(layers["Caustic"][r0 - 1:r0 + 2, c0 - 1:c0 + 2].mean())
    assert np.mean(spots) > 3 * np.mean(rings), (spots, rings)
    assert np.mean(caustics) > 1.0, caustics


def test_cancel_stops_early(bpy_addon, tmp_path):
    bpy = bpy_addon
    from addon import engine
    open_blend(bpy, "figure6_box.blend")   # ~10 s at its saved settings
    calls = {"n": 0}

    def hook():
        calls["n"] += 1
        return calls["n"] > 3   # "Esc" shortly after the render started

    engine.test_break_hook = hook
    try:
        t0 = time.perf_counter()
        bpy.ops.render.render()  # no exception: a cancelled render is not an error
        elapsed = time.perf_counter() - t0
    finally:
        engine.test_break_hook = None
    assert engine.last_render["cancelled"] is True
    assert elapsed < 3.0, elapsed


# --- the full example set at the saved settings (make test-all) ---------------------

def _check_figure3(bpy, scene, layers):
    img = layers["Combined"]
    r, c = project(bpy, scene, (0, -0.7, 1.3))  # front of the red sphere
    px = img[r - 1:r + 2, c - 1:c + 2, :3].mean(axis=(0, 1))
    assert px[0] > 3 * px[1] and px[0] > 3 * px[2], px


def _check_figure6(bpy, scene, layers):
    ind = layers["Indirect"]
    # Colour bleeding: the back wall next to the red wall is redder than next to the green
    # (high up, above the block; the camera looks down at the caustic, not the ceiling).
    rl, cl = project(bpy, scene, (-1.7, 1.99, 3.3))
    rr, cr = project(bpy, scene, (1.7, 1.99, 3.3))
    left = ind[rl - 1:rl + 2, cl - 1:cl + 2].mean(axis=(0, 1))
    right = ind[rr - 1:rr + 2, cr - 1:cr + 2].mean(axis=(0, 1))
    assert left[0] / left[1] > 1.2 * right[0] / right[1], (left, right)


def _check_figure7(bpy, scene, layers):
    # The left wall behind the blocker gets no direct light, only indirect.
    r, c = project(bpy, scene, (-1.99, -1.5, 1.5))
    direct = layers["Direct"][r - 1:r + 2, c - 1:c + 2].mean()
    indirect = layers["Indirect"][r - 1:r + 2, c - 1:c + 2].mean()
    assert indirect > 0.01 and direct < 0.1 * indirect, (direct, indirect)


def _check_figure8(bpy, scene, layers):
    spot, ring = _caustic_contrast(bpy, scene, layers["Combined"])
    assert spot > 5 * ring, (spot, ring)


EXAMPLES = {
    "figure3_sphere.blend": _check_figure3,
    "figure6_box.blend": _check_figure6,
    "figure7_blocker.blend": _check_figure7,
    "figure8_caustic.blend": _check_figure8,
}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_example_blend_renders(bpy_addon, tmp_path, name):
    bpy = bpy_addon
    from addon import engine
    scene = open_blend(bpy, name)
    r = scene.render
    assert (r.resolution_x, r.resolution_y, r.resolution_percentage) == (320, 240, 100)
    t0 = time.perf_counter()
    layers = read_layers(render_exr(bpy, scene, tmp_path / "out.exr", multilayer=True))
    elapsed = time.perf_counter() - t0
    img = layers["Combined"]
    assert img.shape == (240, 320, 4) and np.all(np.isfinite(img))
    assert img[..., :3].mean() > 0.01
    assert not engine.last_render["cancelled"]
    # Speed is the benchmarks' business (bench/), not a test's: report it only.
    print(f"{name}: engine {engine.last_render['stats']['time_total']:.1f} s "
          f"({elapsed:.1f} s with file I/O)")
    EXAMPLES[name](bpy, scene, layers)


@pytest.mark.slow
def test_ray_tracing_only_has_no_indirect(bpy_addon, tmp_path):
    bpy = bpy_addon
    scene = open_blend(bpy, "figure7_blocker.blend")
    cheap(scene, pct=50, spp=4)
    scene.photonmap.photon_mapping = False
    layers = read_layers(render_exr(bpy, scene, tmp_path / "rt.exr", multilayer=True))
    assert layers["Indirect"].max() == 0.0 and layers["Caustic"].max() == 0.0
    assert layers["Direct"].max() > 0.1
