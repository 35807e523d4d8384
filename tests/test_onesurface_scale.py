"""Photon visibility's pre-test at outdoor scale (engine/onesurface.py; issues 13/14): many
triangle orientations (randomly rotated rocks and trees) made its orientation lookup
quadratic and its per-orientation grids grow without bound. The sorted lookup and the
one sole-orientation grid give exactly the old answers (the old code is kept here as the
reference), the grid's memory does not grow with the orientations asked, and a render
keeps its bits."""
import threading
import tracemalloc
from types import SimpleNamespace

import numpy as np

from engine import onesurface
from engine.onesurface import (FINE_DIVISIONS, KeyIndex, OneSurfaceCells,
                               _orientation_index, _orientation_keys, _unique_index)


def _old_index(keys, queries):
    """The lookup before issues 13/14: every query row against every key row."""
    both, ri = np.unique(queries, axis=0, return_inverse=True)
    ri = ri.reshape(-1)
    cmp = np.all(keys[None, :, :] == both[:, None, :], axis=2)
    return np.where(cmp.any(axis=1), np.argmax(cmp, axis=1), -1)[ri]


def _old_clear_of(cells, o):
    """One orientation's grid as it was built (and kept, one per orientation) before."""
    from scipy.ndimage import maximum_filter
    other = ((cells.fine != -1) & (cells.fine != o)).astype(np.uint8)
    reach = FINE_DIVISIONS + 1
    return maximum_filter(other, size=2 * reach + 1, mode="constant") == 0


def _old_free(cells, p, reach, n):
    """OneSurfaceCells.free before issues 13/14 (its quadratic lookup, per-orientation
    grids)."""
    out = np.zeros(len(p), bool)
    reach = np.broadcast_to(np.asarray(reach, np.float64), (len(p),))
    c = np.floor((p - cells.origin) / cells.cell).astype(np.int64)
    inside = np.all((c >= 0) & (c < cells.dims), axis=1) & (reach <= cells.cell)
    ci = c[inside]
    out[inside] = ~cells.busy[ci[:, 0], ci[:, 1], ci[:, 2]]
    f = np.floor((p - cells.fine_origin) / cells.fine_side).astype(np.int64)
    ask = ~out & (reach <= cells.cell) & np.all((f >= 0) & (f < cells.fine_dims), axis=1)
    rows = np.flatnonzero(ask)
    o_of = _old_index(cells.keys, _orientation_keys(n[rows]))
    found = o_of >= 0
    if not found.any():
        return out
    # (Before s29 only the 16 commonest orientations of a call were answered; the old
    # per-orientation grids answer all of them here.)
    for o in np.unique(o_of[found]):
        here = rows[o_of == o]
        if len(here):
            fi = f[here]
            out[here] = _old_clear_of(cells, int(o))[fi[:, 0], fi[:, 1], fi[:, 2]]
    return out


def _rocks_geometry(count=60, seed=0):
    """Geometry-like triangles (v0, e1, e2, ng): a 20 m ground of two triangles and
    `count` randomly rotated and scaled octahedra ("rocks") on it, some overlapping:
    4 orientations each (up to sign), hundreds in all."""
    rng = np.random.default_rng(seed)
    ground = np.array([[[-10, -10, 0], [10, -10, 0], [10, 10, 0]],
                       [[-10, -10, 0], [10, 10, 0], [-10, 10, 0]]], np.float64)
    octa = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                    np.float64)
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5],
                      [3, 1, 5], [0, 3, 5]])
    tris = [ground]
    for _ in range(count):
        q, _r = np.linalg.qr(rng.normal(size=(3, 3)))
        v = octa @ q.T * rng.uniform(0.2, 0.8) + [*rng.uniform(-8, 8, 2), rng.uniform(0, .5)]
        tris.append(v[faces])
    t = np.concatenate(tris)
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    return SimpleNamespace(v0=t[:, 0], e1=e1, e2=e2, ng=np.cross(e1, e2))


def _queries(geo, m=4000, seed=1):
    """Points on the triangles (on the ground and on the rocks' faces) with their facet
    normals, and a few with normals no triangle has."""
    rng = np.random.default_rng(seed)
    tri = rng.integers(0, len(geo.v0), m)
    tri[: m // 2] = rng.integers(0, 2, m // 2)  # half on the ground
    u, v = rng.random(m), rng.random(m)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    p = geo.v0[tri] + u[:, None] * geo.e1[tri] + v[:, None] * geo.e2[tri]
    n = geo.ng[tri] / np.linalg.norm(geo.ng[tri], axis=1, keepdims=True)
    odd = rng.random(m) < 0.05
    n[odd] = rng.normal(size=(odd.sum(), 3))
    n[odd] /= np.linalg.norm(n[odd], axis=1, keepdims=True)
    return p, n


def test_orientation_index_equals_the_pairwise_lookup():
    """The sorted lookup returns the pairwise comparison's index for every row: rows
    whose orientation some key has, rows that no key has (-1), repeated rows, keys in
    the order np.unique leaves them, and the empty cases."""
    rng = np.random.default_rng(11)
    for trial in range(20):
        keys = np.unique(rng.integers(-3, 4, (rng.integers(1, 200), 3)), axis=0)
        if trial % 2:
            keys = keys[rng.permutation(len(keys))]  # any order of distinct rows
        queries = np.concatenate([keys[rng.integers(0, len(keys), rng.integers(1, 300))],
                                  rng.integers(-4, 5, (rng.integers(1, 300), 3))])
        queries = queries[rng.permutation(len(queries))]  # keys' rows and others
        queries[0] = (9, 9, 9)  # one no key has
        got = _orientation_index(keys, queries)
        want = _old_index(keys, queries)
        assert (want == -1).any() and (want >= 0).any()
        np.testing.assert_array_equal(got, want)
    # Keys as the pre-test makes them: unit normals rounded to PLANE_TOLERANCE.
    keys = np.unique(_orientation_keys(rng.normal(size=(3000, 3))), axis=0)
    queries = np.concatenate([keys[rng.integers(0, len(keys), 5000)],
                              _orientation_keys(rng.normal(size=(500, 3)))])
    np.testing.assert_array_equal(_orientation_index(keys, queries), _old_index(keys, queries))
    assert _orientation_index(keys, np.zeros((0, 3), np.int64)).shape == (0,)
    np.testing.assert_array_equal(_orientation_index(np.zeros((0, 3), np.int64), keys[:4]),
                                  [-1] * 4)


def test_key_index_equals_the_joint_sort():
    """OneSurfaceCells' keys sorted once (KeyIndex, hair39) answer each call's rows as the
    joint sort of keys and rows did (_unique_index) and as the pairwise comparison: a
    hair groom's ~10^5 tube orientations, keys in any order, rows no key has, rows whose
    components lie beyond the packing's range (never a key's: -1), and the keys of a
    range the packing cannot hold (the joint sort answers)."""
    rng = np.random.default_rng(12)
    keys = np.unique(_orientation_keys(rng.normal(size=(100_000, 3))), axis=0)
    keys = keys[rng.permutation(len(keys))]
    index = KeyIndex(keys)
    assert index.sorted is not None
    queries = np.concatenate([keys[rng.integers(0, len(keys), 4000)],
                              _orientation_keys(rng.normal(size=(4000, 3))),
                              [[20_000, 0, 0], [-20_000, 5, 5], keys[0] + (1 << 15)]])
    want = _unique_index(keys, queries)
    np.testing.assert_array_equal(index.find(queries), want)
    assert (want[:4000] >= 0).all() and (want[-3:] == -1).all()
    small = keys[:300]
    np.testing.assert_array_equal(KeyIndex(small).find(queries[:500]),
                                  _old_index(small, queries[:500]))
    wide = np.array([[40_000, 0, 0], [0, 1, 0], [-40_000, 2, 0]], np.int64)
    assert KeyIndex(wide).sorted is None  # beyond the packing: the joint sort
    np.testing.assert_array_equal(KeyIndex(wide).find(np.array([[0, 1, 0], [40_000, 0, 0],
                                                                [1, 1, 1]])), [1, 0, -1])
    assert KeyIndex(keys).find(np.zeros((0, 3), np.int64)).shape == (0,)
    np.testing.assert_array_equal(KeyIndex(np.zeros((0, 3), np.int64)).find(keys[:3]),
                                  [-1] * 3)


def test_sole_grid_gives_every_orientations_grid():
    """_clear_of(o) read from the one sole-orientation grid equals the grid the old code
    built for o, for every orientation of the scene (and one no triangle has)."""
    geo = _rocks_geometry()
    cells = OneSurfaceCells(geo, 0.5)
    assert cells.fine is not None and len(cells.keys) > 200
    # Cells of every kind: empty, one orientation, mixed.
    assert (cells.fine == -1).any() and (cells.fine == -2).any() and (cells.fine >= 0).any()
    some_clear = 0
    for o in range(len(cells.keys) + 1):
        want = _old_clear_of(cells, o)
        np.testing.assert_array_equal(cells._clear_of(o), want)
        some_clear += int(want.sum() > (cells._sole() == -1).sum())
    assert some_clear > 10  # orientations that free cells beyond the empty ones


def test_free_equals_the_old_pretest_with_bounded_memory():
    """free() gives the old answers on points of many orientations, and what it keeps
    does not grow with the orientations asked: the old code kept one fine-grid bool
    array per orientation (hundreds here); now one int32 grid is all it keeps."""
    geo = _rocks_geometry()
    p, n = _queries(geo)
    reach = np.random.default_rng(2).uniform(0.05, 0.53, len(p))  # some wider than a cell
    cells = OneSurfaceCells(geo, 0.5)
    want = _old_free(cells, p, reach, n)
    assert want.sum() > 100 and (~want).sum() > 100
    tracemalloc.start()
    try:
        got = cells.free(p, reach, n)
        kept_one, _ = tracemalloc.get_traced_memory()
        # Ask for every orientation, one at a time.
        o_rows = _orientation_index(cells.keys, _orientation_keys(n))
        asked = 0
        for o in np.unique(o_rows[o_rows >= 0]):
            pick = o_rows == o
            np.testing.assert_array_equal(cells.free(p[pick], reach[pick], n[pick]),
                                          _old_free(cells, p[pick], reach[pick], n[pick]))
            asked += 1
        kept_all, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    np.testing.assert_array_equal(got, want)
    assert asked > 100
    grid = cells._sole().nbytes
    assert cells._sole().dtype == np.int32
    # The old per-orientation grids would have kept asked x fine.size bytes.
    assert kept_all - kept_one < grid // 4 < asked * cells.fine.size // 100


def test_free_is_thread_safe():
    """The render's worker threads share one OneSurfaceCells (photonvisibility's
    one_surface_cells): threads asking at once, the first ones building the sole grid,
    all get the single-thread answers and one grid."""
    geo = _rocks_geometry(seed=3)
    p, n = _queries(geo, seed=4)
    want = _old_free(OneSurfaceCells(geo, 0.5), p, 0.5, n)
    cells = onesurface.one_surface_cells(geo, 0.5)
    results, grids = [None] * 4, [None] * 4
    start = threading.Barrier(4)

    def work(i):
        start.wait()
        results[i] = cells.free(p[i::4], 0.5, n[i::4])
        grids[i] = id(cells._sole())

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in range(4):
        np.testing.assert_array_equal(results[i], want[i::4])
    assert len(set(grids)) == 1
    assert onesurface.one_surface_cells(geo, 0.5) is cells


def test_kept_bytes_within_the_memory_estimate():
    """What a OneSurfaceCells keeps (busy bool grid, fine and sole int32 grids) is within
    onesurface.KEPT_BYTES_MAX at its cell caps (here the caps lowered to the grids' own
    sizes), and estimate_memory counts that bound for each radius visibility asks with."""
    from engine import RenderSettings
    from engine.resources import VISIBILITY_RADII, estimate_memory
    from engine.scene import Scene
    geo = _rocks_geometry()
    cells = OneSurfaceCells(geo, 0.5)
    p, n = _queries(geo)
    assert cells.free(p, 0.5, n).any()
    kept = cells.busy.nbytes + cells.fine.nbytes + cells._sole().nbytes
    assert cells.fine.dtype == np.int32
    caps = dict(CELLS_MAX=cells.busy.size, FINE_CELLS_MAX=cells.fine.size)
    assert kept <= caps["CELLS_MAX"] + 8 * caps["FINE_CELLS_MAX"]
    assert onesurface.KEPT_BYTES_MAX == onesurface.CELLS_MAX + 8 * onesurface.FINE_CELLS_MAX
    part = estimate_memory(Scene(), RenderSettings(photons=1000)).parts["visibility pre-test"]
    assert part == VISIBILITY_RADII * onesurface.KEPT_BYTES_MAX


def _rock_field_scene():
    """A small outdoor scene for the render check: a ground, randomly rotated ico-sphere
    rocks (many facet orientations) and boxes, a glass 'water' slab, a sun."""
    from engine.api import PaperScene
    from engine.scene import Material
    rng = np.random.default_rng(5)
    s = PaperScene(width=48, height=36)
    s.add_material(Material("grass", (0.2, 0.4, 0.1), roughness=0.8))
    s.add_material(Material("stone", (0.5, 0.5, 0.45), roughness=0.7))
    s.add_material(Material("water", (1, 1, 1), transmission=1.0, ior=1.33, roughness=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), size=12, material="grass", name="ground")
    s.add_box((2.5, 2, 0.15), (3, 3, 0.3), "water", name="lake")
    for i in range(12):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        c = np.array([*rng.uniform(-4, 4, 2), 0.0])
        r = rng.uniform(0.25, 0.6)
        sph_v, sph_f = _ico(2)
        v = sph_v @ q.T * r + c + [0, 0, 0.6 * r]
        s.add_triangles(v, sph_f, "stone", name=f"rock{i}")
    s.add_sun(direction=(-0.4, 0.3, -0.85), strength=3.0)
    s.set_camera((0, -9, 3), (0, 0, 0.3), view_angle=50)
    return s


def _ico(subdivisions):
    """(vertices, faces) of a unit ico sphere (Blender's primitive_ico_sphere_add)."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
                 np.float64)
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    v = list(v / np.linalg.norm(v, axis=1, keepdims=True))
    for _ in range(subdivisions):
        mid, out = {}, []

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                m = v[a] + v[b]
                v.append(m / np.linalg.norm(m))
                mid[key] = len(v) - 1
            return mid[key]
        for a, b, c in f:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            out += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = out
    return np.array(v), np.array(f)


def test_render_keeps_its_bits(monkeypatch):
    """A render of many orientations with the new pre-test has the bits of one with the
    old pre-test (its quadratic lookup and per-orientation grids), and the pre-test did
    free rows by their own orientation (else the check proves nothing)."""
    from engine import RenderSettings
    from engine.render import render
    settings = RenderSettings(spp=2, photons=20_000, caustic_photons=5_000, seed=3,
                              workers=2)
    calls = []
    new_free = OneSurfaceCells.free

    def counted(self, p, reach, n=None):
        out = new_free(self, p, reach, n)
        if n is not None and len(p):
            coarse = new_free(self, p, reach, None)
            calls.append(int(out.sum() - coarse.sum()))
        return out

    monkeypatch.setattr(OneSurfaceCells, "free", counted)
    new = render(_rock_field_scene(), settings)
    assert sum(calls) > 0
    monkeypatch.setattr(OneSurfaceCells, "free",
                        lambda self, p, reach, n=None: _old_free(self, np.asarray(p, float),
                                                                 reach, np.asarray(n))
                        if n is not None and getattr(self, "fine", None) is not None and len(p)
                        else new_free(self, p, reach, n))
    old = render(_rock_field_scene(), settings)
    for name in ("direct", "indirect", "caustic", "specular", "emission"):
        np.testing.assert_array_equal(np.asarray(getattr(new, name)),
                                      np.asarray(getattr(old, name)), err_msg=name)
