"""Shader AOVs: the AOV Output nodes of a material and the View Layer's Shader AOV passes.

A material's AOV Output node writes its Color into the colour AOV and its Value into the
value AOV of its AOV Name, at the surfaces camera rays meet (engine/datapasses.py, as
Cycles' svm_node_aov_color / _value). The View Layer > Shader AOV list says which AOVs
exist and whether each is a Color or a Value pass; the render result gets one pass per
AOV under its name (Cycles' add-on: RGBA for a colour, X for a value).
"""
from __future__ import annotations


def material_aovs(converter, mat) -> dict:
    """{AOV name: {"color": engine node or RGB, "value": engine node or float}} of the
    AOV Output nodes in mat's node tree (unmuted; the first node of a name wins, as one
    pass takes one writer per surface), through converter (an addon.materials
    MaterialConverter that has just converted mat: its warnings name mat). {} without
    any."""
    nt = getattr(mat, "node_tree", None)
    if nt is None:
        return {}
    out = {}
    for node in nt.nodes:
        if node.type != "OUTPUT_AOV" or getattr(node, "mute", False):
            continue
        name = str(getattr(node, "aov_name", "") or "")
        if not name or name in out:
            continue
        out[name] = {"color": converter.aov_input(node, node.inputs["Color"]),
                     "value": converter.aov_input(node, node.inputs["Value"])}
    return out


def view_layer_aovs(view_layer) -> tuple:
    """RenderSettings.shader_aovs of a view layer: ((name, "color" | "value"), ...), the
    valid Shader AOVs (a duplicate name, which Blender flags invalid, left out)."""
    out, seen = [], set()
    for aov in getattr(view_layer, "aovs", ()):
        if not aov.name or aov.name in seen or not getattr(aov, "is_valid", True):
            continue
        seen.add(aov.name)
        out.append((aov.name, "color" if aov.type == "COLOR" else "value"))
    return tuple(out)


def aov_passes(view_layer) -> list:
    """[(pass name, channels, chan_id, type)] of the view layer's Shader AOVs, as Cycles'
    add-on registers them."""
    return [(name, 4, "RGBA", "COLOR") if kind == "color" else (name, 1, "X", "VALUE")
            for name, kind in view_layer_aovs(view_layer)]
