"""Cryptomatte through the add-on (engine/cryptomatte.py) against live Cycles: the same
passes (CryptoObject00.., CryptoMaterial00.., CryptoAsset00..), the same ids where a
pixel sees one object, coverage within sampling noise at the edges, and the metadata the
compositor's Cryptomatte node reads (layer name, hash, conversion, manifest) in the
multilayer EXR."""
import json
import os
import sys

import numpy as np
import pytest

from blender_helpers import ROOT, cheap, cycles_plain, read_layers, render_exr

pytestmark = pytest.mark.blender

W, H, SPP = 64, 48, 16


def _scene():
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    import bpy
    scene = mb.reset()
    floor = mb.material("Floor Paint", "principled", (0.8, 0.8, 0.8), roughness=1.0)
    red = mb.material("Red Paint", "principled", (0.8, 0.1, 0.1), roughness=0.5)
    mb.plane("Floor", 8, 8, floor)
    mb.sphere("Ball", 0.5, red, (-0.6, 0, 0.5), segments=32, rings=16)
    cube = mb.sphere("Pebble", 0.35, red, (0.7, 0.2, 0.35), segments=24, rings=12)
    holder = bpy.data.objects.new("Group Root", None)
    scene.collection.objects.link(holder)
    cube.parent = holder  # the asset layer names it by its topmost parent
    mb.set_world((0.3, 0.3, 0.3))
    mb.light("Area", "AREA", (1.0, -1.5, 3.0), 300.0, look_at=(0, 0, 0), size=1.0)
    mb.camera((0, -4, 1.6), (0, 0, 0.4))
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.use_compositing = False
    vl = scene.view_layers[0]
    vl.use_pass_cryptomatte_object = vl.use_pass_cryptomatte_material = True
    vl.use_pass_cryptomatte_asset = True
    vl.pass_cryptomatte_depth = 4
    return scene


def _header(path):
    import OpenEXR
    f = OpenEXR.File(str(path))
    header = {}
    for part in f.parts:
        header.update({k: v for k, v in part.header.items() if k.startswith("cryptomatte/")})
    return header


@pytest.fixture(scope="module")
def renders(bpy_addon, tmp_path_factory):
    bpy = bpy_addon
    tmp = tmp_path_factory.mktemp("cryptomatte")
    scene = _scene()
    out = {}
    for engine in ("CYCLES", "PHOTONMAP"):
        scene.render.engine = engine
        if engine == "CYCLES":
            cycles_plain(scene, SPP, 4)
        else:
            cheap(scene, spp=SPP, photons=5000, caustic_photons=0)
        path = render_exr(bpy, scene, tmp / f"{engine}.exr", multilayer=True)
        out[engine] = (read_layers(path), _header(path))
    return out


def _as_text(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def test_the_passes_and_metadata_are_cycles(renders):
    (cyc, cyc_meta), (ours, our_meta) = renders["CYCLES"], renders["PHOTONMAP"]
    for prefix in ("CryptoObject", "CryptoMaterial", "CryptoAsset"):
        names = [f"{prefix}{i:02d}" for i in range(2)]  # Levels 4: two RGBA passes
        for n in names:
            assert n in cyc and n in ours, (n, sorted(ours))
            assert ours[n].shape == cyc[n].shape == (H, W, 4)
        assert f"{prefix}02" not in ours
    # The same keys (cryptomatte/<7 hex>/name, hash, conversion, manifest), the same
    # layer names, and each name we list hashed as Cycles hashes it.
    assert set(our_meta) == set(cyc_meta), (sorted(our_meta), sorted(cyc_meta))
    for key, value in our_meta.items():
        if key.endswith("/manifest"):
            mine, theirs = json.loads(_as_text(value)), json.loads(_as_text(cyc_meta[key]))
            shared = set(mine) & set(theirs)
            assert ({"Floor", "Ball", "Pebble"} <= set(mine) or "Red Paint" in mine
                    or "Group Root" in mine), mine
            assert shared and all(mine[n] == theirs[n] for n in shared), (mine, theirs)
        else:
            assert _as_text(value) == _as_text(cyc_meta[key]), key


@pytest.mark.parametrize("prefix", ["CryptoObject", "CryptoMaterial", "CryptoAsset"])
def test_ids_and_coverage_match_cycles(renders, prefix):
    cyc, ours = renders["CYCLES"][0], renders["PHOTONMAP"][0]
    c0, o0 = cyc[f"{prefix}00"], ours[f"{prefix}00"]
    # Where both see one id in every sample, it is the same id (the hash and its float).
    whole = (c0[..., 1] == 1.0) & (o0[..., 1] == 1.0)
    assert whole.sum() > 0.5 * W * H
    assert (c0[..., 0][whole] == o0[..., 0][whole]).mean() > 0.995
    # Coverage of each id, summed over the ranks, within sampling noise of Cycles'.
    ids = np.unique(np.concatenate([c0[..., 0][whole], o0[..., 0][whole]]))

    def cover(layers, i):
        total = np.zeros((H, W), np.float32)
        for p in layers:
            total += np.where(p[..., 0] == i, p[..., 1], 0) + np.where(p[..., 2] == i,
                                                                         p[..., 3], 0)
        return total

    for i in ids:
        c = cover([cyc[f"{prefix}{k:02d}"] for k in range(2)], i)
        o = cover([ours[f"{prefix}{k:02d}"] for k in range(2)], i)
        assert abs(c.sum() - o.sum()) < 0.02 * max(c.sum(), 1.0) + 4, (prefix, i)
        assert np.abs(c - o).mean() < 0.02, (prefix, i)


def test_the_compositors_cryptomatte_node_pulls_a_matte_by_name(renders, bpy_addon, tmp_path):
    """A user's workflow: Render Layers -> Cryptomatte node (matte 'Ball') -> output. The
    node finds our layers in the render's metadata and its matte is the Ball's coverage
    in our CryptoObject passes."""
    bpy = bpy_addon
    from blender_helpers import read_rgba
    ours = renders["PHOTONMAP"][0]
    scene = _scene()
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=SPP, photons=5000, caustic_photons=0)
    scene.render.use_compositing = True
    if hasattr(scene, "compositing_node_group"):  # Blender 5.0+
        tree = bpy.data.node_groups.new("Matte", "CompositorNodeTree")
        scene.compositing_node_group = tree
        out = tree.nodes.new("NodeGroupOutput")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    else:
        scene.use_nodes = True
        tree = scene.node_tree
        tree.nodes.clear()
        out = tree.nodes.new("CompositorNodeComposite")
    layers = tree.nodes.new("CompositorNodeRLayers")
    node = tree.nodes.new("CompositorNodeCryptomatteV2")
    node.source, node.scene = "RENDER", scene
    node.matte_id = "Ball"
    tree.links.new(layers.outputs["Image"], node.inputs[0])
    tree.links.new(node.outputs["Matte"], out.inputs[0])
    s = scene.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format, s.color_depth = "OPEN_EXR", "32"
    path = tmp_path / "matte.exr"
    scene.render.filepath, scene.render.use_file_extension = str(path), False
    try:
        bpy.ops.render.render(write_still=True)
        items = [i.identifier for i in node.bl_rna.properties["layer_name"].enum_items]
        assert "CryptoObject" in items, items
        matte = read_rgba(bpy, path)[..., 0]
    finally:
        if hasattr(scene, "compositing_node_group"):
            scene.compositing_node_group = None
        else:
            scene.use_nodes = False
        scene.render.use_compositing = False
    ball = np.float32(_hash_float("Ball"))
    coverage = sum(np.where(p[..., 0] == ball, p[..., 1], 0) + np.where(p[..., 2] == ball,
                                                                         p[..., 3], 0)
                   for p in (ours["CryptoObject00"], ours["CryptoObject01"]))
    assert (matte > 0.5).sum() > 100
    assert np.abs(matte - coverage).max() < 1e-3


def _hash_float(name):
    from engine import cryptomatte
    return cryptomatte.hash_to_float(cryptomatte.name_hash(name))
