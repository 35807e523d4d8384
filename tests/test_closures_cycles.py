"""Closures against Cycles: a sun-lit plane seen from 0 to 85 degrees and a ball in a
white-furnace world, per closure (tests/closure_cases.py), our engine against the Cycles
means stored by tools/make_closure_references.py (tests/references/closures.json).

The engine scene is built from the same description as the Cycles one (no Blender here).
The plane is lit by a delta sun in a black world, so every pixel is one BSDF evaluation
of a shadow ray (next-event estimation on every rough lobe): the image has no noise and
the comparison is tight (2 %, as issue 14 asks). The furnace ball is seen by its lobes'
sampled continuation into the world (and world light sampling for the diffuse lobe)."""
import json
import math
import os

import numpy as np
import pytest

import closure_cases as cc
from engine.api import PaperScene
from engine.scene import Material
from engine.settings import RenderSettings

REF = os.path.join(os.path.dirname(__file__), "references", "closures.json")
with open(REF) as f:
    REFS = json.load(f)


def engine_material(spec) -> Material:
    node = spec["node"]
    multi = spec.get("distribution", "MULTI_GGX") == "MULTI_GGX"
    if node == "principled":
        keys = ("base_color", "roughness", "metallic", "ior", "specular_ior_level",
                "specular_tint", "coat_weight", "coat_roughness", "coat_ior", "coat_tint",
                "sheen_weight", "sheen_roughness", "sheen_tint")
        return Material("m", specular=1.0, multiscatter=multi, **{k: spec[k] for k in keys})
    if node == "glossy":
        return Material("m", spec["base_color"], metallic=1.0, roughness=spec["roughness"],
                        node="glossy", multiscatter=multi)
    if node == "glass":
        return Material("m", spec["base_color"], transmission=1.0, roughness=spec["roughness"],
                        ior=spec["ior"], node="glass", multiscatter=multi)
    assert node == "diffuse"
    return Material("m", spec["base_color"], specular=0.0)


def _camera(scene, view_deg, dist, fov):
    v = math.radians(view_deg)
    pos = (-math.sin(v) * dist, 0.0, math.cos(v) * dist)
    up = (0.0, 1.0, 0.0) if view_deg == 0.0 else (0.0, 0.0, 1.0)
    scene.set_camera(pos, (0.0, 0.0, 0.0), up=up, view_angle=fov)


def render_plane(spec, view):
    s = PaperScene(width=cc.SIZE, height=cc.SIZE)
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, engine_material(spec), name="plane")
    z = math.radians(cc.SUN_ZENITH)
    s.add_sun(direction=(-math.sin(z), 0.0, -math.cos(z)), strength=cc.SUN_W)
    _camera(s, view, cc.CAM_DIST, cc.FOV_DEG)
    film = s.render(RenderSettings(spp=4, photon_mapping=False, seed=3, workers=1))
    return film.combined.reshape(-1, 3).mean(axis=0)


PLANES = cc.plane_cases()


def _check(name, got, rel=0.02, floor=0.01):
    ref = np.array(REFS[name]["rgb"])
    # 2 % of each channel, or of the brightest one for a faint channel (a tinted metal's
    # blue): the metric issue 14 asks for, without dividing by near-zero values.
    tol = np.maximum(rel * ref, rel * ref.max()) + floor * rel
    assert np.all(np.abs(got - ref) <= tol), (
        f"{name}: ours {np.round(got, 4)} Cycles {np.round(ref, 4)} "
        f"(ratio {np.round(got / np.maximum(ref, 1e-9), 3)})")


@pytest.mark.parametrize("name", sorted(PLANES))
def test_sunlit_plane_matches_cycles(name):
    spec, view = PLANES[name]
    _check(name, render_plane(spec, view))


def render_furnace(spec, spp=64):
    s = PaperScene(width=cc.FURNACE_SIZE, height=cc.FURNACE_SIZE, background=(1.0, 1.0, 1.0))
    s.add_sphere((0, 0, 0), 1.0, engine_material(spec), name="ball", segments=96)
    _camera(s, cc.FURNACE_VIEW, cc.FURNACE_DIST, cc.FURNACE_FOV)
    # (the references' 32 bounces: tools/make_closure_references.py)
    film = s.render(RenderSettings(spp=spp, photon_mapping=False, seed=5, max_depth=32,
                                   workers=1, max_bounces=32, diffuse_bounces=32,
                                   glossy_bounces=32, transmission_bounces=32))
    return film.combined[cc.ball_mask(cc.FURNACE_SIZE)].mean(axis=0)


FURNACES = cc.furnace_cases()
# Rough glass of IOR 2.4 traps light by total internal reflection and its furnace mean is
# heavy-tailed (test_closures_sweep.FURNACE_SPP): at 64 spp it read 0.9991 against
# Cycles' 0.9596 once the ball's smooth-shaded rim took the raised normal
# (principled.raised_rough_glass), 0.9605 at 16384 spp (~25 CPU s: slow).
FURNACE_SPP = {"furnace_glass_r0.8_ior2.4": 16384}


def _furnace_param(name):
    return pytest.param(name, marks=[pytest.mark.slow] if name in FURNACE_SPP else [])


@pytest.mark.parametrize("name", [_furnace_param(n) for n in sorted(FURNACES)])
def test_white_furnace_matches_cycles(name):
    """Lossless closures come out at 1 (Multiscatter GGX, glass, the layered Principled),
    lossy ones (plain GGX, a coloured metal) at Cycles' albedo. Monte Carlo noise of the
    mean over ~150 pixels x 64 samples stays well under the 2 % (FURNACE_SPP: the cases
    that need more)."""
    _check(name, render_furnace(FURNACES[name], spp=FURNACE_SPP.get(name, 64)))


def test_caustic_casters_are_the_sharp_lobes():
    """engine/effects.sharp_specular: a rough Principled (default roughness 0.5) focuses no
    light; a smooth one, glass, a mirror and a clear coat over a rough base do; a
    transparent pass does not (shadow rays cross it: docs/design.md, Transparent shadows)
    and a Diffuse BSDF is no caster at all."""
    from engine.effects import sharp_specular
    from engine.geometry import MaterialTable
    mats = [Material("rough", roughness=0.5, specular=1.0),
            Material("smooth", roughness=0.1, specular=1.0),
            Material("glass", transmission=1.0, roughness=0.0),
            Material("mirror", metallic=1.0, roughness=0.0),
            Material("coated", roughness=0.8, specular=1.0, coat_weight=1.0,
                     coat_roughness=0.05),
            Material("rough_coat", roughness=0.8, specular=1.0, coat_weight=1.0,
                     coat_roughness=0.6),
            Material("card", alpha=0.5),
            Material("diffuse", specular=0.0)]
    got = dict(zip([m.name for m in mats], sharp_specular(MaterialTable.build(mats))))
    assert got == {"rough": False, "smooth": True, "glass": True, "mirror": True,
                   "coated": True, "rough_coat": False, "card": False, "diffuse": False}
