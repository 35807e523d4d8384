"""Rendered viewport through the bpy wheel (which cannot draw): the view's camera from
Blender's matrices, the partial re-export driven by real depsgraph updates, and the
session behind view_update (addon/viewport.py, addon/export.py: export_viewport)."""
from types import SimpleNamespace

import numpy as np
import pytest

from blender_helpers import open_blend

pytestmark = pytest.mark.blender


def _rays(camera, w, h):
    from engine.integrator import camera_rays
    px, py = np.meshgrid(np.arange(0, w, 7), np.arange(0, h, 5))
    px, py = px.ravel(), py.ravel()
    j = np.full(len(px), 0.5)
    o, d, _ = camera_rays(camera, np.zeros(3), w, h, px, py, j, j)
    return o, d


def _same_rays(a, b, w, h):
    oa, da = _rays(a, w, h)
    ob, db = _rays(b, w, h)
    # Blender's matrices are float32: agreement to its precision.
    np.testing.assert_allclose(da, db, atol=2e-6)
    # The same lines: origins may differ along the ray (an ortho view starts at its
    # near plane), never across it.
    diff = oa - ob
    across = diff - np.sum(diff * da, axis=1, keepdims=True) * da
    np.testing.assert_allclose(across, 0.0, atol=1e-5)


@pytest.mark.parametrize("kind, shift", [("PERSP", (0.0, 0.0)), ("PERSP", (0.13, -0.07)),
                                         ("ORTHO", (0.0, 0.0)), ("ORTHO", (-0.1, 0.2))])
@pytest.mark.parametrize("size", [(64, 36), (30, 48)])
def test_view_camera_from_matrices_matches_the_scene_camera(bpy_addon, kind, shift, size):
    """Looking through the scene camera, the projection Blender draws with
    (Object.calc_matrix_camera) gives the same rays as the F12 export of that camera."""
    bpy = bpy_addon
    import engine as pm
    from addon import export
    from addon.viewport import view_camera
    scene = open_blend(bpy, "figure6_box.blend")
    cam = scene.camera
    cam.data.type = kind
    cam.data.shift_x, cam.data.shift_y = shift
    cam.data.ortho_scale = 5.0
    w, h = size
    depsgraph = bpy.context.evaluated_depsgraph_get()
    window = cam.calc_matrix_camera(depsgraph, x=w, y=h)
    got = view_camera(pm, cam.matrix_world.inverted(), window, kind == "PERSP")
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    want = export.convert_camera(pm, cam.evaluated_get(depsgraph), w, h, scene.render, [])
    _same_rays(got, want, w, h)
    if kind == "PERSP":
        assert got.clip_start == pytest.approx(cam.data.clip_start, rel=1e-4)
        assert got.clip_end == pytest.approx(cam.data.clip_end, rel=1e-3)


def test_ortho_view_starts_at_its_near_plane_behind_the_view_point(bpy_addon):
    """Blender's orthographic 3D view clips from -far/2 to far/2 around the view point:
    the engine camera starts at the near plane (behind it) and sees the whole depth."""
    import engine as pm
    from addon.viewport import view_camera
    r, t, n, f = 4.0, 2.25, -500.0, 500.0  # half extents 4 x 2.25, clip -500..500
    P = np.array([[1 / r, 0, 0, 0], [0, 1 / t, 0, 0],
                  [0, 0, -2 / (f - n), -(f + n) / (f - n)], [0, 0, 0, 1]])
    V = np.eye(4)
    V[:3, 3] = (0.0, 0.0, -10.0)  # the view point at z = 10, looking down -z
    cam = view_camera(pm, V, P, perspective=False)
    np.testing.assert_allclose(cam.position, (0.0, 0.0, 10.0 + 500.0))
    assert cam.clip_start == 0.0 and cam.clip_end == pytest.approx(1000.0)
    assert cam.kind == "ORTHO" and cam.ortho_scale == pytest.approx(8.0)
    hw, hh = cam.half_extents(1600, 900)
    assert (hw, hh) == pytest.approx((4.0, 2.25))


def test_border_pixels_inside_the_camera_frame():
    from addon.viewport import border_pixels
    # A frame covering the middle half of a 100 x 50 view; border = its right half.
    frame = [(-0.5, -0.5), (0.5, 0.5)]
    assert border_pixels(frame, (0.5, 0.0, 1.0, 1.0), 100, 50) == (50, 12, 75, 38)
    # The top-left quarter of the whole view (y up in the border, down in pixels).
    assert border_pixels([(-1, -1), (1, 1)], (0.0, 0.5, 0.5, 1.0), 100, 50) == (0, 0, 50, 25)
    assert border_pixels([(-1, -1), (1, 1)], (0.0, 0.0, 1.0, 1.0), 100, 50) is None


def _fake_context(bpy, scene, w, h):
    """What view_update / view_draw read from a 3D view, looking through the camera."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    view = cam.matrix_world.inverted()
    window = cam.calc_matrix_camera(depsgraph, x=w, y=h)
    rv3d = SimpleNamespace(view_matrix=view, window_matrix=window, is_perspective=True,
                           view_perspective="PERSP", perspective_matrix=window @ view)
    return SimpleNamespace(region=SimpleNamespace(width=w, height=h), region_data=rv3d,
                           space_data=SimpleNamespace(use_render_border=False))


class _Engine:
    """The parts of RenderEngine the viewport calls outside drawing."""

    def __init__(self):
        self.stats = []

    def update_stats(self, a, b):
        self.stats.append(b)

    def tag_redraw(self):
        pass


def _summary(scene):
    return ({m.name: np.round(m.vertices, 9).tobytes() for m in scene.meshes},
            {n: (m.base_color.tolist(), m.emission.tolist()) for n, m in scene.materials.items()},
            [(li.name, li.power, np.round(li.position, 9).tolist()) for li in scene.lights])


def test_edits_re_export_only_what_changed(bpy_addon):
    """Object move, material edit, light edit, mesh edit and deletion through real
    depsgraph updates: each re-reads only what changed, the re-exported scene equals a
    full export, and the session's image after its passes equals a plain progressive
    render of that scene."""
    bpy = bpy_addon
    import engine as pm
    from engine.progressive import Budget, render_progressive
    from addon import export
    from addon.viewport import ViewportRender
    scene = open_blend(bpy, "figure6_box.blend")
    props = scene.photonmap
    props.viewport_passes = 2
    props.viewport_resolution = 50
    props.viewport_photons = 3000
    props.viewport_caustic_photons = 1500
    props.viewport_samples = 1
    context = _fake_context(bpy, scene, 48, 36)
    vp = ViewportRender()
    infos = []

    def handler(_scene, depsgraph):
        vp.update(context, depsgraph)
        infos.append(dict(vp.last_export))

    def edit(change):
        infos.clear()
        change()
        bpy.context.view_layer.update()  # runs the handler with the depsgraph's updates
        assert len(infos) == 1
        return infos[0]

    def check_scene_and_image():
        depsgraph = bpy.context.evaluated_depsgraph_get()
        full, _ = export.export_scene(pm, depsgraph, width=24, height=18)
        assert _summary(vp.scene) == _summary(full)
        assert vp.session.wait_idle(600) and vp.session.error is None, vp.session.error
        settings = pm.RenderSettings(**props.to_viewport_settings_kwargs())
        want = render_progressive(vp.session.view_scene(), settings, Budget(passes=2))
        np.testing.assert_array_equal(vp.session.frame.rgba[..., :3], want.combined)

    bpy.app.handlers.depsgraph_update_post.append(handler)
    try:
        meshes = sorted(o.name for o in scene.objects if o.type == "MESH")
        # First update: everything read (a selection change is enough to trigger it).
        info = edit(lambda: scene.objects["Floor"].select_set(True))
        assert sorted(info["geometry_read"]) == meshes and info["geometry_changed"]
        # Move: transformed from kept geometry, the others reused.
        info = edit(lambda: setattr(scene.objects["Block"].location, "z",
                                    scene.objects["Block"].location.z + 0.3))
        assert info["geometry_read"] == [] and info["transformed"] == ["Block"]
        assert sorted(info["reused"]) == sorted(set(meshes) - {"Block"})
        assert info["geometry_changed"] and not info["lights_changed"]
        check_scene_and_image()
        shots = vp.session.counters.photon_shots
        # Material edit: converted again, no mesh rebuilt, photons re-shot.
        mat = scene.objects["Block"].active_material
        bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_DIFFUSE")
        info = edit(lambda: bsdf.inputs["Color"].default_value.__setitem__(0, 0.2))
        assert info["materials"] == [mat.name] and info["materials_changed"]
        assert info["geometry_read"] == [] and info["transformed"] == []
        assert not info["geometry_changed"]
        check_scene_and_image()
        assert vp.session.counters.photon_shots == shots + 2
        builds = vp.session.counters.geometry_builds
        # Light edit.
        light = next(o for o in scene.objects if o.type == "LIGHT")
        info = edit(lambda: setattr(light.data, "energy", light.data.energy * 1.5))
        assert info["lights_changed"] and not info["geometry_changed"]
        check_scene_and_image()
        assert vp.session.counters.geometry_builds == builds
        # Mesh edit: only that mesh's data read again.
        block = scene.objects["Block"]

        def move_vertex():
            block.data.vertices[0].co.x += 0.05
            block.data.update()
        info = edit(move_vertex)
        assert info["geometry_read"] == ["Block"] and info["geometry_changed"]
        check_scene_and_image()
        # Deletion: found by comparing what the depsgraph still holds.
        info = edit(lambda: bpy.data.objects.remove(block))
        assert info["deleted"] == ["Block"] and info["geometry_changed"]
        check_scene_and_image()
        # Stats line: pass, photons, time.
        from addon.viewport import stats_text
        text = stats_text(vp.session.frame, props.viewport_passes)
        assert text.startswith("Pass 2/2") and "M photons" in text and "Done" in text
        # A viewport setting restarts the session with it.
        old = vp.session
        # (Python sets the property without the UI's update tag: tag the scene as it does.)
        edit(lambda: (setattr(props, "viewport_samples", 2), scene.update_tag()))
        assert vp.session is not old and not old.running
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(handler)
        vp.stop()
    assert vp.session is None


def test_render_engine_free_stops_the_session(bpy_addon):
    """The RenderEngine's view_update starts a session; free() (Blender frees the engine
    when the view leaves Rendered shading) joins its thread. (bpy cannot create a
    RenderEngine outside Blender's viewport: the methods run on a stand-in.)"""
    bpy = bpy_addon
    from addon.engine import PhotonMapRenderEngine
    scene = open_blend(bpy, "figure3_sphere.blend")
    props = scene.photonmap
    props.viewport_passes = 0  # would refine until stopped
    props.viewport_photons = 3000
    props.viewport_caustic_photons = 1000
    engine = _Engine()
    engine._viewport = None
    context = _fake_context(bpy, scene, 40, 30)
    PhotonMapRenderEngine.view_update(engine, context, bpy.context.evaluated_depsgraph_get())
    session = engine._viewport.session
    assert session is not None and session.running and not engine.stats
    PhotonMapRenderEngine.free(engine)
    assert not session.running and engine._viewport.session is None


class _Recorder:
    """Stand-ins for Blender's gpu / gpu_extras modules (the bpy wheel has no GPU: every
    gpu call raises in background mode), recording what view_draw asks them to do."""

    def __init__(self):
        self.calls = []
        rec = self

        class Buffer:
            def __init__(self, kind, size, data):
                assert kind == "FLOAT"
                self.data = np.asarray(data, dtype=np.float32)
                assert self.data.size == size

        class GPUTexture:
            def __init__(self, size, format, data):
                self.size, self.format, self.data = size, format, data
                rec.calls.append(("texture", size, format))

        self.gpu = SimpleNamespace(
            types=SimpleNamespace(Buffer=Buffer, GPUTexture=GPUTexture),
            state=SimpleNamespace(blend_set=lambda mode: rec.calls.append(("blend", mode))))
        self.presets = SimpleNamespace(
            draw_texture_2d=lambda tex, pos, w, h: rec.calls.append(("draw", tex, pos, w, h)))

    def bind_display_space_shader(self, scene):
        self.calls.append(("bind", scene.name))

    def unbind_display_space_shader(self):
        self.calls.append(("unbind",))


def test_view_draw_uploads_the_latest_frame_and_draws_it_in_display_space(bpy_addon,
                                                                          monkeypatch):
    """view_draw as Blender's custom render engine template does it: the session's latest
    frame as an RGBA16F texture (rows flipped to Blender's bottom-up order), drawn over
    the frame's part of the region between binding and unbinding the display-space
    shader, with premultiplied alpha blending, the texture uploaded once per frame."""
    import sys
    bpy = bpy_addon
    from addon.viewport import ViewportRender
    scene = open_blend(bpy, "figure3_sphere.blend")
    props = scene.photonmap
    props.viewport_passes = 1
    props.viewport_photons = 2000
    props.viewport_caustic_photons = 500
    props.viewport_samples = 1
    props.viewport_resolution = 50
    rec = _Recorder()
    monkeypatch.setitem(sys.modules, "gpu", rec.gpu)
    monkeypatch.setitem(sys.modules, "gpu_extras", SimpleNamespace(presets=rec.presets))
    monkeypatch.setitem(sys.modules, "gpu_extras.presets", rec.presets)
    engine = _Engine()
    engine.bind_display_space_shader = rec.bind_display_space_shader
    engine.unbind_display_space_shader = rec.unbind_display_space_shader
    context = _fake_context(bpy, scene, 64, 48)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    vp = ViewportRender()
    try:
        vp.update(context, depsgraph)
        assert vp.session.wait_idle(600) and vp.session.error is None, vp.session.error
        frame = vp.session.frame
        vp.draw(engine, context, depsgraph)
        kinds = [c[0] for c in rec.calls]
        assert kinds == ["texture", "blend", "bind", "draw", "unbind", "blend"], rec.calls
        h, w = frame.rgba.shape[:2]
        assert rec.calls[0][1:] == ((w, h), "RGBA16F")
        assert (w, h) == frame.full_size == (32, 24)  # 50 % of the 64 x 48 region
        np.testing.assert_array_equal(vp.texture.data.data.reshape(h, w, 4),
                                      frame.rgba[::-1].astype(np.float32))
        assert rec.calls[1] == ("blend", "ALPHA_PREMULT") and rec.calls[-1] == ("blend", "NONE")
        _, tex, pos, dw, dh = rec.calls[3]
        assert tex is vp.texture and pos == (0.0, 0.0) and (dw, dh) == (64.0, 48.0)
        assert engine.stats[-1].startswith("Pass 1/1")
        # The same frame again: drawn without a new upload.
        rec.calls.clear()
        vp.draw(engine, context, depsgraph)
        assert [c[0] for c in rec.calls] == ["blend", "bind", "draw", "unbind", "blend"]
    finally:
        vp.stop()
