"""engine/turnedglossy.py: camera paths keep the smooth shading normal at glossy-only
hits (metal) where Veach's guard would replace it, as Cycles does (glossyguard45), and
at Principled materials with a diffuse lobe (plastic: vase47)."""
import math

import numpy as np

from engine import turnedglossy
from engine.closures import principled as pr


def _metal_slab(bend_deg, metallic=1.0):
    """tests/test_glass_adjoint.py's slab (its top face's corner normals leaning bend_deg
    outwards) in a Principled metal (roughness 0.25; Metallic metallic): the Context."""
    from test_glass_adjoint import _slab
    from engine import RenderSettings
    from engine.accel import Accel
    from engine.geometry import prepare
    from engine.lights import prepare_lights
    from engine.render import Context
    from engine.scene import Material
    s = _slab(bend_deg, Material("metal", (0.9, 0.88, 0.85), metallic=metallic,
                                 roughness=0.25))
    s.validate()
    geo, table = prepare(s)
    lights = prepare_lights(s, geo, table)
    return Context(s, RenderSettings(photons=1000, seed=0), geo, table,
                   Accel(geo.vertices32, geo.faces32, 1), lights)


def test_glossy_only_is_metal_and_glossy_nodes_without_other_lobes():
    p = np.zeros((7, pr.N_MAT))
    p[:, pr.M_NODE] = pr.NODE_PRINCIPLED
    p[0, pr.M_METALLIC] = 1.0                      # metal: yes
    p[1, pr.M_METALLIC] = 0.5                      # half diffuse: no
    p[2, pr.M_NODE] = pr.NODE_GLOSSY               # Glossy BSDF: yes
    p[3, [pr.M_METALLIC, pr.M_SHEEN_W]] = 1.0, 0.2  # sheen keeps N in Cycles: no
    p[4, [pr.M_METALLIC, pr.M_TRANS]] = 1.0, 1.0   # transmission: turnedlight's rule
    p[5, pr.M_NODE] = pr.NODE_GLASS                # glass node: no
    # row 6: plain diffuse: no
    np.testing.assert_array_equal(turnedglossy.glossy_only(p),
                                  [True, False, True, False, False, False, False])


def test_diffuse_reflective_is_principled_below_metallic_1_without_other_lobes(monkeypatch):
    monkeypatch.setattr(turnedglossy, "SHEEN", True)
    p = np.zeros((7, pr.N_MAT))
    p[:, pr.M_NODE] = pr.NODE_PRINCIPLED
    p[0, pr.M_METALLIC] = 1.0                      # metal: glossy_only's
    p[1, pr.M_METALLIC] = 0.5                      # half diffuse: yes
    p[2, pr.M_NODE] = pr.NODE_GLOSSY               # Glossy BSDF: glossy_only's
    p[3, pr.M_SHEEN_W] = 0.2                       # sheen: yes (on N as Cycles: sheen55)
    p[4, pr.M_TRANS] = 1.0                         # transmission: turnedlight's rule
    p[5, pr.M_TL] = 0.5                            # translucent: no
    # row 6: plastic (Metallic 0): yes
    np.testing.assert_array_equal(turnedglossy.diffuse_reflective(p),
                                  [False, True, False, True, False, False, True])
    monkeypatch.setattr(turnedglossy, "SHEEN", False)  # the A/B switch: the guard there
    assert not turnedglossy.diffuse_reflective(p)[3]


def _top_hits(ctx, n=200, seed=4):
    g = np.cross(np.asarray(ctx.geo.e1), np.asarray(ctx.geo.e2))
    g /= np.linalg.norm(g, axis=1)[:, None]
    top = np.flatnonzero((g[:, 2] > 0.9) & (np.asarray(ctx.geo.material)
                                               == ctx.table.names.index("metal")))
    assert len(top) == 2  # the slab's top face
    prim = np.repeat(top.astype(np.int64), n // len(top))
    rng = np.random.default_rng(seed)
    u, v = rng.random((2, len(prim)))
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    return prim, u, v


def test_camera_unguarded_marks_exactly_the_rows_the_guard_replaces(monkeypatch):
    """Rows marked are those on glossy-only or diffuse-reflective material whose
    interpolated normal puts the viewer below it (face_shading_normals' test); a view
    from straight above marks none (None: the fused kernel runs, the same bits); with
    DIFFUSE off a diffuse material keeps the guard; the module off: None."""
    ctx = _metal_slab(50.0)
    prim, u, v = _top_hits(ctx)
    ns = ctx.geo.shading_normals(prim, u, v)
    # Grazing views from -y, 30 degrees over the face: the far (+y) half leans away.
    d = np.tile([0.0, math.cos(math.radians(30)), -math.sin(math.radians(30))], (len(prim), 1))
    want = np.einsum("ij,ij->i", ns, -d) <= 1e-6
    assert want.any() and not want.all()
    np.testing.assert_array_equal(
        turnedglossy.camera_unguarded(ctx.geo, ctx.table, prim, u, v, d), want)
    down = np.tile([0.0, 0.0, -1.0], (len(prim), 1))
    assert turnedglossy.camera_unguarded(ctx.geo, ctx.table, prim, u, v, down) is None
    mats = np.asarray(ctx.geo.material)[prim].copy()
    mats[::2] = ctx.table.names.index("floor")  # a Light Path variant that is diffuse
    got = turnedglossy.camera_unguarded(ctx.geo, ctx.table, prim, u, v, d, mats)
    np.testing.assert_array_equal(got, want)
    plain = _metal_slab(50.0, metallic=0.0)  # plastic: marked as the metal (vase47)
    np.testing.assert_array_equal(
        turnedglossy.camera_unguarded(plain.geo, plain.table, prim, u, v, d), want)
    monkeypatch.setattr(turnedglossy, "DIFFUSE", False)  # glossyguard45's rule
    got = turnedglossy.camera_unguarded(ctx.geo, ctx.table, prim, u, v, d, mats)
    np.testing.assert_array_equal(got, want & (np.arange(len(prim)) % 2 == 1))
    assert turnedglossy.camera_unguarded(plain.geo, plain.table, prim, u, v, d) is None
    monkeypatch.setattr(turnedglossy, "ENABLED", False)
    assert turnedglossy.camera_unguarded(ctx.geo, ctx.table, prim, u, v, d) is None


def _placed_slabs(monkeypatch, material, bend_deg):
    """tests/test_glass_adjoint.py's slab (material an engine.scene.Material) placed
    twice as instances of one prototype (the second mirrored, so its corners run 0, 2,
    1), prepared with shared rows (engine/sharedrows.py), and the same scene with
    world-space copies: (instanced, copies) as (geo, table) pairs, and the rows of the
    slabs' top faces (the same rows in both)."""
    from test_glass_adjoint import _slab
    from engine import resources
    from engine.geometry import prepare
    from engine.scene import Mesh, Prototype
    monkeypatch.setattr(resources, "INSTANCE_BUDGET_FRACTION", 0.0)
    out = []
    for instanced in (True, False):
        s = _slab(bend_deg, material)
        slab = next(m for m in s.meshes if m.name == "Slab")
        s.meshes.remove(slab)
        proto = Prototype("slab", slab.vertices, slab.faces, normals=slab.normals)
        for i, M in enumerate((np.eye(4)[:3], [[-1.0, 0, 0, 3.0], [0, 1, 0, 0], [0, 0, 1, 0]])):
            mesh = s.add_instance(proto, np.asarray(M, float), material=material.name,
                                  name=f"Slab{i}")
            if not instanced:  # (a copy: no instance record)
                e = mesh.expanded()
                s.meshes[s.meshes.index(mesh)] = Mesh(e.name, e.vertices, e.faces,
                                                      normals=e.normals,
                                                      materials=list(e.materials))
        s.validate()
        out.append(prepare(s))
    (gi, ti), (gc, tc) = out
    assert gi.shared is not None and gc.shared is None
    g = np.cross(np.asarray(gc.e1), np.asarray(gc.e2))
    top = np.flatnonzero((g[:, 2] > 0.0) & (np.abs(g[:, 2]) > 0.9 * np.linalg.norm(g, axis=1))
                         & (np.asarray(gc.material) == tc.names.index(material.name)))
    assert len(top) == 4  # two triangles a slab
    np.testing.assert_allclose(gi.v0[top], np.asarray(gc.v0)[top], atol=1e-9)
    return (gi, ti), (gc, tc), top


def _grazing(top, n=400, seed=6):
    """Hits spread over the rows top (barycentrics u, v) seen from -y, 30 degrees over
    the faces: (prim, u, v, d)."""
    prim = np.repeat(top.astype(np.int64), n // len(top))
    rng = np.random.default_rng(seed)
    u, v = rng.random((2, len(prim)))
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    d = np.tile([0.0, math.cos(math.radians(30)), -math.sin(math.radians(30))], (len(prim), 1))
    return prim, u, v, d


def test_instanced_hits_are_marked_as_their_copies(monkeypatch):
    """Instances whose rows are shared (a mirrored one among them) mark the same rows as
    their world-space copies: a plastic scene rendered 6.4 % apart as instances and as
    copies while instances kept the guard (tests/test_scenefile_instances.py; vase48)."""
    from engine.scene import Material
    plastic = Material("plastic", (0.8, 0.3, 0.2), roughness=0.25)
    (gi, ti), (gc, tc), top = _placed_slabs(monkeypatch, plastic, 50.0)
    prim, u, v, d = _grazing(top)
    want = turnedglossy.camera_unguarded(gc, tc, prim, u, v, d)
    assert want is not None and not want.all()
    ns = gc.shading_normals(prim, u, v)
    np.testing.assert_array_equal(want, np.einsum("ij,ij->i", ns, -d) <= 1e-6)
    np.testing.assert_array_equal(turnedglossy.camera_unguarded(gi, ti, prim, u, v, d), want)


def test_normals_pointing_into_the_surface_keep_the_guard(monkeypatch):
    """A shading normal with ns . ng <= 0 (corners leaning 100 degrees: broken custom
    normals) is never marked, plastic or metal, from either side: the guard's fall-back
    to the face keeps it from rendering black (tests/test_stability_geometry.py); the
    same slab's rows bent 50 degrees are marked (above)."""
    for metallic in (0.0, 1.0):
        ctx = _metal_slab(100.0, metallic=metallic)
        prim, u, v = _top_hits(ctx)
        ns = ctx.geo.shading_normals(prim, u, v)
        ng = np.asarray(ctx.geo.ng[prim])
        assert (np.einsum("ij,ij->i", ns, ng) < 0.0).all()
        for d in ([0.0, 0.0, -1.0], [0.0, math.cos(math.radians(30)), -math.sin(
                math.radians(30))], [0.0, 0.0, 1.0]):
            d = np.tile(d, (len(prim), 1))
            assert turnedglossy.camera_unguarded(ctx.geo, ctx.table, prim, u, v, d) is None
