"""Text scene files (TOML): the paper's planned "command processor", a scene without code.

Format (documented with an example in docs/scene_format.md):

    background = [0, 0, 0]                 # optional, linear RGB radiance

    [render]                               # any RenderSettings field, e.g.
    width = 400                            # (width / height are the image size)
    height = 300
    photons = 200000
    spp = 16

    [camera]
    position = [0, -7, 2]
    look_at = [0, 0, 2]
    up = [0, 0, 1]
    fov = 38                               # degrees across the wider side
    # type = "ortho", ortho_scale = 5, shift_x = 0, shift_y = 0

    [materials.red]                        # Material fields; predefined: red_plastic,
    base_color = [0.8, 0.1, 0.1]           # white_plastic_dull, glass, mirror, ...
    specular = 1.0

    [[objects]]                            # sphere | plane | box | mesh | file
    type = "sphere"
    center = [0, 0, 1]
    radius = 1
    material = "red"

    [[lights]]                             # point | spot | area | sun
    type = "area"
    position = [0, 0, 3.99]
    direction = [0, 0, -1]
    size = [1, 1]
    power = 60
"""
from __future__ import annotations

import math
import os
import tomllib

import numpy as np

from .api import PaperScene
from .scene import AREA, POINT, SPOT, SUN, Light, Material, Mesh, SceneError
from .settings import RenderSettings

MATERIAL_KEYS = {"base_color", "metallic", "roughness", "transmission", "ior", "specular",
                 "emission", "alpha"}


class SceneFileError(ValueError):
    pass


def _rotation(deg) -> np.ndarray:
    rx, ry, rz = (math.radians(float(a)) for a in deg)
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx  # Blender's XYZ Euler order


def _take(table: dict, where: str, allowed: set) -> dict:
    unknown = set(table) - allowed
    if unknown:
        raise SceneFileError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}; "
                             f"allowed: {', '.join(sorted(allowed))}")
    return table


def load_scene(path: str):
    """Read a TOML scene file. Returns (scene, settings_overrides dict)."""
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise SceneFileError(f"scene file '{path}' not found") from None
    except tomllib.TOMLDecodeError as e:
        raise SceneFileError(f"scene file '{path}': invalid TOML: {e}") from None
    base = os.path.dirname(os.path.abspath(path))
    try:
        return _build(data, base)
    except (SceneError, SceneFileError) as e:
        raise SceneFileError(f"{path}: {e}") from None
    except (TypeError, ValueError, KeyError) as e:
        raise SceneFileError(f"{path}: {e}") from None


def _build(data: dict, base: str):
    _take(data, "scene file", {"render", "camera", "materials", "objects", "lights", "background"})
    render = dict(data.get("render", {}))
    width = int(render.pop("width", 400))
    height = int(render.pop("height", 300))
    bad = set(render) - set(RenderSettings.names())
    if bad:
        raise SceneFileError(f"[render]: unknown setting(s) {', '.join(sorted(bad))}")
    scene = PaperScene(width=width, height=height, background=data.get("background", (0, 0, 0)))
    for name, spec in data.get("materials", {}).items():
        _take(spec, f"[materials.{name}]", MATERIAL_KEYS)
        scene.add_material(Material(name, **spec))

    cam = _take(dict(data.get("camera", {})), "[camera]",
                {"position", "look_at", "up", "fov", "type", "ortho_scale", "shift_x", "shift_y",
                 "clip_start", "clip_end"})
    if "position" not in cam or "look_at" not in cam:
        raise SceneFileError("[camera]: needs position and look_at")
    extra = {}
    if "type" in cam:
        extra["kind"] = "ORTHO" if str(cam["type"]).lower().startswith("ortho") else "PERSP"
    for k in ("ortho_scale", "shift_x", "shift_y", "clip_start", "clip_end"):
        if k in cam:
            extra[k] = float(cam[k])
    scene.set_camera(cam["position"], cam["look_at"], cam.get("up", (0, 0, 1)),
                     float(cam.get("fov", 40.0)), **extra)

    for i, obj in enumerate(data.get("objects", [])):
        _object(scene, obj, i, base)
    for i, spec in enumerate(data.get("lights", [])):
        _light(scene, spec, i)
    return scene, render


# Ray visibility and holdout per object (engine.scene.Mesh; docs/scene_format.md).
VISIBILITY_KEYS = ("visible_camera", "visible_diffuse", "visible_glossy",
                   "visible_transmission", "visible_shadow", "holdout")


def _object(scene, obj, i, base):
    kind = str(obj.get("type", "")).lower()
    where = f"objects[{i}] ({obj.get('name', kind or '?')})"
    common = {"type", "name", "material", "translate", "scale", "rotate"} | set(VISIBILITY_KEYS)
    mat = obj.get("material", "white_plastic_dull")
    name = obj.get("name")
    if kind == "sphere":
        _take(obj, where, common | {"center", "radius", "segments"})
        mesh = scene.add_sphere(obj.get("center", (0, 0, 0)), float(obj.get("radius", 1.0)), mat,
                                name, int(obj.get("segments", 48)))
    elif kind == "plane":
        _take(obj, where, common | {"center", "normal", "size", "up"})
        size = obj.get("size", 10.0)
        mesh = scene.add_plane(obj.get("center", (0, 0, 0)), obj.get("normal", (0, 0, 1)),
                               size if np.isscalar(size) else tuple(size), mat, name, obj.get("up"))
    elif kind == "box":
        _take(obj, where, common | {"center", "size"})
        mesh = scene.add_box(obj.get("center", (0, 0, 0)), obj.get("size", 1.0), mat, name)
    elif kind == "mesh":
        _take(obj, where, common | {"vertices", "faces"})
        mesh = scene.add_triangles(np.asarray(obj["vertices"], float), np.asarray(obj["faces"]),
                                   mat, name)
    elif kind == "file":
        _take(obj, where, common | {"path"})
        path = os.path.join(base, obj["path"])
        mesh = scene.add_mesh(_load_mesh_file(path, name or os.path.basename(path),
                                              scene._material(mat)))
    else:
        raise SceneFileError(f"{where}: type must be sphere, plane, box, mesh or file, got '{kind}'")
    for key in VISIBILITY_KEYS:
        if key in obj:
            if not isinstance(obj[key], bool):
                raise SceneFileError(f"{where}: {key} must be true or false, got {obj[key]!r}")
            setattr(mesh, key, obj[key])
    if any(k in obj for k in ("translate", "scale", "rotate")):
        M = _rotation(obj.get("rotate", (0, 0, 0))) * np.asarray(obj.get("scale", 1.0), float)
        t = np.asarray(obj.get("translate", (0, 0, 0)), float)
        mesh.vertices = mesh.vertices @ M.T + t
        if mesh.normals is not None:
            nm = np.linalg.inv(M).T
            mesh.normals = mesh.normals @ nm.T


def _load_mesh_file(path: str, name: str, material: str) -> Mesh:
    """OBJ / PLY / STL / glTF through trimesh (a well-kept mesh library)."""
    if not os.path.exists(path):
        raise SceneFileError(f"mesh file '{path}' not found")
    try:
        import trimesh
    except ImportError:
        raise SceneFileError("loading mesh files needs the 'trimesh' package "
                             "(pip install trimesh)") from None
    try:
        m = trimesh.load(path, force="mesh", process=False)
    except Exception as e:  # trimesh raises many exception types for bad files
        raise SceneFileError(f"mesh file '{path}': {e}") from None
    normals = None
    if getattr(m, "vertex_normals", None) is not None and len(m.vertex_normals) == len(m.vertices):
        normals = np.asarray(m.vertex_normals)
    return Mesh(name, np.asarray(m.vertices, float), np.asarray(m.faces), normals=normals,
                materials=[material])


def _light(scene, spec, i):
    kind = str(spec.get("type", "")).lower()
    where = f"lights[{i}] ({spec.get('name', kind or '?')})"
    allowed = {"type", "name", "position", "direction", "look_at", "power", "strength", "color",
               "radius", "spot_size", "blend", "size", "shape", "angle", "spread", "visible"}
    _take(spec, where, allowed)
    direction = spec.get("direction", (0, 0, -1))
    if "look_at" in spec:
        direction = np.asarray(spec["look_at"], float) - np.asarray(spec.get("position", (0, 0, 0)), float)
    name = spec.get("name", f"{kind}.{i:03d}")
    color = spec.get("color", (1, 1, 1))
    power = float(spec.get("power", spec.get("strength", 100.0)))
    kinds = {"point": POINT, "spot": SPOT, "area": AREA, "sun": SUN}
    if kind not in kinds:
        raise SceneFileError(f"{where}: type must be point, spot, area or sun, got '{kind}'")
    size = spec.get("size", 1.0)
    sx, sy = (size, size) if np.isscalar(size) else size
    scene.add_light(Light(name, kinds[kind], power, color, spec.get("position", (0, 0, 0)),
                          direction, radius=float(spec.get("radius", 0.0)),
                          spot_size=math.radians(float(spec.get("spot_size", 45.0))),
                          spot_blend=float(spec.get("blend", 0.15)),
                          shape=str(spec.get("shape", "rectangle")).upper(), size_x=float(sx),
                          size_y=float(sy), angle=math.radians(float(spec.get("angle", 0.0))),
                          spread=math.radians(float(spec.get("spread", 180.0))),
                          visible_camera=bool(spec.get("visible", False))))
