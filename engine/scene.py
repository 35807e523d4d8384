"""Scene model: meshes, materials, lights, camera and background as flat numpy arrays.

Everything the renderer needs is validated here, at the boundary, so the rest of the
engine can assume finite numbers and valid indices. Structural mistakes (wrong shapes,
unknown material names) raise SceneError naming the object; repairable defects (NaN
vertices, out-of-range or degenerate faces) drop the offending faces and add a warning
naming the object, so a scene with one broken mesh still renders.

Units follow Blender/Cycles (see docs/units.md): light power in watts, sun strength in
W/m^2, emission as radiance, metres for lengths.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "SceneError", "Material", "Mesh", "Light", "Camera", "Scene",
    "POINT", "SPOT", "AREA", "SUN", "RECTANGLE", "DISK",
]

POINT, SPOT, AREA, SUN = "POINT", "SPOT", "AREA", "SUN"
RECTANGLE, DISK = "RECTANGLE", "DISK"  # area shapes; SQUARE/ELLIPSE map onto these


class SceneError(ValueError):
    """Invalid scene input; the message names the object and what is wrong."""


def _vec3(value, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.size == 1:
        arr = np.repeat(arr, 3)
    if arr.shape != (3,):
        raise SceneError(f"{what}: expected 3 numbers, got {np.asarray(value).shape}")
    if not np.all(np.isfinite(arr)):
        raise SceneError(f"{what}: values must be finite, got {arr.tolist()}")
    return arr


def _finite(value, what: str) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise SceneError(f"{what}: must be finite, got {value}")
    return v


@dataclass
class Material:
    """A Principled-like surface: the lobes Blender scenes use, with Cycles' meaning.

    Lobes, as in Blender's Principled BSDF:
      metallic          tinted mirror (rough with `roughness`)
      transmission      dielectric glass: Fresnel reflection + refraction (tinted)
      otherwise         diffuse base colour under a Fresnel coat of weight `specular`
                        (specular=0: pure Lambert; 1: plastic-like)
    `alpha` < 1 lets the rest of the light pass straight through (Transparent BSDF).
    `emission` is radiance (W/m^2/sr) leaving the front and back of the surface.
    `texture` is an optional HxWx3 linear float image multiplied onto base colour via UVs.
    """

    name: str = "default"
    base_color: tuple | np.ndarray = (0.8, 0.8, 0.8)
    metallic: float = 0.0
    roughness: float = 0.0
    transmission: float = 0.0
    ior: float = 1.5
    specular: float = 0.0
    emission: tuple | np.ndarray = (0.0, 0.0, 0.0)
    alpha: float = 1.0
    texture: np.ndarray | None = None
    warnings: list = field(default_factory=list, repr=False)

    def __post_init__(self):
        who = f"material '{self.name}'"
        self.base_color = _vec3(self.base_color, f"{who} base_color")
        self.emission = _vec3(self.emission, f"{who} emission")
        if np.any(self.emission < 0):
            raise SceneError(f"{who} emission: must be >= 0, got {self.emission.tolist()}")
        if np.any(self.base_color < 0):
            raise SceneError(f"{who} base_color: must be >= 0, got {self.base_color.tolist()}")
        if np.any(self.base_color > 1):
            # Albedo above 1 creates energy; clamp like Cycles' BSDF closures do.
            self.warnings.append(f"{who}: base colour {self.base_color.round(3).tolist()} "
                                 "above 1 clamped to 1 (it would create energy)")
            self.base_color = np.minimum(self.base_color, 1.0)
        for attr in ("metallic", "roughness", "transmission", "specular", "alpha"):
            v = _finite(getattr(self, attr), f"{who} {attr}")
            setattr(self, attr, min(max(v, 0.0), 1.0))
        self.ior = _finite(self.ior, f"{who} ior")
        if self.ior <= 0:
            raise SceneError(f"{who} ior: must be > 0, got {self.ior}")
        if self.texture is not None:
            tex = np.asarray(self.texture, dtype=np.float32)
            if tex.ndim == 2:
                tex = np.repeat(tex[:, :, None], 3, axis=2)
            if tex.ndim != 3 or tex.shape[2] < 3 or tex.shape[0] < 1 or tex.shape[1] < 1:
                raise SceneError(f"{who} texture: expected an HxWx3 image, got {tex.shape}")
            tex = np.nan_to_num(tex[:, :, :3], nan=0.0, posinf=1.0, neginf=0.0)
            self.texture = np.clip(tex, 0.0, 1.0)

    @property
    def is_emissive(self) -> bool:
        return bool(np.any(self.emission > 0))


# The paper's predefined materials (Figures 3-4), in our lobe model.
def predefined_materials() -> dict[str, Material]:
    return {
        "red_plastic": Material("red_plastic", (0.8, 0.05, 0.05), specular=1.0, ior=1.5),
        "green_plastic": Material("green_plastic", (0.05, 0.6, 0.05), specular=1.0, ior=1.5),
        "blue_plastic": Material("blue_plastic", (0.05, 0.05, 0.8), specular=1.0, ior=1.5),
        "white_plastic": Material("white_plastic", (0.8, 0.8, 0.8), specular=1.0, ior=1.5),
        "white_plastic_dull": Material("white_plastic_dull", (0.75, 0.75, 0.75)),
        "white_diffuse": Material("white_diffuse", (0.8, 0.8, 0.8)),
        "red_diffuse": Material("red_diffuse", (0.75, 0.1, 0.1)),
        "green_diffuse": Material("green_diffuse", (0.1, 0.6, 0.1)),
        "glass": Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=1.5),
        "mirror": Material("mirror", (0.95, 0.95, 0.95), metallic=1.0),
        "chrome": Material("chrome", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.15),
        "black": Material("black", (0.0, 0.0, 0.0)),
    }


@dataclass
class Mesh:
    """A triangle mesh in world space (the exporter applies object transforms).

    vertices  (V,3) float      faces (F,3) int (triangles; quads must be split first)
    normals   optional (V,3) per vertex or (F,3,3) per face corner (smooth / custom split
              normals); None = flat shading
    uvs       optional (V,2) per vertex or (F,3,2) per face corner
    material  one material name, or material_ids (F,) int indexing `materials` (names)
    shadow_terminator_offset  Cycles' object setting Shadow Terminator > Geometry Offset
              (`shadow_terminator_geometry_offset`, >= 0, Blender's default 0.1): shadow
              rays from smooth-shaded triangles at grazing light leave from the smooth
              surface the normals describe, not the flat facet (engine/rayoffset.py)
    shadow_terminator_shading_offset  Cycles' Shadow Terminator > Shading Offset (>= 0,
              < 2, default 0): pushes the terminator of direct light towards the light
              (Cycles' shift_cos_in, appleseed's fix)
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    materials: list[str] = field(default_factory=lambda: ["default"])
    material_ids: np.ndarray | None = None
    shadow_terminator_offset: float = 0.1
    shadow_terminator_shading_offset: float = 0.0
    warnings: list = field(default_factory=list, repr=False)

    def __post_init__(self):
        who = f"mesh '{self.name}'"
        try:
            sto = float(self.shadow_terminator_offset)
        except (TypeError, ValueError):
            sto = float("nan")
        if not (math.isfinite(sto) and sto >= 0):
            raise SceneError(f"{who}: shadow_terminator_offset must be a number >= 0, "
                             f"got {self.shadow_terminator_offset!r}")
        self.shadow_terminator_offset = sto
        try:
            sso = float(self.shadow_terminator_shading_offset)
        except (TypeError, ValueError):
            sso = float("nan")
        if not (math.isfinite(sso) and 0 <= sso < 2):
            raise SceneError(f"{who}: shadow_terminator_shading_offset must be a number in "
                             f"[0, 2), got {self.shadow_terminator_shading_offset!r}")
        self.shadow_terminator_shading_offset = sso
        if isinstance(self.materials, str):
            self.materials = [self.materials]
        v = np.asarray(self.vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise SceneError(f"{who}: vertices must have shape (V,3), got {v.shape}")
        f = np.asarray(self.faces)
        if f.size == 0:
            f = f.reshape(0, 3)
        if f.ndim != 2 or f.shape[1] != 3:
            raise SceneError(f"{who}: faces must have shape (F,3) (triangles), got {f.shape}")
        if not np.issubdtype(f.dtype, np.integer):
            if not np.all(np.isfinite(f)) or not np.all(f == np.round(f)):
                raise SceneError(f"{who}: face indices must be integers")
        f = f.astype(np.int64)
        nf = len(f)
        if self.material_ids is None:
            mids = np.zeros(nf, dtype=np.int32)
        else:
            mids = np.asarray(self.material_ids).astype(np.int64).reshape(-1)
            if mids.shape != (nf,):
                raise SceneError(f"{who}: material_ids must have one entry per face ({nf}), "
                                 f"got {mids.shape}")
            if nf and (mids.min() < 0 or mids.max() >= len(self.materials)):
                raise SceneError(f"{who}: material_ids out of range 0..{len(self.materials) - 1}")
            mids = mids.astype(np.int32)
        normals = None if self.normals is None else np.asarray(self.normals, dtype=np.float64)
        if normals is not None and normals.shape not in ((len(v), 3), (nf, 3, 3)):
            raise SceneError(f"{who}: normals must be (V,3) or (F,3,3), got {normals.shape}")
        uvs = None if self.uvs is None else np.asarray(self.uvs, dtype=np.float64)
        if uvs is not None and uvs.shape not in ((len(v), 2), (nf, 3, 2)):
            raise SceneError(f"{who}: uvs must be (V,2) or (F,3,2), got {uvs.shape}")

        # Repairable defects: drop the faces, say how many and why.
        keep = np.ones(nf, dtype=bool)
        bad_index = np.any((f < 0) | (f >= len(v)), axis=1)
        if bad_index.any():
            self.warnings.append(f"{who}: dropped {int(bad_index.sum())} faces with vertex "
                                 f"indices outside 0..{len(v) - 1}")
            keep &= ~bad_index
        fi = np.where(keep[:, None], f, 0)
        if len(v):
            finite_v = np.all(np.isfinite(v), axis=1)
            bad_v = ~np.all(finite_v[fi], axis=1) & keep
            if bad_v.any():
                self.warnings.append(f"{who}: dropped {int(bad_v.sum())} faces that use "
                                     "NaN or infinite vertex coordinates")
                keep &= ~bad_v
            vv = np.where(np.isfinite(v), v, 0.0)
            e1 = vv[fi[:, 1]] - vv[fi[:, 0]]
            e2 = vv[fi[:, 2]] - vv[fi[:, 0]]
            area2 = np.linalg.norm(np.cross(e1, e2), axis=1)
            scale = np.maximum(np.linalg.norm(e1, axis=1), np.linalg.norm(e2, axis=1))
            degenerate = (area2 <= 1e-12 * np.maximum(scale * scale, 1e-300)) & keep
            if degenerate.any():
                self.warnings.append(f"{who}: dropped {int(degenerate.sum())} zero-area faces")
                keep &= ~degenerate
        if normals is not None:
            normals = np.nan_to_num(normals, nan=0.0, posinf=0.0, neginf=0.0)
        if uvs is not None:
            uvs = np.nan_to_num(uvs, nan=0.0, posinf=0.0, neginf=0.0)
        if not keep.all():
            f = f[keep]
            mids = mids[keep]
            if normals is not None and normals.ndim == 3:
                normals = normals[keep]
            if uvs is not None and uvs.ndim == 3:
                uvs = uvs[keep]
        self.vertices = np.where(np.isfinite(v), v, 0.0)
        self.faces = f
        self.material_ids = mids
        self.normals = normals
        self.uvs = uvs


@dataclass
class Light:
    """A light with Blender/Cycles units (docs/units.md).

    kind      POINT, SPOT, AREA or SUN
    power     watts for point/spot/area (total emitted flux), W/m^2 irradiance for sun
    color     RGB multiplier of power
    position  world position (ignored for SUN)
    direction the light's local -Z axis in world space (spot axis, area normal, sun rays)
    radius    point/spot soft-shadow radius (Blender `shadow_soft_size`)
    spot_size full cone angle in radians; spot_blend 0..1
    shape     RECTANGLE or DISK for area lights; size_x, size_y in world units (already
              multiplied by object scale); axis_u gives the local +X direction
    angle     sun angular diameter in radians
    normalize area light power divided by area (Blender default True)
    visible_camera  lights are invisible to camera rays by default in Blender
    """

    name: str = "light"
    kind: str = POINT
    power: float = 100.0
    color: tuple | np.ndarray = (1.0, 1.0, 1.0)
    position: tuple | np.ndarray = (0.0, 0.0, 0.0)
    direction: tuple | np.ndarray = (0.0, 0.0, -1.0)
    axis_u: tuple | np.ndarray = (1.0, 0.0, 0.0)
    radius: float = 0.0
    spot_size: float = math.radians(45.0)
    spot_blend: float = 0.15
    shape: str = RECTANGLE
    size_x: float = 1.0
    size_y: float = 1.0
    angle: float = 0.0
    normalize: bool = True
    visible_camera: bool = False
    warnings: list = field(default_factory=list, repr=False)

    def __post_init__(self):
        who = f"light '{self.name}'"
        self.kind = str(self.kind).upper()
        if self.kind not in (POINT, SPOT, AREA, SUN):
            raise SceneError(f"{who}: unknown kind '{self.kind}' (POINT, SPOT, AREA, SUN)")
        self.shape = {"SQUARE": RECTANGLE, "ELLIPSE": DISK}.get(str(self.shape).upper(),
                                                                 str(self.shape).upper())
        if self.shape not in (RECTANGLE, DISK):
            raise SceneError(f"{who}: unknown area shape '{self.shape}'")
        self.color = _vec3(self.color, f"{who} color")
        if np.any(self.color < 0):
            raise SceneError(f"{who} color: must be >= 0")
        self.position = _vec3(self.position, f"{who} position")
        d = _vec3(self.direction, f"{who} direction")
        n = np.linalg.norm(d)
        if n < 1e-12:
            raise SceneError(f"{who} direction: must not be the zero vector")
        self.direction = d / n
        u = _vec3(self.axis_u, f"{who} axis_u")
        u = u - self.direction * np.dot(u, self.direction)
        if np.linalg.norm(u) < 1e-9:  # pick any perpendicular axis
            u = np.cross(self.direction, [1.0, 0.0, 0.0])
            if np.linalg.norm(u) < 1e-6:
                u = np.cross(self.direction, [0.0, 1.0, 0.0])
        self.axis_u = u / np.linalg.norm(u)
        for attr in ("power", "radius", "spot_size", "spot_blend", "size_x", "size_y", "angle"):
            setattr(self, attr, _finite(getattr(self, attr), f"{who} {attr}"))
        if self.power < 0:
            raise SceneError(f"{who} power: must be >= 0, got {self.power}")
        self.radius = max(self.radius, 0.0)
        self.size_x, self.size_y = abs(self.size_x), abs(self.size_y)
        self.spot_size = min(max(self.spot_size, 1e-4), math.pi)
        self.spot_blend = min(max(self.spot_blend, 0.0), 1.0)
        self.angle = min(max(self.angle, 0.0), math.pi)
        if self.kind == AREA and self.size_x * self.size_y <= 0:
            self.warnings.append(f"{who}: area light of zero size emits nothing")

    @property
    def axis_v(self) -> np.ndarray:
        # Right-handed local frame: u x v = +Z = -direction.
        return np.cross(-self.direction, self.axis_u)

    @property
    def area(self) -> float:
        a = self.size_x * self.size_y
        return a * math.pi / 4.0 if self.shape == DISK else a

    @property
    def flux(self) -> np.ndarray:
        """Total emitted RGB flux in watts (sun: per m^2 of its beam)."""
        p = self.power * self.color
        if self.kind == SPOT:
            # Cycles spot = point light masked by the cone (no renormalisation):
            # flux = I * solid angle with smoothstep falloff, integrated numerically.
            return p * spot_cone_fraction(self.spot_size, self.spot_blend)
        if self.kind == AREA and not self.normalize:
            return p * self.area  # power given per unit area
        return p


def spot_mask(cos_theta, spot_size: float, spot_blend: float):
    """Cycles' spot falloff: smoothstep of the cosine inside the cone."""
    cos_half = math.cos(spot_size / 2.0)
    width = (1.0 - cos_half) * spot_blend
    x = np.asarray(cos_theta, dtype=np.float64) - cos_half
    if width <= 0:
        return (x > 0).astype(np.float64)
    f = np.clip(x / width, 0.0, 1.0)
    return f * f * (3.0 - 2.0 * f)


def spot_cone_fraction(spot_size: float, spot_blend: float) -> float:
    """Fraction of a point light's 4*pi*I flux that leaves through the spot's mask."""
    cos_half = math.cos(spot_size / 2.0)
    c = np.linspace(cos_half, 1.0, 4097)
    m = spot_mask(c, spot_size, spot_blend)
    # Solid angle element 2*pi*d(cos); fraction of the 4*pi sphere.
    return float(np.trapz(m, c) * 2.0 * math.pi / (4.0 * math.pi))


@dataclass
class Camera:
    """Pinhole or orthographic camera, Blender conventions.

    position, and a rotation whose columns are the camera's right (x), up (y) and back
    (z) axes in world space: the camera looks along -z. `fov` is the full angle across the
    larger image dimension (Blender's sensor fit AUTO); `ortho_scale` likewise in world
    units. shift_x / shift_y are in units of the larger image dimension (as Blender's).
    """

    position: tuple | np.ndarray = (0.0, 0.0, 5.0)
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    fov: float = math.radians(39.6)
    kind: str = "PERSP"
    ortho_scale: float = 7.0
    shift_x: float = 0.0
    shift_y: float = 0.0
    sensor_fit: str = "AUTO"  # AUTO (larger dimension), HORIZONTAL or VERTICAL
    clip_start: float = 0.0
    clip_end: float = float("inf")

    def __post_init__(self):
        self.position = _vec3(self.position, "camera position")
        r = np.asarray(self.rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)):
            raise SceneError(f"camera rotation: expected a finite 3x3 matrix, got {r.shape}")
        # Orthonormalise (exporters may pass scaled matrices).
        x = r[:, 0] / max(np.linalg.norm(r[:, 0]), 1e-300)
        z = r[:, 2] - x * np.dot(r[:, 2], x)
        z /= max(np.linalg.norm(z), 1e-300)
        y = np.cross(z, x)
        self.rotation = np.stack([x, y, z], axis=1)
        self.kind = str(self.kind).upper()
        if self.kind not in ("PERSP", "ORTHO"):
            raise SceneError(f"camera kind: must be PERSP or ORTHO, got {self.kind}")
        self.fov = min(max(_finite(self.fov, "camera fov"), 1e-6), math.pi - 1e-6)
        self.ortho_scale = _finite(self.ortho_scale, "camera ortho_scale")
        if self.ortho_scale <= 0:
            raise SceneError("camera ortho_scale: must be > 0")
        self.shift_x = _finite(self.shift_x, "camera shift_x")
        self.shift_y = _finite(self.shift_y, "camera shift_y")
        self.sensor_fit = str(self.sensor_fit).upper()
        self.clip_start = max(float(self.clip_start), 0.0)
        self.clip_end = float(self.clip_end) if self.clip_end > 0 else float("inf")

    @classmethod
    def look_at(cls, position, look_at, up=(0.0, 0.0, 1.0), fov_degrees=40.0, **kw):
        """The paper's camera: position, look-at point, up vector, view angle (degrees)."""
        p = _vec3(position, "camera position")
        forward = _vec3(look_at, "camera look_at") - p
        if np.linalg.norm(forward) < 1e-12:
            raise SceneError("camera: look_at must differ from position")
        forward /= np.linalg.norm(forward)
        upv = _vec3(up, "camera up")
        x = np.cross(forward, upv)
        if np.linalg.norm(x) < 1e-9:
            x = np.cross(forward, [1.0, 0.0, 0.0] if abs(forward[0]) < 0.9 else [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        y = np.cross(x, forward)
        rot = np.stack([x, y, -forward], axis=1)
        return cls(position=p, rotation=rot, fov=math.radians(fov_degrees), **kw)

    def half_extents(self, width: int, height: int) -> tuple[float, float]:
        """Half width and height of the image plane at distance 1 (ortho: world units)."""
        aspect = width / height
        fit = self.sensor_fit
        if fit == "AUTO":
            fit = "HORIZONTAL" if width >= height else "VERTICAL"
        half = math.tan(self.fov / 2.0) if self.kind == "PERSP" else self.ortho_scale / 2.0
        if fit == "HORIZONTAL":
            return half, half / aspect
        return half * aspect, half


@dataclass
class Scene:
    """All scene content. Build with the add_* methods (see engine.api for the paper's
    convenience calls) or assign lists directly; call validate() (render does)."""

    meshes: list[Mesh] = field(default_factory=list)
    materials: dict[str, Material] = field(default_factory=dict)
    lights: list[Light] = field(default_factory=list)
    camera: Camera | None = None
    width: int = 320
    height: int = 240
    background: tuple | np.ndarray = (0.0, 0.0, 0.0)
    background_is_light: bool = True
    warnings: list = field(default_factory=list)

    def add_material(self, material: Material) -> Material:
        self.materials[material.name] = material
        return material

    def add_mesh(self, mesh: Mesh) -> Mesh:
        self.meshes.append(mesh)
        return mesh

    def add_light(self, light: Light) -> Light:
        self.lights.append(light)
        return light

    def all_warnings(self) -> list[str]:
        out = list(self.warnings)
        for m in self.materials.values():
            out += m.warnings
        for m in self.meshes:
            out += m.warnings
        for light in self.lights:
            out += light.warnings
        seen, unique = set(), []
        for w in out:
            if w not in seen:
                seen.add(w)
                unique.append(w)
        return unique

    def validate(self) -> None:
        """Raise SceneError for what cannot render; warn (scene.warnings) for the rest."""
        self.width, self.height = int(self.width), int(self.height)
        if self.width < 1 or self.height < 1:
            raise SceneError(f"resolution must be at least 1x1, got {self.width}x{self.height}")
        if self.camera is None:
            raise SceneError("scene has no camera: add one (Camera.look_at(...))")
        self.background = _vec3(self.background, "background")
        if np.any(self.background < 0):
            raise SceneError("background: colour must be >= 0")
        for mesh in self.meshes:
            for name in mesh.materials:
                if name not in self.materials:
                    if name == "default":
                        self.materials["default"] = Material("default")
                    else:
                        raise SceneError(f"mesh '{mesh.name}': unknown material '{name}'")
        has_emitter = any(m.is_emissive for m in self.materials.values())
        if not self.lights and not has_emitter and not np.any(self.background > 0):
            msg = "scene has no lights, emissive materials or background light: image is black"
            if msg not in self.warnings:
                self.warnings.append(msg)
