"""Brushed metal against Cycles (issue 14): a Principled metal plate (roughness 0.35,
Anisotropic 0.8) and a Glossy BSDF plate (Anisotropy 0.7 and -0.6, rotated) under a
small area light, rendered by our engine and by the bpy wheel's Cycles at 64 spp
(tools/aniso_cycles.py). The plate sits off the world origin, so the highlight follows the
radial tangent about the object's own Z axis (the add-on's exported 'radial_tangent').
Measured (docs/performance.md, `aniso`): image totals 0.999..1.002 x Cycles', every bright
region within 0.5 % (1.7 % on one region of the Glossy plate), the highlight's long axis
within 0.4 degrees and its two lengths within 1.5 %."""
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

pytestmark = [pytest.mark.blender, pytest.mark.slow]


@pytest.fixture(scope="module")
def tool(bpy_addon):
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import aniso_cycles
    return aniso_cycles


@pytest.mark.parametrize("node, aniso, rot", [("principled", 0.8, 0.0),
                                              ("principled", 0.8, 0.2),
                                              ("glossy", 0.7, 0.0),
                                              ("glossy", -0.6, 0.1)])
def test_brushed_highlight_matches_cycles(bpy_addon, tool, node, aniso, rot):
    r = tool.compare(bpy_addon, 64, aniso, rot, node)
    assert abs(r["total"] - 1.0) < 0.02, r["total"]
    ro, rc = r["regions_ours"], r["regions_cycles"]
    bright = rc > 0.02 * rc.max()
    ratio = ro[bright] / rc[bright]
    assert np.all(np.abs(ratio - 1.0) < 0.03), ratio
    (ao, lo, so, _), (ac, lc, sc, _) = r["moments_ours"], r["moments_cycles"]
    assert abs((ao - ac + 90.0) % 180.0 - 90.0) < 3.0, (ao, ac)
    assert abs(lo / lc - 1.0) < 0.05 and abs(so / sc - 1.0) < 0.05, (lo, lc, so, sc)
    # elongated: the anisotropic highlight is not round
    assert lc / sc > 1.5


def test_isotropic_plate_is_round(bpy_addon, tool):
    """Anisotropic 0: the same plate's highlight as Cycles' and much rounder than at 0.8
    (the measurement sees the anisotropy, not the view's foreshortening)."""
    r = tool.compare(bpy_addon, 64, 0.0, 0.0, "principled")
    assert abs(r["total"] - 1.0) < 0.02
    (_, lo, so, _), (_, lc, sc, _) = r["moments_ours"], r["moments_cycles"]
    assert abs(lo / so - lc / sc) < 0.1 and lc / sc < 1.4


def test_turned_plate_keeps_its_highlight(bpy_addon, tool):
    """The plate turned about its own Z axis: the radial tangent turns with the object
    (the add-on's normal transform), so the highlight matches Cycles' as before."""
    r = tool.compare(bpy_addon, 64, 0.8, 0.0, "principled", spin=0.6)
    assert abs(r["total"] - 1.0) < 0.02
    (ao, lo, so, _), (ac, lc, sc, _) = r["moments_ours"], r["moments_cycles"]
    assert abs((ao - ac + 90.0) % 180.0 - 90.0) < 3.0, (ao, ac)
    assert abs(lo / lc - 1.0) < 0.05 and abs(so / sc - 1.0) < 0.05


@pytest.mark.parametrize("named", [False, True])
def test_uv_map_tangent_matches_cycles(bpy_addon, tool, named):
    """A Tangent node in UV Map mode on the lobe's Tangent (the plate's UV map turned 75
    degrees from its x axis): the highlight follows the map's MikkTSpace tangent as in
    Cycles (the add-on exports it in the radial tangent's place), not the radial default
    (measured at 8 spp: the long axis at 96.5 degrees in the image, 131 with the radial
    tangent; a 30 degree map happens to put it near the radial one's, 133). named: the
    turned map is a second one that the Tangent node names (the render map unturned): its
    tangents, not the render map's (nodes35; before, the render map's, warned)."""
    import math
    r = tool.compare(bpy_addon, 64, 0.8, 0.0, "principled", uv_angle=math.radians(75.0),
                     named=named)
    print({k: r[k] for k in ("total", "moments_ours", "moments_cycles")},
          r["regions_ours"] / np.maximum(r["regions_cycles"], 1e-12))
    assert abs(r["total"] - 1.0) < 0.02, r["total"]
    ro, rc = r["regions_ours"], r["regions_cycles"]
    bright = rc > 0.02 * rc.max()
    assert np.all(np.abs(ro[bright] / rc[bright] - 1.0) < 0.03), ro[bright] / rc[bright]
    (ao, lo, so, _), (ac, lc, sc, _) = r["moments_ours"], r["moments_cycles"]
    assert abs((ao - ac + 90.0) % 180.0 - 90.0) < 3.0, (ao, ac)
    assert abs(lo / lc - 1.0) < 0.05 and abs(so / sc - 1.0) < 0.05, (lo, lc, so, sc)
    assert lc / sc > 1.5
    # The radial default would put the long axis elsewhere: our plate without the node.
    scene = tool.build(bpy_addon, 0.8, 0.0)
    ar = tool.moments(tool.render(bpy_addon, scene, "ours", 16) @ np.array(
        [0.2126, 0.7152, 0.0722]))[0]
    assert abs((ar - ac + 90.0) % 180.0 - 90.0) > 10.0, (ar, ac)
