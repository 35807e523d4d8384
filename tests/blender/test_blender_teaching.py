"""Teaching in Blender: the Method setting, the Compare Methods / Parameter Sweep /
Effects Strip operators headless through the bpy wheel, their menu and panel entries,
and the batch command's --compare / --sweep / --strip / --save-passes (addon/operators.py,
addon/batch.py)."""
import os
import subprocess

import numpy as np
import pytest

from blender_helpers import BLENDS, PYTHON, ROOT, cheap, open_blend

pytestmark = pytest.mark.blender
GAP = 2  # engine.teaching.GAP


def _pixels(image):
    w, h = image.size
    a = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(a)
    return np.round(a.reshape(h, w, 4)[::-1, :, :3] * 255).astype(np.uint8)  # rows top-down


def _check_labelled_row(img, count, tile_w, tile_h):
    """`count` tiles of tile_w x tile_h in one row, each with a label band of text that
    ends inside its cell (cells wider than the tile where a label word is: never
    clipped). Returns the x of each tile's image."""
    cell = (img.shape[1] + GAP) // count - GAP
    assert img.shape[1] == count * cell + (count - 1) * GAP and cell >= tile_w
    band = img.shape[0] - tile_h
    assert band > 10
    xs = []
    for i in range(count):
        x = i * (cell + GAP)
        label = img[tile_h:, x:x + cell]
        assert (label.max(axis=2) > 64).sum() > 30, i  # Blender's font drew text
        assert label.min() == 0
        ink = np.flatnonzero(label.max(axis=2).max(axis=0) > 12)
        assert ink[-1] < cell - 1, i  # the text ends inside its cell
        # A gap column of grey between tiles.
        if i:
            assert np.all(img[:, x - 1] == 48)
        xs.append(x + (cell - tile_w) // 2)
    return xs


class _Window:
    """What the modal teaching operator asks of Blender's window manager and workspace,
    recorded (no window in background mode, so the modal path is driven by hand)."""

    def __init__(self):
        self.progress, self.status, self.timers = [], [], 1
        self.window_manager = self

    def progress_update(self, value):
        self.progress.append(value)

    def progress_end(self):
        self.progress.append("end")

    def event_timer_remove(self, timer):
        self.timers -= 1

    def status_text_set(self, text):
        self.status.append(text)

    @property
    def workspace(self):
        return self


class _Event:
    def __init__(self, type_, value="NOTHING"):
        self.type, self.value = type_, value


def _modal_operator(bpy, kind, label, work):
    """A stand-in for the operator instance in Blender's window: its job started, its
    reports kept; the methods are the operator class's own."""
    from addon import operators

    class Op:
        bl_label = label
        _timer = object()
        modal = operators._TeachingOperator.modal
        cancel = operators._TeachingOperator.cancel
        _end_modal = operators._TeachingOperator._end_modal
        _finish = operators._TeachingOperator._finish

        def __init__(self):
            self.kind, self.reports = kind, []
            self._job = operators._running = operators.TeachingJob(work).start()

        def report(self, kinds, text):
            self.reports.append((set(kinds), text))
    return Op()


def test_teaching_renders_on_a_thread_while_blenders_window_stays_live(bpy_addon):
    """In Blender's window a sweep took minutes inside execute(): the UI froze with no way
    to cancel (newuser42). There the renders run on a thread (TeachingJob) while the
    modal operator passes other events through, moves the progress bar on its timer, and
    composes and shows the image when they end; Esc cancels at the renders' next poll."""
    import time
    bpy = bpy_addon
    from addon import operators
    scene = open_blend(bpy, "figure3_sphere.blend")
    cheap(scene)
    work = operators.prepare_teaching("strip", scene, bpy.context.evaluated_depsgraph_get(),
                                      48, "preview")
    window = _Window()
    op = _modal_operator(bpy, "strip", "Effects Strip", work)
    assert op.modal(window, _Event("MOUSEMOVE")) == {"PASS_THROUGH"}
    result = {"RUNNING_MODAL"}
    for _ in range(6000):
        result = op.modal(window, _Event("TIMER"))
        if result != {"RUNNING_MODAL"}:
            break
        time.sleep(0.01)
    assert result == {"FINISHED"}, op.reports
    assert window.progress[-1] == "end" and window.timers == 0 and window.status[-1] is None
    assert any(isinstance(v, int) and v > 0 for v in window.progress)  # the bar moved
    assert "Effects Strip" in bpy.data.images["Photon Mapping: Effects Strip"].name
    assert op.reports and op.reports[-1][0] == {"INFO"}

    # Esc: a work that polls should_cancel as the renders do ends Cancelled, reported.
    def endless(progress, should_cancel):
        while not should_cancel():
            progress("render", 0.5, "Rendering")
            time.sleep(0.01)
        raise load_engine().parallel.Cancelled()
    from addon.core import load_engine
    window = _Window()
    op = _modal_operator(bpy, "sweep", "Parameter Sweep", endless)
    assert op.modal(window, _Event("ESC", "PRESS")) == {"RUNNING_MODAL"}
    assert op._job.wait(10)
    assert op.modal(window, _Event("TIMER")) == {"CANCELLED"}
    assert op.reports == [({"WARNING"}, "Photon Mapping: Parameter Sweep cancelled")]
    # An error in the renders is reported, not raised into Blender.
    op = _modal_operator(bpy, "sweep", "Parameter Sweep",
                         lambda progress, should_cancel: 1 / 0)
    assert op._job.wait(10)
    assert op.modal(_Window(), _Event("TIMER")) == {"CANCELLED"}
    assert op.reports[0][0] == {"ERROR"} and "division by zero" in op.reports[0][1]
    # One at a time: while a job renders the operators cannot start (poll); Blender
    # ending the modal operator (a new file, the window closed) stops the renders too.
    op = _modal_operator(bpy, "sweep", "Parameter Sweep", endless)
    assert operators.running_job() is op._job
    assert not bpy.ops.photonmap.compare_methods.poll()
    window = _Window()
    op.cancel(window)
    assert op._job.wait(10) and isinstance(op._job.error, load_engine().parallel.Cancelled)
    assert operators.running_job() is None and bpy.ops.photonmap.compare_methods.poll()
    assert window.timers == 0 and window.progress == ["end"] and window.status == [None]
    # Background mode and scripts run inside execute(), as before.
    assert not operators.runs_modal(bpy.context)


def test_compare_methods_operator_headless(bpy_addon):
    bpy = bpy_addon
    scene = open_blend(bpy, "figure3_sphere.blend")
    cheap(scene)
    assert bpy.ops.photonmap.compare_methods(preview_size=64) == {"FINISHED"}
    image = bpy.data.images["Photon Mapping: Compare Methods"]
    img = _pixels(image)
    tile_w, tile_h = 64, 48  # the file is 320 x 240
    xs = _check_labelled_row(img, 4, tile_w, tile_h)
    tiles = [img[:tile_h, x:x + tile_w] for x in xs]
    assert all(t.any() for t in tiles)
    assert not np.array_equal(tiles[0], tiles[1])  # local != raytrace


def test_method_setting_reaches_the_engine(bpy_addon):
    bpy = bpy_addon
    from addon.engine import last_render
    scene = open_blend(bpy, "figure3_sphere.blend")
    cheap(scene, pct=10)
    scene.photonmap.method = "local"
    assert scene.photonmap.to_settings_kwargs()["method"] == "local"
    bpy.ops.render.render()
    effects = "\n".join(last_render["stats"]["effects"])
    assert "method: local" in effects and "shadow rays: off" in effects


def test_sweep_and_strip_operators(bpy_addon):
    bpy = bpy_addon
    scene = open_blend(bpy, "figure3_sphere.blend")
    cheap(scene)
    assert bpy.ops.photonmap.parameter_sweep(parameter="spp", values="1,2,4",
                                             preview_size=48) == {"FINISHED"}
    _check_labelled_row(_pixels(bpy.data.images["Photon Mapping: Parameter Sweep"]), 3, 48, 36)
    assert bpy.ops.photonmap.effects_strip(preview_size=48) == {"FINISHED"}
    _check_labelled_row(_pixels(bpy.data.images["Photon Mapping: Effects Strip"]), 6, 48, 36)
    with pytest.raises(RuntimeError, match="'x' is not a whole number"):
        bpy.ops.photonmap.parameter_sweep(parameter="photons", values="1000,x", preview_size=48)


def test_sweep_against_a_reference_image(bpy_addon, tmp_path):
    bpy = bpy_addon
    from addon import operators
    from engine.imageio import write_image
    scene = open_blend(bpy, "figure3_sphere.blend")
    cheap(scene)
    ref = tmp_path / "ref.exr"
    write_image(np.full((36, 48, 3), 0.5, np.float32), str(ref))
    np.testing.assert_allclose(operators.load_reference(str(ref)), 0.5)
    tiles, _ = operators.teaching_image("sweep", scene, bpy.context.evaluated_depsgraph_get(),
                                        48, params={"spp": [1, 2]}, reference=str(ref))
    for t in tiles:  # every tile measured against the file, the last one too
        assert t.error > 0 and t.lines[2].startswith("relMSE")
    small = tmp_path / "small.exr"
    write_image(np.zeros((4, 4, 3), np.float32), str(small))
    with pytest.raises(RuntimeError, match="reference image is 4x4"):
        bpy.ops.photonmap.parameter_sweep(parameter="spp", values="1,2", preview_size=48,
                                          reference=str(small))


def test_menu_and_panel_entries(bpy_addon):
    bpy = bpy_addon
    from addon import ui
    assert ui.draw_render_menu in bpy.types.TOPBAR_MT_render._dyn_ui_initialize()
    assert hasattr(bpy.types, "PHOTONMAP_PT_teaching")
    for op in ("compare_methods", "parameter_sweep", "effects_strip"):
        assert hasattr(bpy.ops.photonmap, op)


def _batch(*args):
    return subprocess.run([PYTHON, "-m", "addon.batch", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)


def test_batch_compare_strip_and_passes(tmp_path):
    from PIL import Image
    blend = os.path.join(BLENDS, "figure3_sphere.blend")
    grid = tmp_path / "grid.png"
    res = _batch(blend, "--compare", "-o", str(grid), "--preview-size", "48", "--samples", "2",
                 "--photons", "5000", "--caustic-photons", "2000")
    assert res.returncode == 0, res.stderr[-2000:]
    assert "Ray tracing" in res.stderr and "Photon hits" in res.stderr
    img = np.asarray(Image.open(grid).convert("RGB"))
    _check_labelled_row(img, 4, 48, 36)
    out = tmp_path / "f3.png"
    res = _batch(blend, "-o", str(out), "--samples", "2", "--photons", "5000",
                 "--caustic-photons", "2000", "--resolution-percentage", "15", "--strip",
                 "--save-passes", "--method", "raytrace", "--quiet")
    assert res.returncode == 0, res.stderr[-2000:]
    for name in ("direct", "indirect", "caustic", "specular", "emission", "photon_hits",
                 "strip"):
        assert (tmp_path / f"f3.{name}.png").is_file(), name
    assert not np.asarray(Image.open(tmp_path / "f3.indirect.png")).any()  # raytrace
    strip = np.asarray(Image.open(tmp_path / "f3.strip.png").convert("RGB"))
    _check_labelled_row(strip, 6, 48, 36)
    res = _batch(blend, "--sweep", "photons=10,x", "-o", str(tmp_path / "l.png"))
    assert res.returncode == 1 and "'x' is not a whole number" in res.stderr
    assert not (tmp_path / "l.png").exists()
