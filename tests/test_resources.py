"""Resources are checked before they are committed (issue 16): settings beyond Blender's
limits are refused, and a render whose estimated peak memory exceeds the available
memory is refused in one line naming the setting, before anything big is allocated."""
import os
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest

from helpers import ROOT
from engine import RenderSettings, ResourceError, render
from engine.progressive import Budget, render_progressive
from engine.resources import (MAX_RESOLUTION, available_memory, check_resources,
                              estimate_memory)
from engine import resources
from engine.scene import Mesh
from engine.scenefile import load_scene
from engine.settings import LIMITS

SCENE = os.path.join(ROOT, "scenes", "figure3.toml")
GB = 1 << 30


def _scene(w=64, h=48):
    scene, _ = load_scene(SCENE)
    scene.width, scene.height = w, h
    return scene


@pytest.mark.parametrize("name, value, limit", [
    ("spp", 65537, "65,536"), ("spp", 10**9, "65,536"),
    ("light_samples", 257, "256"), ("light_samples", 10**9, "256"),
    ("workers", 100_000, "1,024"), ("gather_rays", 10**6, "256"),
    ("photons", 2**63 - 1, "2,147,483,647"), ("photons", 10**12, "2,147,483,647"),
    ("caustic_photons", 2**40, "2,147,483,647"), ("k_nearest", 10**7, "10,000"),
    ("max_depth", 10**6, "1,024"), ("max_photon_depth", 10**6, "1,024"),
])
def test_settings_beyond_the_limits_are_refused_by_name(name, value, limit):
    with pytest.raises(ValueError, match=f"'{name}' must be <= {limit}, got"):
        RenderSettings(**{name: value})
    RenderSettings(**{name: LIMITS[name]})  # the limit itself is accepted


def test_non_numbers_are_refused_not_crashing():
    for bad in (float("inf"), float("nan"), "x", None, True):
        with pytest.raises(ValueError, match="'photons' must be a whole number"):
            RenderSettings(photons=bad)


def test_spp_at_the_limit_allocates_no_huge_buffer():
    """spp = 1e9 used to allocate an 8 GB jitter permutation per chunk; at the limit a
    chunk's working memory stays small (one chunk of a 2x2 image at 65536 spp)."""
    scene = _scene(2, 2)
    s = RenderSettings(spp=LIMITS["spp"], photon_mapping=False, chunk_size=4096, workers=1)
    tracemalloc.start()
    calls = {"n": 0}

    def stop():  # cancel after the first chunk: the point is its peak, not the image
        calls["n"] += 1
        return calls["n"] > 2

    try:
        film = render(scene, s, should_cancel=stop)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert film.stats["cancelled"]
    assert peak < 200 * (1 << 20), peak


def test_photon_count_beyond_memory_is_refused_naming_photons():
    scene = _scene()
    s = RenderSettings(photons=2_000_000_000)
    with pytest.raises(ResourceError) as info:
        check_resources(scene, s, available=8 * GB)
    msg = str(info.value)
    assert "\n" not in msg
    assert "'photons' = 2,000,000,000" in msg and "8.0 GB is available" in msg
    assert "photon maps" in msg and "TB" in msg


def test_resolution_beyond_memory_is_refused_naming_the_resolution():
    scene = _scene(8000, 8000)
    with pytest.raises(ResourceError, match=r"resolution 8000x8000: .* GB of memory .*"
                                            r"image .* but 4\.0 GB is available"):
        check_resources(scene, RenderSettings(), available=4 * GB)
    # The same image fits where there is memory for it.
    est = check_resources(scene, RenderSettings(), available=64 * GB)
    assert est.largest() == "image"


def test_resolution_beyond_blenders_limit_is_refused():
    with pytest.raises(ResourceError, match=f"at most {MAX_RESOLUTION} pixels per side"):
        check_resources(_scene(100_000, 10), RenderSettings(), available=1 << 60)


def test_triangles_beyond_memory_are_refused_naming_them():
    scene = _scene()
    n = 200_000
    v = np.random.default_rng(0).random((3 * n, 3))
    scene.add_mesh(Mesh("dust", v, np.arange(3 * n).reshape(n, 3)))
    with pytest.raises(ResourceError, match="the scene's triangle count: .*triangles"):
        check_resources(scene, RenderSettings(photons=0, caustic_photons=0, spp=1),
                        available=n * resources.BYTES_PER_TRIANGLE // 2)


def test_progressive_and_blender_renders_count_their_extra_buffers():
    scene = _scene(1920, 1080)
    s = RenderSettings()
    plain = estimate_memory(scene, s).parts["image"]
    assert estimate_memory(scene, s, progressive=True).parts["image"] > plain
    assert estimate_memory(scene, s, in_blender=True).parts["image"] > plain
    region = (0, 0, 100, 100)  # a border render holds only its region
    assert estimate_memory(scene, s, region=region).parts["image"] < plain / 100


def test_ordinary_renders_are_never_refused_on_an_ordinary_machine():
    """Defaults at Full HD, and the 'reference' preset at 640x480, fit in 4 GB."""
    from engine import presets
    for (w, h), kw in (((1920, 1080), {}), ((640, 480), presets.PRESETS["reference"])):
        est = check_resources(_scene(w, h), RenderSettings(**kw), available=4 * GB)
        assert est.total < 4 * GB


def test_render_and_progressive_refuse_before_preparing(monkeypatch):
    progressive = sys.modules["engine.progressive"]
    render_mod = sys.modules["engine.render"]  # engine.render is also the function's name

    def no_prepare(*a, **k):
        raise AssertionError("prepared a render that should have been refused")

    monkeypatch.setattr(render_mod, "prepare_context", no_prepare)
    monkeypatch.setattr(progressive, "prepare_context", no_prepare)
    import engine.resources as resources
    monkeypatch.setattr(resources, "available_memory", lambda: 1 << 20)
    with pytest.raises(ResourceError, match="is available"):
        render(_scene(), RenderSettings())
    with pytest.raises(ResourceError, match="is available"):
        render_progressive(_scene(), RenderSettings(), Budget(passes=1))


def test_available_memory_is_read():
    avail = available_memory()
    assert avail is None or avail > 0
    if sys.platform.startswith("linux"):
        assert avail is not None


def test_cli_refuses_in_one_line():
    res = subprocess.run([sys.executable, "-m", "engine.cli", "render", SCENE, "-o",
                          os.path.join("out", "never.png"), "--photons", "2000000000"],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode == 1
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "'photons' = 2,000,000,000" in lines[0], res.stderr
