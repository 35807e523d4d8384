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

    [[instances]]                          # a placement of an object's geometry,
    object = "ball"                        # shared, not copied (engine.scene.Mesh.place)
    translate = [2, 0, 0]                  # or matrix = [[...] x 4] (object to world)
    rotate = [0, 0, 45]
    scale = 0.5
    material = "red"                       # optional override; visibility keys as objects
"""
from __future__ import annotations

import math
import os
import tomllib

import numpy as np

from .api import PaperScene
from .lights import DECLARED_KINDS
from .panorama import KINDS as PANORAMA_KINDS, Panorama
from .scene import (EMISSION_SAMPLING, FLOAT32_MAX, MATERIAL_NODES, MIST_FALLOFF, Light,
                    Material, Mesh, Prototype, SceneError, WorldMedium, euler_rotation)
from .settings import RenderSettings

MAX_RESOLUTION = 65536    # pixels per side, as Blender
MAX_SEGMENTS = 2048       # sphere segments: 2048 x 1024 x 2 = 4M triangles
MAX_INLINE_ELEMENTS = 10_000_000  # vertices / faces written into the scene file itself
OBJECT_KINDS = ("sphere", "plane", "box", "mesh", "file")
# Ray visibility, holdout and shadow catcher per object (engine.scene.Mesh;
# docs/scene_format.md).
VISIBILITY_KEYS = ("visible_camera", "visible_diffuse", "visible_glossy",
                   "visible_transmission", "visible_shadow", "holdout", "shadow_catcher")


class SceneFileError(ValueError):
    """A scene file that cannot be read. `problems`: one line per refused key (the schema
    reports every refused key of a file at once, the first problem of each), each naming
    the table and key; str() is that line, or a count and the lines below it."""

    def __init__(self, *problems):
        self.problems = [str(p) for p in problems] or ["invalid scene file"]
        super().__init__(self.problems[0] if len(self.problems) == 1 else
                         f"{len(self.problems)} problems:\n" + "\n".join(
                             f"  {p}" for p in self.problems))

    def located(self, path: str) -> "SceneFileError":
        """The same problems, each prefixed with the file's path."""
        if len(self.problems) == 1:
            return SceneFileError(f"{path}: {self.problems[0]}")
        err = SceneFileError(*(f"{path}: {p}" for p in self.problems))
        err.args = (f"{path}: {len(self.problems)} problems:\n"
                    + "\n".join(f"  {path}: {p}" for p in self.problems),)
        return err


def _rotation(deg) -> np.ndarray:
    return euler_rotation([math.radians(float(a)) for a in deg])


# --- The schema --------------------------------------------------------------------------
# JSON Schema (draft 7), checked with fastjsonschema (a well-kept, pure-Python validator
# that compiles the schema to Python once). TOML already gives typed values (a string
# stays a string), so each key accepts only the type it documents - never a guess such
# as "no" read as true. Every node that can fail carries the words of its refusal:
# "what" (the value it must be) and, for type errors, "what_type"; _refusal() turns the
# validator's error into one line naming the file, the table and the key.

def _range_text(lo, hi, lo_open=False, hi_open=False) -> str:
    if lo is not None and hi is not None:
        return (f"a number {'>' if lo_open else '>='} {lo:g} and "
                f"{'<' if hi_open else '<='} {hi:g}")
    if lo is not None:
        return f"a number {'>' if lo_open else '>='} {lo:g}"
    return f"a number {'<' if hi_open else '<='} {hi:g}"


def _number(lo=None, hi=None, lo_open=False, hi_open=False, integer=False) -> dict:
    node = {"type": "integer" if integer else "number"}
    if lo is not None:
        node["exclusiveMinimum" if lo_open else "minimum"] = lo
    if hi is not None:
        node["exclusiveMaximum" if hi_open else "maximum"] = hi
    if lo is not None or hi is not None:
        node["what"] = _range_text(lo, hi, lo_open, hi_open)
    return node


_VEC3_TEXT = "3 finite numbers [x, y, z]"


def _vec3(nonneg=False, nonzero=False) -> dict:
    item = {"type": "number", "what_type": _VEC3_TEXT}
    if nonneg:
        item.update(minimum=0, what="3 numbers >= 0")
    node = {"type": "array", "minItems": 3, "maxItems": 3, "items": item,
            "what": _VEC3_TEXT, "what_type": _VEC3_TEXT}
    if nonzero:
        node = {"allOf": [node, {"not": {"const": [0, 0, 0]}, "what": "a non-zero vector"}]}
    return node


def _size(count) -> dict:
    positive = {"type": "number", "exclusiveMinimum": 0}
    return {"anyOf": [positive, {"type": "array", "minItems": 1, "maxItems": count,
                                 "items": positive}],
            "what": f"a number > 0 or {count} numbers > 0"}


def _choice(*names) -> dict:
    return {"type": "string", "pattern": "^(?i:" + "|".join(names) + ")$",
            "what": "one of " + ", ".join(names)}


def _table(properties: dict, required=()) -> dict:
    return {"type": "object", "properties": properties, "additionalProperties": False,
            "required": list(required)}


_BOOL = {"type": "boolean"}
_STRING = {"type": "string"}
_UNIT = _number(0.0, 1.0)

MATERIAL_SCHEMA = _table({"base_color": _vec3(nonneg=True), "emission": _vec3(nonneg=True),
                          "metallic": _UNIT, "roughness": _UNIT, "transmission": _UNIT,
                          "specular": _UNIT, "alpha": _UNIT,
                          "ior": _number(0.0, lo_open=True),
                          # Principled v2 layers (engine/closures/principled.py)
                          "specular_ior_level": _number(0.0), "specular_tint": _vec3(nonneg=True),
                          "coat_weight": _number(0.0), "coat_roughness": _UNIT,
                          "coat_ior": _number(1.0), "coat_tint": _vec3(nonneg=True),
                          "sheen_weight": _number(0.0), "sheen_roughness": _UNIT,
                          "sheen_tint": _vec3(nonneg=True), "glossy_color": _vec3(nonneg=True),
                          "translucent": _UNIT, "translucent_color": _vec3(nonneg=True),
                          "anisotropic": _number(-1.0, 1.0), "anisotropic_rotation": _number(),
                          "multiscatter": _BOOL, "node": _choice(*MATERIAL_NODES),
                          # Blender's Material > Settings > Pass Index (Material Index pass)
                          "pass_index": _number(0, 32767, integer=True),
                          # Material > Settings > Emission Sampling (scene.emission_sides)
                          "emission_sampling": _choice(*EMISSION_SAMPLING),
                          # the medium inside: sigma_a per channel in 1/m (engine/media.py),
                          # and no surface at all (a volume-only material)
                          "absorption": _vec3(nonneg=True), "volume_only": _BOOL,
                          # its scattering sigma_s (1/m) and Henyey-Greenstein g
                          # (engine/volumescatter.py)
                          "scattering": _vec3(nonneg=True),
                          "anisotropy": _number(-1.0, 1.0, lo_open=True, hi_open=True),
                          # its emission, W/m^2/sr per metre (engine/volumeemission.py)
                          "volume_emission": _vec3(nonneg=True),
                          # camera rays see a hole (a Holdout shader)
                          "holdout": _BOOL})
# Light Path in a material (engine/raymaterials.py): [materials.NAME.shadow_rays] (and
# camera_rays, glossy_rays, transmission_rays) is the surface those rays meet instead,
# with the same keys (Material.ray_variants["shadow"], ...).
RAY_VARIANT_KEYS = ("camera_rays", "glossy_rays", "transmission_rays", "shadow_rays")
MATERIAL_SCHEMA = _table({**MATERIAL_SCHEMA["properties"],
                          **{k: MATERIAL_SCHEMA for k in RAY_VARIANT_KEYS}})
MATERIAL_KEYS = set(MATERIAL_SCHEMA["properties"])

CAMERA_SCHEMA = _table({
    "position": _vec3(), "look_at": _vec3(), "up": _vec3(nonzero=True),
    "fov": _number(0.0, 180.0, lo_open=True, hi_open=True),
    "type": _choice("persp", "ortho", "pano"),
    # Panoramic cameras (type "pano", engine/panorama.py): angles in degrees, mm.
    "panorama_type": _choice(*(k.lower() for k in PANORAMA_KINDS)),
    "fisheye_fov": _number(0.0, 360.0, lo_open=True), "fisheye_lens": _number(0.0, lo_open=True),
    "sensor_width": _number(0.0, lo_open=True), "sensor_height": _number(0.0, lo_open=True),
    "latitude_min": _number(-90.0, 90.0), "latitude_max": _number(-90.0, 90.0),
    "longitude_min": _number(-360.0, 360.0), "longitude_max": _number(-360.0, 360.0),
    "ortho_scale": _number(0.0, lo_open=True), "shift_x": _number(), "shift_y": _number(),
    "clip_start": _number(0.0, lo_open=True), "clip_end": _number(0.0, lo_open=True),
    # Depth of field (thin lens, Cycles): radius m, focus m, rotation degrees.
    "aperture_radius": _number(0.0), "focus_distance": _number(0.0, lo_open=True),
    "aperture_blades": _number(0, 64, integer=True), "aperture_rotation": _number(),
    "aperture_ratio": _number(0.0, lo_open=True)},
    required=("position", "look_at"))

# Light Linking (engine/lightlinking.py): object names.
_NAMES_TEXT = "a list of object names"
_NAMES = {"type": "array", "items": {"type": "string", "what_type": _NAMES_TEXT},
          "what": _NAMES_TEXT, "what_type": _NAMES_TEXT}

_OBJECT_COMMON = {
    "type": _STRING, "name": _STRING, "material": _STRING, "translate": _vec3(),
    "rotate": _vec3(),
    "scale": {"anyOf": [{"type": "number", "not": {"const": 0}},
                        {"type": "array", "minItems": 3, "maxItems": 3,
                         "items": {"type": "number", "not": {"const": 0}}}],
              "what": "a finite, non-zero number or 3 of them"},
    **{key: _BOOL for key in VISIBILITY_KEYS},
    # Blender's Object > Relations > Pass Index (the Object Index data pass)
    "pass_index": _number(0, 32767, integer=True),
    # A template is drawn only through its [[instances]] (not itself).
    "template": _BOOL,
    # An emitting object's Light Linking (engine/lightlinking.py): object names.
    "receivers": _NAMES, "non_receivers": _NAMES,
    # An emitting object's Light Group (engine/lightgroups.py; [render] light_groups).
    "lightgroup": _STRING}
_INLINE = {"type": "array", "maxItems": MAX_INLINE_ELEMENTS,
           "what": f"a list of at most {MAX_INLINE_ELEMENTS:,} [a, b, c] rows"}
OBJECT_SCHEMAS = {
    "sphere": _table({**_OBJECT_COMMON, "center": _vec3(), "radius": _number(0.0, lo_open=True),
                      "segments": _number(3, MAX_SEGMENTS, integer=True)}),
    "plane": _table({**_OBJECT_COMMON, "center": _vec3(), "normal": _vec3(nonzero=True),
                     "size": _size(2), "up": _vec3(nonzero=True)}),
    "box": _table({**_OBJECT_COMMON, "center": _vec3(), "size": _size(3)}),
    "mesh": _table({**_OBJECT_COMMON, "vertices": _INLINE, "faces": _INLINE},
                   required=("vertices", "faces")),
    "file": _table({**_OBJECT_COMMON, "path": _STRING}, required=("path",)),
}

# A refusal names the deepest failing schema; the rows and their numbers carry the
# matrix's own description, so a short row reads as what a matrix must be, not "valid".
_MATRIX_TEXT = "3 or 4 rows of 4 finite numbers (object to world)"
_MATRIX = {"type": "array", "minItems": 3, "maxItems": 4,
           "items": {"type": "array", "minItems": 4, "maxItems": 4, "what": _MATRIX_TEXT,
                     "what_type": _MATRIX_TEXT,
                     "items": {"type": "number", "what_type": _MATRIX_TEXT}},
           "what": _MATRIX_TEXT, "what_type": _MATRIX_TEXT}
INSTANCE_SCHEMA = _table({
    "object": _STRING, "name": _STRING, "material": _STRING, "translate": _vec3(),
    "rotate": _vec3(), "scale": _OBJECT_COMMON["scale"], "matrix": _MATRIX,
    **{key: _BOOL for key in VISIBILITY_KEYS}}, required=("object",))

LIGHT_SCHEMA = _table({
    "type": _STRING, "name": _STRING, "position": _vec3(), "direction": _vec3(nonzero=True),
    "look_at": _vec3(), "power": _number(0.0), "strength": _number(0.0),
    "color": _vec3(nonneg=True), "radius": _number(0.0),
    "spot_size": _number(0.0, 180.0, lo_open=True), "blend": _UNIT, "size": _size(2),
    "shape": _choice("rectangle", "square", "disk", "ellipse"),
    "angle": _number(0.0, 180.0), "spread": _number(0.0, 180.0), "visible": _BOOL,
    "visible_diffuse": _BOOL, "visible_glossy": _BOOL, "visible_transmission": _BOOL,
    "cast_shadow": _BOOL, "soft_falloff": _BOOL, "receivers": _NAMES,
    "non_receivers": _NAMES, "blockers": _NAMES, "non_blockers": _NAMES, "ies": _STRING,
    "lightgroup": _STRING})


ENVIRONMENT_SCHEMA = _table({"image": _STRING, "strength": _number(0.0),
                             "rotation": _vec3(), "interpolation": _choice("linear", "closest")},
                            required=("image",))
SKY_SCHEMA = _table({"type": _choice("single_scattering", "nishita", "multiple_scattering",
                                     "preetham", "hosek_wilkie"), "sun_disc": _BOOL,
                     "sun_size": _number(0.0, 180.0), "sun_intensity": _number(0.0),
                     "sun_elevation": _number(), "sun_rotation": _number(),
                     "altitude": _number(0.0, 60000.0), "air_density": _number(0.0),
                     "aerosol_density": _number(0.0), "ozone_density": _number(0.0),
                     "sun_direction": _vec3(nonzero=True), "turbidity": _number(0.0),
                     "ground_albedo": _UNIT,
                     "strength": _number(0.0), "rotation": _vec3()})


def _sections(key) -> dict:
    what = f"an array of tables ([[{key}]] sections)"
    return {"type": "array", "items": {"type": "object", "what_type": what},
            "what": what, "what_type": what}

# Blender's World > Mist Pass (world.mist_settings): the Mist data pass
# (engine/datapasses.py; falloff by name, as Blender's enum).
MIST_SCHEMA = _table({"start": _number(0.0), "depth": _number(0.0),
                      "falloff": _choice(*MIST_FALLOFF)})
# Blender's World > Volume (engine.scene.WorldMedium): a homogeneous medium filling all
# space outside the objects (engine/worldmedium.py), 1/m per channel.
WORLD_MEDIUM_SCHEMA = _table({"absorption": _vec3(nonneg=True),
                              "scattering": _vec3(nonneg=True),
                              "anisotropy": _number(-1.0, 1.0, lo_open=True, hi_open=True),
                              "emission": _vec3(nonneg=True)})


def scene_schema() -> dict:
    """The JSON Schema of a whole scene file (objects and lights are checked per kind
    with OBJECT_SCHEMAS / LIGHT_SCHEMA after their 'type' is known)."""
    render = {name: {} for name in RenderSettings.names()}  # RenderSettings checks these
    render.update(width=_number(1, MAX_RESOLUTION, integer=True),
                  height=_number(1, MAX_RESOLUTION, integer=True))
    return _table({
        "render": _table(render), "camera": CAMERA_SCHEMA,
        "materials": {"type": "object", "additionalProperties": MATERIAL_SCHEMA,
                      "what_type": "a table of [materials.NAME] sections"},
        "objects": _sections("objects"), "lights": _sections("lights"),
        "instances": _sections("instances"),
        "background": _vec3(nonneg=True), "environment": ENVIRONMENT_SCHEMA,
        "camera_background": _vec3(nonneg=True),
        "sky": SKY_SCHEMA, "mist": MIST_SCHEMA,
        "world_medium": WORLD_MEDIUM_SCHEMA,
        # The world's Light Group (engine/lightgroups.py; [render] light_groups).
        "world_lightgroup": _STRING})


_VALIDATORS = {}


def _validator(name: str, schema_of):
    """The compiled validator `name` (fastjsonschema is imported on the first scene file:
    only the CLI and scene-file readers need it, never the Blender extension)."""
    if name not in _VALIDATORS:
        try:
            import fastjsonschema
        except ImportError:
            raise SceneFileError("reading scene files needs the 'fastjsonschema' package "
                                 "(pip install fastjsonschema)") from None
        # fast_fail=False: every refused value of the file, not only the first
        # (JsonSchemaValuesException.errors, fastjsonschema 2.22); an older release
        # reports the first.
        try:
            validate = fastjsonschema.compile(schema_of(), fast_fail=False)
        except TypeError:
            validate = fastjsonschema.compile(schema_of())
        _VALIDATORS[name] = (validate, fastjsonschema.JsonSchemaValueException,
                             getattr(fastjsonschema, "JsonSchemaValuesException",
                                     fastjsonschema.JsonSchemaValueException))
    return _VALIDATORS[name]


class _NotFinite:
    """A non-finite TOML float (nan, inf): no JSON Schema type matches it, so the schema
    refuses it wherever a number is expected, and it shows as written."""

    def __init__(self, value):
        self.value = value

    def __repr__(self):
        if math.isfinite(self.value):
            return f"{self.value!r} (beyond float32's range)"
        return repr(self.value)


def _mark_not_finite(v):
    # Beyond float32's range counts as infinite: the engine traces in float32.
    if isinstance(v, (int, float)) and not isinstance(v, bool) and not (
            math.isfinite(v) and abs(v) <= FLOAT32_MAX):
        return _NotFinite(v)
    if isinstance(v, dict):
        return {k: _mark_not_finite(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_mark_not_finite(x) for x in v]
    return v


_TYPE_TEXT = {"number": "a finite number", "integer": "a whole number",
              "boolean": "true or false", "string": "a string", "array": "a list",
              "object": "a table (key = value lines)"}


def _problems(name, schema_of, data, where) -> list[str]:
    """Validate data against the schema: one line per refused key (the first problem of
    each; [] when valid). where(path) names the table of a path (keys from the schema's
    root) and the key inside it."""
    validate, error, errors = _validator(name, schema_of)
    try:
        validate(data)
    except error as e:
        found = [e]
    except errors as e:
        found = e.errors
    else:
        return []
    out, seen = [], set()
    for e in found:
        key, text = _refusal(e, data, where)
        if key not in seen:  # a vector with two bad numbers: its key once
            seen.add(key)
            out.append(text)
    return out


def _refusal(e, data, where) -> tuple:
    """(the refused table / key, one line naming them) of a validator error."""
    path = list(e.path[1:])  # e.path starts with "data"
    node = e.definition if isinstance(e.definition, dict) else {}
    if e.rule == "additionalProperties" and isinstance(e.value, dict):
        table, _ = where(path + [None])
        allowed = set(node.get("properties", {}))
        unknown = sorted(set(e.value) - allowed)
        return (table, "unknown"), (f"{table}: unknown key(s) {', '.join(unknown)}; "
                                    f"allowed: {', '.join(sorted(allowed))}")
    if e.rule == "required" and isinstance(e.value, dict):
        table, _ = where(path + [None])
        missing = [k for k in node.get("required", []) if k not in e.value]
        return (table, missing[0]), f"{table}: '{missing[0]}' is required"
    # The deepest table key on the path and its value (a whole vector, not the one bad
    # number in it); the validator names list items by their index as a string.
    value, depth, walk = data, 0, data
    for i, k in enumerate(path):
        if isinstance(walk, dict):
            walk = walk[k]
            value, depth = walk, i + 1
        elif isinstance(walk, list):
            walk = walk[int(k)]
        else:
            break
    table, key = where(path[:depth])
    if e.rule == "type":
        what = node.get("what_type") or _TYPE_TEXT.get(node.get("type"), "valid")
    elif node.get("type") == "integer" and isinstance(e.value, float):
        what = "a whole number"  # 1e6 for a pixel count: TOML wrote a float
    else:
        what = node.get("what") or node.get("what_type") or "valid"
    if key is None:
        return (table, None), f"{table}: must be {what}, got {_show(value)}"
    return (table, key), f"{table}: '{key}' must be {what}, got {_show(value)}"


def _top_where(path):
    """(table, key) of a path from the scene file's root."""
    head = path[0] if path else None
    if head in ("render", "camera") and len(path) > 1:
        return f"[{head}]", path[1]
    if head == "materials" and len(path) > 1:
        return f"[materials.{path[1]}]", path[2] if len(path) > 2 else None
    return "scene file", head


def _show(v) -> str:
    text = repr(v) if not isinstance(v, str) else f'"{v}"'
    return text if len(text) <= 60 else text[:57] + "..."


def _vec(v) -> np.ndarray:
    return np.asarray(v, np.float64)


def _size_value(v):
    """A validated size: one number, or one per axis."""
    values = [v] if not isinstance(v, list) else v
    return float(values[0]) if len(values) == 1 else tuple(float(x) for x in values)


def load_scene(path: str):
    """Read a TOML scene file. Returns (scene, settings_overrides dict). Raises
    SceneFileError for anything that is not a valid scene (wrong types, non-finite
    numbers, out-of-range values, unknown keys, face indices outside the vertex list):
    one line per refused key, each naming the file, the table and the key - every
    refused key of the file at once (SceneFileError.problems)."""
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
    except SceneFileError as e:
        raise e.located(path) from None
    except SceneError as e:
        raise SceneFileError(f"{path}: {e}") from None
    except (TypeError, ValueError, KeyError, OverflowError, MemoryError) as e:
        raise SceneFileError(f"{path}: {type(e).__name__}: {e}") from None


def _validate(data: dict) -> list[str]:
    """Every problem of a scene file (its tables, each object and each light), one line
    per refused key, before anything is built: a bad camera key does not hide a bad
    light."""
    problems = _problems("scene", scene_schema, data, _top_where)
    render = data.get("render")
    if isinstance(render, dict) and set(render) <= set(RenderSettings.names()) | {"width",
                                                                                  "height"}:
        try:
            RenderSettings(**{k: v for k, v in render.items() if k not in ("width", "height")})
        except (TypeError, ValueError) as e:  # types and ranges of every setting, named
            problems.append(f"[render]: {e}")
    camera = data.get("camera")
    if isinstance(camera, dict) and not any(p.startswith("[camera]") for p in problems):
        problems += _camera_problems(camera)
    for key, check in (("objects", _object_problems), ("lights", _light_problems),
                       ("instances", _instance_problems(data))):
        items = data.get(key)
        if isinstance(items, list):
            for i, spec in enumerate(items):
                if isinstance(spec, dict):
                    problems += check(spec, i)
    return problems


def _build(data: dict, base: str):
    data = _mark_not_finite(data)
    data.setdefault("camera", {})  # a missing [camera] is refused for its first key
    problems = _validate(data)
    if problems:
        raise SceneFileError(*problems)
    render_table = data.get("render", {})
    width = int(render_table.get("width", 400))
    height = int(render_table.get("height", 300))
    render = {k: v for k, v in render_table.items() if k not in ("width", "height")}
    background = _vec(data.get("background", (0.0, 0.0, 0.0)))
    scene = PaperScene(width=width, height=height, background=background)
    if "environment" in data:
        scene.environment = _environment(data["environment"], base)
    if "camera_background" in data:  # what camera rays see of the world (Scene)
        scene.camera_background = _vec(data["camera_background"])
    if "world_medium" in data:
        w = data["world_medium"]
        scene.world_medium = WorldMedium(absorption=_vec(w.get("absorption", (0.0, 0.0, 0.0))),
                                         scattering=_vec(w.get("scattering", (0.0, 0.0, 0.0))),
                                         anisotropy=float(w.get("anisotropy", 0.0)),
                                         emission=_vec(w.get("emission", (0.0, 0.0, 0.0))))
    if "world_lightgroup" in data:
        scene.world_lightgroup = str(data["world_lightgroup"])
    if "mist" in data:
        m = data["mist"]
        scene.mist = (float(m.get("start", 5.0)), float(m.get("depth", 25.0)),
                      MIST_FALLOFF[m.get("falloff", "QUADRATIC")])
    for name, spec in data.get("materials", {}).items():
        variants = {k[:-5]: Material(f"{name} [{k[:-5]} rays]",
                                     **{kk: _material_value(kk, vv)
                                        for kk, vv in spec[k].items()})
                    for k in RAY_VARIANT_KEYS if k in spec}
        scene.add_material(Material(name, ray_variants=variants or None,
                                    **{k: _material_value(k, v) for k, v in spec.items()
                                       if k not in RAY_VARIANT_KEYS}))
    _camera(scene, data["camera"])
    for i, obj in enumerate(data.get("objects", [])):
        _object(scene, obj, i, base)
    for i, spec in enumerate(data.get("lights", [])):
        _light(scene, spec, i, base)
    _instances(scene, data.get("objects", []), data.get("instances", []))
    if "sky" in data:
        _sky(scene, data["sky"])
    return scene, render


def _instance_problems(data):
    """The check of [[instances]] entries: the schema, then the object they place
    (an object named so must exist) and a matrix that is not singular."""
    objects = data.get("objects")
    names = {o.get("name") for o in objects if isinstance(o, dict)} \
        if isinstance(objects, list) else set()

    def check(spec, i) -> list[str]:
        label = spec.get("name", spec.get("object", "?"))
        where = f"instances[{i}] ({_show(label).strip(chr(34))})"
        problems = _problems("instance", lambda: INSTANCE_SCHEMA, spec,
                             lambda path: (where, path[0] if path else None))
        if problems:
            return problems
        if spec["object"] not in names:
            return [f"{where}: 'object' names no [[objects]] entry with that name "
                    f"({_show(spec['object'])})"]
        if "matrix" in spec and any(k in spec for k in ("translate", "rotate", "scale")):
            return [f"{where}: give 'matrix' or translate / rotate / scale, not both"]
        rows = spec.get("matrix", [])
        if len(rows) == 4 and list(map(float, rows[3])) != [0.0, 0.0, 0.0, 1.0]:
            # A projective last row has no meaning for a placement: refused, not ignored.
            return [f"{where}: 'matrix' row 4 must be [0, 0, 0, 1] (an affine object-to-"
                    f"world matrix; or give 3 rows), got {rows[3]}"]
        if abs(np.linalg.det(_instance_matrix(spec)[:3, :3])) < 1e-300:
            return [f"{where}: 'matrix' is singular (a zero scale flattens the object)"]
        return []
    return check


def _instance_matrix(spec) -> np.ndarray:
    """(4,4) object-to-world matrix of an [[instances]] entry: 'matrix' rows, or
    translate @ rotate (XYZ Euler degrees) @ scale as objects are transformed."""
    M = np.eye(4)
    if "matrix" in spec:
        rows = np.asarray(spec["matrix"], np.float64)
        M[:len(rows)] = rows
        return M
    scale = spec.get("scale", 1.0)
    scale = _vec(scale) if isinstance(scale, list) else float(scale)
    M[:3, :3] = _rotation(spec.get("rotate", (0, 0, 0))) * np.asarray(scale, float)
    M[:3, 3] = _vec(spec.get("translate", (0, 0, 0)))
    return M


def _instances(scene, objects, instances):
    """Turn the objects that [[instances]] place into prototypes (engine.scene.
    Prototype, world space as the object was built) and add a placement without a copy
    per entry; the object itself becomes a placement by the identity (shared too), or
    is dropped when it is a template."""
    used = {spec["object"] for spec in instances}
    templates = {o.get("name") for o in objects if o.get("template")}
    for name in sorted(templates - used, key=str):
        scene.warnings.append(f"object '{name}' is a template (template = true) that no "
                              "[[instances]] entry places: it is not drawn")
    protos = {}
    keep = []
    for mesh in scene.meshes:
        if mesh.name in templates - used:
            continue  # drawn only through its instances: here none
        if mesh.name not in used or mesh.name in protos:
            keep.append(mesh)
            continue
        P = Prototype(mesh.name, mesh.vertices, mesh.faces, normals=mesh.normals,
                      uvs=mesh.uvs, material_ids=mesh.material_ids)
        protos[mesh.name] = (P, mesh)
        if mesh.name not in templates:
            keep.append(_placement(mesh.name, P, np.eye(4), mesh, {}))
    scene.meshes[:] = keep
    for i, spec in enumerate(instances):
        P, mesh = protos[spec["object"]]
        if "material" in spec:
            try:
                scene._material(spec["material"])
            except SceneError as e:
                raise SceneFileError(f"instances[{i}]: {e}") from None
        name = spec.get("name", f"{spec['object']}.instance.{i:03d}")
        scene.add_mesh(_placement(name, P, _instance_matrix(spec), mesh, spec))


def _placement(name, P, M, mesh, spec) -> Mesh:
    flags = {k: spec.get(k, getattr(mesh, k)) for k in VISIBILITY_KEYS}
    materials = list(mesh.materials)
    if "material" in spec:
        materials = [spec["material"]] * len(materials)
    return Mesh.place(name, P, M, materials=materials, pass_index=mesh.pass_index,
                      shadow_terminator_offset=mesh.shadow_terminator_offset,
                      shadow_terminator_shading_offset=mesh.shadow_terminator_shading_offset,
                      **flags)


def _environment(spec, base):
    """[environment]: an equirectangular image lighting the scene (engine/lights/
    environment.py): image (EXR / NPY linear, PNG sRGB), strength, rotation (XYZ Euler
    degrees, the Mapping node's), interpolation. Types and ranges are the schema's."""
    from .imageio import read_image
    from .lights.environment import Environment
    path = spec["image"]
    full = path if os.path.isabs(path) else os.path.join(base, path)
    if not os.path.isfile(full):
        raise SceneFileError(f"[environment] image: file '{path}' not found")
    try:
        pixels = read_image(full)
    except Exception as e:  # noqa: BLE001  (any reader failure: one line naming the file)
        raise SceneFileError(f"[environment] image: '{path}' cannot be read ({e}); use an "
                             "OpenEXR (.exr) or NumPy (.npy) file of linear radiance, or a "
                             "PNG (read as sRGB); Radiance .hdr is not read here (Blender's "
                             "Environment Texture reads it)") from None
    rotation = _rotation(spec["rotation"]) if "rotation" in spec else None
    interpolation = spec.get("interpolation", "linear").capitalize()
    try:
        return Environment(pixels, float(spec.get("strength", 1.0)), rotation, interpolation,
                           name=path)
    except ValueError as e:
        raise SceneFileError(f"[environment]: {e}") from None


def _sky(scene, spec):
    """[sky]: Blender's Sky Texture (engine/lights/sky.py) lighting the scene: baked into
    the environment, its sun disc a sun light added after the file's lights. Angles in
    degrees, altitude in m; Preetham and Hosek / Wilkie take sun_direction (a vector
    towards the sun) and turbidity, Hosek / Wilkie also ground_albedo; types and ranges
    are the schema's."""
    from .lights.sky import SkyTexture
    if scene.environment is not None:
        raise SceneFileError("[sky] and [environment] both light the world; give one")
    deg = {k: math.radians(float(spec[k])) for k in ("sun_size", "sun_elevation",
                                                      "sun_rotation") if k in spec}
    rest = {k: spec[k] for k in ("sun_disc", "sun_intensity", "altitude", "air_density",
                                 "aerosol_density", "ozone_density", "strength", "turbidity",
                                 "ground_albedo")
            if k in spec}
    if "sun_direction" in spec:  # Preetham's and Hosek / Wilkie's sun
        rest["sun_vector"] = tuple(float(v) for v in spec["sun_direction"])
    rotation = _rotation(spec["rotation"]) if "rotation" in spec else None
    try:
        sky = SkyTexture(sky_type=spec.get("type", "single_scattering"), rotation=rotation,
                         name="sky", **deg, **rest)
        scene.environment = sky.environment()
    except ValueError as e:
        raise SceneFileError(f"[sky]: {e}") from None
    if scene.environment.sun_light is not None:
        scene.add_light(Light(**scene.environment.sun_light))


def _material_value(key, v):
    """A validated material value as Material takes it."""
    if isinstance(v, list):
        return _vec(v)
    if key == "node":
        return v.lower()
    if key == "emission_sampling":
        return v.upper()
    if isinstance(v, bool):
        return v
    return float(v)


def _camera_problems(cam) -> list[str]:
    """The relations between camera keys (the schema checks each key alone)."""
    problems = []
    if np.allclose(_vec(cam["position"]), _vec(cam["look_at"])):
        problems.append("[camera]: 'look_at' must differ from 'position'")
    start = float(cam.get("clip_start", 0.0))
    if "clip_end" in cam and not cam["clip_end"] > start:
        problems.append(f"[camera]: 'clip_end' must be {_range_text(start, None, True)}, "
                        f"got {_show(cam['clip_end'])}")
    return problems


def _camera(scene, cam):
    position = _vec(cam["position"])
    look_at = _vec(cam["look_at"])
    up = _vec(cam.get("up", (0, 0, 1)))
    extra = {}
    if "type" in cam:
        extra["kind"] = {"ortho": "ORTHO", "pano": "PANO"}.get(cam["type"].lower(), "PERSP")
    if extra.get("kind") == "PANO":
        pano = {"kind": str(cam.get("panorama_type", "equirectangular")).upper()}
        for k in ("fisheye_fov", "latitude_min", "latitude_max", "longitude_min",
                  "longitude_max"):
            if k in cam:
                pano[k] = math.radians(float(cam[k]))
        for k in ("fisheye_lens", "sensor_width", "sensor_height"):
            if k in cam:
                pano[k] = float(cam[k])
        extra["panorama"] = Panorama(**pano)
    for k in ("ortho_scale", "shift_x", "shift_y", "clip_start"):
        if k in cam:
            extra[k] = float(cam[k])
    if "clip_end" in cam:
        extra["clip_end"] = float(cam["clip_end"])
    for k in ("aperture_radius", "aperture_ratio"):
        if k in cam:
            extra[k] = float(cam[k])
    if "aperture_blades" in cam:
        extra["aperture_blades"] = int(cam["aperture_blades"])
    if "aperture_rotation" in cam:
        extra["aperture_rotation"] = math.radians(float(cam["aperture_rotation"]))
    # Focus: the look-at point's depth unless given (a file's camera aims at its subject).
    extra["focus_distance"] = float(cam.get("focus_distance", float(np.linalg.norm(
        look_at - position))))
    scene.set_camera(position, look_at, up, float(cam.get("fov", 40.0)), **extra)


def _kind(spec, where, kinds, text):
    raw = spec.get("type", "")
    kind = raw.lower() if isinstance(raw, str) else ""
    if kind not in kinds:
        raise SceneFileError(f"{where}: 'type' must be {text}, got {_show(raw)}")
    return kind


def _object_where(obj, i) -> str:
    raw = obj.get("type", "")
    label = obj.get("name", raw.lower() if isinstance(raw, str) and raw else "?")
    return f"objects[{i}] ({_show(label).strip(chr(34))})"


def _object_problems(obj, i) -> list[str]:
    where = _object_where(obj, i)
    try:
        kind = _kind(obj, where, OBJECT_KINDS, "sphere, plane, box, mesh or file")
    except SceneFileError as e:
        return e.problems
    problems = _problems("object." + kind, lambda: OBJECT_SCHEMAS[kind], obj,
                         lambda path: (where, path[0] if path else None))
    if kind == "mesh" and not problems:
        problems += _mesh_problems(obj, where)
    return problems


def _mesh_problems(obj, where) -> list[str]:
    """An inline mesh's rows: vertices (V, 3) numbers, faces (F, 3) whole numbers that
    index the vertices. A face index outside 0..V-1 is refused, naming the face, rather
    than dropped: in a file written by hand or by a script it is a mistake in the file
    (a count off by one, indices from 1 as in OBJ), and dropping faces would render a
    different object than the one described (Blender's importers refuse such files
    too; its Mesh.validate() repairs meshes that a tool corrupted)."""
    try:
        vertices = np.asarray(obj["vertices"], np.float64)
        faces = np.asarray(obj["faces"])
    except (TypeError, ValueError):
        return [f"{where}: 'vertices' / 'faces' must be lists of 3 numbers each"]
    if vertices.size and (vertices.ndim != 2 or vertices.shape[1] != 3
                          or not np.all(np.isfinite(vertices))):
        return [f"{where}: 'vertices' must be rows of 3 finite numbers [x, y, z]"]
    if faces.size == 0:
        return []
    if faces.dtype.kind not in "iu" or faces.ndim != 2 or faces.shape[1] != 3:
        return [f"{where}: 'faces' must be rows of 3 whole-number vertex indices, got "
                f"{_show(obj['faces'])}"]
    bad = np.flatnonzero(np.any((faces < 0) | (faces >= len(vertices)), axis=1))
    if len(bad) == 0:
        return []
    first = int(bad[0])
    more = f" (and {len(bad) - 1} more face(s))" if len(bad) > 1 else ""
    return [f"{where}: 'faces' row {first} {faces[first].tolist()} indexes a vertex outside "
            f"0..{len(vertices) - 1} ({len(vertices)} vertices; indices count from 0)" + more]


def _object(scene, obj, i, base):
    kind = obj["type"].lower()
    mat = obj.get("material", "white_plastic_dull")
    name = obj.get("name")
    if kind == "sphere":
        mesh = scene.add_sphere(_vec(obj.get("center", (0, 0, 0))), float(obj.get("radius", 1.0)),
                                mat, name, int(obj.get("segments", 48)))
    elif kind == "plane":
        up = _vec(obj["up"]) if "up" in obj else None
        mesh = scene.add_plane(_vec(obj.get("center", (0, 0, 0))),
                               _vec(obj.get("normal", (0, 0, 1))),
                               _size_value(obj.get("size", 10.0)), mat, name, up)
    elif kind == "box":
        mesh = scene.add_box(_vec(obj.get("center", (0, 0, 0))),
                             _size_value(obj.get("size", 1.0)), mat, name)
    elif kind == "mesh":  # checked by _mesh_problems
        mesh = scene.add_triangles(np.asarray(obj["vertices"], np.float64),
                                   np.asarray(obj["faces"]), mat, name)
    else:
        path = os.path.join(base, obj["path"])
        mesh = scene.add_mesh(_load_mesh_file(path, name or os.path.basename(path),
                                              scene._material(mat)))
    for key in VISIBILITY_KEYS + ("pass_index", "receivers", "non_receivers", "lightgroup"):
        if key in obj:
            setattr(mesh, key, obj[key])
    if any(k in obj for k in ("translate", "scale", "rotate")):
        scale = obj.get("scale", 1.0)
        scale = _vec(scale) if isinstance(scale, list) else float(scale)
        M = _rotation(obj.get("rotate", (0, 0, 0))) * np.asarray(scale, float)
        mesh.vertices = mesh.vertices @ M.T + _vec(obj.get("translate", (0, 0, 0)))
        if mesh.normals is not None:
            nm = np.linalg.inv(M).T
            mesh.normals = mesh.normals @ nm.T
        if np.linalg.det(M) < 0:
            _mirror_winding(mesh)


def _mirror_winding(mesh) -> None:
    """A mirroring transform (det < 0) turns a mesh inside out: its faces' corners go
    0, 2, 1 (and every per-corner array with them), so the winding normal points out again
    beside the transformed shading normals, as the add-on's export and mirrored instances
    order them (addon/export.py, engine/geometry.py _prototype_order)."""
    F = len(mesh.faces)
    mesh.faces = np.asarray(mesh.faces)[:, [0, 2, 1]]

    def corners(a):
        a = None if a is None else np.asarray(a)
        return a[:, [0, 2, 1]] if a is not None and a.ndim == 3 and len(a) == F else a
    mesh.normals = corners(mesh.normals)
    mesh.uvs = corners(mesh.uvs)
    mesh.colors = corners(mesh.colors)
    if mesh.coordinates:
        mesh.coordinates = {k: corners(v) for k, v in mesh.coordinates.items()}


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
    if os.path.isdir(path):
        raise SceneFileError(f"mesh file '{path}' is a folder, not a mesh file")
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
        kind = os.path.splitext(path)[1].lstrip(".").upper() or "mesh"
        raise SceneFileError(f"mesh file '{path}' is not a readable {kind} file (damaged, "
                             f"or another format; trimesh said {type(e).__name__}: "
                             f"{str(e)[:120]})") from None
    faces = np.asarray(getattr(m, "faces", np.zeros((0, 3))))
    if faces.ndim != 2 or len(faces) == 0:
        raise SceneFileError(f"mesh file '{path}': no triangles found (empty, or not a "
                             "mesh file trimesh can read)")
    normals = None
    if getattr(m, "vertex_normals", None) is not None and len(m.vertex_normals) == len(m.vertices):
        normals = np.asarray(m.vertex_normals)
    return Mesh(name, np.asarray(m.vertices, float), faces, normals=normals,
                materials=[material])


def _light_where(spec, i) -> str:
    raw = spec.get("type", "")
    label = spec.get("name", raw.lower() if isinstance(raw, str) and raw else "?")
    return f"lights[{i}] ({_show(label).strip(chr(34))})"


def _light_problems(spec, i) -> list[str]:
    where = _light_where(spec, i)
    names = [k.lower() for k in DECLARED_KINDS]  # the light registry (engine/lights/)
    try:
        kind = _kind(spec, where, names, f"{', '.join(names[:-1])} or {names[-1]}")
    except SceneFileError as e:
        return e.problems
    problems = _problems("light", lambda: LIGHT_SCHEMA, spec,
                         lambda path: (where, path[0] if path else None))
    # Keys that only one kind reads: anywhere else they would be silently ignored.
    for key, only in (("spread", "area"), ("shape", "area"), ("spot_size", "spot"),
                      ("blend", "spot"), ("angle", "sun")):
        if key in spec and kind != only:
            problems.append(f"{where}: '{key}' applies to {only} lights only, not to a "
                            f"{kind} light")
    if not problems and "look_at" in spec and not np.any(
            _vec(spec["look_at"]) != _vec(spec.get("position", (0, 0, 0)))):
        problems.append(f"{where}: 'look_at' must be a point other than 'position', "
                        f"got {_show(spec['look_at'])}")
    return problems


def _light(scene, spec, i, base=""):
    kinds = {k.lower(): k for k in DECLARED_KINDS}
    kind = spec["type"].lower()
    position = _vec(spec.get("position", (0, 0, 0)))
    if "look_at" in spec:
        direction = _vec(spec["look_at"]) - position
    else:
        direction = _vec(spec.get("direction", (0, 0, -1)))
    name = spec.get("name", f"{kind}.{i:03d}")
    key = "power" if "power" in spec or "strength" not in spec else "strength"
    size = _size_value(spec.get("size", 1.0))
    sx, sy = (size, size) if isinstance(size, float) else size
    shape = spec.get("shape", "rectangle")
    get = spec.get
    scene.add_light(Light(name, kinds[kind], float(get(key, 100.0)),
                          _vec(get("color", (1, 1, 1))), position, direction,
                          radius=float(get("radius", 0.0)),
                          soft_falloff=get("soft_falloff", True),
                          spot_size=math.radians(get("spot_size", 45.0)),
                          spot_blend=float(get("blend", 0.15)),
                          shape=shape.upper(), size_x=sx, size_y=sy,
                          angle=math.radians(get("angle", 0.0)),
                          spread=math.radians(get("spread", 180.0)),
                          visible_camera=get("visible", False),
                          visible_diffuse=get("visible_diffuse", True),
                          visible_glossy=get("visible_glossy", True),
                          visible_transmission=get("visible_transmission", True),
                          cast_shadow=get("cast_shadow", True),
                          receivers=get("receivers"),
                          non_receivers=get("non_receivers", []),
                          blockers=get("blockers"),
                          non_blockers=get("non_blockers", []),
                          ies_path=(None if get("ies") is None else
                                    os.path.join(base, os.path.expanduser(get("ies")))),
                          lightgroup=str(get("lightgroup", ""))))
