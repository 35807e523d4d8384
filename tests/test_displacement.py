"""Material displacement as Cycles' "Bump Only" (engine/displacement.py): the Displacement
and Vector Displacement nodes' vectors in Object and World space, the height along the
normal, the bumped normal against the analytic slope of a linear height, and what
engine.bsdf.surface_hit makes of it (sd->N: no bump shadowing term of its own)."""
import numpy as np
import pytest

from engine import displacement as dp
from engine.bsdf import surface_hit
from engine.geometry import prepare
from engine.bump import Bump
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


# --- True displacement (Displacement Only / Displacement and Bump) ----------------------
def _grid(n=8, size=2.0, normals="vertex"):
    """An n x n quad grid (size m across) at z = 0 facing +z: vertices (V,3), faces (F,3),
    smooth normals per vertex / per corner / none (flat)."""
    xs = np.linspace(-size / 2, size / 2, n + 1)
    gx, gy = np.meshgrid(xs, xs, indexing="xy")
    v = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    f = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    nrm = {"vertex": np.tile([0.0, 0.0, 1.0], (len(v), 1)),
           "corner": np.tile([0.0, 0.0, 1.0], (len(f), 3, 1)), "flat": None}[normals]
    return v, f, nrm


def _wave_height():
    """A height 0.5 + 0.5 sin(pi x) (world x, m) per hit."""
    class Wave:
        def evaluate(self, geo, prim, u, v):
            p = geo.hit_points(np.asarray(prim), np.asarray(u), np.asarray(v)) + geo.offset
            return 0.5 + 0.5 * np.sin(np.pi * p[:, 0])
    return Wave()


@pytest.mark.parametrize("normals", ["vertex", "corner", "flat"])
def test_displacement_only_moves_each_vertex_along_its_normal(normals):
    """Cycles' mesh_displace: every vertex once, by its displacement vector at the vertex
    ((h - midlevel) scale along the normal); normals recomputed as the normalised sum of
    the faces' normals (Displacement Only); flat meshes stay flat."""
    v, f, nrm = _grid(normals=normals)
    disp = dp.Displacement(_wave_height(), midlevel=0.5, scale=0.2, space="WORLD")
    mat = Material("m", displacement=disp, displacement_method="DISPLACEMENT")
    mesh = Mesh("grid", v, f, normals=nrm, materials=["m"])
    out = dp.displace_meshes([mesh], {"m": mat})
    moved = out[0]
    assert moved is not mesh and np.array_equal(mesh.vertices, v)  # the caller's untouched
    want_z = 0.2 * 0.5 * np.sin(np.pi * v[:, 0])
    np.testing.assert_allclose(moved.vertices[:, :2], v[:, :2], atol=1e-12)
    np.testing.assert_allclose(moved.vertices[:, 2], want_z, atol=1e-12)
    if normals == "flat":
        assert moved.normals is None
        return
    got = moved.normals.reshape(-1, 3) if normals == "corner" else moved.normals
    where = f.reshape(-1) if normals == "corner" else np.arange(len(v))
    # slope of the surface 0.1 sin(pi x): the normal leans against dz/dx = 0.1 pi cos(pi x)
    x = v[where, 0]
    inner = np.abs(x) < 0.99  # (edge vertices see faces on one side only)
    slope = 0.1 * np.pi * np.cos(np.pi * x[inner])
    lean = -got[inner, 0] / got[inner, 2]
    assert np.all(np.abs(lean - slope) < 0.05 + 0.05 * np.abs(slope))
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-9)


def test_displacement_and_bump_keeps_the_normals_and_bump_only_moves_nothing():
    v, f, nrm = _grid()
    disp = dp.Displacement(_wave_height(), midlevel=0.5, scale=0.2, space="WORLD")
    both = Material("b", displacement=disp, displacement_method="BOTH")
    bump = Material("u", displacement=disp, displacement_method="BUMP")
    out = dp.displace_meshes([Mesh("g1", v, f, normals=nrm, materials=["b"]),
                              Mesh("g2", v, f, normals=nrm, materials=["u"])],
                             {"b": both, "u": bump})
    np.testing.assert_allclose(out[0].vertices[:, 2], 0.1 * np.sin(np.pi * v[:, 0]),
                               atol=1e-12)
    np.testing.assert_allclose(out[0].normals, nrm)
    assert np.array_equal(out[1].vertices, v)
    with pytest.raises(SceneError, match="displacement_method"):
        Material("x", displacement=disp, displacement_method="SOMETIMES")


def test_displacement_moves_only_the_faces_of_displaced_materials_and_their_vertices():
    v, f, nrm = _grid(n=4)
    ids = (v[f].mean(axis=1)[:, 0] > 0).astype(int)  # right half: slot 1, displaced
    up = dp.VectorDisplacement(np.array([0.0, 0.0, 0.3]), 0.0, 1.0, "WORLD")
    mats = {"flat": Material("flat"),
            "up": Material("up", displacement=up, displacement_method="DISPLACEMENT")}
    out = dp.displace_meshes([Mesh("g", v, f, normals=nrm, materials=["flat", "up"],
                                   material_ids=ids)], mats)
    used = np.unique(f[ids == 1])
    want = np.zeros(len(v))
    want[used] = 0.3
    np.testing.assert_allclose(out[0].vertices[:, 2], want, atol=1e-12)


def test_instances_share_the_prototype_displacement_in_object_space():
    """Cycles displaces mesh data once: a prototype placed twice (scaled 2 and mirrored)
    moves in object space; an Object-space Displacement node scales with the object."""
    from engine.scene import Prototype
    v, f, nrm = _grid(n=4, size=1.0)
    P = Prototype("p", v, f, normals=nrm)
    disp = dp.Displacement(np.float64(1.0), midlevel=0.5, scale=0.2, space="OBJECT")
    mat = Material("m", displacement=disp, displacement_method="DISPLACEMENT")
    m1 = np.array([[2.0, 0, 0, 5], [0, 2, 0, 0], [0, 0, 2, 0]])
    m2 = np.array([[-1.0, 0, 0, -5], [0, 1, 0, 0], [0, 0, 1, 0]])
    def lin(m):
        return tuple(map(tuple, m[:, :3]))
    out = dp.displace_meshes([Mesh.place("a", P, m1, materials=["m"], object_linear=lin(m1)),
                              Mesh.place("b", P, m2, materials=["m"], object_linear=lin(m2))],
                             {"m": mat})
    assert out[0].prototype is out[1].prototype is not P
    np.testing.assert_allclose(out[0].prototype.vertices[:, 2], 0.1, atol=1e-12)
    np.testing.assert_allclose(out[0].expanded().vertices[:, 2], 0.2, atol=1e-12)
    np.testing.assert_allclose(out[1].expanded().vertices[:, 2], 0.1, atol=1e-12)


def test_prepare_merges_the_displaced_triangles_and_bad_vectors_move_nothing():
    v, f, nrm = _grid(n=2)
    class Bad:
        def evaluate(self, geo, prim, u, v_):
            out = np.zeros((len(prim), 3))
            out[:, 2] = np.nan
            return out
    scene = Scene(meshes=[Mesh("g", v, f, normals=nrm, materials=["m"])],
                  materials={"m": Material("m", displacement=dp.VectorDisplacement(
                      np.array([0.0, 0.0, 0.25]), 0.0, 1.0, "WORLD"),
                      displacement_method="DISPLACEMENT")})
    geo, _ = prepare(scene)
    z = geo.vertices32[:, 2] + geo.offset[2]
    np.testing.assert_allclose(z, 0.25, atol=1e-6)
    assert np.array_equal(scene.meshes[0].vertices, v)
    scene.materials["m"].displacement = Bad()
    geo, _ = prepare(scene)
    np.testing.assert_allclose(geo.vertices32[:, 2] + geo.offset[2], 0.0, atol=1e-6)


def test_displacement_and_bump_on_a_flat_mesh_shades_with_the_normals_from_before():
    """Cycles shades "Displacement and Bump" faces of a flat-shaded mesh smooth with the
    undisplaced vertex normals (its flat and smooth renders are the same,
    tests/blender/test_true_displacement_cycles.py); Displacement Only faces stay flat
    facets of the moved surface."""
    v, f, _ = _grid(n=4)
    disp = dp.Displacement(_wave_height(), midlevel=0.5, scale=0.2, space="WORLD")
    ids = (v[f].mean(axis=1)[:, 0] > 0).astype(int)  # right half Displacement Only
    mats = {"b": Material("b", displacement=disp, displacement_method="BOTH"),
            "d": Material("d", displacement=disp, displacement_method="DISPLACEMENT")}
    out = dp.displace_meshes([Mesh("g", v, f, materials=["b", "d"], material_ids=ids)], mats)
    n = out[0].normals
    assert n.shape == (len(f), 3, 3)
    np.testing.assert_allclose(n[ids == 0], np.broadcast_to([0.0, 0.0, 1.0], n[ids == 0].shape),
                               atol=1e-12)
    tri = out[0].vertices[f[ids == 1]]
    facet = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    facet /= np.linalg.norm(facet, axis=1, keepdims=True)
    np.testing.assert_allclose(n[ids == 1], np.repeat(facet[:, None], 3, axis=1), atol=1e-12)
