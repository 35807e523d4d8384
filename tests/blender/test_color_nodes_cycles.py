"""Colour and value nodes against Cycles, texel by texel (issue 14: Blender fidelity on the
node trees real materials use).

An emissive plane (Emission Strength 1: what the camera sees is the node tree's colour)
fills an orthographic view; a Gradient Texture along the plane's x feeds the node under
test, through a Map Range to -0.5 .. 1.5 where the node's behaviour outside 0 .. 1
matters (vectors: Combine XYZ of it). 64 x 4 pixels, 16 samples near each pixel's centre
in both renderers: every pixel within 0.005 (and 0.5 %) of Cycles'.

Cycles bakes Color Ramps and curves into tables of 257 entries from Blender's own
evaluation (intern/cycles/blender/util.h colorramp_to_array, curvemapping_color_to_array;
the kernel's svm/ramp.h reads them): so does the add-on, so every Color Ramp
interpolation and every curve shape reads as in Cycles.
"""
import numpy as np
import pytest

pytestmark = pytest.mark.blender

W, H = 64, 4


def _gradient(nodes, links, lo=0.0, hi=1.0):
    """The Gradient Texture's factor along the plane, mapped to lo .. hi (unclamped)."""
    g = nodes.new("ShaderNodeTexGradient")
    if lo == 0.0 and hi == 1.0:
        return g.outputs["Fac"]
    mr = nodes.new("ShaderNodeMapRange")
    mr.clamp = False
    mr.inputs["To Min"].default_value = lo
    mr.inputs["To Max"].default_value = hi
    links.new(g.outputs["Fac"], mr.inputs["Value"])
    return mr.outputs["Result"]


def _colour(nodes, links, lo=0.0, hi=1.0, combine="ShaderNodeCombineColor"):
    """A colour (or with combine="ShaderNodeCombineXYZ" a vector) that varies along the
    plane: (f, 1 - f, 0.3 + 0.4 f), f = the gradient mapped to lo .. hi."""
    f = _gradient(nodes, links, lo, hi)
    inv = nodes.new("ShaderNodeMath")
    inv.operation = "SUBTRACT"
    inv.inputs[0].default_value = 1.0
    links.new(f, inv.inputs[1])
    blue = nodes.new("ShaderNodeMath")
    blue.operation = "MULTIPLY_ADD"
    blue.inputs[1].default_value = 0.4
    blue.inputs[2].default_value = 0.3
    links.new(f, blue.inputs[0])
    c = nodes.new(combine)
    links.new(f, c.inputs[0])
    links.new(inv.outputs[0], c.inputs[1])
    links.new(blue.outputs[0], c.inputs[2])
    return c.outputs[0]


def _ramp(interpolation):
    def build(nodes, links):
        r = nodes.new("ShaderNodeValToRGB")
        ramp = r.color_ramp
        ramp.interpolation = interpolation
        ramp.elements[0].position, ramp.elements[0].color = 0.1, (0.9, 0.2, 0.1, 1.0)
        ramp.elements[1].position, ramp.elements[1].color = 0.85, (0.1, 0.3, 0.8, 1.0)
        e = ramp.elements.new(0.4)
        e.color = (0.2, 0.9, 0.3, 1.0)
        links.new(_gradient(nodes, links), r.inputs["Fac"])
        return r.outputs["Color"]
    return build


def _curves(extrapolate):
    """RGB Curves: a bent combined curve and a lifted red one, factor 0.8."""
    def build(nodes, links):
        c = nodes.new("ShaderNodeRGBCurve")
        m = c.mapping
        m.curves[3].points.new(0.35, 0.6)   # combined (C)
        m.curves[0].points.new(0.5, 0.25)   # red
        m.curves[0].points[0].location = (0.0, 0.15)
        m.extend = "EXTRAPOLATED" if extrapolate else "HORIZONTAL"
        m.update()
        c.inputs["Fac"].default_value = 0.8
        lo, hi = (-0.5, 1.5) if extrapolate else (0.0, 1.0)
        links.new(_colour(nodes, links, lo, hi), c.inputs["Color"])
        return c.outputs["Color"]
    return build


def _vector_curves(extrapolate):
    """Vector Curves: X bent, Y lifted, Z left straight, factor 0.9, on a vector from
    -1.2 to 1.2 (past the curves' -1 .. 1 range: the extension shows)."""
    def build(nodes, links):
        c = nodes.new("ShaderNodeVectorCurve")
        m = c.mapping
        m.curves[0].points.new(0.2, -0.5)
        m.curves[1].points.new(-0.3, 0.4)
        m.curves[1].points[0].location = (-1.0, -0.6)
        m.extend = "EXTRAPOLATED" if extrapolate else "HORIZONTAL"
        m.update()
        c.inputs[0].default_value = 0.9  # Factor
        links.new(_vector(nodes, links, -1.2, 1.2), c.inputs["Vector"])
        return c.outputs["Vector"]
    return build


def _float_curve(nodes, links):
    c = nodes.new("ShaderNodeFloatCurve")
    pts = c.mapping.curves[0].points
    pts[-1].location = (1.0, 0.2)
    pts.new(0.3, 0.7)
    c.mapping.update()
    links.new(_gradient(nodes, links), c.inputs["Value"])
    return c.outputs["Value"]


def _bright_contrast(nodes, links):
    b = nodes.new("ShaderNodeBrightContrast")
    b.inputs["Bright"].default_value = 0.1
    b.inputs["Contrast"].default_value = 0.6
    links.new(_colour(nodes, links), b.inputs["Color"])
    return b.outputs["Color"]


def _gamma(nodes, links):
    g = nodes.new("ShaderNodeGamma")
    g.inputs["Gamma"].default_value = 2.2
    links.new(_colour(nodes, links, -0.5, 1.5), g.inputs["Color"])
    return g.outputs["Color"]


def _rgb_to_bw(nodes, links):
    b = nodes.new("ShaderNodeRGBToBW")
    links.new(_colour(nodes, links), b.inputs["Color"])
    return b.outputs["Val"]


def _clamp(kind):
    def build(nodes, links):
        c = nodes.new("ShaderNodeClamp")
        c.clamp_type = kind
        c.inputs["Min"].default_value = 0.8 if kind == "RANGE" else 0.2
        c.inputs["Max"].default_value = 0.3 if kind == "RANGE" else 0.9
        links.new(_gradient(nodes, links, -0.5, 1.5), c.inputs["Value"])
        return c.outputs["Result"]
    return build


def _math(op, b=0.7, c=0.25, lo=-1.5, hi=1.5, scale=1.0):
    """Math op on the gradient mapped to lo .. hi, shifted into 0.1 .. 1 for display."""
    def build(nodes, links):
        m = nodes.new("ShaderNodeMath")
        m.operation = op
        m.inputs[1].default_value = b
        m.inputs[2].default_value = c
        links.new(_gradient(nodes, links, lo, hi), m.inputs[0])
        shown = nodes.new("ShaderNodeMath")
        shown.operation = "MULTIPLY_ADD"
        shown.inputs[1].default_value = scale
        shown.inputs[2].default_value = 0.5
        links.new(m.outputs[0], shown.inputs[0])
        return shown.outputs[0]
    return build


def _vector(nodes, links, lo=-1.0, hi=1.0):
    """A vector that varies along the plane: (f, 1 - f, 0.3 + 0.4 f), f from lo to hi."""
    return _colour(nodes, links, lo, hi, combine="ShaderNodeCombineXYZ")


def _blend(kind):
    def build(nodes, links):
        m = nodes.new("ShaderNodeMix")
        m.data_type, m.blend_type = "RGBA", kind
        m.inputs["Factor"].default_value = 0.7
        links.new(_colour(nodes, links), m.inputs[6])
        m.inputs[7].default_value = (0.2, 0.7, 0.45, 1.0)
        return m.outputs[2]
    return build


def _mix_value(data_type, uniform=True):
    def build(nodes, links):
        m = nodes.new("ShaderNodeMix")
        m.data_type = data_type
        if data_type == "FLOAT":
            links.new(_gradient(nodes, links), m.inputs[2])
            m.inputs[3].default_value = 0.8  # B (float)
            m.inputs[0].default_value = 0.3
            return m.outputs[0]
        if not uniform:
            m.factor_mode = "NON_UNIFORM"
            m.inputs[1].default_value = (0.2, 0.5, 0.9)  # Factor (vector)
        else:
            m.inputs[0].default_value = 0.4
        links.new(_vector(nodes, links, 0.0, 1.0), m.inputs[4])  # A (vector)
        m.inputs[5].default_value = (0.9, 0.1, 0.6)  # B (vector)
        return m.outputs[1]
    return build


def _vector_math(op, b=(0.6, -0.3, 0.8), c=(0.2, 0.4, -0.5), scale=1.3, value=False,
                 shown=1.0, lo=-1.0, hi=1.0):
    def build(nodes, links):
        m = nodes.new("ShaderNodeVectorMath")
        m.operation = op
        links.new(_vector(nodes, links, lo, hi), m.inputs[0])
        m.inputs[1].default_value = b
        m.inputs[2].default_value = c
        m.inputs[3].default_value = scale
        out = m.outputs["Value" if value else "Vector"]
        if shown != 1.0:
            k = nodes.new("ShaderNodeVectorMath")
            k.operation = "SCALE"
            k.inputs[3].default_value = shown
            links.new(out, k.inputs[0])
            out = k.outputs[0]
        return out
    return build


def _separate(mode, channel):
    def build(nodes, links):
        sep = nodes.new("ShaderNodeSeparateColor")
        sep.mode = mode
        links.new(_ramp("LINEAR")(nodes, links), sep.inputs[0])  # hue, saturation and
        # lightness all vary along it
        return sep.outputs[channel]
    return build


def _combine(mode):
    """Combine Color HSV / HSL of (f, 0.8, 0.3 + 0.4 f): a hue sweep."""
    def build(nodes, links):
        comb = nodes.new("ShaderNodeCombineColor")
        comb.mode = mode
        f = _gradient(nodes, links)
        links.new(f, comb.inputs[0])
        comb.inputs[1].default_value = 0.8
        third = nodes.new("ShaderNodeMath")
        third.operation = "MULTIPLY_ADD"
        third.inputs[1].default_value = 0.4
        third.inputs[2].default_value = 0.3
        links.new(f, third.inputs[0])
        links.new(third.outputs[0], comb.inputs[2])
        return comb.outputs[0]
    return build


def _white_noise(dims, output):
    """White Noise of snapped coordinates (the hash needs the float32 bits Cycles sees:
    Snap of Generated x by 1/16 gives sixteen exact cells along the plane)."""
    def build(nodes, links):
        tc = nodes.new("ShaderNodeTexCoord")
        snap = nodes.new("ShaderNodeVectorMath")
        snap.operation = "SNAP"
        snap.inputs[1].default_value = (0.0625, 1.0, 1.0)
        links.new(tc.outputs["Generated"], snap.inputs[0])
        wn = nodes.new("ShaderNodeTexWhiteNoise")
        wn.noise_dimensions = dims
        if dims != "1D":
            links.new(snap.outputs[0], wn.inputs["Vector"])
        if dims in ("1D", "4D"):
            sx = nodes.new("ShaderNodeSeparateXYZ")
            links.new(snap.outputs[0], sx.inputs[0])
            links.new(sx.outputs[0], wn.inputs["W"])
        return wn.outputs[output]
    return build


def _tex_coord(output):
    """A Texture Coordinate output as the colour (Camera: camera space, m; Window: the
    frame's 0..1; Reflection: a world-space direction)."""
    def build(nodes, links):
        return nodes.new("ShaderNodeTexCoord").outputs[output]
    return build


def _turned(nodes, links, scale=1.0):
    """Generated coordinates turned 0.6 rad about z (and scaled): x and y both vary
    along the plane, so a pattern's rows and columns both show."""
    tc = nodes.new("ShaderNodeTexCoord")
    m = nodes.new("ShaderNodeMapping")
    m.inputs["Rotation"].default_value = (0.0, 0.0, 0.6)
    m.inputs["Scale"].default_value = (scale, scale, scale)
    links.new(tc.outputs["Generated"], m.inputs["Vector"])
    return m.outputs["Vector"]


def _brick(output, smooth=1.0, **props):
    """Brick Texture on turned coordinates: mortar 0.1 wide, smoothed `smooth` (fully: a
    steeper mortar edge meets Cycles' rare sample a third of a pixel from the centre),
    bias 0.1, three colours; props set the node's offset / squash properties."""
    def build(nodes, links):
        b = nodes.new("ShaderNodeTexBrick")
        for k, val in props.items():
            setattr(b, k, val)
        b.inputs["Color1"].default_value = (0.9, 0.5, 0.2, 1.0)
        b.inputs["Color2"].default_value = (0.2, 0.4, 0.8, 1.0)
        b.inputs["Mortar"].default_value = (0.1, 0.7, 0.3, 1.0)
        b.inputs["Scale"].default_value = 2.0
        b.inputs["Mortar Size"].default_value = 0.1
        b.inputs["Mortar Smooth"].default_value = smooth
        b.inputs["Bias"].default_value = 0.1
        links.new(_turned(nodes, links), b.inputs["Vector"])
        return b.outputs[output]
    return build


def _magic(output, depth, distortion=1.3, scale=1.0, magic_scale=1.7):
    """Magic Texture on turned coordinates (scale > 1: past 2 pi, where Cycles reduces
    the scaled coordinates by fmod)."""
    def build(nodes, links):
        m = nodes.new("ShaderNodeTexMagic")
        m.turbulence_depth = depth
        m.inputs["Scale"].default_value = magic_scale
        m.inputs["Distortion"].default_value = distortion
        links.new(_turned(nodes, links, scale), m.inputs["Vector"])
        return m.outputs[output]
    return build


def _gabor(output, kind="2D", anisotropy=1.0, frequency=2.0):
    """Gabor Texture on turned coordinates (scale 4): anisotropy 1 keeps every kernel
    along the Orientation, less turns them by hashed angles."""
    def build(nodes, links):
        g = nodes.new("ShaderNodeTexGabor")
        g.gabor_type = kind
        ins = {i.identifier: i for i in g.inputs}
        ins["Scale"].default_value = 4.0
        ins["Frequency"].default_value = frequency
        ins["Anisotropy"].default_value = anisotropy
        ins["Orientation 2D"].default_value = 0.4
        ins["Orientation 3D"].default_value = (0.3, 0.8, 0.5)
        links.new(_turned(nodes, links), g.inputs["Vector"])
        return g.outputs[output]
    return build


def _vector_into_value(source):
    """A vector output into a Math node's value input: Cycles converts it to the average
    of its components (a colour would give its luminance)."""
    def build(nodes, links):
        if source == "texcoord":
            vec = _turned(nodes, links, 1.3)
        else:  # a Combine XYZ: the components differ the most
            vec = _vector(nodes, links, -0.5, 1.5)
        m = nodes.new("ShaderNodeMath")
        m.operation = "MULTIPLY"
        m.inputs[1].default_value = 1.0
        links.new(vec, m.inputs[0])
        return m.outputs[0]
    return build


def _object_relative(nodes, links):
    """Texture Coordinate Object relative to an empty (moved, turned, scaled): the hit in
    the empty's space."""
    import bpy
    empty = bpy.data.objects.new("Frame", None)
    empty.location = (0.3, -0.2, 0.5)
    empty.rotation_euler = (0.2, -0.4, 0.7)
    empty.scale = (0.8, 1.5, 1.2)
    bpy.context.scene.collection.objects.link(empty)
    tc = nodes.new("ShaderNodeTexCoord")
    tc.object = empty
    return tc.outputs["Object"]


CASES = {
    "texcoord_object_relative": _object_relative,
    "vector_into_value_mapping": _vector_into_value("texcoord"),
    "vector_into_value_combine": _vector_into_value("combine"),
    "gabor_2d_value": _gabor("Value"),
    "gabor_2d_phase": _gabor("Phase", frequency=0.7),
    "gabor_2d_intensity": _gabor("Intensity"),
    "gabor_2d_isotropic": _gabor("Value", anisotropy=0.2),
    "gabor_3d_value": _gabor("Value", "3D"),
    "gabor_3d_isotropic": _gabor("Value", "3D", anisotropy=0.4),
    "gabor_3d_intensity": _gabor("Intensity", "3D", anisotropy=0.0),
    "brick_color": _brick("Color"),
    "brick_fac": _brick("Factor"),
    "brick_squash_offset": _brick("Color", offset=0.3, offset_frequency=3, squash=0.6,
                                  squash_frequency=3),
    "brick_squashed_fac": _brick("Factor", squash=1.4),
    "magic_color": _magic("Color", 2),
    "magic_depth_0": _magic("Color", 0),
    "magic_depth_10_fac": _magic("Factor", 10, distortion=2.2, magic_scale=0.8),
    "magic_no_distortion": _magic("Color", 0, distortion=0.0),
    "magic_far_coordinates": _magic("Color", 3, scale=7.5, magic_scale=0.5),
    "texcoord_camera": _tex_coord("Camera"),
    "texcoord_window": _tex_coord("Window"),
    "texcoord_camera_perspective": _tex_coord("Camera"),
    "texcoord_window_perspective": _tex_coord("Window"),
    "texcoord_reflection_perspective": _tex_coord("Reflection"),
    "ramp_linear": _ramp("LINEAR"),
    "ramp_constant": _ramp("CONSTANT"),
    "ramp_ease": _ramp("EASE"),
    "ramp_cardinal": _ramp("CARDINAL"),
    "ramp_b_spline": _ramp("B_SPLINE"),
    "rgb_curves": _curves(False),
    "rgb_curves_extrapolated": _curves(True),
    "float_curve": _float_curve,
    "vector_curves": _vector_curves(False),
    "vector_curves_extrapolated": _vector_curves(True),
    "bright_contrast": _bright_contrast,
    "gamma": _gamma,
    "rgb_to_bw": _rgb_to_bw,
    "clamp_minmax": _clamp("MINMAX"),
    "clamp_range": _clamp("RANGE"),
    "math_power": _math("POWER", b=2.0),
    "math_power_fraction": _math("POWER", b=0.5),
    "math_multiply_add": _math("MULTIPLY_ADD"),
    "math_sqrt": _math("SQRT"),
    "math_inverse_sqrt": _math("INVERSE_SQRT", lo=0.2, hi=2.0, scale=0.2),
    "math_exponent": _math("EXPONENT", scale=0.1),
    "math_logarithm": _math("LOGARITHM", b=2.0, lo=0.1, hi=3.0, scale=0.2),
    "math_sign": _math("SIGN", scale=0.3),
    "math_round": _math("ROUND", lo=-2.0, hi=2.0, scale=0.2),
    "math_ceil": _math("CEIL", lo=-2.0, hi=2.0, scale=0.2),
    "math_trunc": _math("TRUNC", lo=-2.0, hi=2.0, scale=0.2),
    "math_floored_modulo": _math("FLOORED_MODULO", b=0.6),
    "math_snap": _math("SNAP", b=0.4),
    "math_wrap": _math("WRAP", b=0.6, c=-0.3),
    "math_pingpong": _math("PINGPONG", b=0.45),
    "math_compare": _math("COMPARE", b=0.2, c=0.3, scale=0.3),
    "math_smooth_min": _math("SMOOTH_MIN", b=0.3, c=0.5),
    "math_smooth_max": _math("SMOOTH_MAX", b=0.3, c=0.5),
    "math_tangent": _math("TANGENT", lo=-1.2, hi=1.2, scale=0.1),
    "math_arcsine": _math("ARCSINE", lo=-1.2, hi=1.2, scale=0.3),
    "math_arccosine": _math("ARCCOSINE", lo=-1.2, hi=1.2, scale=0.3),
    "math_arctangent": _math("ARCTANGENT", scale=0.3),
    "math_arctan2": _math("ARCTAN2", b=-0.4, scale=0.15),
    "math_sinh": _math("SINH", scale=0.2),
    "math_cosh": _math("COSH", scale=0.2),
    "math_tanh": _math("TANH", scale=0.4),
    "math_radians": _math("RADIANS", scale=10.0),
    "math_degrees": _math("DEGREES", scale=0.005),
    **{f"mix_{k.lower()}": _blend(k) for k in (
        "OVERLAY", "EXCLUSION", "DODGE", "BURN", "HUE", "SATURATION", "VALUE", "COLOR",
        "SOFT_LIGHT", "LINEAR_LIGHT", "SCREEN", "DIVIDE", "DIFFERENCE")},
    **{f"separate_{m.lower()}_{k}": _separate(m, k) for m in ("HSV", "HSL")
       for k in range(3)},
    "combine_hsv": _combine("HSV"),
    "combine_hsl": _combine("HSL"),
    **{f"white_noise_{d.lower()}_{o.lower()}": _white_noise(d, o)
       for d in ("1D", "2D", "3D", "4D") for o in ("Value", "Color")},
    "mix_float": _mix_value("FLOAT"),
    "mix_vector": _mix_value("VECTOR"),
    "mix_vector_non_uniform": _mix_value("VECTOR", uniform=False),
    **{f"vector_{k.lower()}": _vector_math(k) for k in (
        "ADD", "SUBTRACT", "MULTIPLY", "MULTIPLY_ADD", "CROSS_PRODUCT", "PROJECT",
        "REFLECT", "REFRACT", "FACEFORWARD", "SCALE", "NORMALIZE", "SNAP", "FLOOR", "CEIL",
        "MODULO", "WRAP", "FRACTION", "ABSOLUTE", "MINIMUM", "MAXIMUM", "SINE", "COSINE",
        "POWER", "SIGN")},
    "vector_divide": _vector_math("DIVIDE", shown=0.25),
    "vector_tangent": _vector_math("TANGENT", shown=0.1, lo=-0.5, hi=0.5),
    **{f"vector_{k.lower()}": _vector_math(k, value=True, shown=0.5) for k in (
        "DOT_PRODUCT", "DISTANCE", "LENGTH")},
}


# Cases seen by a perspective camera (focal length, mm; shift along x, in units of the
# frame's width) instead of the orthographic one: the view direction varies over the plane.
PERSPECTIVE = {"texcoord_camera_perspective": (70.0, 0.0),
               "texcoord_window_perspective": (70.0, 0.06),
               "texcoord_reflection_perspective": (70.0, 0.0)}

# Emission below 0 renders as 0 here (a light of negative power): every case is shown
# lifted by LIFT (a Mix Color, Add) and compared less LIFT.
LIFT = 4.0


def _plane_scene(bpy, scene, build, lift=0.0, perspective=None):
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, "Nodes")
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Strength"].default_value = 1.0
    sock = build(nt.nodes, nt.links)
    if lift:
        mix = nt.nodes.new("ShaderNodeMix")
        mix.data_type, mix.blend_type = "RGBA", "ADD"
        mix.inputs["Factor"].default_value = 1.0
        mix.inputs[7].default_value = (lift, lift, lift, 1.0)  # B (colour)
        nt.links.new(sock, mix.inputs[6])  # A (colour)
        sock = mix.outputs[2]  # Result (colour)
    nt.links.new(sock, e.inputs["Color"])
    nt.links.new(e.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    bpy.context.object.data.materials.append(m)
    from blender_helpers import black_world, looking_down_camera
    if perspective is None:
        looking_down_camera(bpy, scene, 3.0, ortho_scale=1.9)  # inside the plane
    else:
        lens, shift_x = perspective
        looking_down_camera(bpy, scene, 3.0, lens=lens).data.shift_x = shift_x
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    return m


@pytest.mark.parametrize("case", sorted(CASES))
def test_node_matches_cycles_texel_by_texel(fresh_scene, bpy_addon, tmp_path, case):
    bpy = bpy_addon
    scene = fresh_scene
    lift = LIFT
    _plane_scene(bpy, scene, CASES[case], lift, PERSPECTIVE.get(case))
    from blender_helpers import render_pixel_centres
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")[..., :3] - lift
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES")[..., :3] - lift
    row_o, row_r = ours.mean(axis=0), ref.mean(axis=0)  # (W, 3) along the gradient
    err = np.abs(row_o - row_r)
    print(f"{case}: max |ours - Cycles| {err.max():.5f}, Cycles range "
          f"{row_r.min():.3f} .. {row_r.max():.3f}")
    assert np.all(np.isfinite(ours))
    assert np.ptp(row_r) > 0.05  # the case varies along the plane
    assert np.all(err <= 0.005 + 0.005 * np.abs(row_r)), np.argwhere(
        err > 0.005 + 0.005 * np.abs(row_r))[:5]
