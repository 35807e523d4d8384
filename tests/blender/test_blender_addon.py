"""Add-on lifecycle, settings, manifest and the command-line batch path."""
import dataclasses
import os
import subprocess

import pytest

from blender_helpers import BLENDS, PYTHON, ROOT, blender_ext_path

pytestmark = pytest.mark.blender

OUR_PANELS = ("PHOTONMAP_PT_sampling", "PHOTONMAP_PT_photons", "PHOTONMAP_PT_estimate",
              "PHOTONMAP_PT_display", "PHOTONMAP_PT_performance", "PHOTONMAP_PT_passes")


def _state(bpy):
    from addon.engine import PhotonMapRenderEngine
    compat = sorted(p.__name__ for p in bpy.types.Panel.__subclasses__()
                    if "PHOTONMAP" in getattr(p, "COMPAT_ENGINES", ()))
    return dict(
        engine=PhotonMapRenderEngine.is_registered,
        scene_props=hasattr(bpy.types.Scene, "photonmap"),
        layer_props=hasattr(bpy.types.ViewLayer, "photonmap"),
        panels=[n for n in OUR_PANELS if hasattr(bpy.types, n)],
        compat=[c for c in compat if not c.startswith("PHOTONMAP_")],
    )


def test_register_unregister_twice(bpy_addon):
    bpy = bpy_addon
    import addon
    addon.unregister()
    try:
        for _ in range(2):
            off = _state(bpy)
            assert not off["engine"] and not off["scene_props"] and not off["layer_props"]
            assert off["panels"] == [] and off["compat"] == [], off
            addon.register()
            on = _state(bpy)
            assert on["engine"] and on["scene_props"] and on["layer_props"]
            assert on["panels"] == list(OUR_PANELS)
            # Standard panels enabled for us: output format, camera lens, light, material.
            for name in ("RENDER_PT_format", "RENDER_PT_output", "DATA_PT_lens",
                         "DATA_PT_EEVEE_light", "EEVEE_MATERIAL_PT_surface"):
                assert name in on["compat"], name
            scene = bpy.context.scene
            scene.render.engine = "PHOTONMAP"
            assert scene.render.engine == "PHOTONMAP"
            addon.unregister()
        assert _state(bpy)["compat"] == []
    finally:
        if not hasattr(bpy.types.Scene, "photonmap"):
            addon.register()


def test_property_defaults_match_engine(bpy_addon):
    bpy = bpy_addon
    from engine.settings import RenderSettings
    bpy.ops.wm.read_homefile(use_empty=True)  # defaults, whatever an earlier test opened
    pm = bpy.context.scene.photonmap
    kwargs = pm.to_settings_kwargs()
    defaults = {f.name: f.default for f in dataclasses.fields(RenderSettings)}
    for name, value in kwargs.items():
        assert name in defaults, f"unknown setting {name}"
        if name in ("workers", "pixel_filter", "filter_width"):
            continue  # the filter is the scene's (Film > Pixel Filter), not ours
        if name in ("clamp_direct", "clamp_indirect", "cycles_filter_glossy"):
            continue  # Cycles' Clamping (default Indirect 10) and Filter Glossy (1.0)
        assert value == defaults[name], f"{name}: add-on {value!r} != engine {defaults[name]!r}"
    RenderSettings(**kwargs)  # accepted by the engine


def test_cycles_caustics_switches_reach_the_effect_report(bpy_addon):
    """Cycles' Light Paths > Caustics > Reflective / Refractive are read from the scene
    (only named by the effect report: engine/effects.py, _cycles_caustics_note)."""
    bpy = bpy_addon
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    kw = sc.photonmap.to_settings_kwargs()
    assert kw["cycles_caustics_reflective"] is True and kw["cycles_caustics_refractive"] is True
    sc.cycles.caustics_refractive = False
    kw = sc.photonmap.to_settings_kwargs()
    assert kw["cycles_caustics_reflective"] is True and kw["cycles_caustics_refractive"] is False


def test_every_setting_has_a_tooltip(bpy_addon):
    """Every setting of the panels has a tooltip of a sentence (a new user's main help,
    newuser23's trial); Max Photon Depth says that the Light Paths limits end photons
    too (its default 32 looked like the limit that counts)."""
    bpy = bpy_addon
    rna = bpy.types.Scene.bl_rna.properties["photonmap"].fixed_type
    short = [p.identifier for p in rna.properties
             if p.identifier not in ("rna_type", "name") and len(p.description) < 30]
    assert not short, short
    assert "Max Bounces" in rna.properties["max_photon_depth"].description


def test_estimator_menu_names_are_the_reports(bpy_addon):
    """The effect report names the estimator as the panel's menu does."""
    from addon.properties import ESTIMATOR_ITEMS
    from engine.settings import ESTIMATOR_LABELS, ESTIMATORS
    assert {key: label for key, label, _ in ESTIMATOR_ITEMS} == ESTIMATOR_LABELS
    assert set(ESTIMATOR_LABELS) == set(ESTIMATORS)


def test_pixel_filter_is_read_from_the_scene(bpy_addon):
    """Cycles' Film > Pixel Filter (scene.cycles) sets the engine's filter: Blender's
    default is Blackman-Harris 1.5 px; the box is always 1 px (Cycles' sync)."""
    bpy = bpy_addon
    from engine.settings import RenderSettings
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    pm = scene.photonmap
    kw = pm.to_settings_kwargs()
    assert (kw["pixel_filter"], kw["filter_width"]) == ("blackman_harris", 1.5)
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "GAUSSIAN", 2.25
    kw = pm.to_settings_kwargs()
    assert (kw["pixel_filter"], kw["filter_width"]) == ("gaussian", 2.25)
    scene.cycles.pixel_filter_type = "BOX"
    kw = pm.to_settings_kwargs()
    assert (kw["pixel_filter"], kw["filter_width"]) == ("box", 1.0)
    assert pm.to_viewport_settings_kwargs()["pixel_filter"] == "box"
    s = RenderSettings(**kw)
    assert (s.pixel_filter, s.filter_width) == ("box", 1.0)


def test_manifest_validates(bpy_addon):
    res = subprocess.run([PYTHON, blender_ext_path(), "validate", ROOT],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout + res.stderr
    import tomllib
    with open(os.path.join(ROOT, "blender_manifest.toml"), "rb") as f:
        m = tomllib.load(f)
    assert m["blender_version_min"] == "4.2.0" and m["type"] == "add-on"
    assert {"windows-x64", "macos-arm64", "macos-x64", "linux-x64"} <= set(m["platforms"])
    names = " ".join(m["wheels"])
    assert "embreex-4.4.0.post1" in names and "scipy-1.17.1" in names
    excl = m["build"]["paths_exclude_pattern"]
    for p in ("/tests/", "/bench/", "/example_blends/"):
        assert p in excl


def test_batch_writes_image(tmp_path):
    out = tmp_path / "sub" / "fig3.png"
    res = subprocess.run(
        [PYTHON, "-m", "addon.batch", os.path.join(BLENDS, "figure3_sphere.blend"),
         "-o", str(out), "--samples", "1", "--photons", "5000", "--caustic-photons", "2000",
         "--resolution-percentage", "25"],
        cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    assert out.is_file()
    from PIL import Image
    with Image.open(out) as im:
        assert im.size == (80, 60)
        import numpy as np
        assert np.asarray(im.convert("L")).max() > 20  # not black


def test_batch_missing_file_is_one_line_error(tmp_path):
    res = subprocess.run([PYTHON, "-m", "addon.batch", str(tmp_path / "nope.blend"),
                          "-o", str(tmp_path / "x.png")],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode != 0
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "not found" in lines[0] and "nope.blend" in lines[0], res.stderr
    assert not (tmp_path / "x.png").exists()


def test_noise_threshold_reaches_the_engine(bpy_addon):
    """Sampling > Noise Threshold / Min Samples as Cycles names them: off by default (0 to
    the engine), the threshold and min samples when on, Cycles' automatic threshold
    max(0.001, 1 / Samples) for 0; never in the viewport's passes."""
    bpy = bpy_addon
    from engine.settings import RenderSettings
    bpy.ops.wm.read_homefile(use_empty=True)
    pm = bpy.context.scene.photonmap
    assert pm.to_settings_kwargs()["adaptive_threshold"] == 0.0
    pm.use_adaptive_sampling = True
    pm.adaptive_min_samples = 24
    kw = pm.to_settings_kwargs()
    assert kw["adaptive_threshold"] == pytest.approx(0.01)
    assert kw["adaptive_min_samples"] == 24
    pm.adaptive_threshold = 0.0
    pm.spp = 200
    assert pm.to_settings_kwargs()["adaptive_threshold"] == pytest.approx(1 / 200)
    assert pm.to_viewport_settings_kwargs()["adaptive_threshold"] == 0.0
    RenderSettings(**pm.to_settings_kwargs())
    for name in ("use_adaptive_sampling", "adaptive_threshold", "adaptive_min_samples",
                 "spp"):
        pm.property_unset(name)
