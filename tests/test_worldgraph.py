"""engine/worldgraph.py: a world's nodes evaluated per ray (a screen-mapped backplate)."""
import numpy as np
import pytest

from engine import Camera, Environment, RenderSettings, Scene, SceneError
from engine.render import render
from engine.shadernodes import CameraView, Coordinates, ImageLookup, ViewCoordinates
from engine.textures import ImageTexture
from engine.worldgraph import WorldDirections, WorldGraph


def _camera():
    return Camera.look_at((0.0, -4.0, 0.5), (0.0, 0.0, 0.0), fov_degrees=40.0)


def test_view_points_project_through_the_camera_as_cycles_does():
    """A background's Window output is the NDC of the camera position + D (Cycles'
    camera_world_to_ndc for a perspective camera): the view direction reads the frame's
    centre; an orthographic camera projects D itself."""
    cam = _camera()
    view = CameraView(cam, 64, 48)
    forward = -np.asarray(cam.rotation, np.float64)[:, 2]
    geo = WorldDirections(forward[None], view)
    np.testing.assert_allclose(geo.view_points([0], 0, 0)[0], cam.position + forward)
    ndc = ViewCoordinates("WINDOW").evaluate(geo, [0], [0.0], [0.0])[0]
    np.testing.assert_allclose(ndc, (0.5, 0.5, 0.0), atol=1e-12)
    np.testing.assert_allclose(WorldDirections(forward[None]).view_points([0], 0, 0)[0],
                               forward)
    ortho = Camera.look_at((0.0, -4.0, 0.5), (0.0, 0.0, 0.0), kind="ORTHO",
                           ortho_scale=3.0)
    geo = WorldDirections(forward[None], CameraView(ortho, 64, 48))
    np.testing.assert_allclose(geo.view_points([0], 0, 0)[0], forward)
    # Reflection in the world: Cycles' sd->wi, the opposite of the direction.
    np.testing.assert_allclose(ViewCoordinates("REFLECTION").evaluate(
        WorldDirections(forward[None]), [0], [0.0], [0.0])[0], -forward, atol=1e-12)


def test_world_graph_sums_its_terms_with_their_factors_and_clamps_negatives():
    """radiance = sum of const x factors x colour (a Mix factor clamped to 0..1, its
    complement, a Strength as it is), negatives read 0."""
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    z = Coordinates("generated")  # (the direction; its luminance: 0.0722 z + ...)

    class Up:
        """A factor of the direction: its z."""
        def evaluate(self, geo, prim, u, v):
            return geo.dirs[np.asarray(prim), 2]

    env = Environment(np.full((4, 8, 3), 2.0, np.float32), 1.0)
    g = WorldGraph([(0.5, [], np.array([1.0, 2.0, 3.0])),
                    (1.0, [(Up(), "fac")], env),
                    (2.0, [(Up(), "1-fac")], z)])
    out = g.radiance(d)
    up = np.clip(d[:, 2], 0, 1)
    expect = (0.5 * np.array([1.0, 2.0, 3.0]) + up[:, None] * 2.0
              + 2.0 * (1 - up)[:, None] * d)
    np.testing.assert_allclose(out, np.clip(expect, 0, None), atol=1e-6)
    neg = WorldGraph([(1.0, [(Up(), "strength")], np.ones(3))]).radiance(d)
    np.testing.assert_allclose(neg[:, 0], [1.0, 0.0, 0.0])
    assert g.radiance(np.zeros((0, 3))).shape == (0, 3)


def _plate():
    yy, xx = np.mgrid[0:12, 0:16]
    return np.stack([xx / 15.0, yy / 11.0, ((xx // 2 + yy // 2) % 2) * 0.5], -1)[::-1]


def test_camera_rays_see_a_backplate_on_the_pixels():
    """A scene whose camera world is an image of the Window coordinates (nothing in
    view): each pixel of a 16 x 12 render at the image's own size reads its texel (a
    1-pixel box filter: the texel's centre, linear interpolation exact there)."""
    cam = _camera()
    plate = ImageTexture(_plate().astype(np.float32), interpolation="Closest", name="plate")
    graph = WorldGraph([(1.0, [], ImageLookup(plate, ViewCoordinates("WINDOW")))],
                       CameraView(cam, 16, 12))
    scene = Scene(camera=cam, width=16, height=12, background=(0.2, 0.2, 0.2),
                  camera_environment=graph)
    film = render(scene, RenderSettings(spp=4, photon_mapping=False, workers=1, seed=1))
    img = np.asarray(film.combined, np.float64)[..., :3]
    np.testing.assert_allclose(img, _plate(), atol=2e-3)
    with pytest.raises(SceneError, match="environment"):
        Scene(camera=cam, width=16, height=12, environment=graph).validate()
