"""The add-on's settings cannot exceed the engine's limits, and a render that would not
fit in memory is refused with the setting named, before anything is allocated (issue 16)."""
import time

import pytest

from blender_helpers import open_blend

pytestmark = pytest.mark.blender

# add-on property -> engine setting
PROPERTY_SETTING = {"photons": "photons", "caustic_photons": "caustic_photons",
                    "max_photon_depth": "max_photon_depth", "min_photons": "min_photons",
                    "k_nearest": "k_nearest", "gather_rays": "gather_rays", "spp": "spp",
                    "max_depth": "max_depth", "light_samples": "light_samples",
                    "threads": "workers"}


def test_property_hard_maxima_stay_within_the_engine_limits(bpy_addon):
    from engine.settings import LIMITS
    props = bpy_addon.types.Scene.bl_rna.properties["photonmap"].fixed_type.properties
    for prop, setting in PROPERTY_SETTING.items():
        hard_max = props[prop].hard_max
        assert hard_max <= LIMITS[setting], (prop, hard_max, LIMITS[setting])
    assert props["spp"].hard_max == 65536 and props["light_samples"].hard_max == 256


def test_render_beyond_memory_is_refused_naming_the_setting(bpy_addon, tmp_path):
    bpy = bpy_addon
    from addon import engine
    scene = open_blend(bpy, "figure3_sphere.blend")
    try:
        scene.photonmap.photons = 2**31 - 1
        t0 = time.perf_counter()
        with pytest.raises(RuntimeError, match="not rendered: setting 'photons'"):
            bpy.ops.render.render()  # Blender raises for a render that set an error
        elapsed = time.perf_counter() - t0
        err = engine.last_render.get("error", "")
        assert "'photons' = 2,147,483,647" in err and "is available" in err, err
        assert "\n" not in err
        assert elapsed < 10.0  # refused after export, nothing traced
    finally:
        bpy.ops.wm.read_homefile(use_empty=True)
