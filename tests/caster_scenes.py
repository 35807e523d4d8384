"""Scenes with thin caustic casters (engine/casterspheres.py): newuser42's metal half ring
on a table, a torus and a curved glass sheet. Shared by tests/test_caster_spheres.py and
bench/bench_caster_spheres.py."""
import math

import numpy as np

from engine.api import PaperScene
from engine.scene import Material

POLISHED_METAL = Material("polished_metal", (0.95, 0.9, 0.8), metallic=1.0, roughness=0.02)
# Blender's default Principled (specular layer on): as newuser42's table, a rough specular
# surface, so the aimed shot keeps only paths whose first hit is a caster (render.py).
TABLE = Material("table", (0.8, 0.8, 0.8), roughness=0.5, specular=1.0, ior=1.45)


def half_ring_mesh(radius=1.0, height=0.35, thick=0.02, n=64):
    """newuser42's half ring (build_scenes.py half_ring): the back half (y >= 0) of an
    open cylinder wall of radius `radius`, `height` high, `thick` thick (Solidify),
    concave side towards -y. (vertices (V,3), faces (F,3))."""
    a = np.pi * np.arange(n + 1) / n
    verts, faces = [], []
    for r in (radius, radius + thick):  # inner wall, outer wall
        for z in (0.0, height):
            verts += [(r * math.cos(t), r * math.sin(t), z) for t in a]
    verts = np.array(verts)
    m = n + 1
    ib, it, ob, ot = 0, m, 2 * m, 3 * m  # row starts: inner bottom / top, outer bottom / top
    for i in range(n):
        for lo, hi in ((ib, it), (ob, ot), (it, ot), (ib, ob)):  # walls, top, bottom
            faces += [(lo + i, lo + i + 1, hi + i + 1), (lo + i, hi + i + 1, hi + i)]
    for i in (0, n):  # the two end caps
        faces += [(ib + i, ob + i, ot + i), (ib + i, ot + i, it + i)]
    return verts, np.array(faces)


def torus_mesh(center, major, minor, n=48, m=12):
    """A torus about z (vertices, faces)."""
    u = 2 * np.pi * np.arange(n) / n
    v = 2 * np.pi * np.arange(m) / m
    uu, vv = np.meshgrid(u, v, indexing="ij")
    rr = major + minor * np.cos(vv)
    verts = np.stack([rr * np.cos(uu), rr * np.sin(uu), minor * np.sin(vv)], -1).reshape(-1, 3)
    verts = verts + np.asarray(center, float)
    faces = []
    for i in range(n):
        for j in range(m):
            a, b = i * m + j, ((i + 1) % n) * m + j
            c, d = ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m
            faces += [(a, b, c), (a, c, d)]
    return verts, np.array(faces)


def curved_sheet_mesh(center, radius=0.8, angle=2.0, height=0.6, n=32):
    """A thin curved sheet: a cylinder wall piece (single-sided, as a bent glass pane),
    `angle` rad of arc, axis along z."""
    a = np.linspace(-angle / 2, angle / 2, n + 1)
    c = np.asarray(center, float)
    verts = np.array([(c[0] + radius * math.sin(t), c[1] - radius * math.cos(t), c[2] + z)
                      for z in (0.0, height) for t in a])
    m = n + 1
    faces = [f for i in range(n) for f in ((i, i + 1, m + i + 1), (i, m + i + 1, m + i))]
    return verts, np.array(faces)


ROUGH_METAL = Material("rough_metal", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.5)


def ring_scene(res=32, thick=0.02, plate=False):
    """newuser42's scene_ring: a 6 m table (roughness 0.5), the polished half ring, a
    4000 W point light of radius 0.05 at (0, -5, 1); the camera looks down at the
    cardioid. plate: the ring object also holds a 0.3 m plate of rough metal (roughness
    0.5) inside the ring at (0, 0.5, 0.6), facing the lamp (review43: a caster object's
    rough part outside its sharp part's spheres)."""
    s = PaperScene(width=res, height=res)
    s.add_material(POLISHED_METAL)
    s.add_material(TABLE)
    s.add_plane((0, 0, 0), (0, 0, 1), 6, "table", name="Table")
    v, f = half_ring_mesh(thick=thick)
    if plate:
        from engine.scene import Mesh
        s.add_material(ROUGH_METAL)
        c, u = np.array([0.0, 0.5, 0.6]), np.array([1.0, 0.0, 0.0])
        w = np.array([0.0, 1.0, -1.0]) / math.sqrt(2.0)
        corners = np.array([c - .15 * u - .15 * w, c + .15 * u - .15 * w,
                            c + .15 * u + .15 * w, c - .15 * u + .15 * w])
        faces = np.concatenate([f, np.array([[0, 1, 2], [0, 2, 3]]) + len(v)])
        s.add_mesh(Mesh("MetalRing", np.concatenate([v, corners]), faces,
                        materials=["polished_metal", "rough_metal"],
                        material_ids=np.concatenate([np.zeros(len(f), int),
                                                     np.ones(2, int)])))
    else:
        s.add_triangles(v, f, "polished_metal", name="MetalRing")
    s.add_point_light((0.0, -5.0, 1.0), power=4000, radius=0.05, name="Lamp")
    s.set_camera((0, -2.6, 3.2), (0, 0.35, 0), view_angle=54)
    return s


def torus_scene(res=32):
    """A polished metal torus lying on the table, a point light above to the side."""
    s = PaperScene(width=res, height=res)
    s.add_material(POLISHED_METAL)
    s.add_material(TABLE)
    s.add_plane((0, 0, 0), (0, 0, 1), 6, "table", name="Table")
    v, f = torus_mesh((0, 0, 0.08), 0.6, 0.08)
    s.add_triangles(v, f, "polished_metal", name="Torus")
    s.add_point_light((1.5, -2.0, 2.5), power=2000, name="Lamp")
    s.set_camera((0, -2.6, 3.2), (0, 0, 0), view_angle=50)
    return s


def sheet_scene(res=32):
    """A curved sheet of smooth glass standing on the table, a point light in front."""
    s = PaperScene(width=res, height=res)
    s.add_material(TABLE)
    s.add_plane((0, 0, 0), (0, 0, 1), 6, "table", name="Table")
    v, f = curved_sheet_mesh((0, 0.8, 0.0))
    s.add_triangles(v, f, "glass", name="Sheet")
    s.add_point_light((0.3, -3.0, 1.5), power=2000, name="Lamp")
    s.set_camera((0, -2.6, 3.2), (0, 0.3, 0), view_angle=50)
    return s

