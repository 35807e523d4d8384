"""Per-hit evaluation of the colour nodes real node trees put between a texture and a BSDF.

Each node is a small object with evaluate(geo, prim, u, v) over a batch of hits
(triangle prim, barycentrics u, v of an engine.geometry.Geometry), vectorised in numpy:
colours and vectors come back as (N,3), factors and values as (N,). A node tree is a
tree of these objects (inputs are nodes or constants); its root is what a Material's
`texture` holds. Formulas follow Cycles' SVM nodes (intern/cycles/kernel/svm/: mix.h,
color_util.h, ramp.h, math_util.h, mapping_util.h, checker.h); each class names its node.
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


class ImageLookup:
    """Image Texture node with its Vector input: output COLOR (N,3) or ALPHA (N,)."""

    def __init__(self, texture: ImageTexture, vector=None, output="COLOR"):
        self.texture = texture
        self.vector = vector if vector is not None else UVCoord()
        self.output = output

    def evaluate(self, geo, prim, u, v):
        uvw = _eval(self.vector, geo, prim, u, v, 3)
        rgba = self.texture.sample_rgba(uvw[:, :2])
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
}


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


class Invert:
    """Invert Color node: mix(c, 1 - c, factor)."""

    def __init__(self, factor, color):
        self.factor, self.color = factor, color

    def evaluate(self, geo, prim, u, v):
        t = _eval(self.factor, geo, prim, u, v, 1)[:, None]
        c = _eval(self.color, geo, prim, u, v, 3)
        return c + t * ((1.0 - c) - c)


class ColorRamp:
    """Color Ramp node on a factor: positions (K,) ascending, colors (K,3); interpolation
    LINEAR or CONSTANT (a stop's colour up to the next stop); output COLOR or ALPHA
    (alphas (K,))."""

    def __init__(self, factor, positions, colors, alphas=None, interpolation="LINEAR",
                 output="COLOR"):
        if interpolation not in ("LINEAR", "CONSTANT"):
            raise ValueError(f"Color Ramp interpolation {interpolation!r} is not supported "
                             "(LINEAR, CONSTANT)")
        order = np.argsort(np.asarray(positions, np.float64), kind="stable")
        self.factor = factor
        self.positions = np.asarray(positions, np.float64)[order]
        self.colors = np.asarray(colors, np.float64).reshape(-1, 3)[order]
        a = np.ones(len(order)) if alphas is None else np.asarray(alphas, np.float64)
        self.alphas = a[order]
        self.interpolation, self.output = interpolation, output

    def evaluate(self, geo, prim, u, v):
        t = np.clip(_eval(self.factor, geo, prim, u, v, 1), 0.0, 1.0)
        table = np.concatenate([self.colors, self.alphas[:, None]], axis=1)
        if self.interpolation == "CONSTANT":
            i = np.clip(np.searchsorted(self.positions, t, side="right") - 1, 0,
                        len(self.positions) - 1)
            out = table[i]
        else:
            out = np.stack([np.interp(t, self.positions, table[:, k]) for k in range(4)],
                           axis=1)
        return out[:, 3] if self.output == "ALPHA" else out[:, :3]


MATH_OPS = {
    "ADD": lambda a, b: a + b, "SUBTRACT": lambda a, b: a - b,
    "MULTIPLY": lambda a, b: a * b,
    "DIVIDE": lambda a, b: np.where(b != 0, a / np.where(b != 0, b, 1), 0.0),
    "POWER": lambda a, b: np.where(a >= 0, np.power(np.abs(a), b), 0.0),
    "MINIMUM": np.minimum, "MAXIMUM": np.maximum,
    "LESS_THAN": lambda a, b: (a < b).astype(np.float64),
    "GREATER_THAN": lambda a, b: (a > b).astype(np.float64),
    "ABSOLUTE": lambda a, b: np.abs(a),
    "FLOOR": lambda a, b: np.floor(a),
    "FRACT": lambda a, b: a - np.floor(a),
    "MODULO": lambda a, b: np.where(b != 0, np.fmod(a, np.where(b != 0, b, 1)), 0.0),
    "SINE": lambda a, b: np.sin(a), "COSINE": lambda a, b: np.cos(a),
}


class Math:
    """Math node (value): a <operation> b, optionally clamped to 0..1."""

    def __init__(self, operation, a, b=0.0, clamp=False):
        if operation not in MATH_OPS:
            raise ValueError(f"Math operation {operation!r} is not supported "
                             f"(supported: {', '.join(MATH_OPS)})")
        self.operation, self.a, self.b, self.clamp = operation, a, b, clamp

    def evaluate(self, geo, prim, u, v):
        r = MATH_OPS[self.operation](_eval(self.a, geo, prim, u, v, 1),
                                     _eval(self.b, geo, prim, u, v, 1))
        return np.clip(r, 0.0, 1.0) if self.clamp else r


class SeparateChannel:
    """Separate Color (RGB) / Separate XYZ: one channel (0, 1, 2) of a colour or vector."""

    def __init__(self, source, channel):
        self.source, self.channel = source, int(channel)

    def evaluate(self, geo, prim, u, v):
        return _eval(self.source, geo, prim, u, v, 3)[:, self.channel]


class Combine:
    """Combine Color (RGB) / Combine XYZ: three factors into a colour or vector."""

    def __init__(self, x, y, z):
        self.parts = (x, y, z)

    def evaluate(self, geo, prim, u, v):
        return np.stack([_eval(p, geo, prim, u, v, 1) for p in self.parts], axis=1)


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
