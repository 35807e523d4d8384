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
from .lights import DECLARED_KINDS
from .scene import MATERIAL_NODES, Light, Material, Mesh, SceneError
from .settings import RenderSettings

MATERIAL_KEYS = {"base_color", "metallic", "roughness", "transmission", "ior", "specular",
                 "emission", "alpha", "specular_ior_level", "specular_tint", "coat_weight",
                 "coat_roughness", "coat_ior", "coat_tint", "sheen_weight", "sheen_roughness",
                 "sheen_tint", "glossy_color", "multiscatter", "node"}
MAX_RESOLUTION = 65536    # pixels per side, as Blender
MAX_SEGMENTS = 2048       # sphere segments: 2048 x 1024 x 2 = 4M triangles
MAX_INLINE_ELEMENTS = 10_000_000  # vertices / faces written into the scene file itself
_MISSING = object()


class SceneFileError(ValueError):
    pass


def _rotation(deg) -> np.ndarray:
    rx, ry, rz = (math.radians(float(a)) for a in deg)
    cx, sx, cy, sy, cz, sz = (math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry),
                              math.cos(rz), math.sin(rz))
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx  # Blender's XYZ Euler order


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


class _Table:
    """Typed reads from one TOML table. TOML already gives typed values (a string stays a
    string), so each read accepts only the type it documents - never a guess such as
    "no" read as true - and every refusal is one line naming the table and the key."""

    def __init__(self, table, where: str, allowed: set):
        if not isinstance(table, dict):
            raise SceneFileError(f"{where}: must be a table (key = value lines), got "
                                 f"{_show(table)}")
        unknown = set(table) - allowed
        if unknown:
            raise SceneFileError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}; "
                                 f"allowed: {', '.join(sorted(allowed))}")
        self.table = table
        self.where = where

    def __contains__(self, key):
        return key in self.table

    def fail(self, key, what, value):
        raise SceneFileError(f"{self.where}: '{key}' must be {what}, got {_show(value)}")

    def get(self, key, default=_MISSING):
        if key in self.table:
            return self.table[key]
        if default is _MISSING:
            raise SceneFileError(f"{self.where}: '{key}' is required")
        return default

    def number(self, key, default=_MISSING, lo=None, hi=None, lo_open=False, hi_open=False):
        v = self.get(key, default)
        if not _is_number(v) or not math.isfinite(v):
            self.fail(key, "a finite number", v)
        v = float(v)
        if lo is not None and (v < lo or (lo_open and v == lo)):
            self.fail(key, _range_text(lo, hi, lo_open, hi_open), v)
        if hi is not None and (v > hi or (hi_open and v == hi)):
            self.fail(key, _range_text(lo, hi, lo_open, hi_open), v)
        return v

    def integer(self, key, default=_MISSING, lo=None, hi=None):
        v = self.get(key, default)
        if not isinstance(v, int) or isinstance(v, bool):
            self.fail(key, "a whole number", v)
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            self.fail(key, _range_text(lo, hi), v)
        return v

    def boolean(self, key, default=_MISSING):
        v = self.get(key, default)
        if not isinstance(v, bool):
            self.fail(key, "true or false", v)
        return v

    def string(self, key, default=_MISSING, choices=None):
        v = self.get(key, default)
        if not isinstance(v, str):
            self.fail(key, "a string", v)
        if choices is not None and v.lower() not in choices:
            self.fail(key, "one of " + ", ".join(choices), v)
        return v

    def vec3(self, key, default=_MISSING, nonzero=False, nonneg=False):
        v = self.get(key, default)
        if (not isinstance(v, (list, tuple)) or len(v) != 3
                or not all(_is_number(x) and math.isfinite(x) for x in v)):
            self.fail(key, "3 finite numbers [x, y, z]", v)
        arr = np.asarray(v, np.float64)
        if nonzero and not np.any(arr != 0):
            self.fail(key, "a non-zero vector", v)
        if nonneg and np.any(arr < 0):
            self.fail(key, "3 numbers >= 0", v)
        return arr

    def size(self, key, default=_MISSING, count=2):
        """A positive size: one number, or `count` numbers (one per axis)."""
        v = self.get(key, default)
        values = [v] if _is_number(v) else v
        what = f"a number > 0 or {count} numbers > 0"
        if (not isinstance(values, (list, tuple)) or len(values) not in (1, count)
                or not all(_is_number(x) and math.isfinite(x) and x > 0 for x in values)):
            self.fail(key, what, v)
        return float(values[0]) if len(values) == 1 else tuple(float(x) for x in values)


def _show(v) -> str:
    text = repr(v) if not isinstance(v, str) else f'"{v}"'
    return text if len(text) <= 60 else text[:57] + "..."


def _range_text(lo, hi, lo_open=False, hi_open=False) -> str:
    if lo is not None and hi is not None:
        return (f"a number {'>' if lo_open else '>='} {lo:g} and "
                f"{'<' if hi_open else '<='} {hi:g}")
    if lo is not None:
        return f"a number {'>' if lo_open else '>='} {lo:g}"
    return f"a number {'<' if hi_open else '<='} {hi:g}"


def _array_of_tables(data, key) -> list:
    v = data.get(key, [])
    if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
        raise SceneFileError(f"'{key}' must be an array of tables ([[{key}]] sections), "
                             f"got {_show(v)}")
    return v


def load_scene(path: str):
    """Read a TOML scene file. Returns (scene, settings_overrides dict). Raises
    SceneFileError with one line naming the file and the key for anything that is not
    a valid scene: wrong types, non-finite numbers, out-of-range values, unknown keys."""
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise SceneFileError(f"scene file '{path}' not found") from None
    except tomllib.TOMLDecodeError as e:
        raise SceneFileError(f"scene file '{path}': invalid TOML: {e}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise SceneFileError(f"scene file '{path}': cannot be read: {e}") from None
    base = os.path.dirname(os.path.abspath(path))
    try:
        return _build(data, base)
    except (SceneError, SceneFileError) as e:
        raise SceneFileError(f"{path}: {e}") from None
    except (TypeError, ValueError, KeyError, OverflowError, MemoryError) as e:
        raise SceneFileError(f"{path}: {type(e).__name__}: {e}") from None


def _build(data: dict, base: str):
    top = _Table(data, "scene file", {"render", "camera", "materials", "objects", "lights",
                                      "background"})
    render_table = _Table(top.get("render", {}), "[render]",
                          set(RenderSettings.names()) | {"width", "height"})
    width = render_table.integer("width", 400, 1, MAX_RESOLUTION)
    height = render_table.integer("height", 300, 1, MAX_RESOLUTION)
    render = {k: v for k, v in render_table.table.items() if k not in ("width", "height")}
    try:
        RenderSettings(**render)  # types and ranges of every setting, named
    except ValueError as e:
        raise SceneFileError(f"[render]: {e}") from None
    background = top.vec3("background", (0.0, 0.0, 0.0), nonneg=True)
    scene = PaperScene(width=width, height=height, background=background)
    materials = top.get("materials", {})
    if not isinstance(materials, dict):
        raise SceneFileError(f"'materials' must be a table of [materials.NAME] sections, got "
                             f"{_show(materials)}")
    for name, spec in materials.items():
        _material(scene, name, spec)
    _camera(scene, _Table(top.get("camera", {}), "[camera]",
                          {"position", "look_at", "up", "fov", "type", "ortho_scale", "shift_x",
                           "shift_y", "clip_start", "clip_end"}))
    for i, obj in enumerate(_array_of_tables(data, "objects")):
        _object(scene, obj, i, base)
    for i, spec in enumerate(_array_of_tables(data, "lights")):
        _light(scene, spec, i)
    return scene, render


def _material(scene, name, spec):
    t = _Table(spec, f"[materials.{name}]", MATERIAL_KEYS)
    kw = {}
    for key in ("base_color", "emission", "specular_tint", "coat_tint", "sheen_tint",
                "glossy_color"):
        if key in t:
            kw[key] = t.vec3(key, nonneg=True)
    for key in ("metallic", "roughness", "transmission", "specular", "alpha",
                "coat_roughness", "sheen_roughness"):
        if key in t:
            kw[key] = t.number(key, lo=0.0, hi=1.0)
    for key in ("specular_ior_level", "coat_weight", "sheen_weight"):
        if key in t:
            kw[key] = t.number(key, lo=0.0)
    if "ior" in t:
        kw["ior"] = t.number("ior", lo=0.0, lo_open=True)
    if "coat_ior" in t:
        kw["coat_ior"] = t.number("coat_ior", lo=1.0)
    if "multiscatter" in t:
        kw["multiscatter"] = t.boolean("multiscatter")
    if "node" in t:
        kw["node"] = t.string("node", choices=MATERIAL_NODES)
    scene.add_material(Material(name, **kw))


def _camera(scene, cam):
    position = cam.vec3("position")
    look_at = cam.vec3("look_at")
    if np.allclose(position, look_at):
        raise SceneFileError("[camera]: 'look_at' must differ from 'position'")
    up = cam.vec3("up", (0, 0, 1), nonzero=True)
    extra = {}
    if "type" in cam:
        extra["kind"] = "ORTHO" if cam.string("type", choices=("persp", "ortho")).lower() \
            == "ortho" else "PERSP"
    if "ortho_scale" in cam:
        extra["ortho_scale"] = cam.number("ortho_scale", lo=0.0, lo_open=True)
    for k in ("shift_x", "shift_y"):
        if k in cam:
            extra[k] = cam.number(k)
    if "clip_start" in cam:
        extra["clip_start"] = cam.number("clip_start", lo=0.0, lo_open=True)
    if "clip_end" in cam:
        extra["clip_end"] = cam.number("clip_end", lo=extra.get("clip_start", 0.0),
                                       lo_open=True)
    fov = cam.number("fov", 40.0, lo=0.0, hi=180.0, lo_open=True, hi_open=True)
    scene.set_camera(position, look_at, up, fov, **extra)


# Ray visibility and holdout per object (engine.scene.Mesh; docs/scene_format.md).
VISIBILITY_KEYS = ("visible_camera", "visible_diffuse", "visible_glossy",
                   "visible_transmission", "visible_shadow", "holdout")


def _object(scene, obj, i, base):
    raw_kind = obj.get("type", "")
    kind = raw_kind.lower() if isinstance(raw_kind, str) else ""
    label = obj.get("name", kind or "?")
    where = f"objects[{i}] ({label})"
    common = {"type", "name", "material", "translate", "scale", "rotate"} | set(VISIBILITY_KEYS)
    allowed = {"sphere": {"center", "radius", "segments"},
               "plane": {"center", "normal", "size", "up"},
               "box": {"center", "size"}, "mesh": {"vertices", "faces"}, "file": {"path"}}
    if kind not in allowed:
        raise SceneFileError(f"{where}: 'type' must be sphere, plane, box, mesh or file, got "
                             f"{_show(raw_kind)}")
    t = _Table(obj, where, common | allowed[kind])
    mat = t.string("material", "white_plastic_dull")
    name = t.string("name", None) if "name" in t else None
    if kind == "sphere":
        mesh = scene.add_sphere(t.vec3("center", (0, 0, 0)),
                                t.number("radius", 1.0, lo=0.0, lo_open=True), mat, name,
                                t.integer("segments", 48, 3, MAX_SEGMENTS))
    elif kind == "plane":
        up = t.vec3("up", nonzero=True) if "up" in t else None
        mesh = scene.add_plane(t.vec3("center", (0, 0, 0)),
                               t.vec3("normal", (0, 0, 1), nonzero=True),
                               t.size("size", 10.0, 2), mat, name, up)
    elif kind == "box":
        mesh = scene.add_box(t.vec3("center", (0, 0, 0)), t.size("size", 1.0, 3), mat, name)
    elif kind == "mesh":
        vertices, faces = t.get("vertices"), t.get("faces")
        for key, v in (("vertices", vertices), ("faces", faces)):
            if not isinstance(v, list) or len(v) > MAX_INLINE_ELEMENTS:
                t.fail(key, f"a list of at most {MAX_INLINE_ELEMENTS:,} [a, b, c] rows", v)
        try:
            vertices = np.asarray(vertices, np.float64)
            faces = np.asarray(faces)
        except (TypeError, ValueError):
            raise SceneFileError(f"{where}: 'vertices' / 'faces' must be lists of 3 numbers "
                                 "each") from None
        if faces.size and faces.dtype.kind not in "iu":
            t.fail("faces", "rows of 3 whole-number vertex indices", obj["faces"])
        mesh = scene.add_triangles(vertices, faces, mat, name)
    else:
        path = os.path.join(base, t.string("path"))
        mesh = scene.add_mesh(_load_mesh_file(path, name or os.path.basename(path),
                                              scene._material(mat)))
    for key in VISIBILITY_KEYS:
        if key in t:
            setattr(mesh, key, t.boolean(key, True))
    if any(k in t for k in ("translate", "scale", "rotate")):
        scale = t.get("scale", 1.0)
        if _is_number(scale):
            if not math.isfinite(scale) or scale == 0:
                t.fail("scale", "a finite, non-zero number or 3 of them", scale)
            scale = float(scale)
        else:
            scale = t.vec3("scale")
            if np.any(scale == 0):
                t.fail("scale", "a finite, non-zero number or 3 of them", obj["scale"])
        M = _rotation(t.vec3("rotate", (0, 0, 0))) * np.asarray(scale, float)
        mesh.vertices = mesh.vertices @ M.T + t.vec3("translate", (0, 0, 0))
        if mesh.normals is not None:
            nm = np.linalg.inv(M).T
            mesh.normals = mesh.normals @ nm.T


def _check_ply_header(path: str):
    """A PLY header states its element counts; refuse counts the file cannot hold before
    trimesh allocates arrays for them (a header claiming 1e12 vertices)."""
    with open(path, "rb") as f:
        head = f.read(65536)
    if not head.startswith(b"ply"):
        return
    end = head.find(b"end_header")
    if end < 0:
        raise SceneFileError(f"mesh file '{path}': PLY header has no end_header")
    size = os.path.getsize(path)
    for line in head[:end].decode("ascii", "replace").splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "element":
            try:
                count = int(parts[2])
            except ValueError:
                raise SceneFileError(f"mesh file '{path}': PLY header line '{line}' has no "
                                     "whole-number count") from None
            # Every element takes at least one byte (binary) or two characters (ASCII).
            if count < 0 or count > size:
                raise SceneFileError(f"mesh file '{path}': PLY header claims {count:,} "
                                     f"{parts[1]} elements but the file has {size:,} bytes")


def _load_mesh_file(path: str, name: str, material: str) -> Mesh:
    """OBJ / PLY / STL / glTF through trimesh (a well-kept mesh library). A file that
    yields no triangles (empty or not a mesh) is an error, not an empty object."""
    if not os.path.isfile(path):
        raise SceneFileError(f"mesh file '{path}' not found")
    try:
        import trimesh
    except ImportError:
        raise SceneFileError("loading mesh files needs the 'trimesh' package "
                             "(pip install trimesh)") from None
    if path.lower().endswith(".ply"):
        _check_ply_header(path)
    try:
        m = trimesh.load(path, force="mesh", process=False)
    except Exception as e:  # trimesh raises many exception types for bad files
        raise SceneFileError(f"mesh file '{path}': {type(e).__name__}: {e}") from None
    faces = np.asarray(getattr(m, "faces", np.zeros((0, 3))))
    if faces.ndim != 2 or len(faces) == 0:
        raise SceneFileError(f"mesh file '{path}': no triangles found (empty, or not a "
                             "mesh file trimesh can read)")
    normals = None
    if getattr(m, "vertex_normals", None) is not None and len(m.vertex_normals) == len(m.vertices):
        normals = np.asarray(m.vertex_normals)
    return Mesh(name, np.asarray(m.vertices, float), faces, normals=normals,
                materials=[material])


def _light(scene, spec, i):
    raw_kind = spec.get("type", "")
    kind = raw_kind.lower() if isinstance(raw_kind, str) else ""
    where = f"lights[{i}] ({spec.get('name', kind or '?')})"
    kinds = {k.lower(): k for k in DECLARED_KINDS}  # the light registry (engine/lights/)
    if kind not in kinds:
        names = [k.lower() for k in DECLARED_KINDS]
        raise SceneFileError(f"{where}: 'type' must be {', '.join(names[:-1])} or {names[-1]}, "
                             f"got {_show(raw_kind)}")
    t = _Table(spec, where, {"type", "name", "position", "direction", "look_at", "power",
                             "strength", "color", "radius", "spot_size", "blend", "size",
                             "shape", "angle", "spread", "visible",
                             "visible_diffuse", "visible_glossy", "visible_transmission",
                             "cast_shadow"})
    # Keys that only one kind reads: anywhere else they would be silently ignored.
    for key, only in (("spread", "area"), ("shape", "area"), ("spot_size", "spot"),
                      ("blend", "spot"), ("angle", "sun")):
        if key in t and kind != only:
            raise SceneFileError(f"{where}: '{key}' applies to {only} lights only, not to a "
                                 f"{kind} light")
    position = t.vec3("position", (0, 0, 0))
    if "look_at" in t:
        direction = t.vec3("look_at") - position
        if not np.any(direction != 0):
            t.fail("look_at", "a point other than 'position'", spec["look_at"])
    else:
        direction = t.vec3("direction", (0, 0, -1), nonzero=True)
    name = t.string("name", f"{kind}.{i:03d}")
    key = "power" if "power" in t or "strength" not in t else "strength"
    power = t.number(key, 100.0, lo=0.0)
    size = t.size("size", 1.0, 2)
    sx, sy = (size, size) if isinstance(size, float) else size
    shape = t.string("shape", "rectangle", choices=("rectangle", "square", "disk", "ellipse"))
    scene.add_light(Light(name, kinds[kind], power, t.vec3("color", (1, 1, 1), nonneg=True),
                          position, direction, radius=t.number("radius", 0.0, lo=0.0),
                          spot_size=math.radians(t.number("spot_size", 45.0, lo=0.0, hi=180.0,
                                                          lo_open=True)),
                          spot_blend=t.number("blend", 0.15, lo=0.0, hi=1.0),
                          shape=shape.upper(), size_x=sx, size_y=sy,
                          angle=math.radians(t.number("angle", 0.0, lo=0.0, hi=180.0)),
                          spread=math.radians(t.number("spread", 180.0, lo=0.0, hi=180.0)),
                          visible_camera=t.boolean("visible", False),
                          visible_diffuse=t.boolean("visible_diffuse", True),
                          visible_glossy=t.boolean("visible_glossy", True),
                          visible_transmission=t.boolean("visible_transmission", True),
                          cast_shadow=t.boolean("cast_shadow", True)))
