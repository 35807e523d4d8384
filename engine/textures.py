"""Colour sources multiplied onto a material's base colour per hit: image textures looked
up as Cycles' Image Texture node does, and the Color Attribute node (ColorAttribute).

An `ImageTexture` holds an image's stored pixel values (one image, or one per UDIM tile)
with the node's settings, and turns UV coordinates into linear RGBA:

  extension      REPEAT | EXTEND | CLIP | MIRROR: which texel a coordinate outside the
                 image reads (CLIP: transparent black), applied per texel, so a Linear
                 lookup fades to black over the border's half texel as in Cycles.
  interpolation  Linear (bilinear), Closest (nearest texel), Cubic (uniform cubic
                 B-spline, Cycles' `cubic_weights`), Smart (Cubic, as Cycles renders it
                 without mip-maps).
  srgb           the pixels are the sRGB-encoded values of an image Cycles keeps stored
                 as sRGB (8-bit sRGB, or a float file tagged sRGB: addon/materials.py
                 cycles_stores_srgb): Cycles interpolates the encoded values and converts
                 to linear after (color_srgb_to_linear: 0 below 0, not clipped above 1,
                 so a float image's encoded 5.75 is 60), so a filtered edge between dark
                 and bright texels is darker than converting first (a checker at texel
                 scale: 1.68x too bright the other way round).
  associate      the given pixels' alpha is straight (an 8-bit image in Blender): store
                 RGB premultiplied by alpha, as Cycles' loader does for an image whose
                 alpha it associates (blender/image.cpp load_byte_pixels: not a Non-Color
                 image, alpha mode not Channel Packed or None), so the Color output of a
                 lookup is premultiplied: where alpha is 0 it is black, whatever RGB the
                 image stores there.
  premultiplied  the given pixels' alpha is associated already (a float image as Cycles
                 holds it: Blender's float buffer, or a float file's texels as Cycles
                 reads them, addon/materials.py _float_texels): stored as given, and
                 marked associated, so a lookup with the node's Alpha output linked
                 divides by alpha (unassociated()) as for an associated 8-bit image.
  unassociate    divide a lookup's interpolated RGB by its interpolated alpha (neither 0
                 nor 1) before the sRGB conversion: Cycles' NODE_IMAGE_ALPHA_UNASSOCIATE,
                 set where the node's Alpha output is linked (svm/image.h
                 svm_image_texture), so a cut-out's edge keeps its colour (alpha-weighted
                 by the filter) rather than fading to the RGB beyond the outline.
  tiles          UDIM: {1001: pixels, 1002: ...}; a coordinate reads tile
                 1001 + floor(u) + 10 floor(v) at its fractional part; a coordinate with
                 no tile (u < 0, v < 0, u >= 10 or a tile not in the set) reads Cycles'
                 missing-image colour (magenta).

Texel centres sit at (i + 0.5) / width as in Cycles; UV (0, 0) is the image's bottom-left
corner (Blender), the arrays here are stored top row first.
Sources: Cycles kernel/image.h (interpolation, wrap modes, UDIM map) and
svm/image.h (sRGB conversion after the lookup, alpha unassociated before it).
"""
from __future__ import annotations

import numpy as np

from .imageio import srgb_decode

EXTENSIONS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")
INTERPOLATIONS = ("Linear", "Closest", "Cubic", "Smart")
MISSING_RGBA = np.array([1.0, 0.0, 1.0, 1.0])  # Cycles' colour for a missing image / tile


class TextureError(ValueError):
    """Bad texture input (names the texture and the argument)."""


def _as_rgba(pixels, who: str) -> np.ndarray:
    a = np.asarray(pixels, dtype=np.float32)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 1 or a.shape[2] not in (1, 3, 4):
        raise TextureError(f"{who}: expected an HxW, HxWx3 or HxWx4 image, got {a.shape}")
    a = np.nan_to_num(a, nan=0.0, posinf=1.0, neginf=0.0)
    if a.shape[2] == 1:
        a = np.concatenate([np.repeat(a, 3, axis=2), np.ones_like(a)], axis=2)
    elif a.shape[2] == 3:
        a = np.concatenate([a, np.ones_like(a[:, :, :1])], axis=2)
    return np.ascontiguousarray(a)


def _wrap(i: np.ndarray, n: int, extension: str):
    """(index into 0..n-1, valid) for integer texel indices i under an extension mode."""
    if extension == "REPEAT":
        return np.mod(i, n), None
    if extension == "EXTEND":
        return np.clip(i, 0, n - 1), None
    if extension == "MIRROR":
        # Reflect at the image borders, each border texel repeated once (..., 1, 0, 0, 1, ...).
        m = np.mod(i, 2 * n)
        return np.where(m >= n, 2 * n - 1 - m, m), None
    valid = (i >= 0) & (i < n)
    return np.clip(i, 0, n - 1), valid


def _cubic_weights(t: np.ndarray) -> list[np.ndarray]:
    """Uniform cubic B-spline weights of texels -1, 0, +1, +2 for fraction t (Cycles)."""
    t2 = t * t
    t3 = t2 * t
    return [(-t3 + 3 * t2 - 3 * t + 1) / 6.0, (3 * t3 - 6 * t2 + 4) / 6.0,
            (-3 * t3 + 3 * t2 + 3 * t + 1) / 6.0, t3 / 6.0]


class ImageTexture:
    """One Image Texture node's image and settings; see the module docstring.

    pixels         HxW, HxWx3 or HxWx4 stored values, top row first (float; sRGB-encoded
                   when srgb=True, possibly above 1, else linear or non-colour data).
    tiles          optional {udim number (>= 1001): pixels} for a UDIM image; pixels is
                   then ignored (pass None).
    Raises TextureError (naming `name`) on a bad shape, mode or tile number.
    """

    def __init__(self, pixels=None, *, extension: str = "REPEAT",
                 interpolation: str = "Linear", srgb: bool = False, tiles: dict | None = None,
                 name: str = "image", associate: bool = False, unassociate: bool = False,
                 premultiplied: bool = False):
        self.name = name
        self.associated = bool(associate) or bool(premultiplied)
        self.unassociate = bool(unassociate)
        who = f"texture '{name}'"
        if associate and premultiplied:
            raise TextureError(f"{who}: associate (straight pixels) and premultiplied "
                               "(associated pixels) exclude each other")
        extension = str(extension).upper()
        if extension not in EXTENSIONS:
            raise TextureError(f"{who} extension: expected one of {EXTENSIONS}, got {extension!r}")
        interp = str(interpolation).capitalize()
        if interp not in INTERPOLATIONS:
            raise TextureError(f"{who} interpolation: expected one of {INTERPOLATIONS}, "
                               f"got {interpolation!r}")
        self.extension = extension
        self.interpolation = interp
        self.srgb = bool(srgb)
        if tiles:
            self.tiles = {}
            for k, px in tiles.items():
                k = int(k)
                if not 1001 <= k <= 1001 + 10 * 100 - 1:
                    raise TextureError(f"{who}: UDIM tile number {k} is outside 1001..")
                self.tiles[k] = _as_rgba(px, f"{who} tile {k}")
        else:
            if pixels is None:
                raise TextureError(f"{who}: no pixels and no UDIM tiles")
            self.tiles = None
            self.pixels = _as_rgba(pixels, who)
        if associate:
            for px in (self.tiles.values() if self.tiles else [self.pixels]):
                px[:, :, :3] *= px[:, :, 3:4]

    def unassociated(self) -> "ImageTexture":
        """This texture (its pixels shared, not copied) with unassociate set: the lookup of
        a node whose Alpha output is linked."""
        import copy
        out = copy.copy(self)
        out.unassociate = True
        return out

    @property
    def is_udim(self) -> bool:
        return self.tiles is not None

    @property
    def has_alpha(self) -> bool:
        imgs = self.tiles.values() if self.tiles else [self.pixels]
        return any(bool(np.any(a[:, :, 3] < 1.0)) for a in imgs)

    # --- lookups ------------------------------------------------------------------------
    def sample_rgba(self, uv: np.ndarray) -> np.ndarray:
        """(N,4) float64 linear RGB and alpha at uv (N,2)."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        uv = np.nan_to_num(uv, nan=0.0, posinf=0.0, neginf=0.0)
        if self.tiles is None:
            out = self._lookup(self.pixels, uv)
        else:
            out = np.empty((len(uv), 4))
            out[:] = MISSING_RGBA
            tx = np.floor(uv[:, 0]).astype(np.int64)
            ty = np.floor(uv[:, 1]).astype(np.int64)
            inside = (tx >= 0) & (ty >= 0) & (tx < 10)
            number = np.where(inside, 1001 + tx + 10 * ty, 0)
            for k, px in self.tiles.items():
                sel = np.nonzero(number == k)[0]
                if len(sel):
                    local = uv[sel] - np.stack([tx[sel], ty[sel]], axis=1)
                    out[sel] = self._lookup(px, local)
            if self.srgb:  # missing colour is linear already: undo the conversion below
                miss = ~np.isin(number, list(self.tiles))
                res = self._to_linear(out)
                res[miss] = MISSING_RGBA
                return res
        return self._to_linear(out)

    def sample(self, uv: np.ndarray) -> np.ndarray:
        """(N,3) float64 linear RGB at uv (N,2)."""
        return self.sample_rgba(uv)[:, :3]

    def evaluate(self, geo, prim, u, v) -> np.ndarray:
        """(N,3) linear RGB at hits (triangle prim, barycentrics u, v) of an
        engine.geometry.Geometry, through their interpolated UVs."""
        return self.sample(geo.uvs(prim, u, v))

    def _to_linear(self, rgba: np.ndarray) -> np.ndarray:
        if self.unassociate:  # Cycles: r /= alpha unless alpha is 0 or 1, then the sRGB
            a = rgba[:, 3]
            part = (a != 0.0) & (a != 1.0)
            rgba[part, :3] /= a[part, None]
        if self.srgb:
            rgba[:, :3] = srgb_decode(rgba[:, :3])
        return rgba

    def _lookup(self, px: np.ndarray, uv: np.ndarray) -> np.ndarray:
        h, w = px.shape[:2]
        x = uv[:, 0] * w
        # Rows are stored top first: v = 1 is row 0's top edge.
        y = (1.0 - uv[:, 1]) * h
        if self.interpolation == "Closest":
            return self._texels(px, np.floor(x).astype(np.int64),
                                np.floor(y).astype(np.int64))
        x -= 0.5
        y -= 0.5
        x0 = np.floor(x)
        y0 = np.floor(y)
        fx = x - x0
        fy = y - y0
        x0 = x0.astype(np.int64)
        y0 = y0.astype(np.int64)
        if self.interpolation == "Linear":
            wx = [1.0 - fx, fx]
            wy = [1.0 - fy, fy]
            offsets = (0, 1)
        else:  # Cubic, Smart
            wx = _cubic_weights(fx)
            wy = _cubic_weights(fy)
            offsets = (-1, 0, 1, 2)
        out = np.zeros((len(uv), 4))
        for j, oy in enumerate(offsets):
            row = np.zeros((len(uv), 4))
            for i, ox in enumerate(offsets):
                row += wx[i][:, None] * self._texels(px, x0 + ox, y0 + oy)
            out += wy[j][:, None] * row
        return out

    def _texels(self, px: np.ndarray, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        h, w = px.shape[:2]
        ix, vx = _wrap(ix, w, self.extension)
        iy, vy = _wrap(iy, h, self.extension)
        # One gather of rows of the flattened image (np.take: faster than 2-D indexing).
        t = np.take(px.reshape(-1, 4), iy * w + ix, axis=0).astype(np.float64)
        if vx is not None:
            t *= (vx & vy)[:, None]
        return t


class ColorAttribute:
    """Cycles' Color Attribute node: the mesh's colour attribute (vertex colours, linear,
    Mesh.colors) interpolated over the triangle; black on a mesh without one, as Cycles.
    `name` is the attribute the node asked for (informational: the exporter passes the
    mesh's render colour attribute)."""

    def __init__(self, name: str = ""):
        self.name = str(name)

    def evaluate(self, geo, prim, u, v) -> np.ndarray:
        """(N,3) linear RGB at hits (triangle prim, barycentrics u, v)."""
        return geo.colors(prim, u, v)


LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec.709: a colour into a value socket


def factor(node, geo, prim, u, v) -> np.ndarray:
    """(N,) a node's value at hits, as a factor in [0, 1]: a colour output is read as its
    luminance (Blender's colour-to-value socket conversion), NaN as 0."""
    val = np.asarray(node.evaluate(geo, prim, u, v), np.float64)
    if val.ndim == 2:
        val = val[:, :3] @ LUMINANCE
    return np.clip(np.nan_to_num(val, nan=0.0), 0.0, 1.0)


def _rows(geo, sel):
    """geo for the hits at rows sel of a batch (a shadernodes.ShadingGeometry carries
    per-hit view data)."""
    return geo.rows(sel) if hasattr(geo, "rows") else geo


def rows_by_material(nodes, mat):
    """(material index, node, rows) for every material whose entry in nodes (a per-material
    list, None = nothing to evaluate) is set and that has hits among mat (N,) int64:
    rows = the indices i with mat[i] == that material, increasing. How per-material
    nodes (textures, normal maps, scalar maps) are evaluated on a batch of hits."""
    for mi, node in enumerate(nodes or ()):
        if node is None:
            continue
        rows = np.nonzero(mat == mi)[0]
        if len(rows):
            yield mi, node, rows


def material_alpha(table, geo, mat, prim, u, v, constant: bool = True) -> np.ndarray:
    """(N,) alpha (opacity, Cycles' Principled Alpha) at hits of materials mat (N,) on
    triangles prim with barycentrics u, v: the material's constant alpha (table.alpha)
    times its alpha texture's factor (table.alpha_textures: a node per material or None,
    e.g. an Image Texture's Alpha output; engine/shadernodes.py). constant=False leaves
    out the constant (the texture factor alone, 1 where a material has none)."""
    mat = np.asarray(mat, np.int64)
    out = np.take(table.alpha, mat).astype(np.float64) if constant else np.ones(len(mat))
    for _, node, sel in rows_by_material(getattr(table, "alpha_textures", None), mat):
        out[sel] *= factor(node, _rows(geo, sel), prim[sel], u[sel], v[sel])
    return out


def scalar_values(node, geo, prim, u, v, lo, hi, colour: bool = False) -> np.ndarray:
    """(N,) a scalar input's value at hits: the node's value (a colour read as its
    luminance, Blender's colour-to-float conversion), clamped to [lo, hi] as Cycles clamps
    that input (svm/closure.h), NaN as lo. colour=True: (N,3) a colour input's RGB (a
    value read as grey), each channel clamped so."""
    val = np.asarray(node.evaluate(geo, prim, u, v), np.float64)
    if colour:
        val = np.repeat(val[:, None], 3, axis=1) if val.ndim == 1 else val[:, :3]
    elif val.ndim == 2:
        val = val[:, :3] @ LUMINANCE
    return np.clip(np.nan_to_num(val, nan=lo, posinf=hi, neginf=lo), lo, hi)


def scalar_params(table, geo, mat, prim, u, v):
    """(N, principled.N_MAT) closure parameter rows of hits of materials mat (N,): the
    material's row (table.closure_params) with its texture-driven scalar inputs
    (table.scalar_textures: Roughness, Metallic, ... maps) evaluated at the hits; None
    when no material has one. The closure set-up reads these rows instead of the
    material's (bsdf.closures, photons._trace_chunk)."""
    cols = getattr(table, "scalar_textures", None)
    if not cols or all(c is None for c in cols):
        return None
    mat = np.asarray(mat, np.int64)
    out = np.take(table.closure_params, mat, axis=0)
    for _, entries, sel in rows_by_material(cols, mat):
        # One set of row arrays for all the material's inputs: a node they share (a Mix
        # Shader's closure pick) recognises them and is evaluated once (ClosurePick).
        g, p, uu, vv = _rows(geo, sel), prim[sel], u[sel], v[sel]
        for col, node, lo, hi in entries:
            out[sel, col] = scalar_values(node, g, p, uu, vv, lo, hi,
                                          colour=isinstance(col, slice))
    return out


RANGE_SAMPLES = 4096  # points per material at which scalar_ranges evaluates its maps


def _lobe_columns():
    from .closures import principled as pr
    return frozenset((pr.M_ROUGH, pr.M_METALLIC, pr.M_SPEC, pr.M_TRANS, pr.M_LEVEL,
                      pr.M_COAT_W, pr.M_COAT_ROUGH, pr.M_SHEEN_W, pr.M_SHEEN_ROUGH,
                      pr.M_ANISO))


def scalar_ranges(table, geo, seed: int = 0):
    """Summarise each texture-driven scalar input over its material's surface for the
    effect analysis (engine/effects.py reads one value per material): the table's
    constant columns take the extreme that enables a lobe (metallic, transmission, coat
    and sheen weights at their largest, roughness and coat roughness at their smallest,
    the anisotropy at its largest magnitude; the other per-hit inputs, a Mix Shader pick's
    IOR, tints, distribution and rotation, keep the constant), and table.diffuse_share the
    largest (1 - metallic)(1 - transmission). Evaluated at
    RANGE_SAMPLES uniformly random points of the material's triangles (seeded): an
    estimate for deciding which effects to trace; the render itself evaluates every hit
    (scalar_params)."""
    cols = getattr(table, "scalar_textures", None)
    if not cols or all(c is None for c in cols) or geo.count == 0:
        return
    from .closures import principled as pr
    rng = np.random.default_rng(seed)
    share = (1 - table.metallic) * (1 - table.transmission)
    for mi, entries in enumerate(cols):
        if entries is None:
            continue
        tris = np.nonzero(np.asarray(geo.material) == mi)[0]
        if not len(tris):
            continue
        area = geo.area[tris]
        pick = rng.choice(len(tris), RANGE_SAMPLES, p=area / area.sum()) \
            if area.sum() > 0 else rng.integers(0, len(tris), RANGE_SAMPLES)
        prim = tris[pick]
        r1, r2 = rng.random(RANGE_SAMPLES), rng.random(RANGE_SAMPLES)
        s = np.sqrt(r1)
        u, v = s * (1.0 - r2), s * r2  # uniform barycentrics of corners 1 and 2
        # View-dependent nodes (Layer Weight, Fresnel) see uniformly random directions
        # over the front hemisphere of the geometric normal.
        from .shadernodes import ShadingGeometry
        ng = np.asarray(geo.ng[prim], np.float64)
        wi = rng.normal(size=(RANGE_SAMPLES, 3))
        wi /= np.maximum(np.linalg.norm(wi, axis=1, keepdims=True), 1e-300)
        wi *= np.where(np.einsum("ij,ij->i", wi, ng) < 0, -1.0, 1.0)[:, None]
        sg = ShadingGeometry(geo, ng, wi, np.zeros(RANGE_SAMPLES, bool))
        # The inputs that enable a lobe (the IOR, tints, distribution and rotation a Mix
        # Shader's pick sets per hit keep the material's blended constant).
        lobe = _lobe_columns()
        vals = {col: scalar_values(node, sg, prim, u, v, lo, hi)
                for col, node, lo, hi in entries
                if not isinstance(col, slice) and col in lobe}
        metal = vals.get(pr.M_METALLIC, np.full(RANGE_SAMPLES, table.metallic[mi]))
        trans = vals.get(pr.M_TRANS, np.full(RANGE_SAMPLES, table.transmission[mi]))
        share[mi] = float(np.max((1 - metal) * (1 - trans)))
        for col, v_ in vals.items():
            smallest = col in (pr.M_ROUGH, pr.M_COAT_ROUGH, pr.M_SHEEN_ROUGH)
            x = float(v_.min() if smallest else v_.max())
            if col == pr.M_ANISO:
                # Anisotropic somewhere (a Glossy BSDF's may be negative): the tangents
                # are set up for the material (anisotropy.anisotropic_materials).
                x = float(v_[np.argmax(np.abs(v_))])
            table.closure_params[mi, col] = x
            name = {pr.M_ROUGH: "roughness", pr.M_METALLIC: "metallic",
                    pr.M_TRANS: "transmission", pr.M_COAT_W: "coat_weight",
                    pr.M_SPEC: "specular",
                    pr.M_SHEEN_W: "sheen_weight"}.get(col)
            if name is not None:
                getattr(table, name)[mi] = x
    table.diffuse_share = share


def colour_values(node, geo, prim, u, v) -> np.ndarray:
    """(N,3) a colour node's value at hits, negative values and NaN as 0 (a value output
    read as grey)."""
    rgb = np.asarray(node.evaluate(geo, prim, u, v), np.float64)
    if rgb.ndim == 1:
        rgb = np.repeat(rgb[:, None], 3, axis=1)
    return np.maximum(np.nan_to_num(rgb[:, :3], nan=0.0, posinf=0.0), 0.0)


def hit_emission(table, geo, mat, prim, u, v) -> np.ndarray:
    """(N,3) emitted radiance at hits of materials mat (N,): the material's emission
    times its emission texture (table.emission_textures) where it has one."""
    mat = np.asarray(mat, np.int64)
    out = np.take(table.emission, mat, axis=0)
    for _, node, sel in rows_by_material(getattr(table, "emission_textures", None), mat):
        out[sel] *= colour_values(node, _rows(geo, sel), prim[sel], u[sel], v[sel])
    return out


EMISSION_SAMPLES = 1 << 18  # texture evaluations shared by a scene's textured emitters


def triangle_average_emission(table, geo, idx, L, seed: int = 0) -> np.ndarray:
    """(len(idx),3) radiance of emissive triangles idx for light sampling and photon
    emission: L (the material's emission) times the triangle's average emission texture,
    estimated from stratified points on the triangle (EMISSION_SAMPLES shared by the
    textured triangles: at least 16 a triangle, at most 1024; seeded). Within a triangle
    the light and its photons are uniform; the camera sees the texture per hit."""
    nodes = table.emission_textures
    mats = geo.material[idx]
    out = np.array(L, np.float64, copy=True)
    textured = np.nonzero(np.isin(mats, [i for i, t in enumerate(nodes) if t is not None]))[0]
    if not len(textured):
        return out
    k = int(np.clip(EMISSION_SAMPLES // len(textured), 16, 1024))
    side = int(np.ceil(np.sqrt(k)))
    rng = np.random.default_rng(seed)
    # Stratified points on the unit square (side x side cells), folded into the triangle.
    gx, gy = np.meshgrid(np.arange(side), np.arange(side))
    for mi, node in enumerate(nodes):
        if node is None:
            continue
        rows = textured[mats[textured] == mi]
        for a in range(0, len(rows), max(1, EMISSION_SAMPLES // (side * side))):
            part = rows[a:a + max(1, EMISSION_SAMPLES // (side * side))]
            n = len(part)
            r1 = (gx.ravel()[None, :] + rng.random((n, side * side))) / side
            r2 = (gy.ravel()[None, :] + rng.random((n, side * side))) / side
            fold = r1 + r2 > 1.0
            bu = np.where(fold, 1.0 - r1, r1).ravel()
            bv = np.where(fold, 1.0 - r2, r2).ravel()
            prim = np.repeat(idx[part], side * side)
            rgb = colour_values(node, geo, prim, bu, bv).reshape(n, side * side, 3)
            out[part] *= rgb.mean(axis=1)
    return out


def as_texture(tex, name: str = "image"):
    """A colour source (anything with evaluate(geo, prim, u, v): ImageTexture,
    ColorAttribute, engine.shadernodes nodes) as given, or an ImageTexture from a bare
    linear HxW(x3/4) array (Repeat, Linear: the engine's behaviour before textures had
    settings); None stays None."""
    if tex is None or hasattr(tex, "evaluate"):
        return tex
    # Negative texels clipped; values above 1 kept (HDR colours), as Cycles reads them.
    return ImageTexture(np.clip(np.nan_to_num(np.asarray(tex, np.float32), nan=0.0,
                                              posinf=1.0, neginf=0.0), 0.0, None), name=name)
