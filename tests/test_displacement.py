"""Material displacement as Cycles' "Bump Only" (engine/displacement.py): the Displacement
and Vector Displacement nodes' vectors in Object and World space, the height along the
normal, the bumped normal against the analytic slope of a linear height, and what
engine.bsdf.surface_hit makes of it (sd->N: no bump shadowing term of its own)."""
import numpy as np
import pytest

from engine import displacement as dp
from engine.bsdf import surface_hit
from engine.geometry import prepare
from engine.normalmap import Bump
from engine.scene import Material, Mesh, Scene, SceneError


class _Ramp:
    """A height a x (world x, m) per hit, the hits on the plane of _plane."""

    def __init__(self, a):
        self.a = a

    def evaluate(self, geo, prim, u, v):
        p = geo.hit_points(np.asarray(prim), np.asarray(u), np.asarray(v)) + geo.offset
        return self.a * p[:, 0]


def _plane(linear=None, normal_map=None, z=0.0):
    """A 2 x 2 m plane at height z facing +z, one material, object matrix `linear`."""
    v = np.array([[-1, -1, z], [1, -1, z], [1, 1, z], [-1, 1, z]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    mat = Material("m", base_color=(0.5, 0.5, 0.5), normal_map=normal_map)
    mesh = Mesh("plane", v, f, materials=["m"], object_linear=linear)
    return prepare(Scene(meshes=[mesh], materials={"m": mat}))


def _hits(n=64, seed=1):
    rng = np.random.default_rng(seed)
    u, v = rng.random(n) * 0.5, rng.random(n) * 0.5
    prim = rng.integers(0, 2, n)
    return prim, u, v


def test_displacement_object_space_scales_with_the_object():
    h = _Ramp(1.0)
    prim, u, v = _hits()
    for linear, k in ((np.eye(3) * 2.0, 2.0), (np.diag([2.0, 2.0, 1.0]), 1.0),
                      (np.diag([1.0, 1.0, 3.0]), 3.0)):
        geo, _ = _plane(linear)
        d = dp.Displacement(h, midlevel=0.25, scale=0.1, space="OBJECT").evaluate(
            geo, prim, u, v)
        x = geo.hit_points(prim, u, v)[:, 0] + geo.offset[0]
        # along the normal (z), (h - midlevel) scale times the object's scale along its
        # normal: |M^T N| (Cycles' object_inverse_normal_transform, object_dir_transform)
        assert np.allclose(d[:, :2], 0.0, atol=1e-12)
        assert np.allclose(d[:, 2], k * (x - 0.25) * 0.1)
        world = dp.Displacement(h, 0.25, 0.1, space="WORLD").evaluate(geo, prim, u, v)
        assert np.allclose(world[:, 2], (x - 0.25) * 0.1)


def test_displacement_height_is_the_vector_along_the_normal():
    geo, _ = _plane()
    prim, u, v = _hits()
    vec = dp.VectorDisplacement(np.array([0.3, -0.2, 0.7]), midlevel=0.1, scale=2.0,
                                space="WORLD")
    assert np.allclose(dp.DisplacementHeight(vec).evaluate(geo, prim, u, v), (0.7 - 0.1) * 2)
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) * 2.0
    geo2, _ = _plane(rot)
    obj = dp.VectorDisplacement(np.array([0.3, -0.2, 0.7]), 0.0, 1.0, space="OBJECT")
    assert np.allclose(obj.evaluate(geo2, prim, u, v), rot @ [0.3, -0.2, 0.7])
    # A value into the Displacement socket is the vector (v, v, v) (Cycles' conversion).
    val = dp.DisplacementHeight(_Ramp(1.0)).evaluate(geo, prim, u, v)
    x = geo.hit_points(prim, u, v)[:, 0] + geo.offset[0]
    assert np.allclose(val, x)  # (x, x, x) . (0, 0, 1)
    with pytest.raises(ValueError, match="TANGENT"):
        dp.VectorDisplacement(np.zeros(3), space="TANGENT")


def test_bump_from_displacement_gives_the_analytic_slope():
    # h = a x (m) bumps the normal of a +z plane to normalize(-a, 0, 1) at distance 1.
    a, k = 0.3, 2.0
    disp = dp.Displacement(_Ramp(a), midlevel=0.0, scale=1.0 / k, space="OBJECT")
    nmap = dp.DisplacedNormals(Bump(dp.DisplacementHeight(disp), 1.0, 1.0))
    geo, table = _plane(np.eye(3) * k, nmap)
    prim, u, v = _hits()
    d = np.tile([0.0, 0.2, -1.0], (len(prim), 1))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hit = surface_hit(geo, table, prim, u, v, d)
    want = np.array([-a, 0.0, 1.0]) / np.hypot(a, 1.0)
    assert np.allclose(hit.ns, want, atol=1e-6)
    # sd->N itself: the smooth normal equals the shading normal (no bump shadowing term
    # of its own, Cycles' bump_shadowing_term returns 1 where sc->N == sd->N).
    assert np.allclose(hit.n_smooth, hit.ns)


def test_a_bump_node_bumps_the_displaced_normal_again():
    a, b = 0.3, -0.5
    disp = dp.Displacement(_Ramp(a), midlevel=0.0, scale=1.0, space="WORLD")
    then = Bump(_Ramp(b), strength=1.0, distance=1.0)
    nmap = dp.DisplacedNormals(Bump(dp.DisplacementHeight(disp), 1.0, 1.0), then)
    geo, table = _plane(None, nmap)
    prim, u, v = _hits()
    d = np.tile([0.0, 0.0, -1.0], (len(prim), 1))
    hit = surface_hit(geo, table, prim, u, v, d)
    displaced = np.array([-a, 0.0, 1.0]) / np.hypot(a, 1.0)
    assert np.allclose(hit.n_smooth, displaced, atol=1e-6)  # sd->N: the displacement's
    # The Bump node's gradient taken against the displaced normal: n - grad (b x).
    want = displaced - np.array([b, 0.0, 0.0])
    assert np.allclose(hit.ns, want / np.linalg.norm(want), atol=1e-6)
    assert np.allclose(nmap.perturb(geo, prim, u, v, np.tile([0.0, 0.0, 1.0], (len(prim), 1))),
                       hit.ns, atol=1e-9)


def test_scene_takes_displaced_normals_and_rejects_other_objects():
    nmap = dp.DisplacedNormals(Bump(dp.DisplacementHeight(_Ramp(0.1)), 1.0, 1.0))
    assert Material("ok", normal_map=nmap).normal_map is nmap
    with pytest.raises(SceneError, match="DisplacedNormals"):
        Material("bad", normal_map=object())
    with pytest.raises(ValueError, match="space"):
        dp.Displacement(_Ramp(0.1), space="TANGENT")
