"""Paper mode, radius 0, preset labels and the photon-hit pass through the add-on (issue 17)."""
import numpy as np
import pytest

from blender_helpers import cheap, open_blend, read_layers, render_exr

pytestmark = pytest.mark.blender


def test_paper_mode_and_radius_zero_reach_the_engine(bpy_addon):
    bpy = bpy_addon
    from engine import RenderSettings
    bpy.ops.wm.read_homefile(use_empty=True)
    pm = bpy.context.scene.photonmap
    pm.paper_mode = True
    pm.use_auto_radius = False
    pm.radius = 0.25
    st = RenderSettings(**pm.to_settings_kwargs())
    assert st.paper_mode and st.estimator == "classic" and not st.final_gather
    assert st.radius == pytest.approx(0.25)
    pm.radius = 0.0  # typed 0: the automatic radius, never one that finds no photon
    assert pm.radius == 0.0
    assert RenderSettings(**pm.to_settings_kwargs()).radius is None
    pm.radius = 1e-6  # what Blender used to store for 0 (the old minimum)
    assert RenderSettings(**pm.to_settings_kwargs()).radius is None


def test_presets_relabel_to_custom_once_edited(bpy_addon):
    bpy = bpy_addon
    from engine.presets import PRESETS
    bpy.ops.wm.read_homefile(use_empty=True)
    pm = bpy.context.scene.photonmap
    pm.quality_preset = "preview"
    assert pm.quality_preset == "preview"  # applying it set its own values: still Preview
    pm.spp = PRESETS["preview"]["spp"]      # the same value: not an edit
    assert pm.quality_preset == "preview"
    pm.photons = PRESETS["preview"]["photons"] + 1
    assert pm.quality_preset == "custom"
    pm.quality_preset = "medium"
    assert pm.quality_preset == "medium" and pm.photons == PRESETS["medium"]["photons"]


def test_preset_labels_quote_time_at_the_files_resolution(bpy_addon):
    bpy = bpy_addon
    from addon.properties import _preset_items
    from engine.presets import measured
    if not measured():
        pytest.skip("no preset measurements")
    bpy.ops.wm.read_homefile(use_empty=True)
    r = bpy.context.scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 640, 480, 50
    labels = {k: label for k, label, _ in _preset_items(None, bpy.context)}
    assert "at 320x240" in labels["high"]
    secs = float(labels["high"].split("~")[1].split(" s")[0])
    assert secs == pytest.approx(measured()["high"]["seconds"] * 4, rel=0.05, abs=1)
    assert labels["custom"] == "Custom"


def test_photon_hits_pass_is_filled_without_show_photons(bpy_addon, tmp_path):
    bpy = bpy_addon
    scene = open_blend(bpy, "figure6_box.blend")
    cheap(scene, pct=15, spp=1, photons=5000, caustic_photons=5000)
    assert not scene.photonmap.show_photons
    layers = read_layers(render_exr(bpy, scene, tmp_path / "f6.exr", multilayer=True))
    hits = layers["Photon Hits"][..., :3]
    dots = hits.max(axis=2) > 0
    assert 0.01 < dots.mean() < 0.5
    # The combined image is the render, not dots painted over it.
    total = sum(layers[n][..., :3] for n in ("Direct", "Indirect", "Caustic", "Specular",
                                             "Emission"))
    np.testing.assert_allclose(layers["Combined"][..., :3], total, rtol=1e-4, atol=1e-5)


def test_batch_paper_switches_reach_the_render(bpy_addon, tmp_path):
    import os

    from addon import batch, engine
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = tmp_path / "f3.png"
    assert batch.main([os.path.join(root, "example_blends", "figure3_sphere.blend"), "-o",
                       str(out), "--paper", "--radius", "0.3", "--width", "32", "--height",
                       "24", "--samples", "1", "--photons", "2000", "--caustic-photons", "0",
                       "--quiet"]) == 0
    assert out.exists()
    report = engine.last_render["stats"]["effects"][-1]
    assert report.startswith("photon maps: on") and "search radius 0.3 m" in report
    assert "radius set, estimator Classic (paper), paper mode" in report
    assert batch.main([os.path.join(root, "example_blends", "figure3_sphere.blend"), "-o",
                       str(out), "--radius", "0", "--estimator", "knn_cone", "--width", "32",
                       "--height", "24", "--samples", "1", "--photons", "2000",
                       "--caustic-photons", "0", "--quiet"]) == 0
    report = engine.last_render["stats"]["effects"][-1]
    assert "automatic radius, estimator k-NN (cone filter)" in report
