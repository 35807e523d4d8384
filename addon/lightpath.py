"""The Light Path node inside a material: one engine material per ray class that differs.

Cycles evaluates a material's node tree for every ray that meets the surface, with the
ray's path flags (intern/cycles/kernel/svm/light_path.h, svm_node_light_path; the flags
path_state_next sets in integrator/path_state.h). A tree that reads the Light Path node is
therefore a different closure for each kind of ray, which is what the well-known tricks
rely on: glass that shadow rays see as a Transparent BSDF (Mix Shader by Is Shadow Ray),
a lamp the camera looks through (Mix Shader by Is Camera Ray, Emission and Transparent),
a colour only the camera sees.

Here such a tree is converted once per ray class with the node's outputs set to that
class's constants (RAY_CLASSES), and the classes whose material differs from the diffuse
rays' become the engine Material's ray_variants (engine/raymaterials.py says which ray
meets which). The constants, from Cycles:
  camera        Is Camera Ray 1 (also through transparent surfaces: a transparent bounce
                keeps the flags); every other output 0; Ray Depth 0
  shadow        Is Shadow Ray 1 and nothing else: shadow_surface_eval evaluates the
                surface with PATH_RAY_SHADOW alone (integrator/shade_shadow.h); Ray Depth
                is the bounce + 1
  diffuse       Is Diffuse Ray, Is Reflection Ray 1 (a diffuse bounce: LABEL_DIFFUSE |
                LABEL_REFLECT); also what photons and final-gather rays meet
  glossy        Is Glossy Ray, Is Reflection Ray 1 (Is Singular Ray 1 on a sharp mirror)
  transmission  Is Transmission Ray and Is Glossy Ray 1 (glass refraction is LABEL_GLOSSY
                or LABEL_SINGULAR, and path_state_next sets PATH_RAY_GLOSSY for both)
  emission      light sampling's evaluation of an emitter (PATH_RAY_EMISSION): every
                Is ... Ray output 0; the engine samples mesh lights with the diffuse rays'
                emission, so a difference is warned
A Holdout that the camera class picks (Mix Shader(Is Camera Ray, Emission, Holdout)) is a
camera variant that holds out (engine Material.holdout), as an object's holdout does.
Outputs that are not one constant per class (Ray Length, Is Backfacing, the depths past
the first bounce, Is Singular Ray on rough lobes) read their first bounce's value,
warned naming the material and the node.
"""
from __future__ import annotations

# Ray classes, the diffuse rays' first: its material is the one the others are compared to.
RAY_CLASSES = ("diffuse", "camera", "glossy", "transmission", "shadow", "emission")
# Engine Material.ray_variants keys (the classes whose material the renderer picks per ray).
VARIANT_CLASSES = ("camera", "glossy", "transmission", "shadow")

_FLAGS = {
    "camera": {"Is Camera Ray"},
    "shadow": {"Is Shadow Ray"},
    "diffuse": {"Is Diffuse Ray", "Is Reflection Ray"},
    "glossy": {"Is Glossy Ray", "Is Reflection Ray", "Is Singular Ray"},
    "transmission": {"Is Transmission Ray", "Is Glossy Ray", "Is Singular Ray"},
    "emission": set(),
}
# Outputs exact per class (flags the class always or never has).
EXACT = ("Is Camera Ray", "Is Shadow Ray", "Is Diffuse Ray", "Is Glossy Ray",
         "Is Reflection Ray", "Is Transmission Ray", "Is Volume Scatter Ray")
# Each class's first-bounce depths: (Ray Depth, Diffuse, Glossy, Transmission, Transparent).
_DEPTHS = {"camera": (0, 0, 0, 0, 0), "shadow": (1, 0, 0, 0, 0), "emission": (1, 0, 0, 0, 0),
           "diffuse": (1, 1, 0, 0, 0), "glossy": (1, 0, 1, 0, 0),
           "transmission": (1, 0, 0, 1, 0)}
_DEPTH_OUTPUTS = ("Ray Depth", "Diffuse Depth", "Glossy Depth", "Transmission Depth",
                  "Transparent Depth")


def output_value(converter, node, output: str) -> float:
    """The value of Light Path node `node`'s output for the ray class the converter is
    converting for (converter._ray_class; "diffuse" outside a per-class conversion)."""
    cls = getattr(converter, "_ray_class", "diffuse")
    who = f"material '{converter._mat.name}': Light Path '{node.name}'"
    if output in EXACT:
        return 1.0 if output in _FLAGS[cls] else 0.0
    if output == "Is Singular Ray":
        converter._warn(f"{who}: Is Singular Ray reads 1 for every glossy and "
                        "transmission ray (sharp mirrors and glass) and 0 for the others; "
                        "Cycles gives 0 on rough lobes")
        return 1.0 if output in _FLAGS[cls] else 0.0
    if output in _DEPTH_OUTPUTS:
        converter._warn(f"{who}: {output} reads its first bounce's value for each ray kind "
                        "(camera rays 0); deeper bounces read the same")
        return float(_DEPTHS[cls][_DEPTH_OUTPUTS.index(output)])
    converter._warn(f"{who}: output '{output}' varies per hit, not per ray kind; it is not "
                    "supported and reads 0")
    return 0.0


def _upstream_has_light_path(socket, seen: set) -> bool:
    if socket is None or not socket.is_linked:
        return False
    for link in socket.links:
        if getattr(link, "is_muted", False) or not getattr(link, "is_valid", True):
            continue
        node = link.from_node
        if node.type == "LIGHT_PATH":
            return True
        if node.as_pointer() in seen:
            continue
        seen.add(node.as_pointer())
        if node.type == "GROUP":
            # A node group's inside (the converter reads groups through their outputs).
            tree = getattr(node, "node_tree", None)
            if tree is not None and any(n.type == "LIGHT_PATH" for n in tree.nodes):
                return True
        if any(_upstream_has_light_path(s, seen) for s in node.inputs):
            return True
    return False


def reads_light_path(mat, output_node) -> bool:
    """Whether the Surface of material mat's output node reads a Light Path output."""
    nt = getattr(mat, "node_tree", None)
    if nt is None:
        return False
    out = output_node(nt)
    if out is None:
        return False
    return _upstream_has_light_path(out.inputs.get("Surface"), set())


def same_material(pm, a, b) -> bool:
    """Whether two engine Materials of one Blender material render alike for the rays that
    meet them: equal table rows and no per-hit node (a texture's variants are kept apart,
    though they may match: an extra row costs nothing but memory)."""
    import numpy as np
    nodes = ("texture", "normal_map", "alpha_texture", "scalar_textures", "emission_texture")
    if any(getattr(a, n) is not None or getattr(b, n) is not None for n in nodes):
        return False
    ta, tb = (pm.geometry.MaterialTable.build([m]) for m in (a, b))
    for col in ("base_color", "emission", "alpha", "closure_params", "transmission",
                "metallic", "roughness", "ior", "specular", "coat_weight", "sheen_weight",
                "translucent", "emission_sides", "holdout"):
        x, y = getattr(ta, col), getattr(tb, col)
        if x is None and y is None:
            continue
        if x is None or y is None or not np.array_equal(np.asarray(x), np.asarray(y)):
            return False
    return True


def _class_value(node, output: str, cls: str):
    """A Light Path output's value for class cls when it is one of the exact flags, else
    None."""
    if node.type != "LIGHT_PATH" or output not in EXACT:
        return None
    return 1.0 if output in _FLAGS[cls] else 0.0


def picks_holdout(mat, cls: str, output_node) -> bool:
    """Whether the Surface of mat is, for ray class cls, a Holdout shader alone: reached
    through Mix Shaders whose factor is a Light Path flag (0 picks the first shader, 1
    the second), as Mix Shader(Is Camera Ray, Emission, Holdout)."""
    out = output_node(mat.node_tree)
    socket = out.inputs.get("Surface") if out is not None else None
    for _ in range(32):
        if socket is None or not socket.is_linked or getattr(socket.links[0], "is_muted",
                                                             False):
            return False
        node = socket.links[0].from_node
        while node.type == "REROUTE" and node.inputs[0].is_linked:
            node = node.inputs[0].links[0].from_node
        if node.type == "HOLDOUT":
            return True
        if node.type != "MIX_SHADER" or not node.inputs[0].is_linked:
            return False
        link = node.inputs[0].links[0]
        fac = _class_value(link.from_node, link.from_socket.name, cls)
        if fac is None:
            return False
        socket = node.inputs[2] if fac >= 0.5 else node.inputs[1]
    return False


def convert_per_ray_class(converter, mat, key: str, convert_once):
    """The engine Material of Blender material mat (named key) whose Surface reads Light
    Path: the diffuse rays' conversion, with the other classes' that differ as its
    ray_variants ("<key> [camera rays]", ...). convert_once(mat, name) converts with
    converter._ray_class set. Warnings: the diffuse conversion's, then the others' new
    ones."""
    from .materials import output_node
    converted = {}
    try:
        for cls in RAY_CLASSES:
            name = key if cls == "diffuse" else f"{key} [{cls} rays]"
            if cls == "camera" and picks_holdout(mat, cls, output_node):
                # Camera rays see a Holdout: a hole (engine Material.holdout), black and
                # opaque otherwise (no ray but the camera's meets this row).
                converted[cls] = converter.pm.Material(name=name, base_color=(0.0, 0.0, 0.0),
                                                       holdout=True)
                continue
            converter._ray_class = cls
            converted[cls] = convert_once(mat, name)
    finally:
        converter._ray_class = "diffuse"
    base = converted["diffuse"]
    if (converted["camera"].holdout
            and sum(n.type == "HOLDOUT" for n in mat.node_tree.nodes) == 1
            and not any(picks_holdout(mat, c, output_node) for c in RAY_CLASSES
                        if c != "camera")):
        # The one Holdout is the camera's (a Light Path factor of 0 or 1 gave it weight 0
        # for the other classes): the "not supported" line their conversion wrote for it
        # does not apply.
        for m in converted.values():
            m.warnings[:] = [w for w in m.warnings if "(HOLDOUT) is not supported" not in w]
    variants = {cls: converted[cls] for cls in VARIANT_CLASSES
                if not same_material(converter.pm, converted[cls], base)}
    for cls in VARIANT_CLASSES:
        for w in converted[cls].warnings:
            if w not in base.warnings:
                base.warnings.append(w)
    import numpy as np
    if not np.array_equal(np.asarray(converted["emission"].emission),
                          np.asarray(base.emission)):
        base.warnings.append(
            f"material '{mat.name}': its emission depends on Light Path outputs that "
            "Cycles' light sampling reads as 0 (every Is ... Ray): sampled here with the "
            "emission diffuse rays see")
    base.ray_variants = variants or None
    return base
