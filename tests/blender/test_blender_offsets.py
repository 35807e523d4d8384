"""Ray offsets and the shadow terminator against Cycles (issue 12 items 5 and 6).

Tiny renders through the add-on and through Cycles in the same bpy session:
- a 10 cm cube and a 3 cm slab on ground planes of 4 m and 10 km under an area light:
  the contact shadow is as bright as Cycles', whatever the ground's size;
- a smooth-shaded 12 x 6 UV sphere under a grazing sun: no black facet notches where
  Cycles (Shadow Terminator > Geometry Offset 0.1, its default) has none.
"""
import math
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
W, H = 64, 48


@pytest.fixture(scope="module")
def acc(bpy_addon):
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import accuracy_scenes
    return accuracy_scenes


def _render(acc, scene, engine, cycles_samples=256, **ours):
    if engine == "CYCLES":
        acc.set_cycles(scene, cycles_samples, seed=1)
    else:
        acc.set_photonmap_defaults(scene)
        for k, v in ours.items():
            setattr(scene.photonmap, k, v)
    img, _ = acc.render_rgb(scene)
    return img.astype(np.float64)


def _contact_scene(acc, floor):
    mb = acc.mb
    scene = mb.reset()
    scene.render.resolution_x, scene.render.resolution_y = W, H
    grey = mb.material("grey", "diffuse", (0.8, 0.8, 0.8))
    mb.plane("Ground", floor, floor, grey)
    mb.box("Cube", 0.1, 0.1, 0.1, grey, (0.0, 0.0, 0.05))
    mb.box("Slab", 0.12, 0.12, 0.03, grey, (0.16, 0.0, 0.015))
    mb.light("Area", "AREA", (-0.25, 0.1, 0.5), 4.0, look_at=(0.2, -0.05, 0.0),
             shape="SQUARE", size=0.3)
    mb.camera((0.05, -0.3, 0.4), (0.05, 0.02, 0.0), 45.0)
    return scene


def _contact_region(img):
    """Mean luminance in the cube's shadow next to its base (the contact region)."""
    lum = 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]
    return float(lum[26:34, 30:44].mean()), lum


def test_contact_shadow_matches_cycles_on_small_and_huge_ground(acc):
    """Issue 12 item 5: ours was 0.238 / 0.380 / 0.496 on 4 m / 1 km / 10 km floors where
    Cycles stays the same; now ours stays the same too and matches Cycles."""
    values = {}
    for floor in (4.0, 1e4):
        for engine in ("CYCLES", "PHOTONMAP"):
            scene = _contact_scene(acc, floor)
            img = _render(acc, scene, engine, spp=32, photons=100_000)
            values[engine, floor] = _contact_region(img)[0]
    c4, c10k = values["CYCLES", 4.0], values["CYCLES", 1e4]
    o4, o10k = values["PHOTONMAP", 4.0], values["PHOTONMAP", 1e4]
    info = f"Cycles {c4:.4f} / {c10k:.4f}, ours {o4:.4f} / {o10k:.4f}"
    print(info)
    assert abs(c10k - c4) < 0.05 * c4, info  # Cycles: independent of the ground's size
    assert abs(o10k - o4) < 0.05 * o4, info
    assert abs(o4 - c4) < 0.1 * c4, info
    assert abs(o10k - c10k) < 0.1 * c10k, info


def _sphere_scene(acc, offset, sun_deg=80.0, shading_offset=0.0):
    mb = acc.mb
    scene = mb.reset()
    scene.render.resolution_x, scene.render.resolution_y = 96, 96
    grey = mb.material("grey", "diffuse", (0.8, 0.8, 0.8))
    ball = mb.sphere("Ball", 1.0, grey, (0.0, 0.0, 0.0), segments=12, rings=6)
    ball.shadow_terminator_geometry_offset = offset
    ball.shadow_terminator_shading_offset = shading_offset
    t = math.radians(sun_deg)
    mb.light("Sun", "SUN", (0, 0, 5), 3.0, look_at=(-math.sin(t), 0.3, 5.0 - math.cos(t)),
             angle=0.0)
    cam = mb.camera((0.0, -5.0, 0.0), (0.0, 0.0, 0.0), 30.0)
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 2.4
    return scene


def test_shadow_terminator_notches_as_in_cycles(acc):
    """Issue 12 item 6. Notch pixels: lit (> 20 % of the peak) with the geometry offset at
    Cycles' default 0.1, black (< 5 %) with it off. Cycles shows them only with the offset
    off, and ours the same pixels; with 0.1 no pixel is black in one engine and lit in the
    other (ours had 145 notches at 1080p before)."""
    img = {}
    for offset in (0.0, 0.1):
        img["cycles", offset] = _render(acc, _sphere_scene(acc, offset), "CYCLES",
                                        cycles_samples=64)[..., 1]
        img["ours", offset] = _render(acc, _sphere_scene(acc, offset), "PHOTONMAP", spp=16,
                                      photon_mapping=False)[..., 1]
    peak = img["cycles", 0.1].max()

    def notches(engine):
        return (img[engine, 0.1] > 0.2 * peak) & (img[engine, 0.0] < 0.05 * peak)

    n_cycles, n_ours = notches("cycles"), notches("ours")
    a, b = img["cycles", 0.1], img["ours", 0.1]
    mismatch = np.count_nonzero(((a > 0.2 * peak) & (b < 0.05 * peak))
                                | ((b > 0.2 * peak) & (a < 0.05 * peak)))
    lit = a > 0.2 * peak
    info = (f"notch pixels: Cycles {n_cycles.sum()}, ours {n_ours.sum()}, shared "
            f"{np.count_nonzero(n_cycles & n_ours)}; offset 0.1 mismatches {mismatch}; "
            f"lit mean Cycles {a[lit].mean():.4f} ours {b[lit].mean():.4f}")
    print(info)
    assert n_cycles.sum() >= 10, info  # the scene shows the fault
    assert np.count_nonzero(n_cycles & n_ours) >= 0.8 * n_cycles.sum(), info
    assert abs(int(n_ours.sum()) - int(n_cycles.sum())) <= 0.2 * n_cycles.sum(), info
    assert mismatch <= 2, info
    assert abs(b[lit].mean() - a[lit].mean()) < 0.03 * a[lit].mean(), info


def test_shadow_terminator_shading_offset_as_in_cycles(acc):
    """Shading Offset 0.6 on the coarse sphere: ours dims the terminator as Cycles does
    (compared over the pixels either engine lights)."""
    cyc = _render(acc, _sphere_scene(acc, 0.1, 60.0, 0.6), "CYCLES", cycles_samples=64)[..., 1]
    ours = _render(acc, _sphere_scene(acc, 0.1, 60.0, 0.6), "PHOTONMAP", spp=16,
                   photon_mapping=False)[..., 1]
    plain = _render(acc, _sphere_scene(acc, 0.1, 60.0, 0.0), "CYCLES", cycles_samples=64)[..., 1]
    lit = (cyc > 0.02 * cyc.max()) | (ours > 0.02 * cyc.max())
    info = (f"lit sum Cycles {cyc[lit].sum():.2f} ours {ours[lit].sum():.2f} "
            f"(Cycles without the offset {plain[lit].sum():.2f})")
    print(info)
    assert plain[lit].sum() > 1.05 * cyc[lit].sum(), info  # the setting matters here
    assert abs(ours[lit].sum() - cyc[lit].sum()) < 0.02 * cyc[lit].sum(), info
    # Per pixel (antialiased silhouettes and Cycles' 64-sample noise aside).
    assert np.percentile(np.abs(ours - cyc)[lit], 95) < 0.05 * cyc.max(), info
