"""Blender materials (shader node trees) -> engine materials.

Supported: Principled BSDF (Cycles' v2 layers: sheen, coat, metallic with F82 tint,
transmission, specular IOR level and tint; subsurface as a diffuse base of Cycles'
random-walk albedo, warned), Diffuse, Glossy (GGX or Multiscatter GGX), Glass, Refraction
(refraction alone, no Fresnel, as Cycles), Translucent, Sheen (Microfiber), Emission,
Transparent, Principled Hair (approximated, warned: engine/hairbsdf.py), Mix Shader and Add
Shader of those (a Mix of two opaque surfaces whose parameters do not blend linearly, e.g.
a dielectric and a metal, takes one side per hit with the factor's probability, as Cycles'
closure sampling; Add sums the closures: their even mix at closure weight 2, exact for
Diffuse + Diffuse, Diffuse + Glossy and equal surfaces; the
transparent shares of an Add add up too, as Cycles sums them), an Image Texture (its Extension,
Interpolation, UDIM tiles), a Color Attribute or Attribute node (a mesh attribute by
name), an RGB / Value node, or a tree of the
colour nodes in engine/shadernodes.py (Mapping, Mix, Invert, Hue/Saturation, Color Ramp,
Math, Separate/Combine, Map Range (Float), Blackbody, Checker, Gradient, Noise, Voronoi,
Wave, Brick, Magic and Gabor textures, Layer Weight, Fresnel)
on colour inputs, on the scalar inputs Roughness, Metallic, Transmission Weight, Specular
IOR Level, Coat Weight / Roughness, Sheen Weight / Roughness (evaluated per hit), on
Emission Color and as a Mix Shader's factor (per hit for two opaque surfaces and for
cut-outs), and a Normal Map node (tangent or world space) fed by an image or any colour node tree, or a
Bump node on 'Normal' inputs (docs/textures.md). A Light Path node's outputs are constants
per ray class: a surface that reads them is converted once per class, one engine material
for each class that differs (addon/lightpath.py). Anything else falls back to its nearest
approximation (another shader with a Color input: a Diffuse BSDF of that colour; the
material's viewport colour when nothing else is known) and is reported once per material
and node in a warning that names both; an input whose feeding node is not supported
takes the socket's own value, and the warning says which value.
"""
from __future__ import annotations

import os
import traceback
import zlib

import bpy

import numpy as np

from . import lightpath, nodegroups
from .aovs import material_aovs

SUPPORTED_SHADERS = ("BSDF_PRINCIPLED", "BSDF_DIFFUSE", "BSDF_GLOSSY", "BSDF_ANISOTROPIC",
                     "BSDF_GLASS", "BSDF_REFRACTION", "EMISSION", "BSDF_TRANSPARENT",
                     "MIX_SHADER", "ADD_SHADER", "BSDF_TRANSLUCENT", "BSDF_SHEEN",
                     "BSDF_METALLIC", "SUBSURFACE_SCATTERING")
MAX_NODE_DEPTH = 32


def fresnel_conductor(cos_i, n, k):
    """Unpolarised Fresnel reflectance of a conductor of complex IOR n + ik (per channel)
    at incidence cosine cos_i: Cycles' fresnel_conductor (closure/bsdf_util.h)."""
    cos2 = cos_i * cos_i
    tmp_f = n * n + k * k
    tmp = tmp_f * cos2
    r_parl = (tmp - 2.0 * n * cos_i + 1.0) / (tmp + 2.0 * n * cos_i + 1.0)
    r_perp = (tmp_f - 2.0 * n * cos_i + cos2) / (tmp_f + 2.0 * n * cos_i + cos2)
    return 0.5 * (r_parl + r_perp)


def conductor_f82_tint(n, k):
    """(F0, F82 tint) (3,) each of the F82-tint Fresnel (Cycles'
    bsdf_microfacet_setup_fresnel_f82_tint) that equals a conductor's of complex IOR
    n + ik (Cycles' fresnel_conductor) at normal incidence and at cos = 1/7, where the
    tint model is anchored: the tint is F(1/7) over Schlick's F0 + (1 - F0) (6/7)^5 there.
    Between, within 0.024 of the conductor's curve for gold, 0.016 for the node's default
    (a tint matching the curve's cosine-weighted mean instead: 0.069 and 0.029, the same
    ball's brightness within 0.1 %)."""
    n = np.maximum(np.asarray(n, np.float64), 0.0)
    k = np.maximum(np.asarray(k, np.float64), 0.0)
    f0 = np.clip(fresnel_conductor(1.0, n, k), 0.0, 1.0)
    schlick = f0 + (1.0 - f0) * (6.0 / 7.0) ** 5
    tint = np.maximum(fresnel_conductor(1.0 / 7.0, n, k) / np.maximum(schlick, 1e-9), 0.0)
    return f0, tint


# Cycles' largest Henyey-Greenstein |g| (volume_henyey_greenstein_setup: 1 - 1e-3).
G_LIMIT = 0.999
# Tests set this: a node tree the converter cannot read raises instead of falling back to
# the viewport colour (so a converter bug fails the test that meets it, not only its image).
RAISE_UNREADABLE_TREES = False
# Cycles' standard attribute names (scene/attribute.cpp Attribute::standard_name): an
# Attribute node of one of these names reads Cycles' standard attribute, never a mesh
# attribute of that name (AttributeRequestSet::add_standard). On a mesh, those of
# volumes, hair, point clouds and motion blur are absent (0, alpha 1).
CYCLES_STANDARD_ATTRIBUTES = (
    "N", "Ng", "uv", "generated", "generated_transform", "tangent", "tangent_sign",
    "vertex_color", "undeformed", "undisplaced", "motion_P", "motion_N", "particle",
    "curve_intercept", "curve_length", "curve_random", "point_random", "ptex_face_id",
    "ptex_uv", "density", "color", "flame", "heat", "temperature", "velocity",
    "velocity_x", "velocity_y", "velocity_z", "pointiness", "random_per_island",
    "shadow_transparency")
_ABSENT_ON_MESHES = ("generated_transform", "motion_P", "motion_N", "particle",
                     "curve_intercept", "curve_length", "curve_random", "point_random",
                     "ptex_face_id", "ptex_uv", "density", "color", "flame", "heat",
                     "temperature", "velocity", "velocity_x", "velocity_y", "velocity_z",
                     "shadow_transparency")
# Cycles' RAMP_TABLE_SIZE (scene/shader_nodes.h): Color Ramps and curves are baked at
# this many + 1 steps.
RAMP_TABLE_SIZE = 256


def object_attribute_key(name: str, instancer: bool) -> str:
    """The engine's key (Mesh.object_attributes) of an Attribute node of type Object
    (the name) or Instancer ('instancer:' and the name)."""
    return ("instancer:" if instancer else "") + name


def _value_text(v) -> str:
    """A socket value as a warning shows it: 0.5, or (0.8, 0.8, 0.8)."""
    if np.ndim(v) == 0:
        return f"{float(v):.4g}"
    return "(" + ", ".join(f"{float(x):.4g}" for x in np.ravel(v)[:3]) + ")"


def output_node(nt, fallback_type="OUTPUT_MATERIAL"):
    """The output node Cycles renders a node tree with: the active output for the Cycles
    target, else for All, else EEVEE's; else the first node of fallback_type
    (OUTPUT_MATERIAL / OUTPUT_WORLD / OUTPUT_LIGHT); None when there is none. The node
    is a proxy that reads node groups through (addon/nodegroups.py)."""
    for target in ("CYCLES", "ALL", "EEVEE"):
        try:
            out = nt.get_output_node(target)
        except Exception:  # noqa: BLE001 - older API
            out = None
        if out is not None:
            return nodegroups.wrap(out)
    outs = [n for n in nt.nodes if n.type == fallback_type]
    return nodegroups.wrap(outs[0]) if outs else None


def _fold(node, inputs):
    """node (an engine shader node) evaluated once to its constant value (float, or an RGB
    array) when its inputs are all constants; else node itself, evaluated per hit."""
    if any(hasattr(x, "evaluate") for x in inputs):
        return node
    val = np.asarray(node.evaluate(None, np.zeros(1, np.int64), np.zeros(1), np.zeros(1)),
                     np.float64)
    return float(val[0]) if val.ndim == 1 else val[0]


class Closure:
    """Engine material parameters gathered from a shader sub-tree."""

    __slots__ = ("base_color", "metallic", "roughness", "transmission", "ior", "specular",
                 "emission", "alpha", "texture", "has_bsdf", "normal_map", "alpha_texture",
                 "specular_ior_level", "specular_tint", "coat_weight", "coat_roughness",
                 "coat_ior", "coat_tint", "multiscatter", "node", "glossy_color",
                 "sheen_weight", "sheen_roughness", "sheen_tint", "transparent_tint",
                 "scalars", "emission_texture", "weight", "anisotropic",
                 "anisotropic_rotation", "translucent", "translucent_color", "subsurface")

    # Lobe parameters of Principled v2 beyond the basic ones (engine Material fields).
    EXTRA = ("specular_ior_level", "specular_tint", "coat_weight", "coat_roughness",
             "coat_ior", "coat_tint", "multiscatter", "node", "glossy_color", "sheen_weight",
             "sheen_roughness", "sheen_tint", "transparent_tint", "scalars",
             "emission_texture", "weight", "anisotropic", "anisotropic_rotation",
             "translucent", "translucent_color")

    def __init__(self, base_color=(0.8, 0.8, 0.8), metallic=0.0, roughness=0.5,
                 transmission=0.0, ior=1.5, specular=0.0, emission=(0.0, 0.0, 0.0),
                 alpha=1.0, texture=None, has_bsdf=True, normal_map=None, alpha_texture=None,
                 specular_ior_level=0.5, specular_tint=(1.0, 1.0, 1.0), coat_weight=0.0,
                 coat_roughness=0.03, coat_ior=1.5, coat_tint=(1.0, 1.0, 1.0),
                 multiscatter=True, node="principled", glossy_color=None, sheen_weight=0.0,
                 sheen_roughness=0.5, sheen_tint=(1.0, 1.0, 1.0),
                 transparent_tint=(1.0, 1.0, 1.0), scalars=None, emission_texture=None,
                 weight=1.0, anisotropic=0.0, anisotropic_rotation=0.0, translucent=0.0,
                 translucent_color=None):
        self.base_color = np.asarray(base_color, dtype=np.float64)[:3]
        self.metallic = float(metallic)
        self.roughness = float(roughness)
        self.transmission = float(transmission)
        self.ior = float(ior)
        self.specular = float(specular)
        self.emission = np.asarray(emission, dtype=np.float64)[:3]
        self.alpha = float(alpha)
        self.texture = texture
        self.has_bsdf = has_bsdf
        self.normal_map = normal_map
        self.specular_ior_level = float(specular_ior_level)
        self.specular_tint = np.asarray(specular_tint, dtype=np.float64)[:3]
        self.coat_weight = float(coat_weight)
        self.coat_roughness = float(coat_roughness)
        self.coat_ior = float(coat_ior)
        self.coat_tint = np.asarray(coat_tint, dtype=np.float64)[:3]
        self.multiscatter = bool(multiscatter)
        self.node = node
        self.glossy_color = None if glossy_color is None else np.asarray(glossy_color,
                                                                         np.float64)[:3]
        self.sheen_weight = float(sheen_weight)
        self.sheen_roughness = float(sheen_roughness)
        self.sheen_tint = np.asarray(sheen_tint, dtype=np.float64)[:3]
        # Colour of the transparent share (1 - alpha): a Transparent BSDF's Color.
        self.transparent_tint = np.asarray(transparent_tint, dtype=np.float64)[:3]
        self.alpha_texture = alpha_texture  # per-hit factor on alpha (engine node) or None
        # Scalar inputs driven by a node per hit ({field: engine node}, engine
        # Material.scalar_textures); the field's constant is then only its fallback.
        self.scalars = dict(scalars) if scalars else {}
        # A colour node multiplied onto `emission` per hit (Emission Color textures).
        self.emission_texture = emission_texture
        # Cycles' closure weight of the surface (BSDF) part: an Add Shader of two surfaces
        # sums them, i.e. their even mix at weight 2 (engine Material.closure_weight).
        self.weight = float(weight)
        # Anisotropic GGX of the metal and specular lobes (engine Material.anisotropic:
        # Principled's Anisotropic, or a Glossy BSDF's Anisotropy for node "glossy") and
        # the tangent's rotation in turns.
        self.anisotropic = float(anisotropic)
        self.anisotropic_rotation = float(anisotropic_rotation)
        # The Translucent BSDF's share of the surface (diffuse transmission) and its
        # colour (None: the base colour, texture applied: a Translucent BSDF alone).
        self.translucent = float(translucent)
        self.translucent_color = (None if translucent_color is None
                                  else np.asarray(translucent_color, np.float64)[:3])
        # The random-walk BSSRDF (engine.subsurfacewalk.SubsurfaceParams) of a surface
        # that is a Principled with Subsurface Weight or a Subsurface Scattering node as
        # it came; base_color is then its diffuse stand-in. A mix with another surface
        # makes a new closure without it (the stand-in renders).
        self.subsurface = None

    @property
    def is_clear(self) -> bool:
        """A Transparent BSDF (alone): no surface, no emission, alpha 0 everywhere."""
        return (self.has_bsdf and self.alpha == 0.0 and self.alpha_texture is None
                and not np.any(self.emission > 0))


def _alpha_mix(sn, wa, a: Closure, wb, b: Closure):
    """(constant alpha, alpha node or None) of wa * alpha(a) + wb * alpha(b), where a
    side's alpha is its constant times its alpha texture (engine Math nodes per hit)."""
    if a.alpha_texture is None and b.alpha_texture is None:
        return wa * a.alpha + wb * b.alpha, None
    terms = []
    for w, c in ((wa, a), (wb, b)):
        if c.alpha_texture is None:
            terms.append(w * c.alpha)
        else:
            terms.append(sn.Math("MULTIPLY", c.alpha_texture, w * c.alpha))
    return 1.0, sn.Math("ADD", terms[0], terms[1], clamp=True)


def _summed_transparency(a: Closure, b: Closure, ea: float, eb: float, out: Closure):
    """(3,) transparent tint of `out`, the blend of a and b at closure weight wa + wb
    (MaterialConverter._weighted_sum), whose pass lobe must transmit
    T = ea (1 - alpha_a) tint_a + eb (1 - alpha_b) tint_b: Cycles sums the Transparent
    BSDFs' weights as it sums every closure (bsdf_transparent_setup adds each one's to
    closure_transparent_extinction, which shadow rays take unclamped and camera rays
    sample by its share of the summed sample weights). The blend's pass lobe transmits
    (1 - alpha_out) x tint, so tint = T / (1 - alpha_out): above 1 where the surface
    takes a share beside a whole pass (Add of a white Transparent and a Diffuse BSDF:
    alpha 1/2, tint 2, closure weight 2, which transmits 1 and reflects 1 as in Cycles;
    the average transmitted 1/2, 0.38-0.84 x Cycles on a sphere in a grey world).
    With an alpha texture alpha_out varies per hit: exact where both sides have one
    closure weight and one tint (or one side is opaque), T / (1 - alpha_out) being the
    tint x (ea + eb) then (above 1 the caller clamps it to 1, as the engine's Material
    does with an alpha texture, and warns); None otherwise (the caller warns and keeps
    the average)."""
    if a.alpha_texture is None and b.alpha_texture is None:
        if out.alpha >= 1.0:
            return out.transparent_tint
        t = (ea * (1.0 - a.alpha) * a.transparent_tint
             + eb * (1.0 - b.alpha) * b.transparent_tint)
        return t / (1.0 - out.alpha)
    if a.weight != b.weight:
        return None
    clear = [c for c in (a, b) if c.alpha < 1.0 or c.alpha_texture is not None]
    if len(clear) == 2 and not np.allclose(a.transparent_tint, b.transparent_tint):
        return None
    return clear[0].transparent_tint * (ea + eb)


def _weighted(sn, wa, xa, wb, xb):
    """wa xa + wb xb, where xa and xb are constants or engine nodes (then a Math tree of
    engine/shadernodes.py evaluated per hit)."""
    if not (hasattr(xa, "evaluate") or hasattr(xb, "evaluate")):
        return wa * xa + wb * xb
    terms = []
    for w, x in ((wa, xa), (wb, xb)):
        if w == 0:
            continue
        if hasattr(x, "evaluate"):
            terms.append(x if w == 1 else sn.Math("MULTIPLY", x, w))
        else:
            terms.append(w * x)
    if len(terms) == 1:
        return terms[0]
    return sn.Math("ADD", terms[0], terms[1])


def _field_mul(pm, a, b):
    """a x b for a volume's coefficients: numbers / (3,) arrays, or engine nodes (a
    textured emission, engine/volumefields.py) combined by a Vector Math node."""
    if hasattr(a, "evaluate") or hasattr(b, "evaluate"):
        return pm.shadernodes.VectorMath("MULTIPLY", a, b)
    return a * b


def _field_add(pm, a, b):
    """a + b as _field_mul."""
    if hasattr(a, "evaluate") or hasattr(b, "evaluate"):
        return pm.shadernodes.VectorMath("ADD", a, b)
    return a + b


def _emission_mix(sn, wa, a: Closure, wb, b: Closure):
    """(emission, emission texture or None) of wa * emission(a) + wb * emission(b), a
    side's emission being its constant times its texture (a Mix Color per hit)."""
    ea, eb = wa * a.emission, wb * b.emission
    if a.emission_texture is None and b.emission_texture is None:
        return ea + eb, None
    if not np.any(eb > 0) or not np.any(ea > 0):
        # One side emits: its constant and its texture (the other adds nothing).
        c, e = (a, ea) if np.any(ea > 0) else (b, eb)
        return e, c.emission_texture
    # Both emit: sum the two colours per hit, with unit emission outside.
    def colour(c, e):
        return e if c.emission_texture is None else sn.MixColor(1.0, c.emission_texture, e,
                                                                "MULTIPLY")
    return np.ones(3), sn.MixColor(1.0, colour(a, ea), colour(b, eb), "ADD")


# Per-hit parameters (Closure.scalars) of a picked Mix Shader side that a blend takes from
# its lead side, as it takes their constants, and those that are colours.
_LEAD_SCALARS = ("multiscatter", "anisotropic", "anisotropic_rotation", "node")
_COLOUR_SCALARS = ("specular_tint", "coat_tint", "sheen_tint")


def _closure_value(c: Closure, name: str):
    """A closure's parameter: its per-hit node where one is set, else its constant."""
    return c.scalars.get(name, getattr(c, name))


def _no_metal_lobe(c: Closure) -> bool:
    """A Principled side whose lobes do not depend on the colour model: no metal lobe
    (closures/principled.py reads the node for the metal lobe's colour and the
    anisotropy's mapping only)."""
    return (c.node == "principled" and not hasattr(_closure_value(c, "metallic"), "evaluate")
            and c.metallic == 0 and not hasattr(_closure_value(c, "anisotropic"), "evaluate")
            and c.anisotropic == 0)


def _lead(a: Closure, b: Closure, ga: float, gb: float) -> Closure:
    """The side whose colour model (`node`) and distribution a blend keeps: the one with
    more glossy / glass weight (ga, gb); on a tie a Glossy BSDF before a Principled
    BSDF without a metal lobe, which renders the same under either model
    (Mix of Principled and Glossy BSDF named the Glossy side 'polished metal (metallic 1)'
    and coloured it by Principled's metal Fresnel: newuser41b)."""
    if ga == gb and _no_metal_lobe(a) and b.node == "glossy":
        return b
    return a if ga >= gb else b


def _blend(a: Closure, b: Closure, wa: float, wb: float, sn=None) -> Closure:
    """Mix two closures with weights wa, wb (wa + wb = 1 for Mix Shader).

    Alpha and emission mix linearly (an alpha texture on either side per hit, through
    engine.shadernodes `sn`); the surface (BSDF) parameters are weighted by each side's
    constant opacity, so mixing with a Transparent BSDF only changes coverage."""
    out = Closure()
    if sn is None:
        out.alpha = wa * a.alpha + wb * b.alpha
    else:
        out.alpha, out.alpha_texture = _alpha_mix(sn, wa, a, wb, b)
    out.emission, out.emission_texture = _emission_mix(sn, wa, a, wb, b)
    # The transparent shares add up as colours (Cycles sums the transparent closures'
    # weights): tint = (wa (1 - alpha_a) tint_a + wb (1 - alpha_b) tint_b) / (1 - alpha).
    pa, pb = wa * (1.0 - a.alpha), wb * (1.0 - b.alpha)
    if pa + pb > 0:
        out.transparent_tint = (pa * a.transparent_tint + pb * b.transparent_tint) / (pa + pb)
    sa = wa * a.alpha if a.has_bsdf else 0.0
    sb = wb * b.alpha if b.has_bsdf else 0.0
    # An emission-only closure is black as a surface (its share scales the BSDF: weight).
    da = wa * a.alpha if not a.has_bsdf else 0.0
    db = wb * b.alpha if not b.has_bsdf else 0.0
    total = sa + sb
    if total <= 0:
        out.base_color = np.zeros(3)
        out.has_bsdf = False
        out.texture = a.texture if a.texture is not None else b.texture
        return out
    ta, tb = sa / total, sb / total
    # A Translucent BSDF side is a share of the surface beside everything else
    # (principled.setup takes it first): the shares add up, its colour is kept apart,
    # and the other lobes blend over the sides' non-translucent parts alone, so a Mix of
    # any surface and a Translucent BSDF is exact.
    la, lb = ta * a.translucent, tb * b.translucent
    out.translucent = la + lb
    if out.translucent > 0:
        def tl_colour(c):
            return c.translucent_color if c.translucent_color is not None else c.base_color
        if out.translucent < 1 or a.translucent_color is not None \
                or b.translucent_color is not None:
            out.translucent_color = (la * tl_colour(a) + lb * tl_colour(b)) / out.translucent
        if out.translucent < 1:
            ta, tb = (ta - la) / (1 - out.translucent), (tb - lb) / (1 - out.translucent)
    for name in ("metallic", "transmission", "specular", "specular_ior_level",
                 "specular_tint", "coat_weight", "coat_roughness", "coat_ior", "coat_tint",
                 "sheen_weight", "sheen_roughness", "sheen_tint"):
        setattr(out, name, ta * getattr(a, name) + tb * getattr(b, name))
    # Roughness and IOR belong to the reflective / refractive lobes: weight them by how much
    # of those lobes each side brings (a Diffuse BSDF's roughness is Oren-Nayar's, which
    # must not blur a mixed-in mirror: Diffuse + Glossy(0.05) came out at roughness 0.525).
    ga = ta * (a.metallic + a.transmission + a.specular)
    gb = tb * (b.metallic + b.transmission + b.specular)
    if ga + gb > 0:
        out.roughness = (ga * a.roughness + gb * b.roughness) / (ga + gb)
        out.ior = (ga * a.ior + gb * b.ior) / (ga + gb)
    else:
        out.roughness = ta * a.roughness + tb * b.roughness
        out.ior = ta * a.ior + tb * b.ior
    # One microfacet distribution and colour model per material: the side with more
    # glossy / glass weight decides (a Diffuse side has no say).
    lead = _lead(a, b, ga, gb)
    out.multiscatter = lead.multiscatter
    out.node = lead.node
    out.anisotropic = lead.anisotropic
    out.anisotropic_rotation = lead.anisotropic_rotation
    out.base_color = ta * a.base_color + tb * b.base_color
    # An emission-only side is black as a surface: every BSDF lobe of the other side is
    # scaled by its share, as Cycles weights the closures (the closure weight; scaling
    # the colour dimmed a diffuse base but left a Glossy BSDF's colour, a dielectric's
    # specular layer and a sheen whole: Mix of Emission and Glossy read 1.65 x Cycles).
    out.weight = total / (total + da + db)
    if out.node == "glossy":
        # Diffuse + Glossy: the glossy lobe keeps the Glossy BSDF's colour and the diffuse
        # lobe the other side's, instead of both taking the blend of the two.
        ma, mb = ta * a.metallic, tb * b.metallic
        if ma + mb > 0:
            ca = a.glossy_color if a.glossy_color is not None else a.base_color
            cb = b.glossy_color if b.glossy_color is not None else b.base_color
            out.glossy_color = (ma * ca + mb * cb) / (ma + mb)
        na, nb = ta * (1.0 - a.metallic), tb * (1.0 - b.metallic)
        if na + nb > 0:
            out.base_color = (na * a.base_color + nb * b.base_color) / (na + nb)
    # Texture-driven scalar inputs blend with the same constant weights, as node trees;
    # the per-hit IOR, tints, distribution and anisotropy of a picked Mix Shader side
    # (_mix_per_hit) as their constants do: the IOR by glossy share, the tints as colours,
    # the rest the lead side's.
    for name in set(a.scalars) | set(b.scalars):
        if name in _LEAD_SCALARS:
            if name in lead.scalars:
                out.scalars[name] = lead.scalars[name]
            continue
        wa_, wb_ = ta, tb
        if name in ("roughness", "ior") and ga + gb > 0:
            wa_, wb_ = ga / (ga + gb), gb / (ga + gb)
        xa, xb = a.scalars.get(name, getattr(a, name)), b.scalars.get(name, getattr(b, name))
        if name in _COLOUR_SCALARS:
            val = sn.MixColor(wb_, xa, xb) if wa_ * wb_ > 0 else (xa if wb_ == 0 else xb)
        else:
            val = _weighted(sn, wa_, xa, wb_, xb)
        if hasattr(val, "evaluate"):
            out.scalars[name] = val
    # (A texture on a mixed-in Translucent BSDF's colour would tint the other side's
    # base: its constant colour stands instead, out.translucent_color.)
    if out.translucent < 1:
        sa, sb = sa * (1 - a.translucent), sb * (1 - b.translucent)
    out.texture = a.texture if (a.texture is not None and sa > 0) else (
        b.texture if sb > 0 else None)
    # One shading normal per material: the first side's map that has a surface.
    out.normal_map = a.normal_map if (a.normal_map is not None and sa > 0) else (
        b.normal_map if sb > 0 else None)
    return out


class MaterialConverter:
    """Converts Blender materials once each; keeps loaded images in a cache."""

    def __init__(self, pm):
        self.pm = pm            # the engine package
        # Volume objects' materials (convert_volume_object): their nodes read the
        # object's grids; engine material name -> the grid names they read
        self.volume_grid_names = {}
        self._volume_object = False
        self._grid_names = set()
        self.images = {}        # (image name, extension, interpolation) -> ImageTexture
        self.cache = {}         # material name -> engine Material
        self.coordinate_users = set()  # materials reading Generated / Object coordinates
        # (name, from the instancer) of the Attribute nodes of type Object / Instancer
        self.object_attribute_names = set()
        # (scene, view layer) an Attribute node of type View Layer reads (set by the
        # exporter; None: not known, warned)
        self.view_layer = None
        self.tangent_users = set()  # materials with anisotropic lobes (radial tangents)
        # materials whose anisotropic lobe's Tangent is a Tangent node in UV Map mode:
        # name -> the node's UV map ("" = the render UV map)
        self.uv_tangent_users = {}
        # materials whose tangent-space Normal Map names a UV map: name -> that map
        self.normal_map_uvs = {}

    def needs_coordinates(self, material_name) -> bool:
        """Whether meshes with this material must export Generated / Object coordinates."""
        return material_name in self.coordinate_users

    def uv_tangent_map(self, material_name):
        """The UV map ("" = the render map) whose MikkTSpace tangent is this material's
        anisotropy tangent (a Tangent node, UV Map mode, linked to the Tangent input), or
        None (the default radial tangent)."""
        return self.uv_tangent_users.get(material_name)

    def needs_radial_tangent(self, material_name) -> bool:
        """Whether meshes with this material must export the radial tangent (the default
        Tangent of anisotropic lobes, addon/export.py corner_attributes)."""
        return material_name in self.tangent_users

    # --- public -------------------------------------------------------------------
    def convert(self, mat):
        """Engine Material for a Blender material (None = engine default)."""
        key = mat.name if mat is not None else "default"
        if key in self.cache:
            return self.cache[key]
        if mat is not None and lightpath.reads_light_path(mat, output_node):
            # Light Path in the surface: converted once per ray class, the classes that
            # differ from the diffuse rays' as its ray_variants (addon/lightpath.py).
            m = lightpath.convert_per_ray_class(self, mat, key, self._convert_once)
        else:
            m = self._convert_once(mat, key)
        self.cache[key] = m
        return m

    def convert_volume_object(self, mat, density_scale: float = 1.0):
        """Engine Material of a Volume object's material (None: Cycles' default volume
        shader, a Principled Volume at its defaults; Blender's ShaderManager default
        volume), named '<material> (volume object)': its Principled Volume Density
        multiplies the grid its Density Attribute names, its Temperature the Temperature
        Attribute's grid (when Blackbody Intensity > 0), Attribute and Volume Info nodes
        read grids (engine/voxelgrid.GridAttribute; addon/volumegrids.py samples them);
        a surface is not rendered (the mesh around the grid is only the medium's
        boundary). The grid names it reads go to volume_grid_names.

        density_scale: Cycles' object volume density (addon/volumegrids.py
        volume_density_scale: a Volume in Object space scaled by its object), which
        multiplies every volume closure's weight (svm_node_principled_volume's `weight`,
        svm_node_closure_emission): the coefficients, the constant emission and an
        emission field; another material named '<material> (volume object) x<scale>'."""
        key = f"{mat.name if mat is not None else 'default'} (volume object)"
        s = float(density_scale)
        if s != 1.0:
            base = self.convert_volume_object(mat)
            skey = f"{key} x{s:.6g}"
            if skey not in self.cache:
                import copy
                m = copy.copy(base)
                m.name = skey
                m.warnings = list(base.warnings)
                m.absorption = np.asarray(base.absorption, np.float64) * s
                m.scattering = np.asarray(base.scattering, np.float64) * s
                m.volume_emission = np.asarray(base.volume_emission, np.float64) * s
                if base.volume_emission_texture is not None:
                    m.volume_emission_texture = self.pm.shadernodes.VectorMath(
                        "MULTIPLY", base.volume_emission_texture, np.full(3, s))
                self.volume_grid_names[skey] = set(self.volume_grid_names[key])
                self.cache[skey] = m
            return self.cache[skey]
        if key in self.cache:
            return self.cache[key]
        self._volume_object, self._grid_names = True, set()
        try:
            if mat is None:
                m = self._default_volume(key)
            else:
                m = self._convert_once(mat, key)
                if not m.volume_only:
                    m.warnings.append(f"material '{mat.name}': its Surface on volume object"
                                      "s is not rendered (only the Volume)")
                m.volume_only = True
        finally:
            self._volume_object = False
        self.volume_grid_names[key] = set(self._grid_names)
        self.cache[key] = m
        return m

    def _default_volume(self, key):
        """Cycles' default volume shader: Principled Volume, Color 0.5, Density 1 x the
        "density" grid, no emission (sigma_s = sigma_a = 0.5 x density)."""
        return self.pm.Material(
            name=key, base_color=np.zeros(3), absorption=np.full(3, 0.5), volume_only=True,
            scattering=np.full(3, 0.5), anisotropy=0.0, volume_emission=np.zeros(3),
            density_texture=self._grid("density", "FAC", 1.0))

    def _grid(self, name, output, missing):
        """A voxel-grid attribute node of a volume object's material (recorded)."""
        from importlib import import_module
        self._grid_names.add(name)
        return import_module(self.pm.__name__ + ".voxelgrid").GridAttribute(name, output,
                                                                            missing)

    def _grid_attribute(self, node, socket_name):
        """A Principled Volume's attribute name (Density / Temperature / Color Attribute)
        when converting a volume object's material ('' otherwise or when empty)."""
        if not self._volume_object:
            return ""
        s = node.inputs.get(socket_name)
        return str(getattr(s, "default_value", "") or "") if s is not None else ""

    # The ray class whose Light Path values a conversion reads (addon/lightpath.py).
    _ray_class = "diffuse"

    def _convert_once(self, mat, key):
        """convert()'s engine Material of mat named key, for the ray class _ray_class."""
        warnings: list[str] = []
        # (sigma_a (3,) 1/m, volume-only, sigma_s (3,) 1/m, HG g): _volume
        self._medium = (np.zeros(3), False, np.zeros(3), 0.0, np.zeros(3))
        self._density_field = None  # a texture on the medium's Density (_medium_of)
        self._emission_field = None  # textures on its emission (_medium_of; volemit40)
        self._albedo_field = None  # a texture on its Principled Volume's Color
        self._displace = (None, "BUMP")  # (vectors node, method): _displacement
        if mat is None:
            # No material: Cycles (Blender 5.0) renders the default Principled BSDF, its
            # specular layer included (measured: a sunlit plane without a material reads
            # as a new material's Principled, 0.749; a Lambert 0.8 reads 0.784).
            closure = Closure(specular=1.0)
        else:
            try:
                closure = self._material_closure(mat, warnings)
            except Exception as exc:  # noqa: BLE001 - a tree this converter cannot read
                if RAISE_UNREADABLE_TREES:
                    raise
                # (a Blender version's socket it does not know, ...) must not stop the
                # render: the material renders as its viewport colour, warned with where
                # the converter failed (a bug report's first line).
                where = traceback.extract_tb(exc.__traceback__)[-1]
                warnings.append(f"material '{mat.name}': its node tree could not be read "
                                f"({type(exc).__name__}: {exc}, at "
                                f"{os.path.basename(where.filename)}:{where.lineno}); "
                                "using the viewport colour")
                closure = self._viewport(mat)
        m = self.pm.Material(
            name=key,
            base_color=np.clip(closure.base_color, 0.0, None),
            metallic=closure.metallic, roughness=closure.roughness,
            transmission=closure.transmission, ior=closure.ior if closure.ior > 0 else 1.5,
            specular=closure.specular, emission=np.clip(closure.emission, 0.0, None),
            alpha=closure.alpha, texture=closure.texture, normal_map=closure.normal_map,
            alpha_texture=closure.alpha_texture,
            specular_ior_level=max(closure.specular_ior_level, 0.0),
            specular_tint=np.clip(closure.specular_tint, 0.0, None),
            coat_weight=max(closure.coat_weight, 0.0),
            coat_roughness=min(max(closure.coat_roughness, 0.0), 1.0),
            coat_ior=max(closure.coat_ior, 1.0),
            coat_tint=np.clip(closure.coat_tint, 0.0, None),
            sheen_weight=max(closure.sheen_weight, 0.0),
            sheen_roughness=min(max(closure.sheen_roughness, 0.0), 1.0),
            transparent_tint=np.clip(closure.transparent_tint, 0.0, None),
            sheen_tint=np.clip(closure.sheen_tint, 0.0, None),
            multiscatter=closure.multiscatter, node=closure.node,
            glossy_color=(None if closure.glossy_color is None
                          else np.clip(closure.glossy_color, 0.0, 1.0)),
            scalar_textures=closure.scalars or None,
            emission_texture=(closure.emission_texture
                              if np.any(closure.emission > 0) else None),
            closure_weight=max(closure.weight, 0.0),
            anisotropic=min(max(closure.anisotropic, -1.0), 1.0),
            anisotropic_rotation=closure.anisotropic_rotation,
            translucent=min(max(closure.translucent, 0.0), 1.0),
            translucent_color=(None if closure.translucent_color is None
                               else np.clip(closure.translucent_color, 0.0, None)),
            # the random-walk BSSRDF camera paths take (engine/subsurfacewalk.py)
            subsurface=getattr(closure, "subsurface", None),
            # Material > Settings > Pass Index: the Material Index data pass
            pass_index=int(getattr(mat, "pass_index", 0) or 0),
            # Material > Settings > Emission Sampling: the sides shadow rays sample
            emission_sampling=self._emission_sampling(mat, warnings),
            # the medium inside (Volume Absorption / Principled Volume) and whether the
            # material has no surface (engine/media.py)
            absorption=self._medium[0], volume_only=self._medium[1],
            scattering=self._medium[2], anisotropy=self._medium[3],
            volume_emission=self._medium[4],
            # a texture on the Density: a heterogeneous medium (engine/heterogeneous.py;
            # the coefficients above are then at density 1)
            density_texture=self._density_field,
            # textures on its emission and on its Color (the albedo): engine/volumefields.py
            volume_emission_texture=self._emission_field,
            albedo_texture=self._albedo_field,
            # true displacement (Displacement Only / and Bump): vertices moved at prepare
            displacement=self._displace[0], displacement_method=self._displace[1],
            # AOV Output nodes: the Shader AOV passes (addon/aovs.py)
            aovs=self._aovs(mat, warnings))
        m.warnings[:0] = warnings
        return m

    # --- internals ----------------------------------------------------------------
    def _emission_sampling(self, mat, warnings) -> str:
        """Material > Settings > Emission Sampling: material.cycles.emission_sampling
        ('NONE', 'AUTO', 'FRONT', 'BACK', 'FRONT_BACK'; Cycles' add-on keeps it, Blender
        4.2-5.0); a value this engine does not know (a later Blender) warns and samples
        as Auto."""
        # Read on the original material: an evaluated copy keeps a property group's old
        # value until the material is tagged for an update (measured: Blender 5.0).
        settings = getattr(getattr(mat, "original", None) or mat, "cycles", None)
        value = getattr(settings, "emission_sampling", None)
        if value is None:
            value = getattr(mat, "emission_sampling", "AUTO")
        value = str(value or "AUTO")
        if value not in self.pm.scene.EMISSION_SAMPLING:
            warnings.append(f"material '{mat.name}': Emission Sampling {value!r} unknown, "
                            "sampled as Auto")
            return "AUTO"
        return value

    def _viewport(self, mat) -> Closure:
        return Closure(base_color=tuple(mat.diffuse_color)[:3], metallic=mat.metallic,
                       roughness=mat.roughness, specular=0.0)

    def _material_closure(self, mat, warnings) -> Closure:
        self._mat = mat
        self._warnings = warnings
        self._warned = set()
        self._ao_cores = {}  # Ambient Occlusion node name -> its OcclusionCore
        nt = mat.node_tree
        # Blender 5 always uses the node tree (use_nodes is deprecated there).
        use_nodes = bpy.app.version >= (5, 0, 0) or getattr(mat, "use_nodes", True)
        if nt is None or not use_nodes:
            return Closure(base_color=tuple(mat.diffuse_color)[:3], roughness=mat.roughness)
        out = output_node(nt)  # (node groups read through: addon/nodegroups.py)
        if out is None:
            self._warn(f"material '{mat.name}': no Material Output node; "
                       "using the viewport colour")
            return self._viewport(mat)
        # Warn before anything else: a volume-only material (fog in a box) has no surface.
        volume = out.inputs.get("Volume")
        if volume is not None and volume.is_linked:
            # The medium inside the object: its absorption (engine/media.py); a material
            # without a surface lets every ray through to it (Material.volume_only).
            sigma, scatter, g, emit = self._medium_of(volume, fields=True)
            only = out.inputs.get("Surface") is None or not out.inputs["Surface"].is_linked
            self._medium = (sigma, only, scatter, g, emit)
        surface = out.inputs.get("Surface")
        if surface is None or not surface.is_linked:
            # Cycles renders an unconnected surface black.
            return Closure(base_color=(0.0, 0.0, 0.0))
        self._subsurface_mixes = []
        closure = self._shader(self._source(surface), 0)
        if self._subsurface_mixes and getattr(closure, "subsurface", None) is None:
            # (engine/subsurfacewalk.py takes one subsurface surface per material row)
            self._warn(f"material '{mat.name}': shader "
                       f"'{self._subsurface_mixes[0]}' mixes a surface with subsurface "
                       "scattering; the mix renders its subsurface part as the diffuse "
                       "stand-in (no random walk beneath the surface)")
        disp = out.inputs.get("Displacement")
        if disp is not None and disp.is_linked:
            self._displacement(mat, disp, closure)
        return closure

    def _displacement(self, mat, socket, closure: Closure) -> None:
        """Material Output > Displacement as Cycles renders it with the material's
        Displacement method: "Bump Only" (the default) bumps the shading normal by the
        displacement's height along the normal (engine/displacement.py), before the
        BSDF's own Bump node (a BSDF's Normal Map keeps its own normal, as in Cycles);
        "Displacement Only" moves the mesh's vertices (self._displace: the engine
        Material's displacement); "Displacement and Bump" does both."""
        method = str(getattr(mat, "displacement_method", "")
                     or getattr(getattr(mat, "cycles", None), "displacement_method", "BUMP")
                     or "BUMP")
        if method not in ("BUMP", "DISPLACEMENT", "BOTH"):
            self._warn(f"material '{mat.name}': Displacement method '{method}' is not "
                       "known; using Bump Only")
            method = "BUMP"
        if method != "BUMP":
            # Vertices move: only as finely as the mesh is tessellated (Cycles alike).
            moved = self._displacement_vector(socket, moving=True)
            if moved is not None:
                self._displace = (moved, method)
            if method == "DISPLACEMENT":
                return
        vec = self._displacement_vector(socket)
        if vec is None:
            return
        dp = self.pm.displacement
        height = dp.DisplacementHeight(vec)
        try:
            bump = self.pm.Bump(height, strength=1.0, distance=1.0)
        except ValueError as exc:
            self._warn(f"material '{mat.name}': displacement: {exc}")
            return
        own = closure.normal_map
        if own is None or isinstance(own, (self.pm.Bump, self.pm.bevel.Bevel)):
            # sd->N bumped; a BSDF's Bump or Bevel node takes it as its Normal (sd->N).
            closure.normal_map = dp.DisplacedNormals(bump, own)
        # A Normal Map builds its normal from the interpolated vertex normal, not from
        # sd->N (Cycles' svm_node_normal_map): the displacement's bump does not show.

    def _displacement_vector(self, socket, moving=False):
        """The engine node of the world-space displacement vectors feeding `socket` (a
        Displacement or Vector Displacement node, or any vector / value), or None (a node
        not read: warned; a constant displacement unless `moving`: it bumps nothing,
        though it moves a truly displaced surface)."""
        src = self._source(socket)
        if src is None:
            return None
        n, out = src
        dp = self.pm.displacement
        who = f"material '{self._mat.name}'"
        if n.type == "DISPLACEMENT":
            height = self._input(n, n.inputs["Height"], 1)
            if not hasattr(height, "evaluate") and not moving:
                return None  # a constant height: a flat offset, no bump
            normal = self._vector(n, "Normal", 1)
            space = str(getattr(n, "space", "OBJECT"))
            if space not in dp.SPACES:
                self._warn(f"{who}: Displacement '{n.name}' space '{space}' is not "
                           "supported; using Object")
                space = "OBJECT"
            return dp.Displacement(height, self._input(n, n.inputs["Midlevel"], 1),
                                   self._input(n, n.inputs["Scale"], 1),
                                   normal if hasattr(normal, "evaluate") else None, space)
        if n.type == "VECTOR_DISPLACEMENT":
            space = str(getattr(n, "space", "TANGENT"))
            if space not in dp.SPACES:
                self._warn(f"{who}: Vector Displacement '{n.name}' in {space.title()} "
                           "space is not supported (World and Object are); no bump")
                return None
            vector = self._input(n, n.inputs["Vector"], 1)
            if not hasattr(vector, "evaluate") and not moving:
                return None
            return dp.VectorDisplacement(vector, self._input(n, n.inputs["Midlevel"], 1),
                                         self._input(n, n.inputs["Scale"], 1), space)
        val = self._node_output(n, out, 1)
        if val is None:
            self._warn(f"{who}: Displacement from node '{n.name}' ({n.type}) is not "
                       "supported; no bump")
            return None
        if hasattr(val, "evaluate"):
            return val
        # a constant vector (or value v: (v, v, v)) as it is, in world space
        return dp.VectorDisplacement(val, 0.0, 1.0, "WORLD") if moving else None

    def _volume(self, src, depth):
        """(sigma_a, sigma_s, sigma_s x g, emission), each (3,) (1/m; the emission in
        W/m^2/sr per m), of the volume shader tree src feeding the Material Output's
        Volume, as Cycles builds its closures (intern/cycles/kernel/svm/closure.h): Volume
        Absorption sigma_a = density x (1 - Color) (svm_node_closure_volume); Volume
        Scatter sigma_s = density x Color with a Henyey-Greenstein phase of its
        Anisotropy; Principled Volume sigma_s = density x Color and sigma_a = density x
        max(1 - Color, 0) x max(1 - sqrt(Absorption Color), 0) (svm_node_principled_volume:
        its extinction is their sum), its emission Emission Strength x Emission Color
        plus its blackbody (_blackbody); an Emission shader Color x Strength
        (svm_node_closure_emission); Add Shader sums, Mix Shader weighs by its factor
        (the mix weight scales the density and the emission). The anisotropy g is
        clamped to +-0.999 as Cycles' volume_henyey_greenstein_setup does. In a material's
        medium a texture on the emission's inputs makes the emission an engine node
        (evaluated inside the medium: engine/volumefields.py) and one on Principled
        Volume's Color (black Absorption Color) its albedo field (_albedo_color); a phase
        function other than Henyey-Greenstein and a texture on another input (the
        socket's own value used: a homogeneous medium) are warned."""
        zero = (np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
        if src is None or depth > MAX_NODE_DEPTH:
            return zero
        node, _ = src
        name = self._mat.name
        if getattr(node, "mute", False):
            for inp in node.inputs:
                if inp.type == "SHADER":
                    return self._volume(self._source(inp), depth + 1)
            return zero
        t = node.type
        if t == "VOLUME_ABSORPTION":
            color = self._volume_color(node, "Color")
            return (self._density(node) * (1.0 - color), np.zeros(3),
                    np.zeros(3), np.zeros(3))
        if t == "PRINCIPLED_VOLUME":
            color = np.clip(self._albedo_color(node), 0.0, None)
            density = self._density(node)
            absorb = np.sqrt(np.clip(self._volume_color(node, "Absorption Color"), 0.0, None))
            g = self._anisotropy_g(node)
            emit = np.zeros(3)
            strength = self._emission_input(node, "Emission Strength", 0.0, 1)
            if hasattr(strength, "evaluate") or strength > 0:
                emit = _field_mul(self.pm, strength,
                                  self._emission_input(node, "Emission Color", None, 3))
            emit = _field_add(self.pm, emit, self._blackbody(node))
            scatter = density * color
            return (density * np.clip(1.0 - color, 0.0, None)
                    * np.clip(1.0 - absorb, 0.0, None), scatter, scatter * g, emit)
        if t == "ADD_SHADER":
            a = self._volume(self._source(node.inputs[0]), depth + 1)
            b = self._volume(self._source(node.inputs[1]), depth + 1)
            return tuple(_field_add(self.pm, x, y) for x, y in zip(a, b))
        if t == "MIX_SHADER":
            fac = min(max(self._float_socket(node, node.inputs[0], 0.5), 0.0), 1.0)
            a = self._volume(self._source(node.inputs[1]), depth + 1)
            b = self._volume(self._source(node.inputs[2]), depth + 1)
            return tuple(_field_add(self.pm, _field_mul(self.pm, 1.0 - fac, x),
                                    _field_mul(self.pm, fac, y)) for x, y in zip(a, b))
        if t == "VOLUME_SCATTER":
            phase = str(getattr(node, "phase", "HENYEY_GREENSTEIN") or "HENYEY_GREENSTEIN")
            if phase != "HENYEY_GREENSTEIN":
                self._warn(f"material '{name}': the {phase.replace('_', '-').title()} phase "
                           f"of Volume Scatter '{node.name}' is not supported; rendered "
                           "with the Henyey-Greenstein phase of its Anisotropy")
            color = np.clip(self._volume_color(node, "Color"), 0.0, None)
            scatter = self._density(node) * color
            return np.zeros(3), scatter, scatter * self._anisotropy_g(node), np.zeros(3)
        if t == "EMISSION":
            # Cycles' emission closure in a volume shader: radiance per metre of ray
            # (svm_node_closure_emission x the object's volume density, 1 for a mesh).
            emit = _field_mul(self.pm, self._emission_input(node, "Strength", 1.0, 1),
                              self._emission_input(node, "Color", None, 3))
            return np.zeros(3), np.zeros(3), np.zeros(3), emit
        self._warn(f"material '{name}': volume node '{node.name}' ({t}) is not supported "
                   "and ignored")
        return zero

    def _blackbody(self, node) -> np.ndarray:
        """(3,) Principled Volume's blackbody emission (W/m^2/sr per m), as Cycles'
        svm_node_principled_volume: with Blackbody Intensity b > 0 and the Temperature T
        (K, at least 0), sigma_SB 1e-6 / pi x mix(1, T^4, b) x Blackbody Tint x the
        blackbody colour of T (svm_math_blackbody_color_rec709, luminance about 1;
        engine.shadernodes.blackbody_rec709), its negative channels (outside the gamut)
        clipped to 0 as an emission."""
        b = self._emission_input(node, "Blackbody Intensity", 0.0, 1)
        if not hasattr(b, "evaluate") and not b > 0:
            return np.zeros(3)
        T = self._emission_input(node, "Temperature", 1000.0, 1)
        attr = self._grid_attribute(node, "Temperature Attribute")
        if attr and self._fields is not None:
            # A volume object: T x max(the grid, 0) (svm_node_principled_volume)
            T = self.pm.shadernodes.Math("MULTIPLY", T, self.pm.shadernodes.Math(
                "MAXIMUM", self._grid(attr, "FAC", 1.0), 0.0))
        tint = self._emission_input(node, "Blackbody Tint", None, 3)
        sigma = 5.670373e-8 * 1e-6 / np.pi
        if any(hasattr(x, "evaluate") for x in (b, T, tint)):
            # A textured intensity / temperature / tint (fire): the same formula as engine
            # nodes, evaluated at points inside the medium (engine/volumefields.py).
            sn = self.pm.shadernodes
            T = sn.Math("MAXIMUM", T, 0.0)
            mix = sn.Math("ADD", sn.Math("SUBTRACT", 1.0, b),
                          sn.Math("MULTIPLY", b, sn.Math("POWER", T, 4.0)))
            intensity = sn.Math("MULTIPLY", sn.Math("MULTIPLY", mix, sigma),
                                sn.Math("GREATER_THAN", b, 0.0))
            return sn.VectorMath("MULTIPLY", sn.VectorMath("MULTIPLY", sn.Blackbody(T), tint),
                                 intensity)
        T = max(T, 0.0)
        intensity = sigma * ((1.0 - b) + b * T ** 4)
        rgb = self.pm.shadernodes.blackbody_rec709(np.array([T]))[0]
        return np.clip(intensity * tint * rgb, 0.0, None)

    def world_volume(self, world, socket, warnings: list):
        """(sigma_a (3,), sigma_s (3,), g, emission (3,)) (1/m; W/m^2/sr per m) of the
        World Output's Volume input `socket` of Blender world `world`, read as a
        material's medium (_volume: Principled Volume, Volume Scatter, Volume Absorption,
        Emission, Add / Mix of them); warnings get what it drops, naming the world."""
        self._mat, self._warnings, self._warned = world, [], set()
        medium = self._medium_of(socket)
        warnings.extend(w.replace(f"material '{world.name}'", f"world '{world.name}'", 1)
                        for w in self._warnings)
        return medium

    def _medium_of(self, socket, fields=False):
        """(sigma_a (3,), sigma_s (3,), g, emission (3,)) of the volume tree feeding
        `socket` (_volume; 1/m, the emission W/m^2/sr per m), the coefficients clipped at
        0; one phase function for the medium: the scattering-weighted mean of its
        Henyey-Greenstein g (a single scatter node: its own g), within +-G_LIMIT.

        fields: a texture on a volume node's Density may make the medium heterogeneous
        (a material's, not the world's): when the tree has one volume node and its
        Density is driven by a node tree (_density), the coefficients are those at
        density 1 and self._density_field is that tree (engine Material.density_texture:
        sigma(p) = max(tree(p), 0) x them, engine/heterogeneous.py). Several volume
        nodes with a textured Density among them are warned and read at each socket's
        own value (a homogeneous medium)."""
        self._fields, self._volume_nodes = ([] if fields else None), 0
        self._albedo_fields = []
        absorb, scatter, g_scatter, emit = self._volume(self._source(socket), 0)
        if self._albedo_fields and not (len(self._albedo_fields) == 1
                                        and self._volume_nodes == 1):
            node = self._albedo_fields[0][0]
            self._warn(f"material '{self._mat.name}': a texture on the Color of "
                       f"'{node.name}' mixed with other scattering or absorbing volume "
                       "shaders is not supported (one such node per textured medium); "
                       "each Color read at its socket's own value")
            self._fields = None  # (the second reading: every socket's own value)
            self._volume_nodes = 0
            absorb, scatter, g_scatter, emit = self._volume(self._source(socket), 0)
        if self._fields:
            if len(self._fields) == 1 and self._volume_nodes == 1:
                self._density_field = self._fields[0][1]
            else:
                node = self._fields[0][0]
                self._warn(f"material '{self._mat.name}': a texture on the Density of "
                           f"'{node.name}' mixed with other volume shaders is not "
                           "supported (one volume node per heterogeneous medium); each "
                           "Density read at its socket's own value")
                self._fields = None
                self._volume_nodes = 0
                self._albedo_fields = []
                absorb, scatter, g_scatter, emit = self._volume(self._source(socket), 0)
        self._fields = None
        if len(self._albedo_fields) == 1:
            self._albedo_field = self._albedo_fields[0][1]
        self._albedo_fields = []
        if hasattr(emit, "evaluate"):
            # (engine Material.volume_emission_texture; the engine's stand-in is its mean)
            self._emission_field = emit
            emit = np.zeros(3)
        scatter = np.clip(scatter, 0.0, None)
        g = float(g_scatter.sum() / scatter.sum()) if scatter.sum() > 0 else 0.0
        return (np.clip(absorb, 0.0, None), scatter, min(max(g, -G_LIMIT), G_LIMIT),
                np.clip(emit, 0.0, None))

    def _density(self, node) -> float:
        """A volume node's Density (at least 0). A node tree on it, when _medium_of
        allows fields (self._fields a list): recorded there as (node, tree) and 1.0
        returned (the coefficients at density 1); else one constant (_float: a per-point
        tree warned, its socket's own value used)."""
        self._volume_nodes += 1
        s = node.inputs.get("Density")
        attr = self._grid_attribute(node, "Density Attribute")
        if attr and self._fields is not None:
            # A volume object: Density x the grid (svm_node_principled_volume: the
            # attribute multiplies the density where the object has it)
            val = (self._input(node, s, 0) if s is not None and self._source(s) is not None
                   else max(self._float(node, "Density", 1.0), 0.0))
            grid = self._grid(attr, "FAC", 1.0)
            if not hasattr(val, "evaluate") and float(np.mean(val)) == 1.0:
                tree = grid
            else:
                tree = self.pm.shadernodes.Math("MULTIPLY", val, grid)
            self._fields.append((node, tree))
            return 1.0
        if (self._fields is not None and s is not None
                and self._source(s) is not None):
            val = self._input(node, s, 0)
            if hasattr(val, "evaluate"):
                self._fields.append((node, val))
                return 1.0
            return max(float(val) if np.ndim(val) == 0 else float(np.mean(val)), 0.0)
        return max(self._float(node, "Density", 1.0), 0.0)

    def _anisotropy_g(self, node) -> float:
        """A volume node's Anisotropy as the Henyey-Greenstein g Cycles uses: clamped to
        +-(1 - 1e-3) (volume_henyey_greenstein_setup), warned outside (-1, 1)."""
        g = self._float(node, "Anisotropy", 0.0)
        if not -1.0 < g < 1.0:
            self._warn(f"material '{self._mat.name}': the Anisotropy {g:g} of '{node.name}' "
                       f"lies outside (-1, 1); clamped to {np.sign(g) * G_LIMIT:g}")
        return min(max(g, -G_LIMIT), G_LIMIT)

    def _volume_color(self, node, name) -> np.ndarray:
        """A volume node's colour input as one constant (a homogeneous medium): a texture
        on it is warned and the socket's own colour used."""
        rgb, tex = self._color(node, name)
        if tex is None:
            return np.asarray(rgb, np.float64)
        own = self._default(node.inputs[name])
        self._warn(f"material '{self._mat.name}': the texture on '{name}' of node "
                   f"'{node.name}' varies per point, which a homogeneous medium does not; "
                   f"using its own value {_value_text(own)}")
        return np.full(3, float(own)) if np.ndim(own) == 0 else np.asarray(own, np.float64)

    def _aovs(self, mat, warnings) -> dict:
        """Material.aovs of mat (addon/aovs.py); {} when it has none or its AOV nodes
        cannot be read (warned)."""
        if mat is None:
            return {}
        try:
            return material_aovs(self, mat)
        except Exception as exc:  # noqa: BLE001 - an AOV must not stop the render
            warnings.append(f"material '{mat.name}': its AOV Output nodes could not be read "
                            f"({type(exc).__name__}: {exc}); its Shader AOVs stay 0")
            return {}

    def aov_input(self, node, socket):
        """An AOV Output node's Color or Value input for the material just converted: an
        engine node or a constant (addon/aovs.py)."""
        return self._input(node, socket, 0)

    def _albedo_color(self, node) -> np.ndarray:
        """Principled Volume's Color. A texture on it, in a material's medium (not the
        world's) whose Absorption Color is black and unlinked, is the medium's albedo
        (Cycles' sigma_t = density x (Color + max(1 - Color, 0)) = density there: the
        texture moves only the split between scattering and absorption,
        engine/volumefields.py): recorded in self._albedo_fields and the socket's own
        colour (within 0..1) returned for the coefficients. Otherwise _volume_color (a
        texture warned, its own value used)."""
        rgb, tex = self._color(node, "Color")
        attr = self._grid_attribute(node, "Color Attribute")
        if attr and self._fields is not None:
            # A volume object: Color x the grid (svm_node_principled_volume), an albedo
            # field like a texture on the Color
            tex = self.pm.shadernodes.VectorMath(
                "MULTIPLY", tex if tex is not None else np.asarray(rgb, np.float64),
                self._grid(attr, "COLOR", 1.0))
        if tex is None:
            return np.asarray(rgb, np.float64)
        ab = node.inputs.get("Absorption Color")
        black = ab is None or (self._source(ab) is None
                               and not np.any(np.asarray(self._default(ab)) > 0))
        if self._fields is not None and black:
            self._albedo_fields.append((node, tex))
            own = self._default(node.inputs["Color"])
            own = np.full(3, float(own)) if np.ndim(own) == 0 else np.asarray(own)
            return np.clip(own, 0.0, 1.0)
        if self._fields is not None:
            own = self._default(node.inputs["Color"])
            self._warn(f"material '{self._mat.name}': the texture on 'Color' of node "
                       f"'{node.name}' with an Absorption Color changes the medium's "
                       "extinction per point, which is not supported; using its own value "
                       f"{_value_text(own)}")
        return self._volume_color(node, "Color")

    def _emission_input(self, node, name, default, width):
        """A volume node's emission input (Emission Strength / Color, Blackbody
        Intensity / Temperature / Tint, an Emission shader's Strength / Color): an engine
        node when a texture drives it in a material's medium (evaluated at points inside
        it: engine/volumefields.py), else one constant (a float for width 1, else (3,));
        the world's textures are warned and read at the socket's own value."""
        s = node.inputs.get(name)
        if s is not None and self._fields is not None and self._source(s) is not None:
            val = self._input(node, s, 0)
            if hasattr(val, "evaluate"):
                return val
        if width == 1:
            return self._float(node, name, default)
        return self._volume_color(node, name)

    def _warn(self, text):
        if text not in self._warned:
            self._warned.add(text)
            self._warnings.append(text)

    def _unsupported(self, node, what="node"):
        self._warn(f"material '{self._mat.name}': {what} '{node.name}' ({node.type}) is not "
                   "supported; using the material's viewport colour")

    @staticmethod
    def _source(socket):
        """(node, output socket) feeding an input socket, following reroutes."""
        if not socket.is_linked or not socket.links:
            return None
        link = socket.links[0]
        if not getattr(link, "is_valid", True) or getattr(link, "is_muted", False):
            return None
        node, out = link.from_node, link.from_socket
        depth = 0
        while node.type == "REROUTE" and depth < MAX_NODE_DEPTH:
            inp = node.inputs[0]
            if not inp.is_linked:
                return None
            link = inp.links[0]
            node, out = link.from_node, link.from_socket
            depth += 1
        return (node, out)

    def _anisotropy(self, node, c: Closure, name, rotation):
        """Node's anisotropy input `name` (Principled 'Anisotropic', Glossy / Anisotropic
        BSDF 'Anisotropy') and its rotation input onto closure c (one constant each: a
        per-hit texture is warned by _float and its socket's value used). The tangent is
        Cycles' default, radial about the object's Z axis (exported per corner), or a
        Tangent node in UV Map mode: that map's MikkTSpace tangent (svm_node_tangent's
        attribute tangent; exported per corner in its place, addon/export.py); any other
        linked Tangent is warned and the default used."""
        inp = node.inputs
        if name not in inp:
            return
        a = self._float(node, name, 0.0)
        if a == 0.0:
            return
        c.anisotropic = a
        c.anisotropic_rotation = self._float(node, rotation, 0.0) if rotation in inp else 0.0
        self.tangent_users.add(self._mat.name)
        if "Tangent" in inp and inp["Tangent"].is_linked:
            src = self._source(inp["Tangent"])
            tnode = src[0] if src is not None else None
            if (tnode is not None and tnode.type == "TANGENT"
                    and getattr(tnode, "direction_type", "") == "UV_MAP"):
                self.uv_tangent_users[self._mat.name] = str(getattr(tnode, "uv_map", ""))
                return
            self._warn(f"material '{self._mat.name}': the linked 'Tangent' of node "
                       f"'{node.name}' is not supported; the default radial tangent (about "
                       "the object's Z axis) is used")

    def _shader(self, src, depth) -> Closure:
        if src is None:
            return Closure(base_color=(0.0, 0.0, 0.0), has_bsdf=False)
        node, _ = src
        if depth > MAX_NODE_DEPTH:
            self._warn(f"material '{self._mat.name}': shader tree too deep at node "
                       f"'{node.name}'")
            return self._viewport(self._mat)
        if getattr(node, "mute", False):
            # A muted shader node passes its first shader input through (or nothing).
            for inp in node.inputs:
                if inp.type == "SHADER":
                    return self._shader(self._source(inp), depth + 1)
            return Closure(base_color=(0.0, 0.0, 0.0), has_bsdf=False)
        t = node.type
        inp = node.inputs
        if t == "BSDF_PRINCIPLED":
            base, tex = self._color(node, "Base Color")
            sc = {}  # texture-driven scalar inputs, evaluated per hit
            c = Closure(base_color=base, texture=tex,
                        metallic=self._scalar(node, "Metallic", 0.0, "metallic", sc),
                        roughness=self._scalar(node, "Roughness", 0.5, "roughness", sc),
                        transmission=self._scalar(node, "Transmission Weight", 0.0,
                                                  "transmission", sc),
                        ior=self._float(node, "IOR", 1.5),
                        specular=1.0,
                        specular_ior_level=self._scalar(node, "Specular IOR Level", 0.5,
                                                        "specular_ior_level", sc),
                        specular_tint=self._const_color(node, "Specular Tint", (1, 1, 1)),
                        coat_weight=self._scalar(node, "Coat Weight", 0.0, "coat_weight", sc),
                        coat_roughness=self._scalar(node, "Coat Roughness", 0.03,
                                                    "coat_roughness", sc),
                        coat_ior=self._float(node, "Coat IOR", 1.5),
                        coat_tint=self._const_color(node, "Coat Tint", (1, 1, 1)),
                        sheen_weight=self._scalar(node, "Sheen Weight", 0.0, "sheen_weight", sc),
                        sheen_roughness=self._scalar(node, "Sheen Roughness", 0.5,
                                                     "sheen_roughness", sc),
                        sheen_tint=self._const_color(node, "Sheen Tint", (1, 1, 1)),
                        multiscatter=self._distribution(node), scalars=sc)
            c.alpha, c.alpha_texture = self._factor_input(node, "Alpha", 1.0)
            strength = self._float(node, "Emission Strength", 0.0)
            if strength > 0:
                ecol, etex = self._color(node, "Emission Color")
                c.emission = np.asarray(ecol) * strength
                c.emission_texture = etex  # per hit (None: a constant colour)
            self._subsurface(node, c)
            self._anisotropy(node, c, "Anisotropic", "Anisotropic Rotation")
            if c.coat_weight > 0 and "Coat Normal" in inp and inp["Coat Normal"].is_linked:
                self._warn(f"material '{self._mat.name}': 'Coat Normal' of node "
                           f"'{node.name}' is not supported; the coat uses the surface normal")
            c.normal_map = self._normal(node)
            return c
        if t == "BSDF_DIFFUSE":
            base, tex = self._color(node, "Color")
            return Closure(base_color=base, texture=tex, roughness=1.0, specular=0.0,
                           normal_map=self._normal(node))
        if t in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC"):
            base, tex = self._color(node, "Color")
            sc = {}
            c = Closure(base_color=base, texture=tex, metallic=1.0, node="glossy",
                        multiscatter=self._distribution(node),
                        normal_map=self._normal(node),
                        roughness=self._scalar(node, "Roughness", 0.5, "roughness", sc),
                        scalars=sc)
            self._anisotropy(node, c, "Anisotropy", "Rotation")
            return c
        if t == "BSDF_METALLIC":
            return self._metallic(node)
        if t == "SUBSURFACE_SCATTERING":
            # Cycles' node is the BSSRDF alone (albedo = Color, no specular closure):
            # the Principled subsurface stand-in at weight 1 (engine/subsurface.py).
            base, tex = self._color(node, "Color")
            ss = self.pm.subsurface
            # A textured Color walks too, its colour evaluated at each walk's entry
            # (engine/subsurfacewalk.py); photons and gather rays see the stand-in of it.
            walk = self._walk_params(node, 1.0, base, "Radius", "Scale", "IOR", 1.4,
                                     "Anisotropy", self._float(node, "Roughness", 1.0),
                                     color_node=tex)
            if tex is None:
                base = ss.diffuse_color(base, 1.0)
            else:
                tex, base = ss.SubsurfaceColor(tex, 1.0), np.ones(3)
            out = Closure(base_color=base, texture=tex, roughness=1.0, specular=0.0,
                          normal_map=self._normal(node))
            out.subsurface = walk
            return out
        if t in ("BSDF_GLASS", "BSDF_REFRACTION"):
            base, tex = self._color(node, "Color")
            sc = {}
            # Refraction BSDF: the glass lobe's refraction alone, colour x refraction
            # (Cycles: no Fresnel, no reflection, no energy compensation).
            return Closure(base_color=base, texture=tex, transmission=1.0, specular=1.0,
                           node="glass" if t == "BSDF_GLASS" else "refraction",
                           multiscatter=self._distribution(node),
                           normal_map=self._normal(node),
                           roughness=self._scalar(node, "Roughness", 0.5, "roughness", sc),
                           ior=self._float(node, "IOR", 1.5), scalars=sc)
        if t == "EMISSION":
            col, tex = self._color(node, "Color")
            strength = self._float(node, "Strength", 1.0)
            return Closure(base_color=(0.0, 0.0, 0.0), emission=np.asarray(col) * strength,
                           has_bsdf=False, emission_texture=tex)
        if t == "BSDF_TRANSPARENT":
            col, tex = self._color(node, "Color")
            if tex is not None:
                self._warn(f"material '{self._mat.name}': texture on 'Color' of Transparent "
                           f"BSDF '{node.name}' is not supported; using white")
            return Closure(alpha=0.0, transparent_tint=col)
        if t == "MIX_SHADER":
            a = self._shader(self._source(inp[1]), depth + 1)
            b = self._shader(self._source(inp[2]), depth + 1)
            self._note_subsurface_mix(a, b, node)
            fac = self._input(node, inp[0], depth) if self._source(inp[0]) else None
            if hasattr(fac, "evaluate") and (a.translucent > 0 or b.translucent > 0):
                self._warn(f"material '{self._mat.name}': Mix Shader '{node.name}' mixes a "
                           "Translucent BSDF by a texture; per-hit mixing of translucency "
                           f"is not supported: using {_value_text(self._default(inp[0]))} "
                           "(the factor's own value)")
                fac = None
            if hasattr(fac, "evaluate"):
                sn = self.pm.shadernodes
                if a.is_clear or b.is_clear:
                    # A cut-out: the surface side's coverage is the factor per hit (fac
                    # picks the second shader), times its own alpha.
                    surf = b if a.is_clear else a
                    cover = fac if a.is_clear else sn.Math("SUBTRACT", 1.0, fac)
                    cover = sn.Math("MULTIPLY", cover, 1.0, clamp=True)
                    out = _blend(surf, surf, 1.0, 0.0, sn)  # a copy of surf
                    out.alpha = surf.alpha
                    out.weight = surf.weight
                    clear = a if a.is_clear else b
                    out.transparent_tint = clear.transparent_tint.copy()
                    out.alpha_texture = (cover if surf.alpha_texture is None else
                                         sn.Math("MULTIPLY", cover, surf.alpha_texture))
                    if np.any(surf.emission > 0):
                        # Cycles weights the emission by the factor as well.
                        out.emission_texture = (cover if surf.emission_texture is None else
                                                sn.MixColor(1.0, surf.emission_texture, cover,
                                                            "MULTIPLY"))
                    return out
                mixed = self._mix_per_hit(a, b, fac, node)
                if mixed is not None:
                    if a.weight != b.weight:
                        self._warn(f"material '{self._mat.name}': Mix Shader '{node.name}' "
                                   "mixes by a texture two surfaces of different closure "
                                   "weights (an Add Shader on one side); using their mean "
                                   "weight")
                    mixed.weight = 0.5 * (a.weight + b.weight)
                    return mixed
                self._warn(f"material '{self._mat.name}': Mix Shader '{node.name}' mixes two "
                           "surfaces by a texture, one of them emissive or with alpha; "
                           "per-hit mixing is supported for opaque surfaces and cut-outs: "
                           f"using {_value_text(self._default(inp[0]))} (the factor's own "
                           "value)")
                fac = None
            if fac is None:
                fac = self._float_socket(node, inp[0], 0.5) if not self._source(inp[0]) \
                    else self._default(inp[0])
            fac = float(np.mean(fac)) if np.ndim(fac) else float(fac)
            fac = min(max(fac, 0.0), 1.0)
            if (a.weight == 1.0 and b.weight == 1.0 and 0.0 < fac < 1.0
                    and self._opaque(a) and self._opaque(b) and self._blend_inexact(a, b)):
                # Two surfaces whose parameter blend is not their mix: pick one per hit.
                return self._mix_per_hit(a, b, fac, node)
            if a.weight == 1.0 and b.weight == 1.0:
                return _blend(a, b, 1.0 - fac, fac, self.pm.shadernodes)
            # A side of closure weight != 1 (an Add Shader): (1 - f) w_a a + f w_b b is
            # their mix by (1 - f) w_a : f w_b at weight W = (1 - f) w_a + f w_b.
            return self._weighted_sum(node, a, b, (1.0 - fac) * a.weight, fac * b.weight,
                                      1.0 - fac, fac)
        if t == "ADD_SHADER":
            a = self._shader(self._source(inp[0]), depth + 1)
            b = self._shader(self._source(inp[1]), depth + 1)
            self._note_subsurface_mix(a, b, node)
            if a.has_bsdf and b.has_bsdf:
                # Cycles sums the two closures: their mix by w_a : w_b at weight w_a + w_b.
                return self._weighted_sum(node, a, b, a.weight, b.weight, 1.0, 1.0)
            out = a if a.has_bsdf else b
            other = b if a.has_bsdf else a
            res = Closure(base_color=out.base_color, metallic=out.metallic,
                          roughness=out.roughness, transmission=out.transmission,
                          ior=out.ior, specular=out.specular,
                          emission=a.emission + b.emission,
                          # An emission-only side adds light, not coverage: Add of a
                          # Transparent BSDF and an Emission (a glowing hologram) is
                          # see-through (it rendered an opaque grey card, 7.3 / 2.4 /
                          # 5.2 x Cycles).
                          alpha=out.alpha if out.has_bsdf else max(out.alpha, other.alpha),
                          texture=out.texture,
                          has_bsdf=out.has_bsdf, normal_map=out.normal_map,
                          alpha_texture=out.alpha_texture,
                          **{k: getattr(out, k) for k in Closure.EXTRA})
            res.emission, res.emission_texture = _emission_mix(self.pm.shadernodes, 1.0, a,
                                                               1.0, b)
            res.subsurface = out.subsurface  # (emission leaves the BSDF as it is)
            return res
        if t == "BSDF_TRANSLUCENT":
            # Cycles' diffuse transmission (bsdf_translucent): Lambert on the far side.
            base, tex = self._color(node, "Color")
            return Closure(base_color=base, texture=tex, roughness=1.0, specular=0.0,
                           translucent=1.0, normal_map=self._normal(node))
        if t == "BSDF_SHEEN":
            # Cycles' bsdf_sheen (Microfiber, the node's default): the lobe the Principled
            # BSDF's sheen layer uses, alone (no base, no specular layer under it).
            if getattr(node, "distribution", "MICROFIBER") != "MICROFIBER":
                self._warn(f"material '{self._mat.name}': {node.distribution} distribution "
                           f"of Sheen BSDF '{node.name}' is rendered as Microfiber")
            sc = {}
            return Closure(base_color=(0.0, 0.0, 0.0), roughness=1.0, specular=0.0,
                           sheen_weight=1.0,
                           sheen_roughness=self._scalar(node, "Roughness", 0.5,
                                                        "sheen_roughness", sc),
                           sheen_tint=self._const_color(node, "Color", (0.8, 0.8, 0.8)),
                           normal_map=self._normal(node), scalars=sc)
        if t == "BSDF_HAIR_PRINCIPLED":
            return self._principled_hair(node)
        if node.inputs.get("Color") is not None:
            # Toon, Subsurface Scattering, Hair ...: the node's own colour as a
            # Diffuse BSDF is nearer than the viewport colour (a new user's blue Toon ball
            # rendered grey).
            self._warn(f"material '{self._mat.name}': shader '{node.name}' ({node.type}) is "
                       f"not supported; approximated by a Diffuse BSDF of its Color")
            base, tex = self._color(node, "Color")
            return Closure(base_color=base, texture=tex, roughness=1.0, specular=0.0,
                           normal_map=self._normal(node))
        self._unsupported(node)
        return self._viewport(self._mat)

    def _metallic(self, node) -> Closure:
        """Metallic BSDF (Blender 4.3+): Cycles' F82 conductor (svm: f0 = saturate(Base
        Color), the F82-tint Fresnel of saturate(Edge Tint)) is the Principled BSDF's metal
        lobe with that Edge Tint as its Specular Tint: rendered so, with the Principled
        anisotropy mapping (the same aspect formula in Cycles), the node's distribution.
        Physical Conductor (complex IOR n + ik per channel): approximated by the F82-tint
        Fresnel that matches Cycles' fresnel_conductor at normal incidence and at
        acos(1/7) (~82 degrees), where the tint model is anchored (conductor_f82_tint);
        between, the two differ by a few per cent at most. Thin Film: warned, ignored."""
        inp = node.inputs
        sc = {}
        if getattr(node, "fresnel_type", "F82") == "PHYSICAL_CONDUCTOR":
            n = np.asarray(tuple(inp["IOR"].default_value)[:3], np.float64)
            k = np.asarray(tuple(inp["Extinction"].default_value)[:3], np.float64)
            for name, value in (("IOR", n), ("Extinction", k)):
                if inp[name].is_linked:
                    self._warn(f"material '{self._mat.name}': a node plugged into '{name}' of "
                               f"'{node.name}' is not supported; using its value "
                               f"{_value_text(value)}")
            base, tint = conductor_f82_tint(n, k)
            tex = None
        else:
            base, tex = self._color(node, "Base Color")
            base = np.clip(base, 0.0, 1.0) if tex is None else base
            tint = np.clip(self._const_color(node, "Edge Tint", (1, 1, 1)), 0.0, 1.0)
        thickness = inp.get("Thin Film Thickness")
        if thickness is not None and (thickness.is_linked or thickness.default_value > 0.0):
            self._warn(f"material '{self._mat.name}': Thin Film of '{node.name}' is not "
                       "simulated (no iridescence)")
        c = Closure(base_color=base, texture=tex, metallic=1.0, specular_tint=tint,
                    roughness=self._scalar(node, "Roughness", 0.5, "roughness", sc),
                    multiscatter=self._distribution(node), normal_map=self._normal(node),
                    scalars=sc)
        self._anisotropy(node, c, "Anisotropy", "Rotation")
        return c

    def _principled_hair(self, node) -> Closure:
        """Principled Hair BSDF (Chiang, or Huang) as engine.hairbsdf renders it on the
        hair's tubes: a Principled dielectric of the node's IOR, its specular layer the R
        lobe (GGX of the same highlight width), partly transparent so that the tube's
        two walls scatter back and pass on what the fibre does (engine.hairbsdf.surface),
        from the node's sigma_a in each parametrization; the diffuse base per hit when
        an input is linked or the strand's Random varies it. Warned: approximated, with
        what is left out."""
        hb = self.pm.hairbsdf
        sn = self.pm.shadernodes
        inp = node.inputs
        name = self._mat.name
        huang = getattr(node, "model", "CHIANG") == "HUANG"
        param = getattr(node, "parametrization", "COLOR")

        def value(key, default):
            s = inp.get(key)
            return default if s is None else self._input(node, s, 0)
        roughness = self._float(node, "Roughness", 0.3)
        coat = 0.0 if huang else min(max(self._float(node, "Coat", 0.0), 0.0), 1.0)
        radial = value("Roughness" if huang else "Radial Roughness", 0.3)
        random_s = inp.get("Random")
        if random_s is not None and self._source(random_s) is not None:
            random = self._input(node, random_s, 0)
        else:
            # Cycles reads the strand's Random attribute when the input is unlinked
            # (svm_node_closure_bsdf: find_attribute of the node's random attribute).
            random = sn.SeparateChannel(self._coordinates("attr:curves_info"), 2)
        random_color = value("Random Color", 0.0) if param == "MELANIN" else 0.0
        random_roughness = value("Random Roughness", 0.0)
        weights = (1.0, 1.0, 1.0)  # Huang's R, TT, TRT factors (Chiang: 1)
        if huang:
            weights = (max(self._float(node, "Reflection", 1.0), 0.0),
                       max(self._float(node, "Transmission", 1.0), 0.0),
                       max(self._float(node, "Secondary Reflection", 1.0), 0.0))
        # (An IOR at or below 1 has no Fresnel reflection to scale: kept just above 1.)
        ior = max(self._float(node, "IOR", hb.DEFAULT_IOR), 1.001)
        args = (param, value("Color", np.zeros(3)), value("Melanin", 0.8),
                value("Melanin Redness", 1.0), value("Tint", np.ones(3)),
                value("Absorption Coefficient", np.zeros(3)), radial, random_roughness,
                random, random_color, ior)
        # The straight-through share and its tint are one constant per material (the
        # engine's Transparent tint): those of the inputs' own values at Random 0.5.
        keys = (None, "Color", "Melanin", "Melanin Redness", "Tint",
                "Absorption Coefficient", "Roughness" if huang else "Radial Roughness",
                "Random Roughness", None, "Random Color")
        const = list(args[:10])
        const[8] = 0.5
        for i, k in enumerate(keys):
            if k is not None and hasattr(const[i], "evaluate"):
                const[i] = self._default(inp[k])
        mean = hb.HairColor(*const, ior).sigma(None, np.zeros(1, np.int64), np.zeros(1),
                                                np.zeros(1))[0]
        alpha, tint, rho, spec = hb.surface(mean, ior, *weights)
        kw = dict(r_weight=weights[0], tt_weight=weights[1], trt_weight=weights[2])
        colour = hb.HairColor(*args, **kw)
        # Per hit when an input is linked, or when the strand's Random varies the
        # colour (Random Color in Melanin mode; Random Roughness through the radial
        # roughness in the Melanin tint and Direct Coloring); else one constant.
        varies = (any(hasattr(x, "evaluate") for x in (
            colour.color, colour.melanin, colour.redness, colour.tint, colour.absorption,
            colour.radial_roughness, colour.random_color, colour.random_roughness))
            or (param == "MELANIN" and float(random_color) != 0.0)
            or (param != "ABSORPTION" and float(random_roughness) != 0.0))
        c = Closure(base_color=rho, roughness=float(
                        hb.specular_roughness(roughness * (1.0 - coat))),
                    ior=ior, specular=1.0,
                    specular_ior_level=float(hb.specular_level(spec, ior)),
                    alpha=float(alpha), transparent_tint=tint)
        if varies:
            # The diffuse base, opaque share and specular level per hit; the tint of
            # what passes is one colour (the engine's Transparent tint): the mean's.
            c.base_color, c.texture = np.ones(3), colour
            # (One node: the shading of a batch evaluates it once for all three.)
            c.alpha, c.alpha_texture = 1.0, colour.with_output("ALPHA")
            c.scalars["specular_ior_level"] = colour.with_output("LEVEL")
        left = ("what the strand transmits passes straight through (not spread into "
                "Chiang's forward lobe); the secondary highlight's colour and shift, "
                "'Offset' and 'Radial Roughness' shape no lobe")
        if varies:
            left += ("; what passes a strand takes the tint of the inputs' own values at "
                     "Random 0.5 (its share follows each strand)")
        if huang:
            left += "; Huang's elliptic cross-section ('Aspect Ratio') is round"
        if hasattr(random_roughness, "evaluate") or float(random_roughness) != 0.0:
            left += "; 'Random Roughness' varies the colour, not the highlight's width"
        self._warn(f"material '{name}': Principled Hair BSDF '{node.name}' is approximated: "
                   "a specular layer for its primary highlight over a diffuse base, partly "
                   "transparent, that scatter back and pass on what the fibre does "
                   "(its albedo in uniform light); " + left)
        return c

    def _subsurface(self, node, c: Closure):
        """Principled Subsurface Weight > 0: camera paths walk beneath the surface
        (c.subsurface, engine/subsurfacewalk.py; a textured Base Color or Subsurface
        Weight evaluated at each walk's entry); the diffuse base the photons and gather
        rays see takes the albedo Cycles' random walk gives a thick object of that Base
        Color (engine.subsurface; its constant colour, or per hit for a texture or a
        texture-driven weight)."""
        s = node.inputs.get("Subsurface Weight")
        if s is None or not (s.is_linked or self._float(node, "Subsurface Weight", 0.0) > 0):
            return
        if (c.metallic > 0 or c.transmission > 0 or "metallic" in c.scalars
                or "transmission" in c.scalars):
            # Base Color is also the metal's F0 and the glass's tint there: left as it is.
            self._warn(f"material '{self._mat.name}': 'Subsurface Weight' of node "
                       f"'{node.name}' on a metallic or transmissive surface is not "
                       "supported: rendered as a diffuse surface of its Base Color (no "
                       "light spreads beneath the surface, as Cycles' subsurface "
                       "scattering does)")
            return
        w, wnode = self._factor_input(node, "Subsurface Weight", 0.0)
        ss = self.pm.subsurface
        # Walked on camera paths (engine/subsurfacewalk.py): Cycles' Principled takes
        # the material's IOR for the entry (Subsurface IOR only for Random Walk (Skin)).
        skin = getattr(node, "subsurface_method", "RANDOM_WALK") == "RANDOM_WALK_SKIN"
        if skin or getattr(node, "subsurface_method", "RANDOM_WALK") == "BURLEY":
            self._warn(f"material '{self._mat.name}': Subsurface Method "
                       f"'{node.subsurface_method}' of node '{node.name}' is rendered "
                       "as Random Walk")
        # A textured Base Color or Subsurface Weight: both evaluated at each walk's
        # entry; the table's per-hit colour (photons, gather rays, the diffuse share)
        # is the stand-in of them (engine/subsurface.SubsurfaceColor).
        colour = (None if c.texture is None else
                  self.pm.shadernodes.MixColor(1.0, c.texture, c.base_color, "MULTIPLY"))
        c.subsurface = self._walk_params(
            node, w, c.base_color, "Subsurface Radius", "Subsurface Scale",
            "Subsurface IOR" if skin else None, c.ior, "Subsurface Anisotropy",
            c.roughness, color_node=colour, weight_node=wnode)
        if wnode is None and c.texture is None:
            c.base_color = ss.diffuse_color(c.base_color, w)
        else:
            c.texture = ss.SubsurfaceColor(c.base_color if colour is None else colour,
                                           w if wnode is None else wnode)
            c.base_color = np.ones(3)

    def _walk_params(self, node, weight, color, radius, scale, ior, ior_default, anisotropy,
                     roughness, color_node=None, weight_node=None):
        """engine.subsurfacewalk.SubsurfaceParams of a node's inputs (the named sockets;
        ior None: ior_default); color_node / weight_node: the per-hit colour / weight
        (None: the constants). A textured Radius is evaluated per hit (x the Scale); a
        textured Scale is warned and its socket's value used (_float)."""
        rgb, tex = self._color(node, radius)
        s = self._float(node, scale, 0.05)
        radius_node = (None if tex is None else
                       self.pm.shadernodes.MixColor(1.0, tex, np.full(3, s), "MULTIPLY"))
        return self.pm.subsurfacewalk.SubsurfaceParams.make(
            weight, color, np.asarray(rgb if tex is None else (1.0, 0.2, 0.1), np.float64) * s,
            ior_default if ior is None else self._float(node, ior, ior_default),
            self._float(node, anisotropy, 0.0), roughness, color_node, weight_node,
            radius_node)

    def _weighted_sum(self, node, a: Closure, b: Closure, wa, wb, ea, eb) -> Closure:
        """wa a + wb b of two surfaces (wa = mix or add weight x closure weight): their
        blend by wa : wb (_blend) at closure weight wa + wb, so that every BSDF lobe of
        either side keeps its own weight (exact where _blend is: equal or complementary
        lobes, e.g. Diffuse + Diffuse, Diffuse + Glossy); unlike opaque surfaces
        (_blend_inexact) pick one side per hit, b with probability wb / (wa + wb), at that
        weight (_mix_per_hit); emission ea x a's + eb x b's, and the transparent shares
        (alpha < 1) ea x a's + eb x b's too (_summed_transparency; averaged and warned
        where an alpha texture makes their ratio vary per hit)."""
        sn = self.pm.shadernodes
        total = wa + wb
        if (total > 0 and 0 < wb < total and self._opaque(a) and self._opaque(b)
                and self._blend_inexact(a, b)):
            # Surfaces whose parameter blend is not their sum (a Diffuse and a Glass, a
            # dielectric and a metal): each hit takes one side whole, b with probability
            # wb / total, at weight total: wa a + wb b in expectation, as Cycles sums the
            # closures (Add of a Diffuse and a Glass read 4.8 / 1.6 / 0.85 x Cycles).
            out = self._mix_per_hit(a, b, wb / total, node)
            if out is not None:
                out.weight = total
                return out
        if total <= 0:
            out = _blend(a, b, 0.5, 0.5, sn)
            out.weight = 0.0
        else:
            out = _blend(a, b, wa / total, wb / total, sn)
            out.weight = total * out.weight  # (an emission-only side's share: _blend)
        out.emission, out.emission_texture = _emission_mix(sn, ea, a, eb, b)
        if not all(c.alpha == 1.0 and c.alpha_texture is None for c in (a, b)):
            tint = _summed_transparency(a, b, ea, eb, out)
            if tint is None:
                self._warn(f"material '{self._mat.name}': "
                           f"{node.type.replace('_', ' ').title()} '{node.name}' of surfaces "
                           "with a transparent share, an alpha texture on one and another "
                           "colour or closure weight on the other: the surfaces add up, "
                           "their transparent shares are averaged")
            elif out.alpha_texture is not None and np.any(tint > 1.0):
                # An alpha texture lowers alpha per hit and the engine keeps such a tint
                # within 1 (Material: (1 - alpha) x tint must not pass 1 at any hit);
                # clamped here, warned as what it is (not as energy the scene creates).
                out.transparent_tint = np.minimum(tint, 1.0)
                self._warn(f"material '{self._mat.name}': "
                           f"{node.type.replace('_', ' ').title()} '{node.name}' of surfaces "
                           "with a transparent share and an alpha texture: their summed "
                           "transparent colour is kept within 1 (less light passes than "
                           "in Cycles)")
            else:
                out.transparent_tint = tint
        return out

    # Lobe parameters that a per-hit Mix Shader factor blends linearly.
    LINEAR_SCALARS = ("metallic", "specular", "transmission", "specular_ior_level",
                      "coat_weight", "coat_roughness", "sheen_weight", "sheen_roughness")

    # Parameters a blend holds at one value per material (the lead side's, or a constant
    # mix) that a pick takes from its side per hit (engine scene.SCALAR_INPUTS), each
    # cleaned as convert() cleans the material's constant.
    PICKED_SCALARS = {"ior": lambda x: x if x > 0 else 1.5,
                      "coat_ior": lambda x: max(x, 1.0),
                      "multiscatter": float,
                      "anisotropic": lambda x: min(max(x, -1.0), 1.0),
                      "anisotropic_rotation": float}
    PICKED_COLOURS = _COLOUR_SCALARS

    @staticmethod
    def _opaque(c: Closure) -> bool:
        return (c.has_bsdf and c.alpha == 1.0 and c.alpha_texture is None
                and not np.any(c.emission > 0))

    @staticmethod
    def _blend_inexact(a: Closure, b: Closure) -> bool:
        """Whether blending two opaque Principled-model surfaces' parameters is not their
        weighted sum: the lobes are linear in the metallic, specular, transmission, coat
        and sheen weights for one colour, and linear in the colour for one set of weights
        (no transmission: its tint is sqrt(colour)), but not in both at once, nor in the
        roughness. Exact (False): equal colours, or equal lobe weights without
        transmission; and, where both sides have a glossy lobe, equal roughness; or a
        Diffuse and a Glossy side (the glossy colour model keeps both colours)."""
        # The colour model of their blend (_blend: the side with more glossy / glass
        # weight leads), found without building the blend: a side's texture-driven
        # scalars would need engine nodes for that.
        if a.translucent > 0 or b.translucent > 0:
            # _blend keeps a Translucent BSDF's share and colour apart (exact when one
            # side is wholly translucent); translucency is not picked per hit.
            return False
        if (getattr(a, "subsurface", None) is None) != (getattr(b, "subsurface", None) is None):
            # Only a pick keeps the one subsurface side's walk (_picked_walk).
            return True
        ga = a.metallic + a.transmission + a.specular
        gb = b.metallic + b.transmission + b.specular
        lead = _lead(a, b, ga, gb).node
        if lead != "principled":
            # A Glossy / Glass BSDF leads: exact beside a side without a glossy lobe (a
            # Diffuse BSDF) or one of the same roughness; a Principled layer of another
            # roughness would take the blended roughness (Glossy 0.1 + Principled 0.6:
            # highlight blocks 0.91-1.41 of Cycles). The Glossy BSDF's model keeps the two
            # colours in their own lobes (glossy_color); a Glass BSDF's tints its lobes
            # by the one base colour a blend averages (Glass + blue Diffuse: 4.8 / 1.6 /
            # 0.85 x Cycles).
            colours = lead == "glossy" or (a.texture is None and b.texture is None
                                           and np.allclose(a.base_color, b.base_color))
            if ga == 0 or gb == 0:
                # A sheen or coat side would become a layer over the glossy lobe, dimming
                # it by its albedo (Glossy + Sheen BSDF 0.975 x Cycles).
                layered = any(_closure_value(c, k) != 0 if not hasattr(
                    _closure_value(c, k), "evaluate") else True
                    for c in (a, b) for k in ("sheen_weight", "coat_weight"))
                return layered or not colours
            ra, rb = _closure_value(a, "roughness"), _closure_value(b, "roughness")
            return (hasattr(ra, "evaluate") or hasattr(rb, "evaluate") or ra != rb
                    or not colours or not MaterialConverter._same_layers(a, b, ga, gb))

        lobes = [(_closure_value(a, n), _closure_value(b, n))
                 for n in MaterialConverter.LINEAR_SCALARS]
        same_lobes = (all(not hasattr(x, "evaluate") and not hasattr(y, "evaluate")
                          and x == y for x, y in lobes)
                      and a.transmission == 0.0 and b.transmission == 0.0)
        same = same_lobes or (a.texture is None and b.texture is None
                              and np.allclose(a.base_color, b.base_color))
        ka = a.metallic + a.transmission + a.specular
        kb = b.metallic + b.transmission + b.specular
        ra, rb = _closure_value(a, "roughness"), _closure_value(b, "roughness")
        same_rough = (ka == 0 or kb == 0 or (not hasattr(ra, "evaluate")
                                             and not hasattr(rb, "evaluate") and ra == rb))
        return not (same and same_rough and MaterialConverter._same_layers(a, b, ka, kb))

    @staticmethod
    def _same_layers(a: Closure, b: Closure, ka, kb) -> bool:
        """Whether the parameters a blend keeps at one value per material agree where
        they matter: the IOR, distribution and anisotropy where both sides have a glossy
        lobe (with one, the blend takes its side's); the specular, coat and sheen tints and
        the coat's IOR where either side has that lobe (the other's default would dilute
        them)."""
        def equal(name):
            x, y = _closure_value(a, name), _closure_value(b, name)
            if hasattr(x, "evaluate") or hasattr(y, "evaluate"):
                return x is y
            return bool(np.allclose(x, y, rtol=0.0, atol=0.0))

        def has(name):
            return any(hasattr(_closure_value(c, name), "evaluate")
                       or _closure_value(c, name) > 0 for c in (a, b))
        names = []
        if ka > 0 and kb > 0:
            names += ["ior", "multiscatter", "anisotropic", "anisotropic_rotation"]
        if ka > 0 or kb > 0:
            names.append("specular_tint")
        if has("coat_weight"):
            names += ["coat_ior", "coat_tint"]
        if has("sheen_weight"):
            names.append("sheen_tint")
        return all(equal(n) for n in names)

    def _mix_per_hit(self, a: Closure, b: Closure, fac, node=None):
        """Mix Shader of two opaque surfaces by a factor f (per hit: a texture, Layer
        Weight, Fresnel; or a constant): Cycles weights the closures (1 - f) and f (f
        clamped to [0, 1]). Where the parameters blend linearly (_blend_inexact False:
        one colour, or one set of lobe weights; a Diffuse and a Glossy side) they blend
        per hit with those weights (metallic, specular, transmission, ... as
        (1 - f) x_a + f x_b,
        roughness weighted by each side's glossy share). Otherwise (a blue dielectric and
        a gold metal) each hit takes one of the two surfaces whole, the second with
        probability f (engine.shadernodes.ClosurePick, Cycles' closure sampling): every
        lobe parameter, the IOR, distribution, anisotropy, specular / coat / sheen tints
        and the colour come from that side, so the mean over hits is the weighted sum of
        the two BSDFs for camera rays and photons alike, the closure model (Principled,
        Glossy, Glass or Refraction BSDF) included since s42. Still one per material: the
        normal map and the tangent. None when a side is emissive or not opaque (those keep the factor's
        own value)."""
        if not (self._opaque(a) and self._opaque(b)):
            return None
        sn = self.pm.shadernodes
        pick = self._blend_inexact(a, b)
        # (Each pick its own random number: salted by the material and the node.)
        salt = zlib.crc32(f"{getattr(self._mat, 'name', '')}/"
                          f"{getattr(node, 'name', '')}".encode()) + 1
        f = sn.ClosurePick(fac, salt) if pick else sn.Math("MULTIPLY", fac, 1.0, clamp=True)
        g = sn.Math("SUBTRACT", 1.0, f)
        out = _blend(a, b, 0.5, 0.5, sn)
        out.scalars = {}

        def per_hit(xa, xb):
            """(1 - f) xa + f xb, or the constant when both sides agree."""
            if not hasattr(xa, "evaluate") and not hasattr(xb, "evaluate") and xa == xb:
                return xa
            return sn.Math("ADD", sn.Math("MULTIPLY", g, xa), sn.Math("MULTIPLY", f, xb))
        for name in self.LINEAR_SCALARS:
            val = per_hit(_closure_value(a, name), _closure_value(b, name))
            if hasattr(val, "evaluate"):
                out.scalars[name] = val
            else:
                setattr(out, name, val)
        # Roughness belongs to the glossy lobes: a side without one has no say.
        ka = a.metallic + a.transmission + a.specular
        kb = b.metallic + b.transmission + b.specular
        ra, rb = _closure_value(a, "roughness"), _closure_value(b, "roughness")
        if pick:
            rough = per_hit(ra, rb)  # the picked side's, whole
        elif ka > 0 and kb > 0:
            rough = sn.Math("DIVIDE", per_hit(sn.Math("MULTIPLY", ra, ka),
                                              sn.Math("MULTIPLY", rb, kb)),
                            per_hit(ka, kb))
        else:
            rough = ra if ka > 0 else rb
        if hasattr(rough, "evaluate"):
            out.scalars["roughness"] = rough
        else:
            out.roughness = float(rough)
        if pick:
            # The rest of the picked side whole too: its IOR, distribution, anisotropy
            # and tints (the blend's one value per material, e.g. IOR 1.95 of 1.5 and
            # 2.4, would stand everywhere).
            def clean(c, name, fix):
                x = _closure_value(c, name)
                return x if hasattr(x, "evaluate") else fix(x)
            for name, fix in self.PICKED_SCALARS.items():
                val = per_hit(clean(a, name, fix), clean(b, name, fix))
                if hasattr(val, "evaluate"):
                    out.scalars[name] = val
            for name in self.PICKED_COLOURS:
                ca = clean(a, name, lambda x: np.clip(x, 0.0, None))
                cb = clean(b, name, lambda x: np.clip(x, 0.0, None))
                if hasattr(ca, "evaluate") or hasattr(cb, "evaluate") or not np.array_equal(ca, cb):
                    out.scalars[name] = sn.MixColor(f, ca, cb)
            if a.node != b.node or "node" in a.scalars or "node" in b.scalars:
                # The picked side's closure model too (its metal lobe's colour and
                # Fresnel, a Glass BSDF's tinted reflection, a Refraction BSDF's missing
                # one): one model per material rendered rough Glass + Refraction 1.6-1.9 x
                # Cycles, a metal + Refraction 1.03-1.08 x.
                def model(c):  # a nested pick's per-hit model, else the side's own
                    x = c.scalars.get("node")
                    return x if x is not None else float(self.pm.geometry.node_code(c.node))
                out.scalars["node"] = per_hit(model(a), model(b))
            # The material's constant row enables the tangents where either side is
            # anisotropic (anisotropy.anisotropic_materials).
            xa, xb = a.anisotropic, b.anisotropic
            out.anisotropic = xa if abs(xa) >= abs(xb) else xb
            if "node" in out.scalars and out.anisotropic < 0:
                # A Glossy BSDF's negative anisotropy under a Principled row: the
                # constant only enables the tangents (a > 0 for Principled's), the hits
                # read their own value (review42).
                out.scalars["anisotropic"] = sn.Math(
                    "ADD", sn.Math("MULTIPLY", g, xa), sn.Math("MULTIPLY", f, xb))
                out.anisotropic = abs(out.anisotropic)
            self._warn_per_material(a, b, node)

        def colour(c):
            if c.texture is None:
                return c.base_color
            return sn.MixColor(1.0, c.texture, c.base_color, "MULTIPLY")
        one_glossy = out.node == "glossy" and (a.metallic > 0) != (b.metallic > 0)
        same = (a.texture is None and b.texture is None
                and np.allclose(a.base_color, b.base_color))
        if not one_glossy and not same:
            # The colour per hit (the Glossy BSDF colour model keeps each side's colour in
            # its own lobe when one side is the glossy one: nothing to mix there).
            out.base_color = np.ones(3)
            out.texture = sn.MixColor(f, colour(a), colour(b))
            if out.node == "glossy":
                # Both sides' glossy lobes: the picked colour (the base), not _blend's
                # constant glossy_color (two Glossy BSDFs: 0.84 / 1.04 / 1.33 x Cycles).
                out.glossy_color = None
        ssa, ssb = getattr(a, "subsurface", None), getattr(b, "subsurface", None)
        if pick and (ssa is None) != (ssb is None):
            out.subsurface = self._picked_walk(a, b, ssa, ssb, f, colour)
        return out

    def _note_subsurface_mix(self, a: Closure, b: Closure, node):
        """Record a Mix / Add Shader with a subsurface side: a pick keeps the walk of its
        one subsurface side (_picked_walk); whatever else the shader makes carries none,
        warned once the surface is known (_material_closure)."""
        if getattr(a, "subsurface", None) is not None \
                or getattr(b, "subsurface", None) is not None:
            self._subsurface_mixes = [*getattr(self, "_subsurface_mixes", ()), node.name]

    def _picked_walk(self, a: Closure, b: Closure, ssa, ssb, f, colour):
        """The walk of a pick's one subsurface side (engine/subsurfacewalk.py): its
        weight where a hit takes that side, 0 where it takes the other; the colour the
        walk entry compares with the hit's base (SubsurfaceWalks.entries): the side's
        own Base Color there, the other side's colour elsewhere (whose diffuse closure
        is then left as it is). A Mix Shader of a skin and a Glossy BSDF walked nowhere
        before s42 (the diffuse stand-in, warned)."""
        from dataclasses import replace
        sn = self.pm.shadernodes
        ss = ssa if ssa is not None else ssb
        other = b if ssa is not None else a
        w = ss.weight if ss.weight_node is None else ss.weight_node
        c = np.asarray(ss.color, np.float64) if ss.color_node is None else ss.color_node
        if ssa is not None:
            weight = sn.Math("MULTIPLY", sn.Math("SUBTRACT", 1.0, f), w)
            color = sn.MixColor(f, c, colour(other))
        else:
            weight = sn.Math("MULTIPLY", f, w)
            color = sn.MixColor(f, colour(other), c)
        return replace(ss, weight_node=weight, color_node=color)

    def _warn_per_material(self, a: Closure, b: Closure, node):
        """Warn where a picked Mix / Add Shader's sides differ in what stays one per
        material: the shading normal (a Normal Map / Bump is evaluated per material, before
        the closure rows, engine.bsdf.surface_hit). (The closure model, `node`, is picked
        per hit since s42.)"""
        who = (f"{node.type.replace('_', ' ').title()} '{node.name}'" if node is not None
               else "a Mix Shader")
        if a.normal_map is not b.normal_map:
            self._warn(f"material '{self._mat.name}': {who} picks one of two surfaces per "
                       "hit, but their 'Normal' inputs differ: one shading normal per "
                       "material is used for both (the first side's that has one)")

    def _normal(self, node):
        """engine NormalMap for a BSDF's 'Normal' input (a Normal Map node fed by an
        image, a procedural texture or any colour the tree evaluates), or None (the surface's own normal) after warning what is not
        supported."""
        s = node.inputs.get("Normal")
        src = self._source(s) if s is not None else None
        if src is None:
            return None
        n, _ = src
        if n.type == "BUMP":
            return self._bump(n)
        if n.type == "BEVEL":
            return self._bevel(n)
        if n.type != "NORMAL_MAP":
            self._warn(f"material '{self._mat.name}': 'Normal' input of node '{node.name}' "
                       f"is driven by node '{n.name}' ({n.type}), which is not supported; "
                       "using the surface normal")
            return None
        space = str(getattr(n, "space", "TANGENT"))
        if space not in ("TANGENT", "WORLD"):
            self._warn(f"material '{self._mat.name}': Normal Map '{n.name}' space '{space}' "
                       "is not supported; using the surface normal")
            return None
        # A named UV map: its tangents (addon/export.py named_tangent_maps); the image
        # is placed by its own Vector input (a UV Map node naming the map, usually).
        uv_map = str(getattr(n, "uv_map", "") or "") if space == "TANGENT" else ""
        if self._source(n.inputs["Color"]) is None:
            return None  # the default colour (0.5, 0.5, 1) is the unperturbed normal
        # Any colour the tree makes (an image through its own Vector and projection, a
        # procedural texture, a Mix / Combine Color of them; a value reads as grey, as
        # Cycles converts it): evaluated per hit like a BSDF's colour. What cannot be
        # evaluated is warned by _input and gives the socket's own value.
        tex = self._input(n, n.inputs["Color"], 0)
        if not hasattr(tex, "evaluate"):
            c = np.broadcast_to(np.asarray(tex, np.float64).ravel()[:3], (3,))
            if np.allclose(c, (0.5, 0.5, 1.0)):
                return None  # the unperturbed normal
            tex = c  # a constant colour tilts every normal alike
        strength = self._float(n, "Strength", 1.0)
        if uv_map:
            self.normal_map_uvs[self._mat.name] = uv_map
        try:
            return self.pm.NormalMap(tex, strength=strength, space=space, uv_map=uv_map)
        except ValueError as exc:
            self._warn(f"material '{self._mat.name}': Normal Map '{n.name}': {exc}")
            return None

    def _bevel(self, n):
        """engine Bevel for a Bevel node (engine/bevel.py: rays around each hit, Radius per
        hit, Samples), offsetting the normal of a Normal Map / Bump on its Normal input."""
        inner = self._normal(n)  # (its own 'Normal' input: None when unlinked)
        return self.pm.bevel.Bevel(self._input(n, n.inputs["Radius"], 0),
                                   samples=int(getattr(n, "samples", 4)), normal=inner)

    def _bump(self, n):
        """engine Bump for a Bump node (its Height evaluated per hit), or None."""
        if n.inputs.get("Normal") is not None and self._source(n.inputs["Normal"]):
            self._warn(f"material '{self._mat.name}': the 'Normal' input of Bump '{n.name}' "
                       "(a chained normal) is not supported; bumping the surface normal")
        height = self._input(n, n.inputs["Height"], 0)
        if not hasattr(height, "evaluate"):
            return None  # a constant height: no bump
        try:
            # Filter Width (Blender 4.5+; 0.1 where the node has none): the
            # share of the ray's footprint the height's differences span (engine/bump.py).
            return self.pm.Bump(height, strength=self._float(n, "Strength", 1.0),
                                distance=self._float(n, "Distance", 1.0),
                                invert=bool(getattr(n, "invert", False)),
                                filter_width=self._float(n, "Filter Width", 0.1))
        except ValueError as exc:
            self._warn(f"material '{self._mat.name}': Bump '{n.name}': {exc}")
            return None

    def _factor_input(self, node, name, default=1.0):
        """(constant, node or None) for a factor input such as Principled Alpha: a linked
        texture or node tree is evaluated per hit (constant 1, the node returned);
        otherwise its value."""
        s = node.inputs.get(name)
        if s is None:
            return float(default), None
        val = self._input(node, s, 0)
        if hasattr(val, "evaluate"):
            return 1.0, val
        return (float(val) if np.ndim(val) == 0 else float(np.mean(val))), None

    def _scalar(self, node, name, default, field, texture_inputs) -> float:
        """A scalar BSDF input (Roughness, Metallic, ...): its constant; when a texture or
        node tree drives it, that engine node goes into texture_inputs[field] (evaluated
        per hit: engine Material.scalar_textures) and the socket's own value is returned
        as the fallback."""
        s = node.inputs.get(name)
        if s is None:
            return float(default)
        val = self._input(node, s, 0)
        if hasattr(val, "evaluate"):
            texture_inputs[field] = val
            val = self._default(s)
        return float(val) if np.ndim(val) == 0 else float(np.mean(val))

    def _float(self, node, name, default=0.0) -> float:
        s = node.inputs.get(name)
        if s is None:
            return float(default)
        return self._float_socket(node, s, default)

    def _float_socket(self, node, socket, default) -> float:
        """A lobe parameter that must be one constant: its own value, or what a node tree
        of constants feeding it evaluates to (Value, Map Range, Blackbody of constants);
        a per-hit or unsupported node is warned and the socket's own value used."""
        try:
            v = socket.default_value
            own = float(v if np.ndim(v) == 0 else np.mean(tuple(v)[:3]))
        except (AttributeError, TypeError):
            own = float(default)
        src = self._source(socket)
        if src is not None:
            n, out = src
            if n.type == "VALUE":
                return float(out.default_value)
            val = self._node_output(n, out, 1)
            if val is not None and not hasattr(val, "evaluate"):
                if np.ndim(val) == 0:
                    return float(val)
                # Cycles' conversion: a vector's average, a colour's luminance
                return (float(np.mean(val)) if getattr(out, "type", "") == "VECTOR"
                        else float(np.asarray(val, np.float64)[:3]
                                   @ np.array([0.2126, 0.7152, 0.0722])))
            why = ("is not supported here" if val is None else
                   "varies over the surface, but this input takes one value per material")
            self._warn(f"material '{self._mat.name}': {socket.name} of '{node.name}': node "
                       f"'{n.name}' ({n.type}) {why}; using {_value_text(own)}, the "
                       "value typed in the socket (hidden while it is linked)")
        return own

    def _const_color(self, node, name, default):
        """A colour input that must be constant (a lobe parameter, not a texture): its
        value, or `default` with a warning when a texture drives it."""
        rgb, tex = self._color(node, name)
        if tex is not None:
            self._warn(f"material '{self._mat.name}': texture on '{name}' of node "
                       f"'{node.name}' is not supported; using {tuple(default)}")
            return np.asarray(default, np.float64)
        return rgb

    def _distribution(self, node) -> bool:
        """True for Multiscatter GGX (energy-compensated), False for GGX; Beckmann and
        Ashikhmin-Shirley are rendered as GGX, with a warning."""
        dist = getattr(node, "distribution", "MULTI_GGX")
        if dist in ("BECKMANN", "ASHIKHMIN_SHIRLEY"):
            self._warn(f"material '{self._mat.name}': {dist} distribution of node "
                       f"'{node.name}' is rendered as GGX")
        return dist == "MULTI_GGX"

    def _color(self, node, name):
        """(rgb, colour source or None) for a colour input: a constant colour, or ones and
        an engine node evaluated per hit (engine/shadernodes.py)."""
        s = node.inputs.get(name)
        if s is None:
            return np.array([0.8, 0.8, 0.8]), None
        val = self._input(node, s, 0)
        if hasattr(val, "evaluate"):
            return np.ones(3), val
        arr = np.asarray(val, dtype=np.float64)
        return (np.full(3, float(arr)) if arr.ndim == 0 else arr[:3]), None

    @staticmethod
    def _default(socket):
        """A socket's own value: float, or an RGB / XYZ array."""
        try:
            v = socket.default_value
        except AttributeError:
            return 0.0
        if np.ndim(v) == 0:
            return float(v)
        return np.asarray(tuple(v)[:3], dtype=np.float64)

    def _input(self, node, socket, depth):
        """What feeds an input socket: an engine node, or a constant (its own value when
        unlinked, or when the feeding node cannot be evaluated: warned once, naming the
        material and the node)."""
        src = self._source(socket)
        if src is None:
            return self._default(socket)
        n, out = src
        if depth > MAX_NODE_DEPTH:
            self._warn(f"material '{self._mat.name}': node tree too deep at node '{n.name}'")
            return self._default(socket)
        if getattr(n, "mute", False) and n.type not in ("GROUP", "REROUTE"):
            # A muted node passes the input its internal link joins to this output (as
            # Cycles' blender/shader.cpp: a proxy per internal link); an output without
            # one leaves the socket unlinked: its own value (newuser41: a muted
            # Hue/Saturation read as "not supported", the ball red instead of blue).
            via = next((link.from_socket for link in getattr(n, "internal_links", ())
                        if link.to_socket.identifier == out.identifier), None)
            if via is None or self._source(via) is None:
                # (Cycles' remove_proxy_nodes: a proxy whose input is unlinked is dropped
                # with its links, so a value typed into the muted node is not passed on:
                # newuser41b, a muted Mix's typed yellow read grey in Cycles)
                return self._default(socket)
            val = self._input(n, via, depth + 1)
            if getattr(via, "type", "") == "VECTOR" and getattr(socket, "type", "") == "VALUE":
                return self._vector_to_value(val)
            return val
        val = self._node_output(n, out, depth + 1)
        if val is None:
            own = self._default(socket)
            self._warn(f"material '{self._mat.name}': {socket.name} of '{node.name}': node "
                       f"'{n.name}' ({n.type}) not supported, using {_value_text(own)} (the "
                       "socket's own value)")
            return own
        if getattr(out, "type", "") == "VECTOR" and getattr(socket, "type", "") == "VALUE":
            return self._vector_to_value(val)
        return val

    def _vector_to_value(self, val):
        """A vector into a value socket: the average of its components, as Cycles'
        ConvertNode (svm/convert.h NODE_CONVERT_VF: average(f); a colour takes its
        luminance instead, NODE_CONVERT_CF, which the engine's nodes do by default)."""
        if hasattr(val, "evaluate"):
            return self.pm.shadernodes.VectorMath("DOT_PRODUCT", val, np.full(3, 1.0 / 3.0),
                                                  output="VALUE")
        return float(np.mean(np.broadcast_to(np.asarray(val, np.float64), (3,))))

    def _vector(self, node, name, depth):
        """A Vector input; None when unlinked (the node's default coordinates)."""
        s = node.inputs.get(name)
        if s is None or self._source(s) is None:
            return None
        return self._input(node, s, depth)

    def _texture_vector(self, n, depth):
        """A texture node's Vector input, or Generated coordinates when it is unlinked
        (Cycles: the texture nodes' Vector sockets are LINK_TEXTURE_GENERATED,
        scene/shader_nodes.cpp)."""
        vec = self._vector(n, "Vector", depth)
        return self._coordinates("generated") if vec is None else vec

    def _curves(self, n, depth):
        """RGB Curves / Vector Curves / Float Curve baked as Cycles bakes them
        (blender/util.h curvemapping_color_to_array, curvemapping_float_to_array): the
        curves evaluated by Blender at RAMP_TABLE_SIZE + 1 steps over the range of their
        points (RGB: each of R, G, B applied to the combined curve C; Vector: X, Y, Z
        each alone), read by the kernel's table lookup (svm_node_curves: the vector's
        components as a colour's)."""
        sn = self.pm.shadernodes
        m = n.mapping
        m.initialize()
        m.update()
        rgb = n.type == "CURVE_RGB"
        vector = n.type == "CURVE_VEC"
        curves = list(m.curves)[:4 if rgb else 3 if vector else 1]
        lo = min(c.points[0].location[0] for c in curves)
        hi = max(c.points[-1].location[0] for c in curves)
        xs = [lo + i / RAMP_TABLE_SIZE * (hi - lo) for i in range(RAMP_TABLE_SIZE + 1)]
        extrapolate = m.extend == "EXTRAPOLATED"
        fac_in = n.inputs.get("Fac") or n.inputs.get("Factor") or n.inputs[0]
        fac = self._input(n, fac_in, depth)
        if vector:
            table = [[m.evaluate(ch, x) for ch in curves] for x in xs]
            vec = self._input(n, n.inputs["Vector"], depth)
            return _fold(sn.RGBCurves(fac, vec, table, lo, hi, extrapolate), [fac, vec])
        if rgb:
            r, g, b, c = curves
            table = [[m.evaluate(ch, m.evaluate(c, x)) for ch in (r, g, b)] for x in xs]
            col = self._input(n, n.inputs["Color"], depth)
            return _fold(sn.RGBCurves(fac, col, table, lo, hi, extrapolate), [fac, col])
        table = [m.evaluate(curves[0], x) for x in xs]
        val = self._input(n, n.inputs["Value"], depth)
        return _fold(sn.FloatCurve(fac, val, table, lo, hi, extrapolate), [fac, val])

    def _node_output(self, n, out, depth):
        """Engine node (or constant) for output `out` of Blender node n; None = not
        supported. Evaluated per hit in engine/shadernodes.py (numpy over hits)."""
        sn = self.pm.shadernodes
        t = n.type
        oname = out.name
        if getattr(n, "mute", False):
            return None
        if t == "RGB":
            return np.asarray(tuple(out.default_value)[:3], dtype=np.float64)
        if t == "VALUE":
            return float(out.default_value)
        if t == "LIGHT_PATH":  # a constant per ray class (addon/lightpath.py)
            return lightpath.output_value(self, n, oname)
        if t == "VOLUME_INFO":
            # Volume Info: the grids "color", "density", "flame", "temperature" of a
            # volume object (Cycles' standard volume attributes); 0 elsewhere
            grid, kind = {"Color": ("color", "COLOR"), "Density": ("density", "FAC"),
                          "Flame": ("flame", "FAC"),
                          "Temperature": ("temperature", "FAC")}.get(oname, (None, None))
            if grid is None or not self._volume_object:
                return np.zeros(3) if oname == "Color" else 0.0
            return self._grid(grid, kind, 0.0)
        if t == "VERTEX_COLOR":  # the Color Attribute node
            name = str(getattr(n, "layer_name", ""))
            if oname == "Color" and not name:
                return self.pm.ColorAttribute("")  # the render colour attribute
            if oname == "Alpha":  # 0 where the mesh lacks it (svm_node_vertex_color)
                return self.pm.shadernodes.SeparateChannel(
                    self._coordinates(f"attr:{name}.alpha"), 0)
            # (a name here is a mesh attribute's, never Cycles' standard one:
            # VertexColorNode::attributes adds it as it is)
            return self._attribute(name, "Color", standard=False)
        if t == "HAIR_INFO":
            # Curves Info: per corner on hair (addon/export.py extract_hair_geometry:
            # 'curves_info' = Intercept, Length, Random; 'curves_info2' = Thickness, Is
            # Strand); meshes lack them and read 0, as Cycles' svm_node_hair_info there.
            where = {"Intercept": ("curves_info", 0), "Length": ("curves_info", 1),
                     "Random": ("curves_info", 2), "Thickness": ("curves_info2", 0),
                     "Is Strand": ("curves_info2", 1)}.get(oname)
            if where is None:
                self._warn(f"material '{self._mat.name}': output '{oname}' of Curves Info "
                           f"'{n.name}' is not supported; reads 0")
                return np.zeros(3)
            return sn.SeparateChannel(self._coordinates(f"attr:{where[0]}"), where[1])
        if t == "POINT_INFO":
            # Point Info: per corner on point clouds (addon/export.py
            # extract_pointcloud_geometry: 'point_position' the point's centre, in world
            # space; 'point_info' = Radius, Random); elsewhere 0, as Cycles'
            # svm_node_point_info off a point.
            if oname == "Position":
                return self._coordinates("attr:point_position")
            where = {"Radius": 0, "Random": 1}.get(oname)
            if where is None:
                self._warn(f"material '{self._mat.name}': output '{oname}' of Point Info "
                           f"'{n.name}' is not supported; reads 0")
                return np.zeros(3)
            return sn.SeparateChannel(self._coordinates("attr:point_info"), where)
        if t == "ATTRIBUTE":
            kind = getattr(n, "attribute_type", "GEOMETRY")
            if kind in ("OBJECT", "INSTANCER"):
                # Per object (addon/export.py object_attribute): the names export reads
                name = str(n.attribute_name)
                self.object_attribute_names.add((name, kind == "INSTANCER"))
                return sn.ObjectAttribute(
                    object_attribute_key(name, kind == "INSTANCER"),
                    {"Alpha": "ALPHA", "Fac": "FAC", "Factor": "FAC"}.get(oname, "COLOR"))
            if kind == "VIEW_LAYER" and self.view_layer is not None:
                # One constant per render (addon/export.py view_layer_attribute)
                from .export import view_layer_attribute
                rgba = np.asarray(view_layer_attribute(*self.view_layer,
                                                       str(n.attribute_name)), np.float64)
                if oname == "Alpha":
                    return float(rgba[3])
                return float(rgba[:3].mean()) if oname in ("Fac", "Factor") else rgba[:3]
            if kind != "GEOMETRY":
                self._warn(f"material '{self._mat.name}': Attribute '{n.name}' of type "
                           f"{kind} is not supported (Geometry, Object, Instancer, View Layer "
                           "are)")
                return None
            return self._attribute(str(n.attribute_name), oname)
        if t == "TEX_IMAGE":
            tex = self._image(n)
            if tex is None:
                return None
            if n.outputs["Alpha"].is_linked and getattr(tex, "associated", False):
                tex = self._unassociated(n, tex)
            vec = self._vector(n, "Vector", depth)
            projection = getattr(n, "projection", "FLAT")
            output = "ALPHA" if oname == "Alpha" else "COLOR"
            if projection == "BOX":
                normal = sn.ObjectNormal(self._coordinates("normal"))
                return sn.BoxLookup(tex, vec, normal, getattr(n, "projection_blend", 0.0),
                                    output=output)
            if vec is None and oname == "Color" and projection == "FLAT":
                return tex  # UVs of the active render map
            return sn.ImageLookup(tex, vec, output=output, projection=projection)
        if t == "TEX_COORD":
            if oname == "UV":
                return sn.UVCoord()
            if oname == "Normal":
                return sn.ObjectNormal(self._coordinates("normal"))
            if oname in ("Generated", "Object"):
                other = getattr(n, "object", None)
                if other is not None and oname == "Object":
                    # Cycles' ob_itfm: world positions into that object's space (its
                    # matrix when the material is converted)
                    matrix = np.array(other.matrix_world, np.float64)
                    try:
                        return sn.ObjectSpacePosition(np.linalg.inv(matrix))
                    except np.linalg.LinAlgError:
                        self._warn(f"material '{self._mat.name}': Texture Coordinate "
                                   f"'{n.name}' relative to object '{other.name}', whose "
                                   "matrix is singular: read in the mesh's own space")
                return self._coordinates(oname.lower())
            if oname in ("Camera", "Window", "Reflection"):
                return sn.ViewCoordinates(oname.upper())
            self._warn(f"material '{self._mat.name}': Texture Coordinate '{n.name}' output "
                       f"'{oname}' is not supported (UV, Generated, Object, Normal, Camera, "
                       "Window, Reflection are)")
            return None
        if t == "UVMAP":
            name = str(getattr(n, "uv_map", "") or "")
            if name:
                # A named map: the mesh attribute of that name (Cycles' UVMapNode asks
                # for it by name; a mesh without it reads 0)
                return self._attribute(name, "Vector", standard=False)
            return sn.UVCoord()
        if t == "MAPPING":
            vec = self._input(n, n.inputs["Vector"], depth)  # unlinked: its own value
            consts = []
            for k in ("Location", "Rotation", "Scale"):
                sock = n.inputs.get(k)
                if sock is None:
                    consts.append((0, 0, 0) if k != "Scale" else (1, 1, 1))
                    continue
                if sock.is_linked:
                    self._warn(f"material '{self._mat.name}': linked '{k}' of Mapping "
                               f"'{n.name}' is not supported; using "
                               f"{_value_text(self._default(sock))} (the socket's own value)")
                consts.append(self._default(sock))
            return sn.Mapping(vec, *consts, kind=getattr(n, "vector_type", "POINT"))
        if t == "MIX" and getattr(n, "data_type", "RGBA") in ("FLOAT", "VECTOR"):
            ins = {i.identifier: i for i in n.inputs}
            vec = n.data_type == "VECTOR"
            uniform = not vec or getattr(n, "factor_mode", "UNIFORM") == "UNIFORM"
            fac = self._input(n, ins["Factor_Float" if uniform else "Factor_Vector"], depth)
            suffix = "_Vector" if vec else "_Float"
            a = self._input(n, ins["A" + suffix], depth)
            b = self._input(n, ins["B" + suffix], depth)
            return _fold(sn.MixValue(fac, a, b, width=3 if vec else 1,
                                     clamp_factor=getattr(n, "clamp_factor", True),
                                     uniform=uniform), [fac, a, b])
        if t == "VECT_MATH":
            if n.operation not in sn.VECTOR_MATH_OPS:
                return None
            ins = [self._input(n, n.inputs[k], depth) for k in range(3)]
            scale = self._input(n, n.inputs[3], depth)  # Scale (named IOR for Refract)
            return _fold(sn.VectorMath(n.operation, *ins, scale=scale,
                                       output="VALUE" if oname == "Value" else "VECTOR"),
                         ins + [scale])
        if t == "MIX":
            if getattr(n, "data_type", "RGBA") != "RGBA":
                return None
            ins = {i.identifier: i for i in n.inputs}
            fac = self._input(n, ins.get("Factor_Float", n.inputs[0]), depth)
            a = self._input(n, ins["A_Color"], depth)
            b = self._input(n, ins["B_Color"], depth)
            return self._mix(n, fac, a, b, n.blend_type, getattr(n, "clamp_factor", True),
                             getattr(n, "clamp_result", False))
        if t == "MIX_RGB":
            fac = self._input(n, n.inputs["Fac"], depth)
            a = self._input(n, n.inputs["Color1"], depth)
            b = self._input(n, n.inputs["Color2"], depth)
            return self._mix(n, fac, a, b, n.blend_type, True, getattr(n, "use_clamp", False))
        if t == "INVERT":
            return sn.Invert(self._input(n, n.inputs["Fac"], depth),
                             self._input(n, n.inputs["Color"], depth))
        if t == "VALTORGB":
            # Baked as Cycles bakes it (blender/util.h colorramp_to_array): Blender's own
            # evaluation at RAMP_TABLE_SIZE + 1 steps, so every interpolation reads alike.
            ramp = n.color_ramp
            table = [tuple(ramp.evaluate(i / RAMP_TABLE_SIZE))
                     for i in range(RAMP_TABLE_SIZE + 1)]
            fac = self._input(n, n.inputs["Fac"], depth)
            return _fold(sn.RampTable(fac, table, interpolate=ramp.interpolation != "CONSTANT",
                                      output="ALPHA" if oname == "Alpha" else "COLOR"), [fac])
        if t in ("CURVE_RGB", "CURVE_FLOAT", "CURVE_VEC"):
            return self._curves(n, depth)
        if t == "NEW_GEOMETRY":  # the Geometry node
            if oname == "Random Per Island":  # (addon/export.py random_per_island)
                return self._attribute("random_per_island", "Factor")
            if oname == "Pointiness":  # per vertex (addon/export.py mesh_pointiness)
                return self._attribute("pointiness", "Factor")
            out_kind = {"Position": "POSITION", "Normal": "NORMAL",
                        "True Normal": "TRUE_NORMAL", "Incoming": "INCOMING",
                        "Backfacing": "BACKFACING"}.get(oname)
            return None if out_kind is None else sn.GeometryInfo(out_kind)
        if t == "OBJECT_INFO":
            if oname == "Material Index":
                # Cycles' shader_pass_id: the pass index of the material whose tree this
                # is, one constant per tree.
                return float(getattr(self._mat, "pass_index", 0) or 0)
            out_kind = {"Random": "RANDOM", "Color": "COLOR", "Alpha": "ALPHA",
                        "Object Index": "OBJECT_INDEX", "Location": "LOCATION"}.get(oname)
            return None if out_kind is None else sn.ObjectInfo(out_kind)
        # (A tree fed only by constants is evaluated once here: _fold.)
        if t == "BRIGHTCONTRAST":
            ins = [self._input(n, n.inputs[k], depth) for k in ("Color", "Bright", "Contrast")]
            return _fold(sn.BrightContrast(*ins), ins)
        if t == "GAMMA":
            ins = [self._input(n, n.inputs[k], depth) for k in ("Color", "Gamma")]
            return _fold(sn.Gamma(*ins), ins)
        if t == "RGBTOBW":
            ins = [self._input(n, n.inputs["Color"], depth)]
            return _fold(sn.ToGray(*ins), ins)
        if t == "CLAMP":
            ins = [self._input(n, n.inputs[k], depth) for k in ("Value", "Min", "Max")]
            return _fold(sn.Clamp(*ins, kind=n.clamp_type), ins)
        if t == "MATH":
            if n.operation not in sn.MATH_OPS:
                return None
            ins = [self._input(n, n.inputs[k], depth) for k in range(3)]
            return _fold(sn.Math(n.operation, ins[0], ins[1], clamp=n.use_clamp, c=ins[2]),
                         ins)
        if t == "MAP_RANGE":
            vector = getattr(n, "data_type", "FLOAT") == "FLOAT_VECTOR"
            if getattr(n, "data_type", "FLOAT") not in ("FLOAT", "FLOAT_VECTOR"):
                return None
            ins = {i.identifier: i for i in n.inputs}
            names = sn.MapRange.VECTOR_SOCKETS if vector else sn.MapRange.SOCKETS
            inputs = {k: self._input(n, ins[k], depth) for k in names if k in ins}
            return _fold(sn.MapRange(inputs, kind=getattr(n, "interpolation_type", "LINEAR"),
                                     clamp=getattr(n, "clamp", True), vector=vector),
                         inputs.values())
        if t == "BLACKBODY":
            kelvin = self._input(n, n.inputs["Temperature"], depth)
            return _fold(sn.Blackbody(kelvin), [kelvin])
        if t in ("SEPARATE_COLOR", "SEPRGB", "SEPXYZ"):
            # (HSV / HSL outputs are named Hue, Saturation, Value / Lightness)
            channel = {"Red": 0, "R": 0, "X": 0, "Hue": 0, "Green": 1, "G": 1, "Y": 1,
                       "Saturation": 1, "Blue": 2, "B": 2, "Z": 2, "Value": 2,
                       "Lightness": 2}.get(oname)
            if channel is None:
                return None
            src = self._input(n, n.inputs[0], depth)
            return _fold(sn.SeparateChannel(src, channel, mode=getattr(n, "mode", "RGB")),
                         [src])
        if t in ("COMBINE_COLOR", "COMBRGB", "COMBXYZ"):
            ins = [self._input(n, n.inputs[i], depth) for i in range(3)]
            return _fold(sn.Combine(*ins, mode=getattr(n, "mode", "RGB")), ins)
        if t == "HUE_SAT":
            i = n.inputs
            return sn.HueSaturation(*(self._input(n, i[k], depth)
                                      for k in ("Hue", "Saturation", "Value", "Fac", "Color")))
        if t == "TEX_GRADIENT":
            vec = self._texture_vector(n, depth)
            return sn.Gradient(vec, n.gradient_type, output="FAC" if oname == "Fac" else "COLOR")
        if t == "TEX_CHECKER":
            vec = self._texture_vector(n, depth)
            return sn.Checker(vec, self._input(n, n.inputs["Color1"], depth),
                              self._input(n, n.inputs["Color2"], depth),
                              self._input(n, n.inputs["Scale"], depth),
                              output="FAC" if oname == "Fac" else "COLOR")
        if t in ("TEX_NOISE", "TEX_VORONOI"):
            return self._procedural(n, oname, depth)
        if t == "TEX_WHITE_NOISE":
            vec = self._texture_vector(n, depth)
            dims = int(str(getattr(n, "noise_dimensions", "3D"))[0])
            w_in = n.inputs.get("W")  # (no W socket by name unless 1D / 4D)
            w = 0.0 if w_in is None else self._input(n, w_in, depth)
            return sn.WhiteNoise(vec, w, dims, output="COLOR" if oname == "Color" else "VALUE")
        if t == "TEX_BRICK":
            vec = self._texture_vector(n, depth)
            inputs = {k: self._input(n, n.inputs[k], depth) for k in sn.Brick.SOCKETS
                      if k in n.inputs}
            return sn.Brick(vec, inputs, offset=n.offset, offset_frequency=n.offset_frequency,
                            squash=n.squash, squash_frequency=n.squash_frequency,
                            output="FAC" if oname in ("Fac", "Factor") else "COLOR")
        if t == "TEX_GABOR":
            vec = self._texture_vector(n, depth)
            # (Both Orientation sockets are named "Orientation": by identifier.)
            ins = {i.identifier: i for i in n.inputs}
            inputs = {k: self._input(n, ins[k], depth) for k in sn.Gabor.SOCKETS
                      if k in ins}
            return sn.Gabor(vec, inputs, dims=3 if n.gabor_type == "3D" else 2,
                            output=oname.upper())
        if t == "TEX_MAGIC":
            vec = self._texture_vector(n, depth)
            return sn.Magic(vec, self._input(n, n.inputs["Scale"], depth),
                            self._input(n, n.inputs["Distortion"], depth),
                            depth=n.turbulence_depth,
                            output="FAC" if oname in ("Fac", "Factor") else "COLOR")
        if t == "TEX_WAVE":
            vec = self._texture_vector(n, depth)
            kind = n.wave_type
            inputs = {k: self._input(n, n.inputs[k], depth) for k in sn.Wave.SOCKETS
                      if k in n.inputs}
            return sn.Wave(vec, inputs, kind=kind,
                           direction=n.bands_direction if kind == "BANDS" else n.rings_direction,
                           profile=n.wave_profile,
                           output="FAC" if oname in ("Fac", "Factor") else "COLOR")
        if t == "AMBIENT_OCCLUSION":
            return self._ambient_occlusion(n, oname, depth)
        if t in ("LAYER_WEIGHT", "FRESNEL"):
            if n.inputs.get("Normal") is not None and self._source(n.inputs["Normal"]):
                self._warn(f"material '{self._mat.name}': the 'Normal' input of "
                           f"'{n.name}' is not supported; using the surface normal")
            if t == "FRESNEL":
                return sn.Fresnel(self._input(n, n.inputs["IOR"], depth))
            return sn.LayerWeight(self._input(n, n.inputs["Blend"], depth),
                                  output="FACING" if oname == "Facing" else "FRESNEL")
        return None

    def _ambient_occlusion(self, n, oname, depth):
        """Ambient Occlusion node (engine/ambientocclusion.py: rays from each hit, Samples,
        Distance, Normal, Inside and Only Local as Cycles' svm_ao; an unlinked Distance of
        0 reads the world's AO distance, as Cycles): output Color (AO x Color) or AO; both
        outputs of one node share its rays."""
        ao = self.pm.ambientocclusion
        core = self._ao_cores.get(n.name)
        if core is None:
            distance = self._input(n, n.inputs["Distance"], depth)
            if not n.inputs["Distance"].is_linked and distance == 0.0:
                # Cycles' NODE_AO_GLOBAL_RADIUS: World > Settings > Ambient Occlusion >
                # Distance (its integrator's ao_distance; 10 m without a world)
                scene = self.view_layer[0] if self.view_layer is not None else None
                world = getattr(scene, "world", None)
                distance = (float(world.light_settings.distance) if world is not None
                            else 10.0)
            core = ao.OcclusionCore(distance,
                                    self._vector(n, "Normal", depth),
                                    samples=int(getattr(n, "samples", 16)),
                                    inside=bool(getattr(n, "inside", False)),
                                    only_local=bool(getattr(n, "only_local", False)))
            self._ao_cores[n.name] = core
        if oname == "AO":
            return core
        return ao.AmbientOcclusion(core, self._input(n, n.inputs["Color"], depth))

    def _procedural(self, n, oname, depth):
        """Noise or Voronoi Texture node: evaluated per hit (engine/procedural.py)."""
        sn = self.pm.shadernodes
        vec = self._texture_vector(n, depth)
        noise = n.type == "TEX_NOISE"
        names = sn.Noise.SOCKETS if noise else sn.Voronoi.SOCKETS
        inputs = {k: self._input(n, n.inputs[k], depth) for k in names if k in n.inputs}
        if noise:
            return sn.Noise(vec, inputs, dims=int(n.noise_dimensions[0]),
                            kind=getattr(n, "noise_type", "FBM"),
                            normalize=getattr(n, "normalize", True),
                            output="FAC" if oname in ("Fac", "Factor") else "COLOR")
        return sn.Voronoi(vec, inputs, dims=int(n.voronoi_dimensions[0]), feature=n.feature,
                          metric=n.distance, normalize=getattr(n, "normalize", False),
                          output=oname.upper())

    def _attribute(self, name, output, standard=True):
        """A mesh attribute by name (addon/export.py named_attributes; "" the render
        colour attribute) at the hits, as Cycles' svm_node_attr: output Color / Vector
        (N,3), Fac (N,) or Alpha (N,); 0 (alpha 1) on meshes without it."""
        sn = self.pm.shadernodes
        fac = output in ("Fac", "Factor")  # (Blender 5 names it Factor)
        if self._volume_object:
            # A volume object's attributes are its grids (0 where it has none, as
            # Cycles' attribute not found)
            return self._grid(name, "FAC" if fac else "ALPHA" if output == "Alpha" else
                              "VECTOR" if output == "Vector" else "COLOR", 0.0)
        if standard and name in CYCLES_STANDARD_ATTRIBUTES:
            if name in _ABSENT_ON_MESHES:
                self._warn(f"material '{self._mat.name}': attribute '{name}' is a Cycles "
                           "standard attribute that meshes lack: reads 0 (as in Cycles)")
                return 1.0 if output == "Alpha" else 0.0 if fac else np.zeros(3)
            if output == "Alpha":
                return 1.0
            if name == "uv":  # the render UV map: Fac is u
                return sn.SeparateChannel(sn.UVCoord(), 0) if fac else sn.UVCoord()
            if name in ("random_per_island", "pointiness"):  # exported by addon/export.py
                return (sn.SeparateChannel(self._coordinates(f"attr:{name}.fac"), 0) if fac
                        else self._coordinates(f"attr:{name}"))
            if name == "generated":  # Fac the average, as for any 3-D vector
                g = self._coordinates("generated")
                return sn.VectorMath("DOT_PRODUCT", g, np.full(3, 1.0 / 3.0),
                                     output="VALUE") if fac else g
            self._warn(f"material '{self._mat.name}': Cycles' standard attribute '{name}' "
                       "is not supported")
            return None
        if fac:
            return sn.SeparateChannel(self._coordinates(f"attr:{name}.fac"), 0)
        if output == "Alpha":
            return sn.Math("SUBTRACT", 1.0, sn.SeparateChannel(
                self._coordinates(f"attr:{name}.transparency"), 0))
        return self._coordinates(f"attr:{name}")

    def _coordinates(self, name):
        self.coordinate_users.add(self._mat.name)
        return self.pm.shadernodes.Coordinates(name)

    def _mix(self, n, fac, a, b, blend, clamp_factor, clamp_result):
        if blend not in self.pm.shadernodes.MIX_BLENDS:
            self._warn(f"material '{self._mat.name}': Mix '{n.name}' blend type '{blend}' "
                       "is not supported; using Mix")
            blend = "MIX"
        return self.pm.shadernodes.MixColor(fac, a, b, blend, clamp_factor, clamp_result)

    def _image(self, node):
        """engine ImageTexture for an Image Texture node (its image, Extension,
        Interpolation, UDIM tiles), or None after a warning."""
        img = node.image
        if img is None:
            self._warn(f"material '{self._mat.name}': image node '{node.name}' has no image; "
                       "it renders magenta, as in Cycles")
            return self._missing_image()
        extension = str(getattr(node, "extension", "REPEAT"))
        interpolation = str(getattr(node, "interpolation", "Linear"))
        key = (img.name, extension, interpolation)
        if key in self.images:
            return self.images[key]
        tex = None
        try:
            srgb = self._stored_as_srgb(img)
            if img.source == "TILED":
                tiles = self._udim_tiles(img)
                pixels = None
            else:
                tiles, pixels = None, _pixels(img)
            if img.is_float:
                # (a TIFF's alpha association is read from each tile's own file)
                for number, px in ([(None, pixels)] if tiles is None else tiles.items()):
                    self._float_texels(img, px, srgb, number)
            associate = cycles_associates_alpha(img)
            premultiplied = img.is_float and cycles_unassociates_alpha(img)
            if str(getattr(img, "alpha_mode", "STRAIGHT")) == "NONE":
                # Cycles ignores the alpha channel (IMAGE_ALPHA_IGNORE: alpha 1).
                for px in ([pixels] if tiles is None else tiles.values()):
                    px[:, :, 3] = 1.0
            tex = self.pm.ImageTexture(pixels, tiles=tiles, extension=extension,
                                       interpolation=interpolation, srgb=srgb,
                                       name=img.name, associate=associate,
                                       premultiplied=premultiplied)
        except Exception as exc:  # noqa: BLE001 - any image failure becomes a warning
            self._warn(f"material '{self._mat.name}': image '{img.name}' in node "
                       f"'{node.name}' could not be read ({exc}); it renders magenta, as "
                       "in Cycles")
            tex = self._missing_image()
        self.images[key] = tex
        return tex

    def _float_texels(self, img, px, srgb, tile=None):
        """In place: a float image's RGB as Blender holds it (`img.pixels`, px HxWx4) ->
        the texels Cycles holds for it (measured: tests/blender/
        test_image_alpha_association_cycles.py).

        Read through Blender (packed, generated: cycles_builtin) Cycles copies Blender's
        float buffer as it is (blender/image.cpp load_float_pixels), linear and, but for
        Non-Color / Channel Packed / None, premultiplied. Read from its file (OIIO) Cycles
        takes the file's values and premultiplies them itself only where the file says
        its alpha is straight (scene/image_oiio.cpp: oiio:UnassociatedAlpha - PNG, a TIFF
        so marked, TGA; not EXR): Image > Alpha Straight / Premultiplied do not change
        what it reads. Blender, though, premultiplied a file it was told is straight
        (IMB premultiply at load) and linearised the straight colour (a float PNG or TIFF
        in sRGB). So: the straight colour P / a, encoded back to the file's sRGB where
        Cycles keeps it so (srgb: cycles_stores_srgb), times a if Blender read the file as
        premultiplied (that is how the file holds it), times a again if Cycles
        premultiplies at load. Where a is 0 Blender's premultiplied buffer is 0 and the
        file's colour there is lost: 0 (Cycles' lookups of the colour alone read the
        file's value there)."""
        encode = _srgb_encoder(self.pm) if srgb else None
        if cycles_builtin(img):
            return  # Blender's buffer, as Cycles copies it (srgb is False for these)
        if not cycles_unassociates_alpha(img):
            # Data, Channel Packed, None: Blender leaves RGB straight, as the file holds it
            if encode is not None:
                px[:, :, :3] = encode(px[:, :, :3])
            return
        a = px[:, :, 3:4]
        seen = a > 0.0
        rgb = np.where(seen, px[:, :, :3] / np.where(seen, a, 1.0), 0.0)
        if encode is not None:
            rgb = encode(rgb)
        if str(getattr(img, "alpha_mode", "STRAIGHT")) == "PREMUL":
            rgb = rgb * a
        if file_alpha_unassociated(img, tile):
            rgb = rgb * a
        px[:, :, :3] = rgb

    def _unassociated(self, node, tex):
        """The texture of an Image Texture node whose Alpha output is linked: Cycles
        divides the filtered colour by the filtered alpha (svm/image.h
        NODE_IMAGE_ALPHA_UNASSOCIATE); the pixels shared with the other lookups."""
        key = (node.image.name, str(getattr(node, "extension", "REPEAT")),
               str(getattr(node, "interpolation", "Linear")), "unassociate")
        if key not in self.images:
            self.images[key] = tex.unassociated()
        return self.images[key]

    def _missing_image(self):
        """The texture Cycles shows for an image it cannot load (or no image): magenta
        (TEX_IMAGE_MISSING_R/G/B 1, 0, 1), alpha 1, everywhere."""
        if "missing" not in self.images:
            self.images["missing"] = self.pm.ImageTexture(
                np.array([[[1.0, 0.0, 1.0, 1.0]]], np.float32), extension="EXTEND",
                interpolation="Closest", srgb=False, name="missing image")
        return self.images["missing"]

    def _stored_as_srgb(self, img) -> bool:
        """True when Cycles keeps the image's texels sRGB-encoded (interpolates those as
        stored and converts after): cycles_stores_srgb; an 8-bit image in a colour space
        other than sRGB and the linear ones warns."""
        srgb = cycles_stores_srgb(img)
        space = img.colorspace_settings.name
        if srgb and not img.is_float and space not in ("sRGB", "sRGB EOTF", "Filmic sRGB",
                                                        "AgX Base sRGB"):
            self._warn(f"material '{self._mat.name}': image '{img.name}' colour space "
                       f"'{space}' is treated as sRGB")
        return srgb

    def _udim_tiles(self, img) -> dict:
        """{tile number: pixels} of a UDIM image, each tile read from its own file
        (Blender's `pixels` holds only the first tile)."""
        tiles = {}
        for t in img.tiles:
            fname = image_file_path(img, t.number)
            if not os.path.isfile(fname):
                self._warn(f"material '{self._mat.name}': UDIM tile {t.number} of image "
                           f"'{img.name}' has no file ({fname}); it renders as missing")
                continue
            one = bpy.data.images.load(fname, check_existing=False)
            try:
                one.colorspace_settings.name = img.colorspace_settings.name
                one.alpha_mode = img.alpha_mode  # how Blender premultiplies it at load
                tiles[t.number] = _pixels(one)
            finally:
                bpy.data.images.remove(one)
        if not tiles:
            raise ValueError("no UDIM tile could be read")
        return tiles


# Colour spaces Cycles reads as stored (scene/colorspace.cpp detect_known_colorspace: an
# identity conversion to scene linear is u_colorspace_raw).
LINEAR_SPACES = ("Non-Color", "Linear Rec.709", "Linear", "Raw", "Linear CIE-XYZ E",
                 "Linear Rec.2020", "Working Space")


def cycles_builtin(img) -> bool:
    """Whether Cycles reads the image through Blender (BlenderImageLoader: packed,
    generated, a movie, or a UDIM image with a generated tile; blender/util.h
    image_is_builtin) rather than from its file (OIIOImageLoader)."""
    if img.source == "TILED" and any(getattr(t, "is_generated_tile", False)
                                     for t in img.tiles):
        return True
    return bool(img.packed_file) or img.source in ("GENERATED", "MOVIE")


def cycles_associates_alpha(img) -> bool:
    """Whether Cycles premultiplies the image's RGB by its alpha at load (associated
    alpha; blender/image.cpp load_byte_pixels, "byte images are always straight for
    Blender"): an 8-bit image (4 channels) whose colour space is not Non-Color and whose
    alpha mode is not Channel Packed or None (scene/image.cpp). Float images are left as
    Blender gives them."""
    if img.is_float or img.channels < 4:
        return False
    if str(getattr(img, "alpha_mode", "STRAIGHT")) in ("CHANNEL_PACKED", "NONE"):
        return False
    return not bool(getattr(img.colorspace_settings, "is_data", False))


def cycles_unassociates_alpha(img) -> bool:
    """Whether Cycles holds the image's RGB premultiplied by its alpha and so divides a
    lookup by the filtered alpha where the Image Texture node's Alpha output is linked
    (scene/shader_nodes.cpp ImageTextureNode::compile NODE_IMAGE_ALPHA_UNASSOCIATE): any
    image (8-bit or float) but a Non-Color one or one of alpha mode Channel Packed or
    None."""
    if str(getattr(img, "alpha_mode", "STRAIGHT")) in ("CHANNEL_PACKED", "NONE"):
        return False
    return not bool(getattr(img.colorspace_settings, "is_data", False))


# File formats whose alpha OpenImageIO reports as straight (oiio:UnassociatedAlpha), or
# which Cycles premultiplies anyway (scene/image_oiio.cpp: TGA, DDS, PSD). TIFF: per file.
STRAIGHT_ALPHA_FORMATS = ("PNG", "TARGA", "TARGA_RAW", "DDS", "PSD")


def image_file_path(img, tile=None) -> str:
    """The absolute path of an image's file; for a UDIM image (source TILED) the file of
    tile number `tile` (default: its first tile), its <UDIM> or <UVTILE> token filled in
    as Blender does (1001 + u + 10 v; u1_v1 for 1001)."""
    path = bpy.path.abspath(img.filepath_raw or img.filepath)
    if getattr(img, "source", "FILE") != "TILED":
        return path
    if tile is None:
        tile = img.tiles[0].number if len(img.tiles) else 1001
    k = tile - 1001
    return path.replace("<UDIM>", str(tile)).replace("<UVTILE>",
                                                     f"u{k % 10 + 1}_v{k // 10 + 1}")


def file_alpha_unassociated(img, tile=None) -> bool:
    """Whether Cycles, reading the image from its file, premultiplies its RGB by alpha at
    load (OIIOImageLoader::load_pixels): the format holds straight alpha (PNG, TGA), or a
    TIFF whose ExtraSamples tag says unassociated alpha (Blender writes associated TIFFs;
    a UDIM image's tile number `tile`: that tile's file, image_file_path). EXR, HDR and
    the rest: never."""
    fmt = str(getattr(img, "file_format", ""))
    if fmt in STRAIGHT_ALPHA_FORMATS:
        return True
    if fmt == "TIFF":
        return tiff_extra_sample(image_file_path(img, tile)) == 2
    return False


def tiff_extra_sample(path) -> int:
    """The first value of a TIFF file's ExtraSamples tag (338) in its first image: 0
    unspecified, 1 associated alpha, 2 unassociated alpha; 0 when the tag is absent or
    the file cannot be read (TIFF 6.0 section 18; BigTIFF read too)."""
    import struct
    try:
        with open(path, "rb") as f:
            head = f.read(16)
            e = {b"II": "<", b"MM": ">"}.get(head[:2])
            if e is None:
                return 0
            big = struct.unpack(e + "H", head[2:4])[0] == 43
            f.seek(struct.unpack(e + "Q", head[8:16])[0] if big
                   else struct.unpack(e + "I", head[4:8])[0])
            count = struct.unpack(e + ("Q" if big else "H"), f.read(8 if big else 2))[0]
            size = 20 if big else 12
            for _ in range(min(count, 4096)):
                entry = f.read(size)
                if len(entry) < size:
                    return 0
                tag = struct.unpack(e + "H", entry[:2])[0]
                if tag != 338:
                    continue
                # SHORT values: inline in the entry when they fit, else at an offset
                n = struct.unpack(e + ("Q" if big else "I"), entry[4:12] if big else entry[4:8])[0]
                value = entry[12:20] if big else entry[8:12]
                if 2 * n > len(value):
                    f.seek(struct.unpack(e + ("Q" if big else "I"), value)[0])
                    value = f.read(2)
                return struct.unpack(e + "H", value[:2])[0]
    except (OSError, struct.error):
        return 0
    return 0


def cycles_stores_srgb(img) -> bool:
    """Whether Cycles keeps the image's texels sRGB-encoded and decodes them after
    interpolating (scene/image.cpp ImageMetaData::detect_colorspace: compress_as_srgb when
    detect_known_colorspace finds sRGB; svm/image.h: color_srgb_to_linear after the
    lookup). An 8-bit image in any space but the linear ones (others than sRGB are read
    as sRGB here). A float image read from its file and tagged sRGB (Blender 5's
    Image.save() writes such EXRs; Blender decodes them to linear at load, Cycles does
    not); a float image Cycles reads through Blender is linear already
    (BlenderImageLoader: "Float images are already converted on the Blender side",
    colorspace raw), as is one in any other space (converted to scene linear at load)."""
    space = img.colorspace_settings.name
    if not img.is_float:
        return space not in LINEAR_SPACES
    return space == "sRGB" and not cycles_builtin(img)


def _srgb_encoder(pm):
    """The engine's imageio.srgb_encode (Cycles' color_linear_to_srgb, not clipped)."""
    from importlib import import_module
    return import_module(pm.__name__ + ".imageio").srgb_encode


def _pixels(img) -> np.ndarray:
    """HxWx4 float32 stored values of an image, top row first."""
    w, h = img.size
    ch = img.channels
    if w * h == 0 or ch == 0:
        raise ValueError("image has no pixels (missing file?)")
    buf = np.empty(w * h * ch, dtype=np.float32)
    img.pixels.foreach_get(buf)
    buf = buf.reshape(h, w, ch)[::-1]  # Blender rows run bottom to top
    if ch >= 4:
        return np.ascontiguousarray(buf[:, :, :4])
    rgb = buf[:, :, :3] if ch >= 3 else np.repeat(buf[:, :, :1], 3, axis=2)
    return np.ascontiguousarray(np.concatenate([rgb, np.ones_like(rgb[:, :, :1])], axis=2))
