"""Per-hit evaluation of the colour nodes real node trees put between a texture and a BSDF.

Each node is a small object with evaluate(geo, prim, u, v) over a batch of hits
(triangle prim, barycentrics u, v of an engine.geometry.Geometry), vectorised in numpy:
colours and vectors come back as (N,3), factors and values as (N,). A node tree is a
tree of these objects (inputs are nodes or constants); its root is what a Material's
`texture` holds. Formulas follow Cycles' SVM nodes (intern/cycles/kernel/svm/: mix.h,
color_util.h, ramp.h, math_util.h, mapping_util.h, checker.h, map_range.h, blackbody.h,
wave.h); each class names its node.
"""
from __future__ import annotations

import numpy as np

from .scene import euler_rotation
from .textures import ImageTexture


def _eval(x, geo, prim, u, v, width):
    """A node's value or a constant broadcast to the batch: (N,) for width 1, else (N,3)."""
    n = len(prim)
    if hasattr(x, "evaluate"):
        val = np.asarray(x.evaluate(geo, prim, u, v), np.float64)
        if width == 1 and val.ndim == 2:
            # Colour into a value socket: Cycles takes the luminance (Rec.709 weights).
            return val @ np.array([0.2126, 0.7152, 0.0722])
        if width == 3 and val.ndim == 1:
            return np.repeat(val[:, None], 3, axis=1)
        return val
    c = np.asarray(x, np.float64)
    if width == 1:
        return np.full(n, float(c) if c.ndim == 0 else float(c[:3] @ [0.2126, 0.7152, 0.0722]))
    c = np.broadcast_to(c[:3] if c.ndim else np.full(3, float(c)), (3,))
    return np.tile(c, (n, 1))


class UVCoord:
    """Texture Coordinate / UV Map node, UV output: (u, v, 0) of the active UV map."""

    def evaluate(self, geo, prim, u, v):
        uv = geo.uvs(prim, u, v)
        return np.concatenate([uv, np.zeros((len(uv), 1))], axis=1)


class Coordinates:
    """Texture Coordinate node, Generated or Object output: the mesh's per-corner
    coordinates of that name (Mesh.coordinates), interpolated; zeros where a mesh has
    none."""

    def __init__(self, name: str):
        self.name = name

    def evaluate(self, geo, prim, u, v):
        return geo.coordinates(self.name, prim, u, v)


class ObjectSpacePosition:
    """Texture Coordinate node, Object output relative to another object (Cycles'
    svm_node_tex_coord NODE_TEXCO_OBJECT with a transform: the hit's world position
    by the inverse of that object's matrix): `world_to_object` (3,4) or (4,4). (N,3);
    zeros without a Geometry."""

    def __init__(self, world_to_object):
        m = np.asarray(world_to_object, np.float64)
        self.rot, self.shift = m[:3, :3], m[:3, 3]

    def evaluate(self, geo, prim, u, v):
        prim = np.asarray(prim, np.int64)
        if geo is None:
            return np.zeros((len(prim), 3))
        p = geo.hit_points(prim, np.asarray(u, np.float64),
                           np.asarray(v, np.float64)) + np.asarray(geo.offset)
        return p @ self.rot.T + self.shift


class Mapping:
    """Mapping node. kind POINT: R(S v) + T; TEXTURE: the inverse, S^-1 R^-1 (v - T);
    VECTOR: R(S v); NORMAL: normalize(R(v / S)). location / rotation (XYZ Euler, radians)
    / scale are constants."""

    KINDS = ("POINT", "TEXTURE", "VECTOR", "NORMAL")

    def __init__(self, vector, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1),
                 kind="POINT"):
        if kind not in self.KINDS:
            raise ValueError(f"Mapping type: expected one of {self.KINDS}, got {kind!r}")
        self.vector = vector
        self.location = np.asarray(location, np.float64)
        self.rot = euler_rotation(rotation)
        self.scale = np.asarray(scale, np.float64)
        self.kind = kind

    def evaluate(self, geo, prim, u, v):
        p = _eval(self.vector, geo, prim, u, v, 3)
        if self.kind == "POINT":
            return (p * self.scale) @ self.rot.T + self.location
        if self.kind == "TEXTURE":
            safe = np.where(self.scale != 0, self.scale, 1.0)
            return np.where(self.scale != 0, ((p - self.location) @ self.rot) / safe, 0.0)
        if self.kind == "VECTOR":
            return (p * self.scale) @ self.rot.T
        safe = np.where(self.scale != 0, self.scale, 1.0)
        n = (p / safe) @ self.rot.T
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)


def map_to_tube(co):
    """Cycles util/math.h map_to_tube: (N,3) -> (N,2) uv."""
    ln = np.sqrt(co[:, 0] ** 2 + co[:, 1] ** 2)
    ok = ln > 0
    s = np.where(ok, ln, 1.0)
    u = (1.0 - np.arctan2(co[:, 0] / s, co[:, 1] / s) / np.pi) * 0.5
    return np.stack([np.where(ok, u, 0.0), np.where(ok, (co[:, 2] + 1.0) * 0.5, 0.0)], axis=1)


def map_to_sphere(co):
    """Cycles util/math.h map_to_sphere: (N,3) -> (N,2) uv."""
    l2 = np.einsum("ij,ij->i", co, co)
    ok = l2 > 0
    pole = (co[:, 0] == 0) & (co[:, 1] == 0)
    u = np.where(pole, 0.0, 0.5 - np.arctan2(co[:, 0], co[:, 1]) / (2.0 * np.pi))
    v = 1.0 - np.arccos(np.clip(co[:, 2] / np.sqrt(np.where(ok, l2, 1.0)), -1.0, 1.0)) / np.pi
    return np.stack([np.where(ok, u, 0.0), np.where(ok, v, 0.0)], axis=1)


class ImageLookup:
    """Image Texture node with its Vector input: output COLOR (N,3) or ALPHA (N,).
    projection FLAT (the vector's x, y), SPHERE or TUBE (Cycles svm_node_tex_image_mapping:
    the vector remapped from 0..1 to -1..1, then map_to_sphere / map_to_tube)."""

    def __init__(self, texture: ImageTexture, vector=None, output="COLOR", projection="FLAT"):
        if projection not in ("FLAT", "SPHERE", "TUBE"):
            raise ValueError(f"Image projection {projection!r}: expected FLAT, SPHERE or "
                             "TUBE (BOX: BoxLookup)")
        self.texture = texture
        self.vector = vector if vector is not None else UVCoord()
        self.output, self.projection = output, projection

    def evaluate(self, geo, prim, u, v):
        uvw = _eval(self.vector, geo, prim, u, v, 3)
        if self.projection == "SPHERE":
            uv = map_to_sphere((uvw - 0.5) * 2.0)
        elif self.projection == "TUBE":
            uv = map_to_tube((uvw - 0.5) * 2.0)
        else:
            uv = uvw[:, :2]
        rgba = self.texture.sample_rgba(uv)
        return rgba[:, 3] if self.output == "ALPHA" else rgba[:, :3]


class ObjectNormal:
    """Texture Coordinate node, Normal output: the hit's object-space normal (Cycles
    svm_node_tex_coord: sd->N by the object's inverse normal transform, normalised), from
    the per-corner object-space normals (a Coordinates node of 'normal', interpolated),
    negated on a back face as Cycles flips sd->N there (the ShadingGeometry's backfacing;
    without a view, front)."""

    def __init__(self, normals):
        self.normals = normals

    def evaluate(self, geo, prim, u, v):
        n = _eval(self.normals, geo, prim, u, v, 3)
        ln = np.linalg.norm(n, axis=1, keepdims=True)
        n = np.where(ln > 0, n / np.where(ln > 0, ln, 1.0), n)
        if geo is not None:
            back = np.asarray(_view(geo, prim)[2], bool)
            n = np.where(back[:, None], -n, n)
        return n


def box_weights(n, blend):
    """Cycles svm_node_tex_image_box's weights (N,3) of the x, y, z projections for
    object-space normals n (N,3) and the node's Blend (0..1)."""
    a = np.abs(n)
    a = a / np.maximum(a.sum(axis=1, keepdims=True), 1e-300)
    x, y, z = a[:, 0], a[:, 1], a[:, 2]
    limit = 0.5 * (1.0 + blend)
    w = np.zeros_like(a)
    todo = np.ones(len(a), bool)

    def take(mask, wx, wy, wz):
        m = todo & mask
        w[m, 0], w[m, 1], w[m, 2] = (np.broadcast_to(c, x.shape)[m] for c in (wx, wy, wz))
        todo[m] = False

    with np.errstate(all="ignore"):
        take((x > limit * (x + y)) & (x > limit * (x + z)), 1.0, 0.0, 0.0)
        take((y > limit * (x + y)) & (y > limit * (y + z)), 0.0, 1.0, 0.0)
        take((z > limit * (x + z)) & (z > limit * (y + z)), 0.0, 0.0, 1.0)
        if blend > 0.0:
            def ramp(t):
                return np.clip((t - 0.5 * (1.0 - blend)) / blend, 0.0, 1.0)
            wxy = ramp(x / (x + y))
            take(z < (1.0 - limit) * (y + x), wxy, 1.0 - wxy, 0.0)
            wyz = ramp(y / (y + z))
            take(x < (1.0 - limit) * (y + z), 0.0, wyz, 1.0 - wyz)
            wxz = ramp(x / (x + z))
            take(y < (1.0 - limit) * (x + z), wxz, 0.0, 1.0 - wxz)
            k = (limit - 1.0) / (2.0 * limit - 1.0)
            g = (2.0 - limit) / (2.0 * limit - 1.0)
            take(np.ones(len(a), bool), g * x + k, g * y + k, g * z + k)
        else:
            take(np.ones(len(a), bool), 1.0, 0.0, 0.0)  # Cycles' "desperate mode"
    return w


class BoxLookup:
    """Image Texture node with Box projection (Cycles svm_node_tex_image_box): the image
    on each axis' plane of the vector (x: (y, z), y: (x, z), z: (y, x), mirrored on the
    faces whose normal points the other way, so no face reads flipped), weighted by
    box_weights of the object-space normal and Blend."""

    def __init__(self, texture: ImageTexture, vector, normal, blend=0.0, output="COLOR"):
        self.texture, self.normal = texture, normal
        self.vector = vector if vector is not None else UVCoord()
        self.blend, self.output = float(blend), output

    def evaluate(self, geo, prim, u, v):
        co = _eval(self.vector, geo, prim, u, v, 3)
        n = _eval(self.normal, geo, prim, u, v, 3)
        w = box_weights(n, self.blend)
        planes = (np.stack([np.where(n[:, 0] < 0, 1.0 - co[:, 1], co[:, 1]), co[:, 2]], 1),
                  np.stack([np.where(n[:, 1] > 0, 1.0 - co[:, 0], co[:, 0]), co[:, 2]], 1),
                  np.stack([np.where(n[:, 2] > 0, 1.0 - co[:, 1], co[:, 1]), co[:, 0]], 1))
        rgba = np.zeros((len(co), 4))
        for k, uv in enumerate(planes):
            m = w[:, k] > 0
            if m.any():
                rgba[m] += w[m, k, None] * self.texture.sample_rgba(uv[m])
        return rgba[:, 3] if self.output == "ALPHA" else rgba[:, :3]


def _screen(a, b, t):
    return 1.0 - (1.0 - t + t * (1.0 - b)) * (1.0 - a)


MIX_BLENDS = {
    "MIX": lambda a, b, t: a + t * (b - a),
    "ADD": lambda a, b, t: a + t * b,
    "MULTIPLY": lambda a, b, t: a * (1.0 - t + t * b),
    "SUBTRACT": lambda a, b, t: a - t * b,
    "SCREEN": _screen,
    "DIFFERENCE": lambda a, b, t: a + t * (np.abs(a - b) - a),
    "DARKEN": lambda a, b, t: a + t * (np.minimum(a, b) - a),
    "LIGHTEN": lambda a, b, t: a + t * (np.maximum(a, b) - a),
    "DIVIDE": lambda a, b, t: np.where(b != 0, a * (1.0 - t) + t * a / np.where(b != 0, b, 1),
                                       a),
    "OVERLAY": lambda a, b, t: np.where(a < 0.5, a * (1.0 - t + 2.0 * t * b),
                                        1.0 - (1.0 - t + 2.0 * t * (1.0 - b)) * (1.0 - a)),
    "EXCLUSION": lambda a, b, t: np.maximum(a + t * (a + b - 2.0 * a * b - a), 0.0),
    "DODGE": lambda a, b, t: _dodge(a, b, t),
    "BURN": lambda a, b, t: _burn(a, b, t),
    "HUE": lambda a, b, t: _mix_hsv(a, b, t, "HUE"),
    "SATURATION": lambda a, b, t: _mix_hsv(a, b, t, "SATURATION"),
    "VALUE": lambda a, b, t: _mix_hsv(a, b, t, "VALUE"),
    "COLOR": lambda a, b, t: _mix_hsv(a, b, t, "COLOR"),
    "SOFT_LIGHT": lambda a, b, t: (1.0 - t) * a + t * ((1.0 - a) * b * a
                                                       + a * (1.0 - (1.0 - b) * (1.0 - a))),
    "LINEAR_LIGHT": lambda a, b, t: a + t * (2.0 * b - 1.0),
}


def _dodge(a, b, t):
    # svm_mix_dodge: a / (1 - t b), 1 where that is >= 1 or the divisor <= 0; a = 0 stays
    d = 1.0 - t * b
    q = np.where(d > 0, a / np.where(d > 0, d, 1.0), 1.0)
    return np.where(a != 0, np.minimum(q, 1.0), a)


def _burn(a, b, t):
    # svm_mix_burn: 1 - (1 - a) / (1 - t + t b), clamped to 0..1; 0 where the divisor <= 0
    d = 1.0 - t + t * b
    q = 1.0 - (1.0 - a) / np.where(d > 0, d, 1.0)
    return np.where(d > 0, np.clip(q, 0.0, 1.0), 0.0)


def _mix_hsv(a, b, t, kind):
    # svm_mix_hue / _sat / _val / _color (util/color.h rgb_to_hsv, hsv_to_rgb)
    hsv, hsv2 = rgb_to_hsv(a), rgb_to_hsv(b)
    tt = t[:, 0] if np.ndim(t) == 2 else np.broadcast_to(t, len(a))
    if kind == "VALUE":
        hsv[:, 2] = (1.0 - tt) * hsv[:, 2] + tt * hsv2[:, 2]
        return hsv_to_rgb(hsv)
    if kind == "SATURATION":
        out = hsv.copy()
        out[:, 1] = (1.0 - tt) * hsv[:, 1] + tt * hsv2[:, 1]
        return np.where((hsv[:, 1] != 0)[:, None], hsv_to_rgb(out), a)
    hsv[:, 0] = hsv2[:, 0]
    if kind == "COLOR":
        hsv[:, 1] = hsv2[:, 1]
    mixed = a + tt[:, None] * (hsv_to_rgb(hsv) - a)
    return np.where((hsv2[:, 1] != 0)[:, None], mixed, a)


class MixColor:
    """Mix node (Color) / legacy MixRGB: blend a and b by factor (clamped to 0..1 unless
    clamp_factor is False), optionally clamping the result (Cycles svm_mix)."""

    def __init__(self, factor, a, b, blend="MIX", clamp_factor=True, clamp_result=False):
        if blend not in MIX_BLENDS:
            raise ValueError(f"Mix blend type {blend!r} is not supported "
                             f"(supported: {', '.join(MIX_BLENDS)})")
        self.factor, self.a, self.b = factor, a, b
        self.blend, self.clamp_factor, self.clamp_result = blend, clamp_factor, clamp_result

    def evaluate(self, geo, prim, u, v):
        t = _eval(self.factor, geo, prim, u, v, 1)
        if self.clamp_factor:
            t = np.clip(t, 0.0, 1.0)
        out = MIX_BLENDS[self.blend](_eval(self.a, geo, prim, u, v, 3),
                                     _eval(self.b, geo, prim, u, v, 3), t[:, None])
        return np.clip(out, 0.0, 1.0) if self.clamp_result else out


class MixValue:
    """Mix node of floats (svm_node_mix_float) or vectors (svm_node_mix_vector, Uniform or
    Non-Uniform factor): a + t (b - a), t clamped to 0..1 when clamp_factor. width 1
    (floats, (N,)) or 3 (vectors, (N,3)); a non-uniform factor is a vector."""

    def __init__(self, factor, a, b, width=1, clamp_factor=True, uniform=True):
        self.factor, self.a, self.b = factor, a, b
        self.width, self.clamp_factor, self.uniform = width, clamp_factor, uniform

    def evaluate(self, geo, prim, u, v):
        w = self.width
        t = _eval(self.factor, geo, prim, u, v, 1 if (w == 1 or self.uniform) else 3)
        if self.clamp_factor:
            t = np.clip(t, 0.0, 1.0)
        if w == 3 and t.ndim == 1:
            t = t[:, None]
        a, b = _eval(self.a, geo, prim, u, v, w), _eval(self.b, geo, prim, u, v, w)
        return a * (1.0 - t) + b * t


def _safe_normalize(a):
    n = np.linalg.norm(a, axis=1, keepdims=True)
    return np.where(n != 0, a / np.where(n != 0, n, 1.0), a)


def _vector_op(op, a, b, c, scale):
    """Cycles' svm_vector_math (kernel/svm/math_util.h): (vector (N,3), value (N,))."""
    zero_v, zero_s = np.zeros_like(a), np.zeros(len(a))
    dot = np.einsum("ij,ij->i", a, b)
    if op == "DOT_PRODUCT":
        return zero_v, dot
    if op == "DISTANCE":
        return zero_v, np.linalg.norm(a - b, axis=1)
    if op == "LENGTH":
        return zero_v, np.linalg.norm(a, axis=1)
    if op == "PROJECT":
        bb = np.einsum("ij,ij->i", b, b)
        return np.where((bb != 0)[:, None], b * (dot / np.where(bb != 0, bb, 1.0))[:, None],
                        0.0), zero_s
    if op == "REFLECT":
        n = _safe_normalize(b)
        return a - 2.0 * np.einsum("ij,ij->i", a, n)[:, None] * n, zero_s
    if op == "REFRACT":
        n = _safe_normalize(b)
        d = np.einsum("ij,ij->i", n, a)
        k = 1.0 - scale * scale * (1.0 - d * d)
        out = scale[:, None] * a - (scale * d + np.sqrt(np.maximum(k, 0.0)))[:, None] * n
        return np.where((k < 0)[:, None], 0.0, out), zero_s
    if op == "FACEFORWARD":
        return np.where((np.einsum("ij,ij->i", c, b) < 0)[:, None], a, -a), zero_s
    if op == "CROSS_PRODUCT":
        return np.cross(a, b), zero_s
    if op == "SCALE":
        return a * scale[:, None], zero_s
    if op == "NORMALIZE":
        return _safe_normalize(a), zero_s
    # The rest are the Math node's operations per component (svm_vector_math calls the
    # same safe_* functions component by component).
    return MATH_OPS[_VECTOR_AS_MATH.get(op, op)](a, b, c), zero_s


# Vector Math operations whose Math node twin has another name.
_VECTOR_AS_MATH = {"FRACTION": "FRACT"}


VECTOR_MATH_OPS = ("ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "MULTIPLY_ADD", "CROSS_PRODUCT",
                   "PROJECT", "REFLECT", "REFRACT", "FACEFORWARD", "DOT_PRODUCT", "DISTANCE",
                   "LENGTH", "SCALE", "NORMALIZE", "SNAP", "FLOOR", "CEIL", "MODULO", "WRAP",
                   "FRACTION", "ABSOLUTE", "MINIMUM", "MAXIMUM", "SINE", "COSINE", "TANGENT",
                   "POWER", "SIGN")


class VectorMath:
    """Vector Math node (svm_node_vector_math): <operation>(a, b, c, scale) with output
    VECTOR ((N,3)) or VALUE ((N,): Dot Product, Distance, Length; 0 for the others)."""

    def __init__(self, operation, a, b=0.0, c=0.0, scale=1.0, output="VECTOR"):
        if operation not in VECTOR_MATH_OPS:
            raise ValueError(f"Vector Math operation {operation!r} is not supported")
        self.operation, self.a, self.b, self.c = operation, a, b, c
        self.scale, self.output = scale, output

    def evaluate(self, geo, prim, u, v):
        a, b, c = (_eval(x, geo, prim, u, v, 3) for x in (self.a, self.b, self.c))
        scale = _eval(self.scale, geo, prim, u, v, 1)
        with np.errstate(all="ignore"):
            vec, val = _vector_op(self.operation, a, b, c, scale)
        return val if self.output == "VALUE" else vec


class Invert:
    """Invert Color node: mix(c, 1 - c, factor)."""

    def __init__(self, factor, color):
        self.factor, self.color = factor, color

    def evaluate(self, geo, prim, u, v):
        t = _eval(self.factor, geo, prim, u, v, 1)[:, None]
        c = _eval(self.color, geo, prim, u, v, 3)
        return c + t * ((1.0 - c) - c)


class ColorRamp:
    """Color Ramp node from its stops (the engine API's form; the add-on bakes Blender's
    own evaluation into a RampTable): positions (K,) ascending, colors (K,3), alphas (K,);
    interpolation LINEAR or CONSTANT (a stop's colour up to the next stop); output COLOR
    or ALPHA. Baked at RAMP_STEPS + 1 equal steps and read as a RampTable (Cycles' table
    and lookup, so the two forms cannot disagree)."""

    RAMP_STEPS = 256

    def __init__(self, factor, positions, colors, alphas=None, interpolation="LINEAR",
                 output="COLOR"):
        if interpolation not in ("LINEAR", "CONSTANT"):
            raise ValueError(f"Color Ramp interpolation {interpolation!r} is not supported "
                             "(LINEAR, CONSTANT)")
        order = np.argsort(np.asarray(positions, np.float64), kind="stable")
        pos = np.asarray(positions, np.float64)[order]
        a = np.ones(len(order)) if alphas is None else np.asarray(alphas, np.float64)[order]
        stops = np.concatenate([np.asarray(colors, np.float64).reshape(-1, 3)[order],
                                a[:, None]], axis=1)
        x = np.arange(self.RAMP_STEPS + 1) / self.RAMP_STEPS
        if interpolation == "CONSTANT":
            i = np.clip(np.searchsorted(pos, x, side="right") - 1, 0, len(pos) - 1)
            table = stops[i]
        else:
            table = np.stack([np.interp(x, pos, stops[:, k]) for k in range(4)], axis=1)
        self._table = RampTable(factor, table, interpolate=interpolation != "CONSTANT",
                                output=output)
        self.factor, self.interpolation, self.output = factor, interpolation, output

    def evaluate(self, geo, prim, u, v):
        return self._table.evaluate(geo, prim, u, v)


def _safe_divide(a, b):
    return np.where(b != 0, a / np.where(b != 0, b, 1.0), 0.0)


def _safe_power(a, b):
    # util/math.h safe_powf: a negative base takes integer exponents only.
    return np.where((a < 0) & (b != np.trunc(b)), 0.0, np.power(a, b))


def _safe_log(a, b):
    # safe_logf: 0 unless both are positive; then log a / log b (safe_divide).
    ok = (a > 0) & (b > 0)
    return np.where(ok, _safe_divide(np.log(np.where(ok, a, 1.0)),
                                     np.log(np.where(ok, b, 2.0))), 0.0)


def _wrap(value, vmax, vmin):
    # wrapf(value, max, min)
    r = vmax - vmin
    return np.where(r != 0, value - r * np.floor(_safe_divide(value - vmin, r)), vmin)


def _pingpong(a, b):
    # pingpongf: |fract((a - b) / 2b) 2b - b|, 0 for b = 0
    q = _safe_divide(a - b, b * 2.0)
    return np.where(b != 0, np.abs((q - np.floor(q)) * b * 2.0 - b), 0.0)


def _smooth_min(a, b, k):
    # smoothminf: min(a, b) - h^3 k / 6, h = max(k - |a - b|, 0) / k (k != 0)
    h = _safe_divide(np.maximum(k - np.abs(a - b), 0.0), k)
    return np.where(k != 0, np.minimum(a, b) - h * h * h * k / 6.0, np.minimum(a, b))


# Cycles' svm_math (kernel/svm/math_util.h) by Blender's operation name: f(a, b, c), the
# node's three inputs (most read one or two).
MATH_OPS = {
    "ADD": lambda a, b, c: a + b, "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b,
    "DIVIDE": lambda a, b, c: _safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "POWER": lambda a, b, c: _safe_power(a, b),
    "LOGARITHM": lambda a, b, c: _safe_log(a, b),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0.0)),
    "INVERSE_SQRT": lambda a, b, c: np.where(a > 0, 1.0 / np.sqrt(np.where(a > 0, a, 1.0)),
                                             0.0),
    "ABSOLUTE": lambda a, b, c: np.abs(a),
    "EXPONENT": lambda a, b, c: np.exp(a),
    "MINIMUM": lambda a, b, c: np.minimum(a, b),
    "MAXIMUM": lambda a, b, c: np.maximum(a, b),
    "LESS_THAN": lambda a, b, c: (a < b).astype(np.float64),
    "GREATER_THAN": lambda a, b, c: (a > b).astype(np.float64),
    "SIGN": lambda a, b, c: np.sign(a),
    "COMPARE": lambda a, b, c: ((a == b) | (np.abs(a - b) <= np.maximum(
        c, np.finfo(np.float32).eps))).astype(np.float64),
    "SMOOTH_MIN": lambda a, b, c: _smooth_min(a, b, c),
    "SMOOTH_MAX": lambda a, b, c: -_smooth_min(-a, -b, c),
    "ROUND": lambda a, b, c: np.floor(a + 0.5),
    "FLOOR": lambda a, b, c: np.floor(a),
    "CEIL": lambda a, b, c: np.ceil(a),
    "TRUNC": lambda a, b, c: np.trunc(a),
    "FRACT": lambda a, b, c: a - np.floor(a),
    "MODULO": lambda a, b, c: np.where(b != 0, np.fmod(a, np.where(b != 0, b, 1)), 0.0),
    "FLOORED_MODULO": lambda a, b, c: np.where(
        b != 0, a - np.floor(_safe_divide(a, b)) * b, 0.0),
    "WRAP": lambda a, b, c: _wrap(a, b, c),
    "SNAP": lambda a, b, c: np.floor(_safe_divide(a, b)) * b,
    "PINGPONG": lambda a, b, c: _pingpong(a, b),
    "SINE": lambda a, b, c: np.sin(a), "COSINE": lambda a, b, c: np.cos(a),
    "TANGENT": lambda a, b, c: np.tan(a),
    "ARCSINE": lambda a, b, c: np.arcsin(np.clip(a, -1.0, 1.0)),
    "ARCCOSINE": lambda a, b, c: np.arccos(np.clip(a, -1.0, 1.0)),
    "ARCTANGENT": lambda a, b, c: np.arctan(a),
    "ARCTAN2": lambda a, b, c: np.arctan2(a, b),
    "SINH": lambda a, b, c: np.sinh(a), "COSH": lambda a, b, c: np.cosh(a),
    "TANH": lambda a, b, c: np.tanh(a),
    "RADIANS": lambda a, b, c: a * (np.pi / 180.0),
    "DEGREES": lambda a, b, c: a * (180.0 / np.pi),
}


class Math:
    """Math node (value): <operation>(a, b, c) as Cycles' svm_math, optionally clamped to
    0..1."""

    def __init__(self, operation, a, b=0.0, clamp=False, c=0.0):
        if operation not in MATH_OPS:
            raise ValueError(f"Math operation {operation!r} is not supported "
                             f"(supported: {', '.join(MATH_OPS)})")
        self.operation, self.a, self.b, self.c, self.clamp = operation, a, b, c, clamp

    def evaluate(self, geo, prim, u, v):
        with np.errstate(all="ignore"):
            r = MATH_OPS[self.operation](_eval(self.a, geo, prim, u, v, 1),
                                         _eval(self.b, geo, prim, u, v, 1),
                                         _eval(self.c, geo, prim, u, v, 1))
        return np.clip(r, 0.0, 1.0) if self.clamp else r


def ramp_lookup(table, f, interpolate=True, extrapolate=False):
    """Cycles' rgb_ramp_lookup / float_ramp_lookup (kernel/svm/ramp.h) of a baked table
    (K,) or (K,C) at positions f (N,): f in 0..1 reads between entries (linearly with
    interpolate, else the entry at or below); outside, the end entry, or with extrapolate
    the line through the two end entries. NaN reads entry 0 (saturatef). Returns (N,) or
    (N,C)."""
    table = np.asarray(table, np.float64)
    f = np.asarray(f, np.float64)
    n = len(table)
    g = np.clip(np.nan_to_num(f, nan=0.0), 0.0, 1.0) * (n - 1)
    i = np.clip(np.floor(g).astype(np.int64), 0, n - 1)
    t = g - i
    out = table[i]
    if interpolate:
        j = np.minimum(i + 1, n - 1)
        w = (t if table.ndim == 1 else t[:, None])
        out = np.where(w > 0, (1.0 - w) * out + w * table[j], out)
    if extrapolate:
        lo, hi = f < 0.0, f > 1.0
        if lo.any():
            d = (-f[lo]) * (n - 1)
            out[lo] = table[0] + (table[0] - table[1]) * (d if table.ndim == 1 else d[:, None])
        if hi.any():
            d = (f[hi] - 1.0) * (n - 1)
            out[hi] = table[-1] + (table[-1] - table[-2]) * (
                d if table.ndim == 1 else d[:, None])
    return out


class RampTable:
    """Color Ramp node as Cycles renders it: the table Blender's ColorRamp.evaluate gives
    at K equal steps (intern/cycles/blender/util.h colorramp_to_array, K = 257), looked
    up by ramp_lookup (every interpolation mode: Linear, Ease, Cardinal, B-Spline read
    linearly between the baked entries; Constant reads the entry at or below). table
    (K,4) RGBA; output COLOR or ALPHA."""

    def __init__(self, factor, table, interpolate=True, output="COLOR"):
        self.factor, self.interpolate, self.output = factor, bool(interpolate), output
        self.table = np.asarray(table, np.float64).reshape(-1, 4)

    def evaluate(self, geo, prim, u, v):
        out = ramp_lookup(self.table, _eval(self.factor, geo, prim, u, v, 1),
                          self.interpolate)
        return out[:, 3] if self.output == "ALPHA" else out[:, :3]


class RGBCurves:
    """RGB Curves node (svm_node_curves): each channel c of the colour reads the baked
    table (K,3) (Blender's curves R, G, B applied to the combined curve C, at K equal
    steps of min_x .. max_x: curvemapping_color_to_array) at (c - min_x) / (max_x -
    min_x), with the mapping's extrapolation; mix(colour, result, factor)."""

    def __init__(self, factor, color, table, min_x=0.0, max_x=1.0, extrapolate=False):
        self.factor, self.color = factor, color
        self.table = np.asarray(table, np.float64).reshape(-1, 3)
        self.min_x, self.max_x, self.extrapolate = float(min_x), float(max_x), extrapolate

    def evaluate(self, geo, prim, u, v):
        fac = _eval(self.factor, geo, prim, u, v, 1)[:, None]
        c = _eval(self.color, geo, prim, u, v, 3)
        rel = (c - self.min_x) / (self.max_x - self.min_x)
        out = np.stack([ramp_lookup(self.table[:, k], rel[:, k], True, self.extrapolate)
                        for k in range(3)], axis=1)
        return (1.0 - fac) * c + fac * out


class FloatCurve:
    """Float Curve node (svm_node_curve): the value reads the baked table (K,) of the
    curve over min_x .. max_x; mix(value, result, factor)."""

    def __init__(self, factor, value, table, min_x=0.0, max_x=1.0, extrapolate=False):
        self.factor, self.value = factor, value
        self.table = np.asarray(table, np.float64).ravel()
        self.min_x, self.max_x, self.extrapolate = float(min_x), float(max_x), extrapolate

    def evaluate(self, geo, prim, u, v):
        fac = _eval(self.factor, geo, prim, u, v, 1)
        x = _eval(self.value, geo, prim, u, v, 1)
        out = ramp_lookup(self.table, (x - self.min_x) / (self.max_x - self.min_x), True,
                          self.extrapolate)
        return (1.0 - fac) * x + fac * out


class BrightContrast:
    """Bright/Contrast node (svm_brightness_contrast): max((1 + contrast) c + bright -
    contrast / 2, 0) per channel."""

    def __init__(self, color, bright, contrast):
        self.color, self.bright, self.contrast = color, bright, contrast

    def evaluate(self, geo, prim, u, v):
        c = _eval(self.color, geo, prim, u, v, 3)
        k = _eval(self.contrast, geo, prim, u, v, 1)[:, None]
        b = _eval(self.bright, geo, prim, u, v, 1)[:, None]
        return np.maximum((1.0 + k) * c + (b - 0.5 * k), 0.0)


class Gamma:
    """Gamma node (svm_math_gamma_color): c^gamma for the positive channels (the others as
    they are); white for gamma 0."""

    def __init__(self, color, gamma):
        self.color, self.gamma = color, gamma

    def evaluate(self, geo, prim, u, v):
        c = _eval(self.color, geo, prim, u, v, 3)
        g = _eval(self.gamma, geo, prim, u, v, 1)[:, None]
        with np.errstate(all="ignore"):
            out = np.where(c > 0, np.power(np.where(c > 0, c, 1.0), g), c)
        return np.where(g == 0, 1.0, out)


class ToGray:
    """RGB to BW node: the colour's luminance (Rec.709 weights, Cycles' linear_rgb_to_gray
    in the scene's linear space), (N,)."""

    def __init__(self, color):
        self.color = color

    def evaluate(self, geo, prim, u, v):
        return _eval(self.color, geo, prim, u, v, 3) @ np.array([0.2126, 0.7152, 0.0722])


class ObjectInfo:
    """Object Info node (svm_node_object_info) per hit, from the hit triangle's object
    (Geometry.object_id; an instance's own): RANDOM (Mesh.random, 0..1), COLOR, ALPHA
    (Mesh.object_color), OBJECT_INDEX (Mesh.pass_index) or LOCATION ((N,3) world-space
    origin of the object, m: Cycles' object_location, the translation of its object
    matrix; Mesh.location). Without a Geometry (a constant fold) or its tables: 0,
    white, 1, 0, the origin. (Material Index is the material's pass index, a constant
    of the tree: the add-on reads it.)"""

    OUTPUTS = ("RANDOM", "COLOR", "ALPHA", "OBJECT_INDEX", "LOCATION")

    def __init__(self, output="RANDOM"):
        if output not in self.OUTPUTS:
            raise ValueError(f"Object Info output {output!r}: expected one of {self.OUTPUTS}")
        self.output = output

    def evaluate(self, geo, prim, u, v):
        n = len(prim)
        oid = None if geo is None else np.take(geo.object_id, np.asarray(prim, np.int64))
        if self.output == "LOCATION":
            table = None if geo is None else getattr(geo, "object_location", None)
            return np.zeros((n, 3)) if table is None else np.take(table, oid, axis=0)
        if self.output == "COLOR" or self.output == "ALPHA":
            table = None if geo is None else getattr(geo, "object_color", None)
            rgba = np.ones((n, 4)) if table is None else np.take(table, oid, axis=0)
            return rgba[:, :3] if self.output == "COLOR" else rgba[:, 3]
        name = "object_random" if self.output == "RANDOM" else "object_pass_index"
        table = None if geo is None else getattr(geo, name, None)
        return np.zeros(n) if table is None else np.take(table, oid)


class ObjectAttribute:
    """Attribute node of type Object or Instancer (Cycles' ATTR_ELEMENT_OBJECT attribute,
    svm_node_attr on a float4): the hit object's RGBA of that name (Geometry.
    object_attributes, from Blender's object, instancer or mesh property); output COLOR
    (N,3), FAC (N,) the average of RGB, or ALPHA (N,). An object without it reads 0."""

    def __init__(self, name, output="COLOR"):
        if output not in ("COLOR", "FAC", "ALPHA"):
            raise ValueError(f"Attribute output {output!r}: expected COLOR, FAC or ALPHA")
        self.name, self.output = str(name), output

    def evaluate(self, geo, prim, u, v):
        n = len(prim)
        table = None if geo is None else (getattr(geo, "object_attributes", None)
                                          or {}).get(self.name)
        if table is None:
            rgba = np.zeros((n, 4))
        else:
            rgba = np.take(table, np.take(geo.object_id, np.asarray(prim, np.int64)), axis=0)
        if self.output == "ALPHA":
            return rgba[:, 3]
        return rgba[:, :3].mean(axis=1) if self.output == "FAC" else rgba[:, :3]


class Clamp:
    """Clamp node (svm_node_clamp): MINMAX clamp(value, min, max) (min wins where they
    cross); RANGE swaps min and max where min > max."""

    def __init__(self, value, vmin, vmax, kind="MINMAX"):
        if kind not in ("MINMAX", "RANGE"):
            raise ValueError(f"Clamp type {kind!r}: expected MINMAX or RANGE")
        self.value, self.vmin, self.vmax, self.kind = value, vmin, vmax, kind

    def evaluate(self, geo, prim, u, v):
        x = _eval(self.value, geo, prim, u, v, 1)
        lo = _eval(self.vmin, geo, prim, u, v, 1)
        hi = _eval(self.vmax, geo, prim, u, v, 1)
        if self.kind == "RANGE":
            lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
        # util/math.h clamp(a, mn, mx) = min(max(a, mn), mx)
        return np.minimum(np.maximum(x, lo), hi)


def _smoothstep(edge0, edge1, x):
    """Cycles util/math.h smoothstep: 0 below edge0, 1 from edge1 on, 3t^2 - 2t^3 between."""
    t = (x - edge0) / np.where(edge1 != edge0, edge1 - edge0, 1.0)
    return np.where(x < edge0, 0.0, np.where(x >= edge1, 1.0, (3.0 - 2.0 * t) * (t * t)))


def _smootherstep(edge0, edge1, x):
    """Cycles map_range.h smootherstep: t = clamp((x - edge0) / (edge1 - edge0)) (0 where
    the range is empty: safe_divide), then 6t^5 - 15t^4 + 10t^3."""
    d = edge1 - edge0
    t = np.clip(np.where(d != 0, (x - edge0) / np.where(d != 0, d, 1.0), 0.0), 0.0, 1.0)
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


MAP_RANGE_TYPES = ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP")


def map_range(value, from_min, from_max, to_min, to_max, steps=4.0, kind="LINEAR",
              clamp=True):
    """Map Range node, Float (Cycles svm_node_map_range; its Clamp is the Clamp node
    (Range) that Cycles' MapRangeNode::expand puts after it: between To Min and To Max,
    whichever is larger). Arrays broadcast; an empty From range gives 0 (as Cycles).

    LINEAR        f = (value - from_min) / (from_max - from_min)
    STEPPED       floor(f (steps + 1)) / steps (0 for steps <= 0)
    SMOOTHSTEP    smoothstep(from_min, from_max, value) (1 - it, edges swapped, for a
                  reversed range); SMOOTHERSTEP likewise with 6t^5 - 15t^4 + 10t^3
    result = to_min + f (to_max - to_min)."""
    if kind not in MAP_RANGE_TYPES:
        raise ValueError(f"Map Range interpolation {kind!r}: expected one of "
                         f"{MAP_RANGE_TYPES}")
    value, from_min, from_max, to_min, to_max, steps = np.broadcast_arrays(
        *(np.asarray(x, np.float64) for x in (value, from_min, from_max, to_min, to_max,
                                               steps)))
    empty = from_max == from_min
    span = np.where(empty, 1.0, from_max - from_min)
    if kind in ("LINEAR", "STEPPED"):
        f = (value - from_min) / span
        if kind == "STEPPED":
            f = np.where(steps > 0.0,
                         np.floor(f * (steps + 1.0)) / np.where(steps > 0.0, steps, 1.0), 0.0)
    else:
        step = _smoothstep if kind == "SMOOTHSTEP" else _smootherstep
        rev = from_min > from_max
        f = np.where(rev, 1.0 - step(from_max, from_min, value),
                     step(from_min, from_max, value))
    r = to_min + f * (to_max - to_min)
    if clamp:
        r = np.clip(r, np.minimum(to_min, to_max), np.maximum(to_min, to_max))
    return np.where(empty, 0.0, r)


def vector_map_range(value, from_min, from_max, to_min, to_max, steps=4.0, kind="LINEAR",
                     clamp=True):
    """Map Range node, Vector (Cycles svm_node_vector_map_range), per component: arrays
    broadcast to (..., 3). Unlike the Float node: an empty From range gives the factor 0
    (safe_divide: the result is To Min), SMOOTHSTEP / SMOOTHERSTEP clamp the factor to
    [0, 1] without swapping reversed edges, and Clamp holds for LINEAR and STEPPED only."""
    if kind not in MAP_RANGE_TYPES:
        raise ValueError(f"Map Range interpolation {kind!r}: expected one of "
                         f"{MAP_RANGE_TYPES}")
    value, from_min, from_max, to_min, to_max, steps = np.broadcast_arrays(
        *(np.asarray(x, np.float64) for x in (value, from_min, from_max, to_min, to_max,
                                               steps)))
    span = from_max - from_min
    f = np.where(span != 0.0, (value - from_min) / np.where(span != 0.0, span, 1.0), 0.0)
    if kind == "STEPPED":
        f = np.where(steps > 0.0, np.floor(f * (steps + 1.0)) / np.where(steps > 0.0, steps, 1.0),
                     0.0)
    elif kind == "SMOOTHSTEP":
        f = np.clip(f, 0.0, 1.0)
        f = (3.0 - 2.0 * f) * (f * f)
    elif kind == "SMOOTHERSTEP":
        f = np.clip(f, 0.0, 1.0)
        f = f * f * f * (f * (f * 6.0 - 15.0) + 10.0)
    r = to_min + f * (to_max - to_min)
    if clamp and kind in ("LINEAR", "STEPPED"):
        r = np.clip(r, np.minimum(to_min, to_max), np.maximum(to_min, to_max))
    return r


class MapRange:
    """Map Range node: map_range() of its inputs per hit (Float), or vector_map_range()
    per component (Vector, `vector=True`: (N,3)). inputs: keyed by SOCKETS (Float) or
    VECTOR_SOCKETS (Blender's socket identifiers of the Vector inputs), nodes or
    constants; kind one of MAP_RANGE_TYPES."""

    SOCKETS = ("Value", "From Min", "From Max", "To Min", "To Max", "Steps")
    DEFAULTS = {"Value": 1.0, "From Min": 0.0, "From Max": 1.0, "To Min": 0.0,
                "To Max": 1.0, "Steps": 4.0}
    VECTOR_SOCKETS = ("Vector", "From_Min_FLOAT3", "From_Max_FLOAT3", "To_Min_FLOAT3",
                      "To_Max_FLOAT3", "Steps_FLOAT3")
    VECTOR_DEFAULTS = {"Vector": (0.0, 0.0, 0.0), "From_Min_FLOAT3": (0.0, 0.0, 0.0),
                       "From_Max_FLOAT3": (1.0, 1.0, 1.0), "To_Min_FLOAT3": (0.0, 0.0, 0.0),
                       "To_Max_FLOAT3": (1.0, 1.0, 1.0), "Steps_FLOAT3": (4.0, 4.0, 4.0)}

    def __init__(self, inputs=None, kind="LINEAR", clamp=True, vector=False):
        if kind not in MAP_RANGE_TYPES:
            raise ValueError(f"Map Range interpolation {kind!r}: expected one of "
                             f"{MAP_RANGE_TYPES}")
        self.vector = bool(vector)
        self.inputs = {**(self.VECTOR_DEFAULTS if self.vector else self.DEFAULTS),
                       **(inputs or {})}
        self.kind, self.clamp = kind, bool(clamp)

    def evaluate(self, geo, prim, u, v):
        if self.vector:
            ins = [_eval(self.inputs[k], geo, prim, u, v, 3) for k in self.VECTOR_SOCKETS]
            return vector_map_range(*ins, kind=self.kind, clamp=self.clamp)
        ins = [_eval(self.inputs[k], geo, prim, u, v, 1) for k in self.SOCKETS]
        return map_range(*ins, kind=self.kind, clamp=self.clamp)


# Cycles' blackbody fit (kernel/tables.h blackbody_table_r/g/b, used by
# svm_math_blackbody_color_rec709 in kernel/svm/math_util.h): per temperature segment,
# R and G = a / T + b T + c, B = ((a T + b) T + c) T + d, linear Rec.709.
_BLACKBODY_R = np.array([
    [1.61919106e+03, -2.05010916e-03, 5.02995757e+00],
    [2.48845471e+03, -1.11330907e-03, 3.22621544e+00],
    [3.34143193e+03, -4.86551192e-04, 1.76486769e+00],
    [4.09461742e+03, -1.27446582e-04, 7.25731635e-01],
    [4.67028036e+03, 2.91258199e-05, 1.26703442e-01],
    [4.59509185e+03, 2.87495649e-05, 1.50345020e-01],
    [3.78717450e+03, 9.35907826e-06, 3.99075871e-01]])
_BLACKBODY_G = np.array([
    [-4.88999748e+02, 6.04330754e-04, -7.55807526e-02],
    [-7.55994277e+02, 3.16730098e-04, 4.78306139e-01],
    [-1.02363977e+03, 1.20223470e-04, 9.36662319e-01],
    [-1.26571316e+03, 4.87340896e-06, 1.27054498e+00],
    [-1.42529332e+03, -4.01150431e-05, 1.43972784e+00],
    [-1.17554822e+03, -2.16378048e-05, 1.30408023e+00],
    [-5.00799571e+02, -4.59832026e-06, 1.09098763e+00]])
_BLACKBODY_B = np.array([
    [5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -4.07936148e-03],
    [2.40430366e-11, 5.55021075e-08, -1.98503712e-04, 2.89312858e-02],
    [-1.40949732e-11, 1.89878968e-07, -3.56632824e-04, 9.10767778e-02],
    [-3.61460868e-11, 2.84822009e-07, -4.93211319e-04, 1.56723440e-01],
    [-1.97075738e-11, 1.75359352e-07, -2.50542825e-04, -2.22783266e-02],
    [-1.61997957e-13, -1.64216008e-08, 3.86216271e-04, -7.38077418e-01],
    [6.72650283e-13, -2.73078809e-08, 4.24098264e-04, -7.52335691e-01]])
# Lower bounds (K) of the fit's segments 1..6 (segment 0 from 800 K).
_BLACKBODY_EDGES = np.array([965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0])
_BLACKBODY_HOT = np.array([0.8262954810464208, 0.9945080501520986, 1.566307710274283])
_BLACKBODY_COLD = np.array([5.413294490189271, -0.20319390035873933, -0.0822535242887164])


def blackbody_rec709(temperature) -> np.ndarray:
    """Cycles' svm_math_blackbody_color_rec709: temperature (K, array (N,)) -> (N,3)
    linear Rec.709 RGB of luminance about 1, not clamped (negative outside the gamut):
    the fit between 800 K and 12000 K, constants below and above."""
    t = np.atleast_1d(np.asarray(temperature, np.float64))
    i = np.searchsorted(_BLACKBODY_EDGES, t, side="right")
    ts = np.where(t > 0, t, 1.0)
    r, g, b = _BLACKBODY_R[i], _BLACKBODY_G[i], _BLACKBODY_B[i]
    rgb = np.stack([r[:, 0] / ts + r[:, 1] * ts + r[:, 2],
                    g[:, 0] / ts + g[:, 1] * ts + g[:, 2],
                    ((b[:, 0] * ts + b[:, 1]) * ts + b[:, 2]) * ts + b[:, 3]], axis=1)
    rgb = np.where((t >= 12000.0)[:, None], _BLACKBODY_HOT, rgb)
    return np.where((t < 800.0)[:, None], _BLACKBODY_COLD, rgb)


class Blackbody:
    """Blackbody node (Cycles svm_node_blackbody): blackbody_rec709(Temperature) with
    negatives clamped to 0, as a colour (N,3). The engine's colours are linear Rec.709
    (Cycles' rec709_to_rgb is the identity in Blender's default scene-linear space)."""

    def __init__(self, temperature=1500.0):
        self.temperature = temperature

    def evaluate(self, geo, prim, u, v):
        return np.maximum(blackbody_rec709(_eval(self.temperature, geo, prim, u, v, 1)),
                          0.0)


COLOR_MODES = ("RGB", "HSV", "HSL")


class SeparateChannel:
    """Separate Color / Separate XYZ: one channel (0, 1, 2) of a colour or vector; the
    colour's HSV or HSL channel for mode HSV / HSL (Cycles svm_separate_color)."""

    def __init__(self, source, channel, mode="RGB"):
        if mode not in COLOR_MODES:
            raise ValueError(f"Separate Color mode {mode!r}: expected one of {COLOR_MODES}")
        self.source, self.channel, self.mode = source, int(channel), mode

    def evaluate(self, geo, prim, u, v):
        c = _eval(self.source, geo, prim, u, v, 3)
        if self.mode == "HSV":
            c = rgb_to_hsv(c)
        elif self.mode == "HSL":
            c = rgb_to_hsl(c)
        return c[:, self.channel]


class Combine:
    """Combine Color / Combine XYZ: three factors into a colour or vector; for mode HSV /
    HSL the factors are hue, saturation and value / lightness (svm_combine_color)."""

    def __init__(self, x, y, z, mode="RGB"):
        if mode not in COLOR_MODES:
            raise ValueError(f"Combine Color mode {mode!r}: expected one of {COLOR_MODES}")
        self.parts, self.mode = (x, y, z), mode

    def evaluate(self, geo, prim, u, v):
        c = np.stack([_eval(p, geo, prim, u, v, 1) for p in self.parts], axis=1)
        if self.mode == "HSV":
            return hsv_to_rgb(c)
        return hsl_to_rgb(c) if self.mode == "HSL" else c


class Checker:
    """Checker Texture node: colour1 where floor(x) + floor(y) + floor(z) of the scaled
    coordinate is even, else colour2 (Cycles svm_checker, with its tiny offset that keeps
    integer coordinates off the cell borders); output COLOR or FAC."""

    def __init__(self, vector, color1, color2, scale=5.0, output="COLOR"):
        self.vector, self.color1, self.color2 = vector, color1, color2
        self.scale, self.output = scale, output

    def evaluate(self, geo, prim, u, v):
        scale = _eval(self.scale, geo, prim, u, v, 1)
        p = _eval(self.vector, geo, prim, u, v, 3) * scale[:, None]
        p = (p + 0.000001) * 0.999999
        i = np.abs(np.floor(p)).astype(np.int64) % 2
        fac = ((i[:, 0] == i[:, 1]) == (i[:, 2] == 1)).astype(np.float64)
        if self.output == "FAC":
            return fac
        c1 = _eval(self.color1, geo, prim, u, v, 3)
        c2 = _eval(self.color2, geo, prim, u, v, 3)
        return np.where(fac[:, None] == 1.0, c1, c2)


def rgb_to_hsv(c: np.ndarray) -> np.ndarray:
    """(N,3) RGB -> HSV with hue in [0, 1) (Cycles color_util.h rgb_to_hsv)."""
    cmax = c.max(axis=1)
    cmin = c.min(axis=1)
    delta = cmax - cmin
    s = np.where(cmax != 0, delta / np.where(cmax != 0, cmax, 1.0), 0.0)
    safe = np.where(delta != 0, delta, 1.0)
    cc = (cmax[:, None] - c) / safe[:, None]
    h = np.where(c[:, 0] == cmax, cc[:, 2] - cc[:, 1],
                 np.where(c[:, 1] == cmax, 2.0 + cc[:, 0] - cc[:, 2], 4.0 + cc[:, 1] - cc[:, 0]))
    h = h / 6.0
    h = np.where(h < 0, h + 1.0, h)
    h = np.where(s != 0, h, 0.0)
    return np.stack([h, s, cmax], axis=1)


def hsv_to_rgb(hsv: np.ndarray) -> np.ndarray:
    """(N,3) HSV -> RGB (Cycles color_util.h hsv_to_rgb)."""
    h, s, v = hsv[:, 0], hsv[:, 1], hsv[:, 2]
    h = np.where(h == 1.0, 0.0, h) * 6.0
    i = np.floor(h)
    f = h - i
    p = v * (1 - s)
    q = v * (1 - s * f)
    t = v * (1 - s * (1 - f))
    i = i.astype(np.int64) % 6
    table = np.stack([np.stack([v, t, p], 1), np.stack([q, v, p], 1), np.stack([p, v, t], 1),
                      np.stack([p, q, v], 1), np.stack([t, p, v], 1), np.stack([v, p, q], 1)])
    rgb = table[i, np.arange(len(i))]
    return np.where((s != 0)[:, None], rgb, v[:, None])


def rgb_to_hsl(c: np.ndarray) -> np.ndarray:
    """(N,3) RGB -> HSL (Cycles util/color.h rgb_to_hsl: lightness at most 1)."""
    cmax, cmin = c.max(axis=1), c.min(axis=1)
    lum = np.minimum(1.0, (cmax + cmin) / 2.0)
    d = cmax - cmin
    grey = d == 0
    sd = np.where(grey, 1.0, d)
    with np.errstate(all="ignore"):
        s = np.where(lum > 0.5, d / (2.0 - cmax - cmin), d / (cmax + cmin))
    r, g, b = c[:, 0], c[:, 1], c[:, 2]
    h = np.where(cmax == r, (g - b) / sd + np.where(g < b, 6.0, 0.0),
                 np.where(cmax == g, (b - r) / sd + 2.0, (r - g) / sd + 4.0))
    return np.stack([np.where(grey, 0.0, h) / 6.0, np.where(grey, 0.0, s), lum], axis=1)


def hsl_to_rgb(hsl: np.ndarray) -> np.ndarray:
    """(N,3) HSL -> RGB (Cycles util/color.h hsl_to_rgb)."""
    h, s, lum = hsl[:, 0], hsl[:, 1], hsl[:, 2]
    nr = np.clip(np.abs(h * 6.0 - 3.0) - 1.0, 0.0, 1.0)
    ng = np.clip(2.0 - np.abs(h * 6.0 - 2.0), 0.0, 1.0)
    nb = np.clip(2.0 - np.abs(h * 6.0 - 4.0), 0.0, 1.0)
    chroma = (1.0 - np.abs(2.0 * lum - 1.0)) * s
    return np.stack([(n - 0.5) * chroma + lum for n in (nr, ng, nb)], axis=1)


class HueSaturation:
    """Hue/Saturation/Value node: hue shifted by (hue - 0.5), saturation and value scaled,
    mixed with the input by factor, negatives clamped (Cycles svm_node_hsv)."""

    def __init__(self, hue, saturation, value, factor, color):
        self.hue, self.saturation, self.value = hue, saturation, value
        self.factor, self.color = factor, color

    def evaluate(self, geo, prim, u, v):
        c = _eval(self.color, geo, prim, u, v, 3)
        hsv = rgb_to_hsv(c)
        h = hsv[:, 0] + _eval(self.hue, geo, prim, u, v, 1) + 0.5
        hsv[:, 0] = h - np.floor(h)
        hsv[:, 1] = np.clip(hsv[:, 1] * _eval(self.saturation, geo, prim, u, v, 1), 0.0, 1.0)
        hsv[:, 2] = hsv[:, 2] * _eval(self.value, geo, prim, u, v, 1)
        t = _eval(self.factor, geo, prim, u, v, 1)[:, None]
        return np.maximum(t * hsv_to_rgb(hsv) + (1.0 - t) * c, 0.0)


class Gradient:
    """Gradient Texture node (Cycles svm_gradient), clamped to 0..1; output COLOR (grey)
    or FAC. kinds: LINEAR, QUADRATIC, EASING, DIAGONAL, RADIAL, QUADRATIC_SPHERE,
    SPHERICAL."""

    KINDS = ("LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "RADIAL", "QUADRATIC_SPHERE",
             "SPHERICAL")

    def __init__(self, vector, kind="LINEAR", output="COLOR"):
        if kind not in self.KINDS:
            raise ValueError(f"Gradient type {kind!r}: expected one of {self.KINDS}")
        self.vector, self.kind, self.output = vector, kind, output

    def evaluate(self, geo, prim, u, v):
        p = _eval(self.vector, geo, prim, u, v, 3)
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        k = self.kind
        if k == "LINEAR":
            f = x
        elif k == "QUADRATIC":
            f = np.maximum(x, 0.0) ** 2
        elif k == "EASING":
            r = np.clip(x, 0.0, 1.0)
            f = 3.0 * r * r - 2.0 * r * r * r
        elif k == "DIAGONAL":
            f = (x + y) * 0.5
        elif k == "RADIAL":
            f = np.arctan2(y, x) / (2.0 * np.pi) + 0.5
        else:
            r = np.maximum(0.999999 - np.sqrt(x * x + y * y + z * z), 0.0)
            f = r * r if k == "QUADRATIC_SPHERE" else r
        f = np.clip(f, 0.0, 1.0)
        return f if self.output == "FAC" else np.repeat(f[:, None], 3, axis=1)


def _procedural_inputs(node, geo, prim, u, v):
    """A Noise / Voronoi node's texture coordinates (N,3) (zeros for a 1-D texture, which
    reads W only) and its float inputs in node.SOCKETS order, each (N,)."""
    pts = (_eval(node.vector, geo, prim, u, v, 3) if node.dims > 1
           else np.zeros((len(prim), 3)))
    ins = [np.ascontiguousarray(_eval(node.inputs[k], geo, prim, u, v, 1))
           for k in node.SOCKETS]
    return pts, ins


class Noise:
    """Noise Texture node (Cycles svm_node_tex_noise; kernels in engine/procedural.py).

    vector  coordinates node (N,3) (the add-on passes Generated when unlinked)
    inputs  dict of socket values or nodes: W, Scale, Detail, Roughness, Lacunarity,
            Offset, Gain, Distortion
    dims    1-4 (Blender's noise_dimensions), kind one of procedural.NOISE_TYPES,
    normalize (fBM only), output FAC (the value) or COLOR."""

    SOCKETS = ("W", "Scale", "Detail", "Roughness", "Lacunarity", "Offset", "Gain",
               "Distortion")
    DEFAULTS = {"W": 0.0, "Scale": 5.0, "Detail": 2.0, "Roughness": 0.5, "Lacunarity": 2.0,
                "Offset": 0.0, "Gain": 1.0, "Distortion": 0.0}

    def __init__(self, vector, inputs=None, dims=3, kind="FBM", normalize=True,
                 output="FAC"):
        from . import procedural
        if dims not in (1, 2, 3, 4):
            raise ValueError(f"Noise Texture dimensions: expected 1-4, got {dims!r}")
        if kind not in procedural.NOISE_TYPES:
            raise ValueError(f"Noise Texture type {kind!r}: expected one of "
                             f"{procedural.NOISE_TYPES}")
        self.vector, self.dims, self.kind = vector, int(dims), kind
        self.inputs = {**self.DEFAULTS, **(inputs or {})}
        self.normalize, self.output = bool(normalize), output
        self._offsets = procedural.noise_offsets(self.dims)

    def evaluate(self, geo, prim, u, v):
        from . import procedural
        n = len(prim)
        pts, ins = _procedural_inputs(self, geo, prim, u, v)
        value = np.empty(n)
        color = np.empty((n, 3))
        want_color = self.output == "COLOR"
        # Socket order of the kernel: scale, w, detail, roughness, lacunarity, offset,
        # gain, distortion.
        procedural.noise_texture(self.dims, procedural.NOISE_TYPES.index(self.kind),
                                 self.normalize, np.ascontiguousarray(pts), ins[1], ins[0],
                                 ins[2], ins[3], ins[4], ins[5], ins[6], ins[7],
                                 self._offsets, want_color, value, color)
        return color if want_color else value


class Voronoi:
    """Voronoi Texture node (Cycles svm_node_tex_voronoi; kernels in
    engine/procedural.py).

    vector  coordinates node (N,3) (Generated when unlinked)
    inputs  dict of socket values or nodes: W, Scale, Detail, Roughness, Lacunarity,
            Smoothness, Exponent, Randomness
    dims 1-4, feature one of procedural.VORONOI_FEATURES, metric one of
    procedural.VORONOI_METRICS, normalize; output DISTANCE, COLOR, POSITION, W or RADIUS."""

    SOCKETS = ("W", "Scale", "Detail", "Roughness", "Lacunarity", "Smoothness", "Exponent",
               "Randomness")
    DEFAULTS = {"W": 0.0, "Scale": 5.0, "Detail": 0.0, "Roughness": 0.5, "Lacunarity": 2.0,
                "Smoothness": 1.0, "Exponent": 0.5, "Randomness": 1.0}
    OUTPUTS = ("DISTANCE", "COLOR", "POSITION", "W", "RADIUS")

    def __init__(self, vector, inputs=None, dims=3, feature="F1", metric="EUCLIDEAN",
                 normalize=False, output="DISTANCE"):
        from . import procedural
        if dims not in (1, 2, 3, 4):
            raise ValueError(f"Voronoi Texture dimensions: expected 1-4, got {dims!r}")
        if feature not in procedural.VORONOI_FEATURES:
            raise ValueError(f"Voronoi Texture feature {feature!r}: expected one of "
                             f"{procedural.VORONOI_FEATURES}")
        if metric not in procedural.VORONOI_METRICS:
            raise ValueError(f"Voronoi Texture distance {metric!r}: expected one of "
                             f"{procedural.VORONOI_METRICS}")
        if output not in self.OUTPUTS:
            raise ValueError(f"Voronoi Texture output {output!r}: expected one of "
                             f"{self.OUTPUTS}")
        self.vector, self.dims, self.feature, self.metric = vector, int(dims), feature, metric
        self.inputs = {**self.DEFAULTS, **(inputs or {})}
        self.normalize, self.output = bool(normalize), output

    def evaluate(self, geo, prim, u, v):
        from . import procedural
        n = len(prim)
        pts, ins = _procedural_inputs(self, geo, prim, u, v)
        dist, w_out, radius = np.zeros(n), np.zeros(n), np.zeros(n)
        color, position = np.zeros((n, 3)), np.zeros((n, 3))
        procedural.voronoi_texture(
            self.dims, procedural.VORONOI_FEATURES.index(self.feature),
            procedural.VORONOI_METRICS.index(self.metric), self.normalize,
            np.ascontiguousarray(pts), *ins, dist, color, position, w_out, radius)
        return {"DISTANCE": dist, "COLOR": color, "POSITION": position, "W": w_out,
                "RADIUS": radius}[self.output]


class Wave:
    """Wave Texture node (Cycles svm_node_tex_wave; kernel in engine/procedural.py).

    vector     coordinates node (N,3) (the add-on passes Generated when unlinked)
    inputs     dict of socket values or nodes: Scale, Distortion, Detail, Detail Scale,
               Detail Roughness, Phase Offset
    kind       BANDS or RINGS; direction: X, Y, Z, DIAGONAL (bands) or X, Y, Z, SPHERICAL
               (rings); profile SIN, SAW or TRI; output FAC (N,) or COLOR (N,3) grey."""

    SOCKETS = ("Scale", "Distortion", "Detail", "Detail Scale", "Detail Roughness",
               "Phase Offset")
    DEFAULTS = {"Scale": 5.0, "Distortion": 0.0, "Detail": 2.0, "Detail Scale": 1.0,
                "Detail Roughness": 0.5, "Phase Offset": 0.0}

    def __init__(self, vector, inputs=None, kind="BANDS", direction="X", profile="SIN",
                 output="FAC"):
        from . import procedural
        if kind not in procedural.WAVE_TYPES:
            raise ValueError(f"Wave Texture type {kind!r}: expected one of "
                             f"{procedural.WAVE_TYPES}")
        dirs = (procedural.WAVE_BANDS_DIRECTIONS if kind == "BANDS"
                else procedural.WAVE_RINGS_DIRECTIONS)
        if direction not in dirs:
            raise ValueError(f"Wave Texture {kind.lower()} direction {direction!r}: "
                             f"expected one of {dirs}")
        if profile not in procedural.WAVE_PROFILES:
            raise ValueError(f"Wave Texture profile {profile!r}: expected one of "
                             f"{procedural.WAVE_PROFILES}")
        self.vector, self.kind, self.direction, self.profile = vector, kind, direction, profile
        self._codes = (procedural.WAVE_TYPES.index(kind), dirs.index(direction),
                       procedural.WAVE_PROFILES.index(profile))
        self.inputs = {**self.DEFAULTS, **(inputs or {})}
        self.output = output

    def evaluate(self, geo, prim, u, v):
        from . import procedural
        pts = np.ascontiguousarray(_eval(self.vector, geo, prim, u, v, 3))
        ins = [np.ascontiguousarray(_eval(self.inputs[k], geo, prim, u, v, 1))
               for k in self.SOCKETS]
        fac = np.empty(len(prim))
        procedural.wave_texture(*self._codes, pts, *ins, fac)
        return np.repeat(fac[:, None], 3, axis=1) if self.output == "COLOR" else fac


class WhiteNoise:
    """White Noise Texture node (Cycles svm_node_tex_white_noise; kernel in
    engine/procedural.py): dims 1-4, vector (N,3) coordinates node, w the W socket;
    output VALUE (N,) or COLOR (N,3)."""

    def __init__(self, vector, w=0.0, dims=3, output="VALUE"):
        if dims not in (1, 2, 3, 4):
            raise ValueError(f"White Noise dimensions {dims!r}: expected 1, 2, 3 or 4")
        self.vector, self.w, self.dims, self.output = vector, w, int(dims), output

    def evaluate(self, geo, prim, u, v):
        from . import procedural
        pts = np.ascontiguousarray(_eval(self.vector, geo, prim, u, v, 3))
        w = np.ascontiguousarray(_eval(self.w, geo, prim, u, v, 1))
        val, col = np.empty(len(pts)), np.empty((len(pts), 3))
        procedural.white_noise_texture(self.dims, pts, w, val, col)
        return col if self.output == "COLOR" else val


def brick_noise(n):
    """Cycles' brick_noise (kernel/svm/brick.h): fast integer noise of uint32 n (N,) ->
    (N,) in [0, 1), wrapping uint32 arithmetic as in C."""
    n = np.asarray(n).astype(np.uint32)
    with np.errstate(over="ignore"):
        n = (n + np.uint32(1013)) & np.uint32(0x7FFFFFFF)
        n = (n >> np.uint32(13)) ^ n
        nn = (n * (n * n * np.uint32(60493) + np.uint32(19990303)) + np.uint32(1376312589)) \
            & np.uint32(0x7FFFFFFF)
    # (float)nn rounds to float32 in Cycles
    return 0.5 * (nn.astype(np.float32).astype(np.float64) / 1073741824.0)


def svm_brick(p, mortar_size, mortar_smooth, bias, brick_width, row_height, offset_amount,
              offset_frequency, squash_amount, squash_frequency):
    """Cycles' svm_brick (kernel/svm/brick.h) per point: p (N,3) scaled coordinates, the
    other inputs (N,) or scalars (frequencies ints). Returns (tint (N,), mortar (N,)):
    the brick's random tint (brick_noise of its row and column, plus bias, clamped) and
    the mortar factor (1 within mortar_size of a brick's edge, smoothed by
    mortar_smooth with the clamped smoothstep)."""
    x0, y0 = p[:, 0], p[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        rownum = np.floor(y0 / row_height)
        width = np.broadcast_to(np.asarray(brick_width, np.float64), x0.shape).copy()
        offset = np.zeros_like(x0)
        if offset_frequency and squash_frequency:
            # (C's int % only matters for being 0, which Python's agrees on)
            width = np.where(np.fmod(rownum, squash_frequency) != 0, width,
                             width * squash_amount)
            offset = np.where(np.fmod(rownum, offset_frequency) != 0, 0.0,
                              width * offset_amount)
        bricknum = np.floor((x0 + offset) / width)
        x = (x0 + offset) - width * bricknum
        y = y0 - row_height * rownum
    rn = np.nan_to_num(rownum).astype(np.int64)
    bn = np.nan_to_num(bricknum).astype(np.int64)
    h = ((rn << 16) + (bn & 0xFFFF)) & 0xFFFFFFFF
    tint = np.clip(brick_noise(h) + bias, 0.0, 1.0)
    min_dist = np.minimum(np.minimum(x, y), np.minimum(width - x, row_height - y))
    with np.errstate(divide="ignore", invalid="ignore"):
        f = (1.0 - min_dist / mortar_size) / mortar_smooth
    smooth = np.where(f <= 0.0, 0.0, np.where(f >= 1.0, 1.0, (3.0 - 2.0 * f) * f * f))
    mortar = np.where(min_dist >= mortar_size, 0.0,
                      np.where(np.asarray(mortar_smooth) == 0.0, 1.0, smooth))
    return tint, mortar


class Brick:
    """Brick Texture node (Cycles svm_node_tex_brick, kernel/svm/brick.h).

    vector   coordinates node (N,3) (the add-on passes Generated when unlinked)
    inputs   dict of socket values or nodes: Color1, Color2, Mortar (colours), Scale,
             Mortar Size, Mortar Smooth, Bias, Brick Width, Row Height
    offset, offset_frequency, squash, squash_frequency: the node's properties
    output   COLOR (N,3): mix(Color1, Color2, tint) off the mortar, blended to Mortar by
             the mortar factor; FAC (N,): the mortar factor."""

    SOCKETS = ("Color1", "Color2", "Mortar", "Scale", "Mortar Size", "Mortar Smooth",
               "Bias", "Brick Width", "Row Height")
    DEFAULTS = {"Color1": (0.8, 0.8, 0.8), "Color2": (0.2, 0.2, 0.2),
                "Mortar": (0.0, 0.0, 0.0), "Scale": 5.0, "Mortar Size": 0.02,
                "Mortar Smooth": 0.1, "Bias": 0.0, "Brick Width": 0.5, "Row Height": 0.25}

    def __init__(self, vector, inputs=None, offset=0.5, offset_frequency=2, squash=1.0,
                 squash_frequency=2, output="COLOR"):
        if output not in ("COLOR", "FAC"):
            raise ValueError(f"Brick Texture output {output!r}: expected COLOR or FAC")
        self.vector, self.inputs = vector, {**self.DEFAULTS, **(inputs or {})}
        self.offset, self.offset_frequency = float(offset), int(offset_frequency)
        self.squash, self.squash_frequency = float(squash), int(squash_frequency)
        self.output = output

    def evaluate(self, geo, prim, u, v):
        ins = {k: _eval(self.inputs[k], geo, prim, u, v, 3 if k in ("Color1", "Color2",
                                                                      "Mortar") else 1)
               for k in self.SOCKETS}
        p = _eval(self.vector, geo, prim, u, v, 3) * ins["Scale"][:, None]
        tint, f = svm_brick(p, ins["Mortar Size"], ins["Mortar Smooth"], ins["Bias"],
                            ins["Brick Width"], ins["Row Height"], self.offset,
                            self.offset_frequency, self.squash, self.squash_frequency)
        if self.output == "FAC":
            return f
        c1 = np.where((f != 1.0)[:, None], (1.0 - tint)[:, None] * ins["Color1"]
                      + tint[:, None] * ins["Color2"], ins["Color1"])
        return c1 * (1.0 - f)[:, None] + ins["Mortar"] * f[:, None]


def svm_magic(p, scale, depth, distortion):
    """Cycles' svm_magic (kernel/svm/magic.h) per point: p (N,3), scale and distortion
    (N,), depth 0..10 (the node's turbulence depth). Returns (N,3) colours. The
    coordinates are reduced by fmod(p, 2 pi) before the scale, as Blender 5.0's Cycles
    does (a later Cycles reduces p scale instead: the pattern differs wherever a
    coordinate passes 2 pi unless 5 scale is an integer)."""
    two_pi = 2.0 * np.pi
    q = np.fmod(p, two_pi) * (5.0 * scale[:, None])
    px, py, pz = q[:, 0], q[:, 1], q[:, 2]
    x = np.sin(px + py + pz)
    y = np.cos(-px + py - pz)
    z = -np.cos(-px - py + pz)
    d = distortion
    if depth > 0:
        x, y, z = x * d, y * d, z * d
        y = -np.cos(x - y + z) * d
        steps = (("x", lambda x, y, z: np.cos(x - y - z)),
                 ("z", lambda x, y, z: np.sin(-x - y - z)),
                 ("x", lambda x, y, z: -np.cos(-x + y - z)),
                 ("y", lambda x, y, z: -np.sin(-x + y + z)),
                 ("y", lambda x, y, z: -np.cos(-x + y + z)),
                 ("x", lambda x, y, z: np.cos(x + y + z)),
                 ("z", lambda x, y, z: np.sin(x + y - z)),
                 ("x", lambda x, y, z: -np.cos(-x - y + z)),
                 ("y", lambda x, y, z: -np.sin(x - y + z)))
        for name, f in steps[:depth - 1]:
            val = f(x, y, z) * d
            if name == "x":
                x = val
            elif name == "y":
                y = val
            else:
                z = val
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(d != 0.0, 2.0 * d, 1.0)
        x, y, z = x / k, y / k, z / k
    return np.stack([0.5 - x, 0.5 - y, 0.5 - z], axis=1)


class Magic:
    """Magic Texture node (Cycles svm_node_tex_magic, kernel/svm/magic.h): vector (N,3)
    coordinates node, scale and distortion (socket values or nodes), depth 0..10;
    output COLOR (N,3) or FAC (N,), the colour's average."""

    def __init__(self, vector, scale=5.0, distortion=1.0, depth=2, output="COLOR"):
        if output not in ("COLOR", "FAC"):
            raise ValueError(f"Magic Texture output {output!r}: expected COLOR or FAC")
        self.vector, self.scale, self.distortion = vector, scale, distortion
        self.depth, self.output = min(max(int(depth), 0), 10), output

    def evaluate(self, geo, prim, u, v):
        c = svm_magic(_eval(self.vector, geo, prim, u, v, 3),
                      _eval(self.scale, geo, prim, u, v, 1), self.depth,
                      _eval(self.distortion, geo, prim, u, v, 1))
        return c.mean(axis=1) if self.output == "FAC" else c


class Gabor:
    """Gabor Texture node (Cycles svm_node_tex_gabor, kernel/svm/gabor.h; kernel in
    engine/procedural.py gabor_texture).

    vector   coordinates node (N,3) (the add-on passes Generated when unlinked)
    inputs   dict of socket values or nodes: Scale, Frequency, Anisotropy,
             Orientation 2D (radians), Orientation 3D (a vector, normalised)
    dims     2 or 3; output VALUE (phasor's sine / (6 sigma), to 0..1), PHASE (its
             angle, 0..1) or INTENSITY (its length / (6 sigma)), (N,)."""

    SOCKETS = ("Scale", "Frequency", "Anisotropy", "Orientation 2D", "Orientation 3D")
    DEFAULTS = {"Scale": 5.0, "Frequency": 2.0, "Anisotropy": 1.0,
                "Orientation 2D": np.pi / 4.0, "Orientation 3D": (2 ** 0.5, 2 ** 0.5, 0.0)}
    OUTPUTS = ("VALUE", "PHASE", "INTENSITY")

    def __init__(self, vector, inputs=None, dims=2, output="VALUE"):
        if dims not in (2, 3):
            raise ValueError(f"Gabor Texture type: expected 2 or 3 dimensions, got {dims!r}")
        if output not in self.OUTPUTS:
            raise ValueError(f"Gabor Texture output {output!r}: expected one of "
                             f"{self.OUTPUTS}")
        self.vector, self.inputs = vector, {**self.DEFAULTS, **(inputs or {})}
        self.dims, self.output = int(dims), output

    def evaluate(self, geo, prim, u, v):
        ins = {k: _eval(self.inputs[k], geo, prim, u, v, 3 if k == "Orientation 3D" else 1)
               for k in self.SOCKETS}
        from . import procedural
        pts = np.ascontiguousarray(_eval(self.vector, geo, prim, u, v, 3))
        # Visit the hits cell by cell: the kernel hashes a cell's neighbourhood once.
        cell = np.floor(pts * ins["Scale"][:, None])
        order = np.lexsort((cell[:, 2], cell[:, 1], cell[:, 0])).astype(np.int64)
        out = np.empty(len(prim))
        procedural.gabor_texture(self.dims, pts,
                                 *(np.ascontiguousarray(ins[k]) for k in self.SOCKETS),
                                 self.OUTPUTS.index(self.output), order, out)
        return out


class ShadingGeometry:
    """A Geometry seen from a batch of hits: every attribute of `geo`, plus what the
    view-dependent nodes (LayerWeight, Fresnel) read per hit, row for row with the
    batch's prim, u, v:
      n           (N,3) Cycles' sd->N: the smooth shading normal (before Normal Map /
                  Bump nodes) turned to the side the ray arrived from
      wi          (N,3) unit direction back along the arriving ray (Cycles' sd->wi): to
                  the camera on camera paths, to the light for photons
      backfacing  (N,) bool: the ray hit the back of the triangle (Cycles' SD_BACKFACING)
    rows(sel) gives the same for a subset of the hits."""

    def __init__(self, geo, n, wi, backfacing):
        self._geo = geo
        self.n = n
        self.wi = wi
        self.backfacing = backfacing

    def __getattr__(self, name):
        return getattr(self._geo, name)

    def rows(self, sel) -> "ShadingGeometry":
        return ShadingGeometry(self._geo, self.n[sel], self.wi[sel], self.backfacing[sel])


def _view(geo, prim):
    """(n, wi, backfacing) of a batch: the ShadingGeometry's, else (no view known: shadow
    rays, the effect analysis) the triangles' geometric normal seen head-on from its
    front."""
    if isinstance(geo, ShadingGeometry):
        return geo.n, geo.wi, geo.backfacing
    ng = np.asarray(geo.ng[np.asarray(prim, np.int64)], np.float64).reshape(-1, 3)
    return ng, ng, np.zeros(len(ng), bool)


class GeometryInfo:
    """Geometry node (svm_node_geometry) per hit: POSITION (world space, m), NORMAL
    (sd->N: the smooth shading normal turned to the arriving ray's side), TRUE_NORMAL
    (sd->Ng, turned alike), INCOMING (sd->wi, back along the arriving ray) or BACKFACING
    (1 on a triangle's back). Normal and Incoming read the ShadingGeometry's view (without
    one: the geometric normal head-on, _view)."""

    OUTPUTS = ("POSITION", "NORMAL", "TRUE_NORMAL", "INCOMING", "BACKFACING")

    def __init__(self, output):
        if output not in self.OUTPUTS:
            raise ValueError(f"Geometry output {output!r}: expected one of {self.OUTPUTS}")
        self.output = output

    def evaluate(self, geo, prim, u, v):
        prim = np.asarray(prim, np.int64)
        if geo is None:
            return np.zeros(len(prim)) if self.output == "BACKFACING" else np.zeros(
                (len(prim), 3))
        if self.output == "POSITION":
            return geo.hit_points(prim, np.asarray(u, np.float64),
                                  np.asarray(v, np.float64)) + np.asarray(geo.offset)
        n, wi, back = _view(geo, prim)
        if self.output == "NORMAL":
            return np.asarray(n, np.float64)
        if self.output == "INCOMING":
            return np.asarray(wi, np.float64)
        if self.output == "BACKFACING":
            return np.asarray(back, np.float64)
        ng = np.asarray(geo.ng[prim], np.float64).reshape(-1, 3)
        return np.where(np.asarray(back)[:, None], -ng, ng)


class CameraView:
    """What the Texture Coordinate node's Camera and Window outputs need of the camera
    (Cycles' kernel_data.cam.worldtocamera and worldtondc, scene/camera.cpp), from an
    engine Camera (scene.Camera: world-space position, rotation columns right, up, back)
    and the full frame's width and height in pixels."""

    def __init__(self, camera, width: int, height: int):
        self.position = np.asarray(camera.position, np.float64)
        self.rotation = np.asarray(camera.rotation, np.float64)
        self.ortho = camera.kind == "ORTHO"
        # A panorama: its frame in the camera axes and its packed projection
        # (engine/panorama.py): Cycles' camera space and ndc are the panorama's.
        pano = getattr(camera, "panorama", None)
        self.pano = None if pano is None else pano.pack(int(width), int(height),
                                                        camera.sensor_fit)
        self.frame = None if pano is None else pano.frame
        self.hw, self.hh = camera.half_extents(int(width), int(height))
        big = 2.0 * max(self.hw, self.hh)  # shift is in units of the larger dimension
        self.shift = np.array([camera.shift_x * big, camera.shift_y * big])

    def to_camera(self, p):
        """(N,3) world points (m) in Cycles' camera space: x right, y up, z along the view
        (Blender's camera matrix with z negated, blender/camera.cpp), m; a panorama's:
        its frame's axes (x along the view, z up)."""
        c = (np.asarray(p, np.float64) - self.position) @ self.rotation
        if self.frame is not None:
            return c @ self.frame
        c[:, 2] = -c[:, 2]
        return c

    def to_ndc(self, p):
        """(N,3) world points in normalised device coordinates (Cycles' camera_world_to_ndc
        for a perspective or orthographic camera): x, y 0..1 across the full frame from its
        lower left corner, shift included; z 0 (the Window output sets it so). A
        panorama: its image coordinates of the direction (direction_to_panorama, no
        shift, as Cycles; 0 where none maps there)."""
        c = self.to_camera(p)
        if self.pano is not None:
            from .panorama import directions_to_uv
            ndc = np.zeros_like(c)
            ndc[:, :2] = np.nan_to_num(directions_to_uv(self.pano, c), nan=0.0)
            return ndc
        xy = c[:, :2]
        if not self.ortho:
            with np.errstate(divide="ignore", invalid="ignore"):
                xy = xy / c[:, 2:3]
        ndc = np.zeros_like(c)
        ndc[:, 0] = 0.5 * ((xy[:, 0] - self.shift[0]) / self.hw + 1.0)
        ndc[:, 1] = 0.5 * ((xy[:, 1] - self.shift[1]) / self.hh + 1.0)
        return ndc


class ViewCoordinates:
    """Texture Coordinate node, output CAMERA (the hit in Cycles' camera space, m),
    WINDOW (its normalised device coordinates, 0..1 across the frame, z 0) or REFLECTION
    (the direction back along the ray mirrored about sd->N, world space: 2 (N . wi) N -
    wi), as Cycles' svm_node_tex_coord (kernel/svm/tex_coord.h). Camera and Window read
    the Geometry's camera_view (a CameraView; without one: zeros); Reflection reads the
    hits' view (_view: without one, the geometric normal head-on gives N)."""

    OUTPUTS = ("CAMERA", "WINDOW", "REFLECTION")

    def __init__(self, output):
        if output not in self.OUTPUTS:
            raise ValueError(f"Texture Coordinate output {output!r}: expected one of "
                             f"{self.OUTPUTS}")
        self.output = output

    def evaluate(self, geo, prim, u, v):
        prim = np.asarray(prim, np.int64)
        if geo is None:
            return np.zeros((len(prim), 3))
        if self.output == "REFLECTION":
            n, wi, _ = _view(geo, prim)
            n, wi = np.asarray(n, np.float64), np.asarray(wi, np.float64)
            return 2.0 * np.einsum("ij,ij->i", n, wi)[:, None] * n - wi
        view = getattr(geo, "camera_view", None)
        if view is None:
            return np.zeros((len(prim), 3))
        if hasattr(geo, "view_points"):  # a world's directions (engine/worldgraph.py)
            p = geo.view_points(prim, u, v)
        else:
            p = geo.hit_points(prim, np.asarray(u, np.float64),
                               np.asarray(v, np.float64)) + np.asarray(geo.offset)
        return view.to_camera(p) if self.output == "CAMERA" else view.to_ndc(p)


def fresnel_dielectric_cos(cosi, eta):
    """Cycles' fresnel_dielectric_cos (kernel/closure/bsdf_util.h): unpolarised dielectric
    reflectance for |cosi| and relative IOR eta; 1 under total internal reflection."""
    c = np.abs(cosi)
    g = eta * eta - 1.0 + c * c
    ok = g > 0
    g = np.sqrt(np.where(ok, g, 1.0))
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return np.where(ok, 0.5 * a * a * (1.0 + b * b), 1.0)


class LayerWeight:
    """Layer Weight node (Cycles' svm_node_layer_weight), output FRESNEL or FACING, with
    the Normal input unlinked (sd->N):
      Fresnel  fresnel_dielectric_cos(wi . N, eta), eta = max(1 - blend, 1e-5), inverted
               on the front (1 / eta), as is on a back face
      Facing   1 - |wi . N|^b with b = 2 blend below 0.5 and 0.5 / (1 - blend) above
               (blend clamped to [0, 1 - 1e-5]; b = 1 at 0.5)."""

    def __init__(self, blend=0.5, output="FRESNEL"):
        if output not in ("FRESNEL", "FACING"):
            raise ValueError(f"Layer Weight output: expected FRESNEL or FACING, got {output!r}")
        self.blend = blend
        self.output = output

    def evaluate(self, geo, prim, u, v):
        blend = _eval(self.blend, geo, prim, u, v, 1)
        n, wi, back = _view(geo, prim)
        cos = np.einsum("ij,ij->i", wi, n)
        if self.output == "FRESNEL":
            eta = np.maximum(1.0 - blend, 1e-5)
            eta = np.where(back, eta, 1.0 / eta)
            return fresnel_dielectric_cos(cos, eta)
        b = np.clip(blend, 0.0, 1.0 - 1e-5)
        b = np.where(b < 0.5, 2.0 * b, 0.5 / (1.0 - b))
        f = np.abs(cos)
        f = np.where(blend == 0.5, f, f ** b)
        return 1.0 - f


class Fresnel:
    """Fresnel node (Cycles' svm_node_fresnel), Normal input unlinked: dielectric
    reflectance fresnel_dielectric_cos(wi . N, eta), eta = max(IOR, 1e-5), inverted on a
    back face (the ray leaves the medium)."""

    def __init__(self, ior=1.5):
        self.ior = ior

    def evaluate(self, geo, prim, u, v):
        eta = np.maximum(_eval(self.ior, geo, prim, u, v, 1), 1e-5)
        n, wi, back = _view(geo, prim)
        eta = np.where(back, 1.0 / eta, eta)
        return fresnel_dielectric_cos(np.einsum("ij,ij->i", wi, n), eta)


def hit_random(prim, u, v, salt: int = 0) -> np.ndarray:
    """(N,) float64 in [0, 1): a hash of the hit (triangle prim, barycentrics u, v as their
    float64 bits; splitmix64's finaliser, as integrator._mix64), uniform and independent of
    the sampler's dimensions. A function of the hit point alone, so every evaluation at one
    hit (its closure, its colour, its light sample and its bounce) agrees, and a render is
    reproducible without a seed: the camera's jitter and the photons' random streams (both
    seeded) decide where the hits fall. salt (a 64-bit integer, 0: none) gives another
    independent number at the same hit (a Mix Shader's pick inside another's)."""
    from .integrator import _mix64 as mix  # splitmix64's finaliser (integrator imports us)
    p = np.asarray(prim).astype(np.uint64)
    bu = np.ascontiguousarray(u, np.float64).view(np.uint64)
    bv = np.ascontiguousarray(v, np.float64).view(np.uint64)
    with np.errstate(over="ignore"):
        h = mix(p * np.uint64(0x9E3779B97F4A7C15) + np.uint64(0x632BE59BD9B4E019))
        h = mix(h ^ bu)
        h = mix(h ^ bv)
        if salt:
            h = mix(h ^ np.uint64(salt & 0xFFFFFFFFFFFFFFFF))
    return (h >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


class ClosurePick:
    """Cycles' closure sampling for a Mix Shader (kernel/closure/alloc.h, the path picks
    one closure by its weight, svm_node_mix_closure weights them (1 - f) and f): 1 where a
    hit takes the second closure, with probability the factor (clamped to 0..1), 0 where it
    takes the first. A Mix Shader of two surfaces whose parameters do not blend linearly
    (a blue dielectric and a gold metal: their parameter blend is a teal half-metal)
    selects every lobe parameter and colour by this value, so each hit is one of the two
    BSDFs and their mean over hits is (1 - f) f_a + f f_b, camera and photon pass alike
    (the one-sample estimate of the weighted sum; addon/materials.py _mix_per_hit)."""

    def __init__(self, factor, salt: int = 0):
        self.factor = factor
        # Each pick's own random number at a hit (hit_random's salt): a pick nested in
        # another (Mix inside a Mix or an Add) read the outer's number, so its choice
        # followed the outer one (Mix 0.5 of Mix 0.5 of blue and gold, and green: 50 / 0 /
        # 50 % for 25 / 25 / 50 %: found by review42).
        self.salt = int(salt)
        # The last batch and its pick (_PickBatch): every parameter of a picked mix is a
        # Math tree reading this node (about 20 reads a hit set), and the factor (a Noise
        # Texture) and the hash cost more than all of them. Not pickled.
        self._last = None

    def __getstate__(self):
        return {"factor": self.factor, "salt": getattr(self, "salt", 0), "_last": None}

    def evaluate(self, geo, prim, u, v):
        """(N,) float64, read-only: 1 where the hit takes the second closure, else 0. The
        same batch again (the same hits seen the same way: equal triangles, barycentrics
        and, on a ShadingGeometry, view) returns the last value without evaluating
        anything: the pick is a function of exactly those."""
        last = self._last
        if last is not None and last.matches(geo, prim, u, v):
            return last.pick
        f = np.clip(_eval(self.factor, geo, prim, u, v, 1), 0.0, 1.0)
        pick = (hit_random(prim, u, v, getattr(self, "salt", 0)) < f).astype(np.float64)
        pick.flags.writeable = False  # shared by every reader of the batch
        if geo is not None:
            self._last = _PickBatch(geo, prim, u, v, pick)
        return pick


def _same_array(a, b) -> bool:
    """a and b hold equal values of one dtype and shape (no NaN). Compared even when a is
    b: a caller may refill one buffer between two batches."""
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and bool(np.array_equal(a, b))


class _PickBatch:
    """A ClosurePick's last batch: its Geometry (weakly: a cached pick must not keep a
    scene alive), the hits' prim, u, v and their view (ShadingGeometry's n, wi,
    backfacing; None without one), and the pick."""

    __slots__ = ("geo", "prim", "u", "v", "view", "pick")

    def __init__(self, geo, prim, u, v, pick):
        import weakref
        base = geo._geo if isinstance(geo, ShadingGeometry) else geo
        try:
            self.geo = weakref.ref(base)
        except TypeError:  # an object without weak references: held while cached
            self.geo = (lambda obj: (lambda: obj))(base)
        self.prim, self.u, self.v = prim, u, v
        self.view = ((geo.n, geo.wi, geo.backfacing) if isinstance(geo, ShadingGeometry)
                     else None)
        self.pick = pick

    def matches(self, geo, prim, u, v) -> bool:
        if geo is None:
            return False
        shading = isinstance(geo, ShadingGeometry)
        base = geo._geo if shading else geo
        if self.geo() is not base or shading != (self.view is not None):
            return False
        if not (_same_array(prim, self.prim) and _same_array(u, self.u)
                and _same_array(v, self.v)):
            return False
        return not shading or all(_same_array(x, y) for x, y in
                                  zip((geo.n, geo.wi, geo.backfacing), self.view))
