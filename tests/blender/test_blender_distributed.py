"""The add-on on a Dask cluster (engine/distributed.py): F12 with a scheduler address gives
the image of this machine, the Distributed panel names what is missing, and the batch
command renders a frame range (docs/distributed.md)."""
import os
import subprocess
from types import SimpleNamespace

import numpy as np
import pytest

from blender_helpers import BLENDS, PYTHON, ROOT, cheap, open_blend, read_rgba, render_exr

pytestmark = pytest.mark.blender
distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def scheduler():
    """A LocalCluster of 2 worker processes; its tcp://127.0.0.1 address is what the
    panel's Scheduler field takes."""
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address=None)
    yield cluster.scheduler_address
    cluster.close()


def test_f12_on_a_scheduler_is_the_local_image(bpy_addon, tmp_path, scheduler):
    bpy = bpy_addon
    from addon import engine
    scene = open_blend(bpy, "figure3_sphere.blend")
    cheap(scene, pct=15, spp=1, photons=3000, caustic_photons=1000)
    pm = scene.photonmap
    pm.progressive = True
    pm.max_passes = 3
    pm.dask_scheduler = ""
    local = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "local.exr"))
    assert "distributed" not in engine.last_render["stats"]
    pm.dask_scheduler = scheduler
    on_dask = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "dask.exr"))
    stats = engine.last_render["stats"]
    assert stats["distributed"]["workers"] == 2 and stats["passes"] == 3
    assert on_dask.tobytes() == local.tobytes()
    # An address alone turns the passes on (the Progressive budget applies).
    pm.progressive = False
    again = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "again.exr"))
    assert again.tobytes() == local.tobytes()
    pm.dask_scheduler = ""


class _Layout:
    """Records what a panel's draw() puts on screen."""

    def __init__(self, texts):
        self.texts = texts
        self.use_property_split = self.use_property_decorate = self.alert = False

    def prop(self, data, name, **kw):
        self.texts.append(f"prop:{name}")

    def label(self, text="", **kw):
        self.texts.append(text)

    def column(self, **kw):
        return self


def _draw(address):
    from addon.ui import PHOTONMAP_PT_distributed
    texts = []
    panel = SimpleNamespace(layout=_Layout(texts))
    context = SimpleNamespace(scene=SimpleNamespace(photonmap=SimpleNamespace(
        dask_scheduler=address)))
    PHOTONMAP_PT_distributed.draw(panel, context)
    return texts


def test_panel_says_what_is_missing_and_how_to_install(bpy_addon, monkeypatch):
    import importlib.util
    assert any(t.startswith("Off") for t in _draw(""))
    assert any("on the cluster" in t for t in _draw("tcp://127.0.0.1:8786"))
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name in ("dask", "distributed") else real(name, *a))
    texts = _draw("tcp://127.0.0.1:8786")
    assert "Missing Python packages: dask, distributed" in " ".join(texts)
    assert any('-m pip install "dask[distributed]"' in t for t in texts)


def _batch(tmp_path, out, *extra):
    res = subprocess.run(
        [PYTHON, "-m", "addon.batch", os.path.join(BLENDS, "figure3_sphere.blend"),
         "-o", str(out), "--samples", "1", "--photons", "2000", "--caustic-photons", "500",
         "--resolution-percentage", "10", *extra],
        cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    return res


def _pixels(path):
    from PIL import Image
    with Image.open(path) as im:
        return np.asarray(im).copy()


def test_batch_frame_range_and_seeds(tmp_path):
    _batch(tmp_path, tmp_path / "still" / "f_##.png", "--frames", "3..5")
    frames = [tmp_path / "still" / f"f_{n:02d}.png" for n in (3, 4, 5)]
    assert all(p.is_file() for p in frames)
    imgs = [_pixels(p) for p in frames]
    assert imgs[0].max() > 20
    # A static scene with one seed: every frame is the same image.
    assert all(np.array_equal(imgs[0], im) for im in imgs[1:])
    _batch(tmp_path, tmp_path / "anim" / "f.png", "--frames", "1..2", "--animated-seed")
    a, b = (_pixels(tmp_path / "anim" / f"f_{n:04d}.png") for n in (1, 2))
    assert not np.array_equal(a, b)  # the noise changes from frame to frame


def test_batch_frames_on_a_scheduler(tmp_path, scheduler):
    """Two frames, their passes spread over the cluster's workers in whatever order:
    both frames of the static scene are the same image."""
    _batch(tmp_path, tmp_path / "d_#.exr", "--frames", "1..2", "--dask", scheduler)
    a, b = (tmp_path / f"d_{n}.exr" for n in (1, 2))
    assert a.is_file() and b.is_file()
    import OpenEXR
    pa, pb = (OpenEXR.File(str(p)).parts[0].channels["RGBA"].pixels for p in (a, b))
    assert pa.tobytes() == pb.tobytes() and np.isfinite(pa).all() and pa[..., :3].mean() > 0
