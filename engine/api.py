"""A scene-building API that reads like the paper's Figures 3-4.

    from engine.api import PaperScene
    scene = PaperScene(width=400, height=300)
    scene.add_plane((0, 0, 0), (0, 0, 1), size=10, material="white_plastic_dull")
    scene.add_sphere((0, 0, 1), 1.0, material="red_plastic")
    scene.add_rect_area_light((0, 0, 4), size=(1, 1), power=500)
    scene.set_camera(position=(0, -8, 3), look_at=(0, 0, 1), up=(0, 0, 1),
                     view_angle=40)
    film = scene.render(photons=100_000, spp=8)
    write_image(film.combined, "out.png")

The paper's own names (docs/paper_mode.md) work too, and a misspelt one is refused with
the valid names listed (an attribute nobody reads would be silently ignored):

    scene.EnablePhotonMapping()
    scene.MaxRayTraceDepth = 5          # max_depth
    scene.MaxPhotonTraceDepth = 10      # max_photon_depth
    scene.MaxPhotonSearchRadius = 0.4   # radius, in scene units (metres)
    light = scene.add_point_light((0, 0, 3.5))
    light.MaxRayPerLightSrc = 100_000   # photons this light emits
    film = scene.render(paper_mode=True, spp=8)
"""
from __future__ import annotations

import math

import numpy as np

from .scene import (AREA, POINT, SPOT, SUN, Camera, Light, Material, Mesh, Prototype, Scene,
                    SceneError)
from .scene import predefined_materials
from .settings import RenderSettings

# The paper's parameter names (Yu, Lowther, Shene 2005; docs/paper_mode.md) and the
# RenderSettings fields they set. MinPhotonsForEstimate names the paper's "too few
# photons: no estimate" threshold in the same style.
PAPER_SETTINGS = {
    "MaxRayTraceDepth": "max_depth",
    "MaxPhotonTraceDepth": "max_photon_depth",
    "MaxPhotonSearchRadius": "radius",
    "MinPhotonsForEstimate": "min_photons",
}
PAPER_METHODS = ("EnablePhotonMapping", "DisablePhotonMapping")
# The paper's Figure 6 radii (4.0, 2.0, 1.0, 0.4) are in its own scene units; its box is
# five times as wide as a search radius of 1: in our 4 m box (cornell_box) a paper radius
# r is r x 0.2 m. Paper mode takes radii in scene units (metres): convert with this.
PAPER_FIGURE6_RADIUS_SCALE = 0.2
PAPER_FIGURE6_LADDER = ((1_000, 4.0), (10_000, 2.0), (100_000, 1.0), (200_000, 0.4))


def _refuse(obj, name: str, valid) -> AttributeError:
    return AttributeError(f"{type(obj).__name__} has no attribute '{name}'; valid names: "
                          + ", ".join(sorted(set(valid))))


class PaperLight(Light):
    """A Light that also takes the paper's per-light photon count,
    `MaxRayPerLightSrc` (photons this light emits for the global map), and refuses
    attributes it does not have instead of silently keeping them."""

    def __post_init__(self):
        super().__post_init__()
        self.max_ray_per_light_src = None
        object.__setattr__(self, "_sealed", True)

    @property
    def MaxRayPerLightSrc(self):
        return self.max_ray_per_light_src

    @MaxRayPerLightSrc.setter
    def MaxRayPerLightSrc(self, value):
        self.max_ray_per_light_src = _photon_count(value, f"light '{self.name}' MaxRayPerLightSrc")

    def __setattr__(self, name, value):
        if (self.__dict__.get("_sealed") and name not in self.__dict__
                and not hasattr(type(self), name)):
            raise _refuse(self, name, [n for n in self.__dict__ if not n.startswith("_")]
                          + ["MaxRayPerLightSrc"])
        super().__setattr__(name, value)


def _photon_count(value, what: str) -> int:
    ok = not isinstance(value, bool) and isinstance(value, (int, np.integer, float)) \
        and float(value).is_integer() and value >= 0
    if not ok:
        raise SceneError(f"{what} must be a whole number >= 0, got {value!r}")
    return int(value)


def _frame(normal):
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u), n


def sphere_mesh(center, radius, segments=48, rings=24):
    """UV sphere with smooth per-vertex normals."""
    theta = np.linspace(0, math.pi, rings + 1)
    phi = np.linspace(0, 2 * math.pi, segments + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    n = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    v = np.asarray(center, np.float64) + radius * n
    uv = np.stack([p / (2 * math.pi), 1 - t / math.pi], axis=-1).reshape(-1, 2)
    faces = []
    cols = segments + 1
    r, c = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a = r * cols + c
    b = a + cols
    quad = np.stack([a, b, b + 1, a + 1], axis=-1).reshape(-1, 4)
    lower = quad[:, [0, 1, 2]][(r.reshape(-1) != rings - 1)]  # skip collapsed pole triangles
    upper = quad[:, [0, 2, 3]][(r.reshape(-1) != 0)]
    faces = np.concatenate([lower, upper])
    return v, faces, n, uv


def box_mesh(center, size):
    """Axis-aligned box with outward normals (flat shading)."""
    c = np.asarray(center, np.float64)
    s = np.broadcast_to(np.asarray(size, np.float64), (3,)) / 2
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], np.float64)
    v = c + corners * s
    faces = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                      [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])
    return v, faces


class PaperScene(Scene):
    """Scene with the paper's predefined materials and convenience builders."""

    def __init__(self, width=400, height=300, background=(0, 0, 0), **kw):
        super().__init__(width=width, height=height, background=background, **kw)
        self.materials.update(predefined_materials())
        self.paper_settings = {}         # RenderSettings fields set through the paper's names
        self.max_ray_per_light_src = None  # the scene-wide MaxRayPerLightSrc
        self.photons_per_light = None    # {light name: photons} for render (engine/render.py)
        object.__setattr__(self, "_sealed", True)

    # --- the paper's names -----------------------------------------------------------
    def _paper_names(self):
        return list(PAPER_SETTINGS) + list(PAPER_METHODS) + ["MaxRayPerLightSrc"]

    def __setattr__(self, name, value):
        if name in PAPER_SETTINGS:
            key = PAPER_SETTINGS[name]
            try:
                RenderSettings(**{key: value})
            except ValueError as e:
                raise SceneError(f"{name}: {e}") from None
            self.paper_settings[key] = value
            return
        if name == "MaxRayPerLightSrc":
            self.max_ray_per_light_src = _photon_count(value, "MaxRayPerLightSrc")
            return
        if (self.__dict__.get("_sealed") and name not in self.__dict__
                and not hasattr(type(self), name)):
            raise _refuse(self, name, self._paper_names()
                          + [n for n in self.__dict__ if not n.startswith("_")])
        super().__setattr__(name, value)

    def __getattr__(self, name):  # only for names not found the ordinary way
        if name in PAPER_SETTINGS:
            key = PAPER_SETTINGS[name]
            return self.paper_settings.get(key, getattr(RenderSettings(), key))
        if name == "MaxRayPerLightSrc":
            return self.max_ray_per_light_src
        if name.startswith("__") or not self.__dict__.get("_sealed"):
            raise AttributeError(name)
        raise _refuse(self, name, self._paper_names()
                      + [n for n in dir(type(self)) if not n.startswith("_")])

    def EnablePhotonMapping(self):
        """The paper's switch: photon mapping on (the default)."""
        self.paper_settings["photon_mapping"] = True

    def DisablePhotonMapping(self):
        """The paper's switch: plain ray tracing (the paper's Fig. 5b)."""
        self.paper_settings["photon_mapping"] = False

    def _photon_counts(self):
        """{light name: photons} from MaxRayPerLightSrc (each light's own, else the
        scene's), or None when neither is set (photons then shared by power)."""
        counts = {}
        for light in self.lights:
            own = getattr(light, "max_ray_per_light_src", None)
            n = own if own is not None else self.max_ray_per_light_src
            if n is not None:
                counts[light.name] = n
        return counts or None

    def _material(self, material) -> str:
        if isinstance(material, Material):
            self.materials[material.name] = material
            return material.name
        if material not in self.materials:
            raise SceneError(f"unknown material '{material}'; known: {', '.join(self.materials)}")
        return material

    def _name(self, base):
        return f"{base}.{len(self.meshes):03d}"

    def add_sphere(self, center, radius, material="white_plastic_dull", name=None, segments=48):
        if not radius > 0:
            raise SceneError(f"sphere radius must be > 0, got {radius}")
        v, f, n, uv = sphere_mesh(center, radius, segments, max(3, segments // 2))
        return self.add_mesh(Mesh(name or self._name("sphere"), v, f, normals=n, uvs=uv,
                                  materials=[self._material(material)]))

    def add_plane(self, center, normal=(0, 0, 1), size=10.0, material="white_plastic_dull",
                  name=None, up=None):
        """A square (or size=(w, h) rectangle) facing `normal`."""
        sx, sy = (size, size) if np.isscalar(size) else size
        u, v, n = _frame(normal)
        if up is not None:
            v = np.asarray(up, np.float64) - n * np.dot(up, n)
            v /= np.linalg.norm(v)
            u = np.cross(v, n)
        c = np.asarray(center, np.float64)
        verts = np.array([c - u * sx / 2 - v * sy / 2, c + u * sx / 2 - v * sy / 2,
                          c + u * sx / 2 + v * sy / 2, c - u * sx / 2 + v * sy / 2])
        faces = np.array([[0, 1, 2], [0, 2, 3]])
        uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
        return self.add_mesh(Mesh(name or self._name("plane"), verts, faces, uvs=uvs,
                                  materials=[self._material(material)]))

    def add_box(self, center, size, material="white_plastic_dull", name=None):
        v, f = box_mesh(center, size)
        return self.add_mesh(Mesh(name or self._name("box"), v, f,
                                  materials=[self._material(material)]))

    def add_triangles(self, vertices, faces, material="white_plastic_dull", name=None, normals=None):
        return self.add_mesh(Mesh(name or self._name("mesh"), vertices, faces, normals=normals,
                                  materials=[self._material(material)]))

    def add_instance(self, prototype, matrix, material=None, name=None, **flags):
        """Place `prototype` (an engine.scene.Prototype, or a Mesh added before, whose
        geometry becomes one) by the (4,4) or (3,4) object-to-world `matrix` without a
        world-space copy (Mesh.place): instanced geometry is stored once
        (docs/performance.md, "Instancing"). material: one material for every slot, or
        a list per slot (default: the mesh's, or "white_plastic_dull"); flags: ray
        visibility, holdout and shadow terminator keywords of Mesh. Returns the Mesh."""
        if isinstance(prototype, Mesh):
            mesh = prototype
            if mesh.copyless:
                prototype = mesh.prototype
            else:
                # The mesh's geometry becomes a prototype once; the mesh a placement of it.
                cached = getattr(mesh, "_as_prototype", None)
                if cached is None:
                    cached = Prototype(mesh.name, mesh.vertices, mesh.faces,
                                       normals=mesh.normals, uvs=mesh.uvs,
                                       material_ids=mesh.material_ids)
                    mesh._as_prototype = cached
                prototype = cached
            if material is None:
                material = list(mesh.materials)
        if not isinstance(prototype, Prototype):
            raise SceneError(f"add_instance: prototype must be an engine.scene.Prototype or "
                             f"a Mesh, got {type(prototype).__name__}")
        if material is None:
            material = "white_plastic_dull"
        slots = int(prototype.material_ids.max()) + 1 if len(prototype.material_ids) else 1
        names = [material] * slots if isinstance(material, (str, Material)) else list(material)
        names = [self._material(m) for m in names]
        return self.add_mesh(Mesh.place(name or self._name(f"{prototype.name}.instance"),
                                        prototype, matrix, materials=names, **flags))

    def add_rect_area_light(self, center, size=(1.0, 1.0), power=100.0, color=(1, 1, 1),
                            direction=(0, 0, -1), name=None, disk=False):
        """One-sided area light facing `direction` (Blender: the light's -Z)."""
        sx, sy = (size, size) if np.isscalar(size) else size
        u, _, _ = _frame(direction)
        return self.add_light(PaperLight(name or f"area.{len(self.lights):03d}", AREA, power, color,
                                    center, direction, axis_u=u, size_x=sx, size_y=sy,
                                    shape="DISK" if disk else "RECTANGLE"))

    def add_point_light(self, position, power=100.0, color=(1, 1, 1), radius=0.0, name=None,
                        soft_falloff=True, ies=None, direction=(0, 0, -1)):
        """soft_falloff: Blender's Soft Falloff (a light with a radius is a disk facing the
        lit point); False, a sphere (engine/lights/point.py). ies: an IES (LM-63) profile's
        path (engine/ies.py; its 0 degrees along direction, the lamp's -Z)."""
        return self.add_light(PaperLight(name or f"point.{len(self.lights):03d}", POINT, power, color,
                                    position, direction, radius=radius,
                                    soft_falloff=soft_falloff, ies_path=ies))

    def add_spot_light(self, position, look_at, power=100.0, color=(1, 1, 1),
                       spot_size_degrees=45.0, blend=0.15, radius=0.0, name=None,
                       soft_falloff=True, ies=None):
        """ies: an IES (LM-63) profile's path (engine/ies.py; its 0 degrees along the
        spot's axis)."""
        d = np.asarray(look_at, np.float64) - np.asarray(position, np.float64)
        return self.add_light(PaperLight(name or f"spot.{len(self.lights):03d}", SPOT, power, color,
                                    position, d, radius=radius, soft_falloff=soft_falloff,
                                    ies_path=ies,
                                    spot_size=math.radians(spot_size_degrees), spot_blend=blend))

    def add_sun(self, direction=(0, 0, -1), strength=1.0, color=(1, 1, 1), angle_degrees=0.0,
                name=None):
        return self.add_light(PaperLight(name or f"sun.{len(self.lights):03d}", SUN, strength, color,
                                    direction=direction, angle=math.radians(angle_degrees)))

    def set_environment(self, image, strength=1.0, rotation_degrees=(0.0, 0.0, 0.0),
                        interpolation="Linear"):
        """Light the scene with an equirectangular HDRI (Blender's Environment Texture):
        image = (H, W, 3) linear radiance (top row first) or a file path (EXR / NPY
        linear, PNG sRGB); rotation_degrees = the XYZ Euler rotation of a Mapping node in
        front of it. Replaces the background colour (engine/lights/environment.py)."""
        from .lights.environment import Environment
        from .scene import euler_rotation
        name = "environment"
        if isinstance(image, str):
            from .imageio import read_image
            name, image = image, read_image(image)
        rotation = euler_rotation([math.radians(float(a)) for a in rotation_degrees])
        self.environment = Environment(image, strength, rotation, interpolation, name=name)
        return self.environment

    def set_camera(self, position, look_at, up=(0, 0, 1), view_angle=40.0, aspect=None, **kw):
        """The paper's camera. view_angle in degrees across the wider image side; aspect
        (width / height) adjusts the height of the image if given."""
        if aspect is not None:
            self.height = max(1, int(round(self.width / float(aspect))))
        self.camera = Camera.look_at(position, look_at, up, view_angle, **kw)
        return self.camera

    def render(self, settings: RenderSettings | None = None, **overrides):
        """Render with `settings` or keyword settings; what was set through the paper's
        names applies on top. With MaxRayPerLightSrc set (per light or scene-wide),
        those lights emit exactly that many global photons; lights without a count
        share `photons` by power, and `photons` is the total when every light has one."""
        from dataclasses import replace

        from .render import render
        if settings is not None and overrides:
            raise TypeError("pass either a RenderSettings or keyword settings, not both")
        counts = self._photon_counts()
        paper = dict(self.paper_settings)
        if counts is not None:
            fixed = sum(counts.values())
            every = all(li.name in counts for li in self.lights)
            base = (settings.photons if settings is not None
                    else overrides.get("photons", RenderSettings().photons))
            paper["photons"] = fixed if every else fixed + base
        if settings is None:
            settings = RenderSettings(**{**overrides, **paper})
        elif paper:
            settings = replace(settings, **paper)
        self.photons_per_light = counts
        return render(self, settings)


def cornell_box(width=160, height=120, glass_sphere=True, block=True, light_power=60.0,
                green_wall=True) -> PaperScene:
    """The paper's Figure 6 scene: a 4 m box, green left wall, block, glass sphere,
    area light under the ceiling. Z is up (Blender)."""
    s = PaperScene(width=width, height=height)
    L = 4.0
    s.add_plane((0, 0, 0), (0, 0, 1), L, "white_diffuse", name="floor")
    s.add_plane((0, 0, L), (0, 0, -1), L, "white_diffuse", name="ceiling")
    s.add_plane((0, L / 2, L / 2), (0, -1, 0), L, "white_diffuse", name="back")
    s.add_plane((-L / 2, 0, L / 2), (1, 0, 0), L, "green_diffuse" if green_wall else "white_diffuse",
                name="left")
    s.add_plane((L / 2, 0, L / 2), (-1, 0, 0), L, "red_diffuse", name="right")
    if block:
        s.add_box((0.8, 0.7, 0.7), (1.0, 1.0, 1.4), "white_diffuse", name="block")
    if glass_sphere:
        s.add_sphere((-0.7, -0.4, 0.7), 0.7, "glass", name="glass_sphere")
    s.add_rect_area_light((0, 0, L - 0.01), (1.0, 1.0), power=light_power, name="ceiling_light")
    s.set_camera((0, -7.0, L / 2), (0, 0, L / 2), (0, 0, 1), view_angle=38.0)
    return s
