"""Progressive rendering, quality presets and the effects report through the add-on."""
import numpy as np
import pytest

from blender_helpers import cheap, open_blend, read_rgba, render_exr

pytestmark = pytest.mark.blender


def test_progressive_passes_update_the_image(bpy_addon, tmp_path, monkeypatch):
    bpy = bpy_addon
    from addon import engine
    scene = open_blend(bpy, "figure6_box.blend")
    cheap(scene, pct=20, spp=1, photons=5000, caustic_photons=2000)
    pm = scene.photonmap
    pm.progressive = True
    pm.max_passes = 3
    writes = []
    original = engine.PhotonMapRenderEngine._write_result
    monkeypatch.setattr(engine.PhotonMapRenderEngine, "_write_result",
                        lambda self, film, *a: (writes.append(film.combined.mean()),
                                                original(self, film, *a)))
    img = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "prog.exr"))
    stats = engine.last_render["stats"]
    assert stats["passes"] == 3 and stats["progressive"]
    assert len(writes) >= 3  # the image was shown after every pass
    assert np.isfinite(stats["error_estimate"]) and stats["error_estimate"] > 0
    assert np.isfinite(img).all() and img[..., :3].mean() > 0


def test_quality_preset_sets_the_engine_settings(bpy_addon):
    bpy = bpy_addon
    from engine.presets import PRESETS
    bpy.ops.wm.read_homefile(use_empty=True)
    pm = bpy.context.scene.photonmap
    assert pm.quality_preset == "high"
    # The default preset is the engine's defaults, and the add-on's properties start there.
    from engine import RenderSettings
    defaults = RenderSettings()
    for key, value in PRESETS["high"].items():
        assert getattr(defaults, key) == value, key
        assert getattr(pm, key) == value, key
    pm.quality_preset = "preview"
    for key, value in PRESETS["preview"].items():
        assert getattr(pm, key) == value, key


def test_effect_decisions_are_reported(bpy_addon, tmp_path):
    bpy = bpy_addon
    from addon import engine
    scene = open_blend(bpy, "figure3_sphere.blend")
    cheap(scene, pct=20, spp=1, photons=3000, caustic_photons=1000)
    render_exr(bpy, scene, tmp_path / "f3.exr")
    lines = engine.last_render["stats"]["effects"]
    assert any(line.startswith("indirect light (global map): on") for line in lines)
    assert any(line.startswith("soft shadows") for line in lines)
