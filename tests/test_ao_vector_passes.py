"""Cycles' Ambient Occlusion and Vector passes in the engine (engine/aopass.py,
engine/vectorpass.py): analytic values, the image's bits untouched. Live Cycles:
tests/blender/test_ao_vector_passes_cycles.py.

AO: a floor under a ceiling h = 1 m above it that the camera does not see. A direction
drawn cosine-weighted leaves the floor at angle theta and meets the ceiling at
h / cos(theta): it reaches the distance D unblocked when cos(theta) < h / D, whose
probability under the cosine-weighted law (cos^2 theta uniform) is (h / D)^2. Through a
ceiling of alpha a (Cycles' transparent shadows) the blocked rays get 1 - a through:
(h / D)^2 + (1 - (h / D)^2)(1 - a).
Vector: a floor moving 0.1 m a frame along x seen from straight above (pixels a metre
W / (2 z tan(fov / 2))), and the camera moving instead (the opposite image motion)."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.render import render
from engine.scene import Camera, Material, Mesh
from engine.vectorpass import SceneMotion, shown

W, H = 12, 9
EYE = 0.5  # the camera's height over the floor (m), under the ceiling at 1 m
VIEW = 60.0


def _quad(z, half):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]],
                 float)
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def _scene(ceiling_alpha=1.0, floor_half=40.0):
    s = PaperScene(W, H, background=(0.2, 0.2, 0.2))
    s.add_material(Material("m", (0.5, 0.5, 0.5)))
    s.add_material(Material("c", (0.5, 0.5, 0.5), alpha=ceiling_alpha))
    v, f = _quad(0.0, floor_half)
    s.add_mesh(Mesh("floor", v, f, materials=["m"]))
    v, f = _quad(1.0, 40.0)
    s.add_mesh(Mesh("ceiling", v, f, materials=["c"], visible_camera=False))
    s.add_point_light((0.0, 0.0, 0.8), power=100.0)
    s.set_camera((0.0, 0.0, EYE), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), view_angle=VIEW)
    return s


def _render(scene, passes=("ao",), spp=64, **kw):
    return render(scene, RenderSettings(workers=1, spp=spp, seed=3, photons=2_000,
                                        caustic_photons=200, data_passes=passes, **kw))


@pytest.mark.parametrize("distance, alpha", [(2.0, 1.0), (4.0, 1.0), (2.0, 0.5)])
def test_ao_under_a_ceiling(distance, alpha):
    film = _render(_scene(ceiling_alpha=alpha), ao_distance=distance)
    ao = film.data["ao"]
    assert ao.shape == (H, W, 3)
    c2 = (1.0 / distance) ** 2
    expect = c2 + (1.0 - c2) * (1.0 - alpha)
    # 6912 samples: the standard error of the mean is below 0.006
    assert abs(float(ao.mean()) - expect) < 0.02, (ao.mean(), expect)
    assert np.all(ao[..., 0] == ao[..., 1])


def test_ao_within_reach_and_zero_distance():
    assert np.all(_render(_scene(), ao_distance=0.9).data["ao"] == 1.0)  # (shorter than h)
    assert np.all(_render(_scene(), ao_distance=0.0, spp=4).data["ao"] == 0.0)


def test_ao_background_is_zero():
    film = _render(_scene(floor_half=0.1), ao_distance=0.9, spp=4)
    ao = film.data["ao"][..., 0]
    assert ao[0, 0] == 0.0 and ao[H // 2, W // 2] == 1.0


def _pixels_per_metre():
    return W / (2.0 * EYE * math.tan(math.radians(VIEW) / 2.0))


def _shift(dx):
    m = np.zeros((3, 4))
    m[:, :3] = np.eye(3)
    m[0, 3] = dx
    return m


def test_vector_of_a_moving_object():
    s = _scene()
    # The floor a frame ago was 0.1 m to the right (+x), a frame on 0.1 m to the left.
    s.vector_motion = SceneMotion(objects={"floor": (_shift(0.1), _shift(-0.1))})
    vec = shown(_render(s, ("vector",), spp=4).data)
    ppm = _pixels_per_metre()
    assert vec.shape == (H, W, 4)
    assert np.allclose(vec[..., 0], 0.1 * ppm, atol=1e-6)
    assert np.allclose(vec[..., 2], 0.1 * ppm, atol=1e-6)
    assert np.allclose(vec[..., [1, 3]], 0.0, atol=1e-6)


def test_vector_of_a_moving_camera_and_the_background():
    s = _scene(floor_half=0.1)
    cam = s.camera
    # The camera moves +y (the image's up) 0.05 m a frame: the floor moves down in it.
    prev = Camera(**{**cam.__dict__, "position": cam.position - np.array([0.0, 0.05, 0.0])})
    nxt = Camera(**{**cam.__dict__, "position": cam.position + np.array([0.0, 0.05, 0.0])})
    s.vector_motion = SceneMotion(prev_camera=prev, next_camera=nxt)
    vec = shown(_render(s, ("vector",), spp=4).data)
    ppm = _pixels_per_metre()
    centre = vec[H // 2, W // 2]
    assert np.allclose(centre, [0.0, 0.05 * ppm, 0.0, 0.05 * ppm], atol=1e-6), centre
    assert np.all(vec[0, 0] == 0.0)  # the background: no surface wrote


def test_passes_leave_the_image_bits():
    s = _scene()
    s.vector_motion = SceneMotion(objects={"floor": (_shift(0.1), _shift(-0.1))})
    a = _render(s, (), spp=4)
    b = _render(s, ("ao", "vector"), spp=4, ao_distance=2.0)
    for name in ("direct", "indirect", "caustic", "specular", "emission"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_ao_distance_setting():
    assert RenderSettings().ao_distance == 10.0
    for bad in (-1.0, float("nan"), "far", True):
        with pytest.raises(ValueError, match="ao_distance"):
            RenderSettings(ao_distance=bad)


def test_write_data_passes(tmp_path):
    s = _scene()
    s.vector_motion = SceneMotion(objects={"floor": (_shift(0.1), _shift(-0.1))})
    film = _render(s, ("ao", "vector"), spp=2, ao_distance=2.0)
    names = sorted(p.rsplit(".", 2)[1] for p in film.write_data_passes(str(tmp_path / "x")))
    assert names == ["ao", "vector_post", "vector_pre"]


def test_vector_of_a_deforming_mesh():
    """A floor whose vertices spread out by 10 % a frame about the origin (deformation
    motion, SceneMotion.deform: no object transform explains it): a point P a frame ago
    was at 1.1 P... seen from straight above, pre = 0.1 x its image offset from the centre
    (the barycentric interpolation of a linear displacement is exact)."""
    s = _scene(floor_half=3.0)
    floor = s.meshes[0]
    d = 0.1 * np.asarray(floor.vertices, np.float64)
    s.vector_motion = SceneMotion(deform={"floor": (d, -d)})
    film = _render(s, ("vector", "position"), spp=1)
    vec = shown(film.data)
    pos = film.data["position"]
    ppm = _pixels_per_metre()
    assert np.allclose(vec[..., 0], 0.1 * ppm * pos[..., 0], atol=1e-4)
    assert np.allclose(vec[..., 1], 0.1 * ppm * pos[..., 1], atol=1e-4)
    assert np.allclose(vec[..., 2:], vec[..., :2], atol=1e-4)
    assert np.abs(vec).max() > 0.5


def test_ao_through_a_half_transparent_sheet():
    """The camera sees the floor through a sheet of alpha 0.5 at 1 m (both in view, the
    camera 2 m up): the sheet writes throughput x alpha = 0.5 x its AO (1: nothing above
    it), the floor the other half x its AO through the sheet, (1/2)^2 + (1 - (1/2)^2) x
    0.5 = 0.625 at D = 2 (Cycles' AO at every camera-chain surface): 0.8125."""
    s = PaperScene(W, H, background=(0.2, 0.2, 0.2))
    s.add_material(Material("m", (0.5, 0.5, 0.5)))
    s.add_material(Material("c", (0.5, 0.5, 0.5), alpha=0.5))
    v, f = _quad(0.0, 40.0)
    s.add_mesh(Mesh("floor", v, f, materials=["m"]))
    v, f = _quad(1.0, 40.0)
    s.add_mesh(Mesh("sheet", v, f, materials=["c"]))
    s.add_point_light((0.0, 0.0, 3.0), power=100.0)
    s.set_camera((0.0, 0.0, 2.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), view_angle=VIEW)
    ao = _render(s, ao_distance=2.0).data["ao"]
    assert abs(float(ao.mean()) - 0.8125) < 0.02, ao.mean()


def test_ao_of_a_holdout_is_zero():
    """A holdout surface ends the camera path before Cycles' AO: the pass reads 0 there."""
    s = _scene()
    s.meshes[0].holdout = True
    ao = _render(s, ao_distance=0.9, spp=2).data["ao"]
    assert np.all(ao == 0.0)
