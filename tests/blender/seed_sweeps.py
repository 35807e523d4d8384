"""Seed sweeps behind the bounds of the stochastic Cycles comparisons (flaky50; not a test
file: pytest collects it only when named). Each prints ours / Cycles over seeds 0..N-1
(SWEEP_N, default 8) with its mean, standard deviation, range and CPU seconds a render,
and where it matters Cycles' own spread over its seeds against a converged render:

    PYTHONPATH=$PWD .venv/bin/python -m pytest -q -s tests/blender/seed_sweeps.py -k NAME

NAME (-k matches substrings: "water" runs both water sweeps, "lobe" both lobe ones):
test_water (tests/blender/test_glass_of_water_cycles.py; WATER_SPP, WATER_PHOTONS,
WATER_CAUSTIC, WATER_SEEDS: the seeds averaged a draw), test_water_cycles (its stored
means' convergence), test_night (test_night_room_cycles.py; NIGHT_SPP, NIGHT_PHOTONS),
test_lobe (test_light_lobe_visibility_cycles.py), test_lobe_area (its area lamp with
Diffuse off; LOBE_SPP, comma-separated), test_sss (test_subsurface_cycles.py),
test_vase (test_vase_aniso_cycles.py; VASE_SPP), test_sky (test_sky_cycles.py's
ground), test_pane_sun (test_pane_sun_cycles.py; PANE_SPP), test_linking_fog
(test_light_linking_cycles.py's world fog, the lamp unlinked; LINK_SPP),
test_linking_bar (its glowing bar; LINK_SPP), test_glossy_split (test_glossy_split.py's
sharp floor and figure6_box floor; SPLIT_SPP, SPLIT_GATHER, BLUR_GATHER).
docs/accuracy.md "flaky50" lists what they read."""
import os
import sys
import time

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
N = int(os.environ.get("SWEEP_N", "8"))


def _report(name, r, cpu):
    r = np.asarray(r)
    ax = 0 if r.ndim > 1 else None
    print(f"SWEEP {name}: {np.round(r, 4).tolist()} mean {np.round(r.mean(axis=ax), 4)} "
          f"sd {np.round(r.std(axis=ax, ddof=1), 4)} min {np.round(r.min(axis=ax), 4)} "
          f"max {np.round(r.max(axis=ax), 4)}; CPU s a draw {cpu:.2f}", flush=True)


def test_water(bpy_addon, tmp_path):
    """The glass of water's ratio (its test's _scene and stored means) with draws of
    WATER_SEEDS seeds each (draw i averages seeds i*WATER_SEEDS ..), at WATER_SPP (4),
    WATER_PHOTONS global (20k) and WATER_CAUSTIC caustic photons (100k): the test's."""
    import test_glass_of_water_cycles as W
    from blender_helpers import cheap
    bpy = bpy_addon
    spp = int(os.environ.get("WATER_SPP", "4"))
    caustic = int(os.environ.get("WATER_CAUSTIC", "100000"))
    per = int(os.environ.get("WATER_SEEDS", "1"))
    photons = int(os.environ.get("WATER_PHOTONS", "20000"))
    for shading in W.SHADINGS:
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = bpy.context.scene
        W._scene(bpy, scene, shading)
        cheap(scene, spp=spp, photons=photons, caustic_photons=caustic)
        scene.cycles.blur_glossy = 0.0
        want = W._stored_means()[shading]
        t0, r = time.process_time(), []
        for i in range(N):
            each = []
            for seed in range(i * per, (i + 1) * per):
                scene.photonmap.seed = seed
                each.append(W._mean(bpy, scene, tmp_path / "o.exr", "PHOTONMAP"))
            r.append(sum(each) / len(each) / want)
        _report(f"water {shading} {spp} spp, {photons} / {caustic} photons, {per} seed(s) a "
                f"draw", r, (time.process_time() - t0) / N)


def test_water_cycles(bpy_addon, tmp_path):
    """Cycles' glass of water at 4096 spp (seeds 1, 2) and 32,768 (seed 0) against the
    stored 4096-spp seed-0 means."""
    import test_glass_of_water_cycles as W
    from blender_helpers import cycles_plain
    bpy = bpy_addon
    for shading in W.SHADINGS:
        want = W._stored_means()[shading]
        for spp, seed in ((4096, 1), (4096, 2), (32768, 0)):
            bpy.ops.wm.read_homefile(use_empty=True)
            scene = bpy.context.scene
            W._scene(bpy, scene, shading)
            cycles_plain(scene, spp, 12).seed = seed
            t0 = time.process_time()
            m = W._mean(bpy, scene, tmp_path / "c.exr", "CYCLES")
            print(f"SWEEP water Cycles {shading} {spp} spp seed {seed}: {m / want:.4f} of "
                  f"the stored mean ({time.process_time() - t0:.0f} CPU s)", flush=True)


def test_night(bpy_addon, tmp_path):
    import test_night_room_cycles as T
    from blender_helpers import stored_cycles_means
    bpy = bpy_addon
    cycles = stored_cycles_means(T.REF_PATH)["image"]
    scene = T._scene(bpy)
    spp = int(os.environ.get("NIGHT_SPP", T.OUR_SPP))
    photons = int(os.environ.get("NIGHT_PHOTONS", T.OUR_PHOTONS))
    scene.photonmap.spp, scene.photonmap.photons = spp, photons
    t0, r = time.process_time(), []
    for s in range(N):
        scene.photonmap.seed = s
        r.append(T._mean(bpy, scene, tmp_path / f"o{s}.exr", "PHOTONMAP") / cycles)
    _report(f"night room {spp} spp, {photons} photons", r, (time.process_time() - t0) / N)


def _lobe_ours(bpy, scene, tmp_path, spp, seed):
    from blender_helpers import cheap, read_rgba, render_exr
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=spp, photons=2_000, caustic_photons=0)
    scene.photonmap.photon_mapping = False
    scene.photonmap.seed = seed
    return float(read_rgba(bpy, render_exr(bpy, scene, tmp_path / "o.exr"))[..., :3].mean())


def _lobe_cycles(bpy, scene, tmp_path, spp, seed):
    from blender_helpers import cycles_plain, read_rgba, render_exr
    scene.render.engine = "CYCLES"
    cycles_plain(scene, spp, 0).seed = seed
    return float(read_rgba(bpy, render_exr(bpy, scene, tmp_path / "c.exr"))[..., :3].mean())


def test_lobe(bpy_addon, tmp_path):
    """Every case at the test's 64 spp, and Cycles at 256 spp (seeds 0-3), against Cycles
    at 8192."""
    import test_light_lobe_visibility_cycles as L
    bpy = bpy_addon
    for kind in ("AREA", "POINT"):
        scene, lamp = L._scene(bpy, kind)
        for case, d, g in (("both", True, True), ("no_glossy", True, False),
                           ("no_diffuse", False, True)):
            lamp.visible_diffuse, lamp.visible_glossy = d, g
            ref = _lobe_cycles(bpy, scene, tmp_path, 8192, 0)
            c256 = [_lobe_cycles(bpy, scene, tmp_path, 256, s) / ref for s in range(4)]
            print(f"SWEEP lobe {kind} {case}: Cycles 256 spp seeds 0-3 / 8192 spp "
                  f"{np.round(c256, 4).tolist()}")
            t0 = time.process_time()
            r = [_lobe_ours(bpy, scene, tmp_path, 64, s) / ref for s in range(N)]
            _report(f"lobe {kind} {case} ours 64 spp", r, (time.process_time() - t0) / N)


def test_lobe_area(bpy_addon, tmp_path):
    import test_light_lobe_visibility_cycles as L
    bpy = bpy_addon
    scene, lamp = L._scene(bpy, "AREA")
    lamp.visible_diffuse, lamp.visible_glossy = False, True
    ref = _lobe_cycles(bpy, scene, tmp_path, 8192, 0)
    for spp in (int(x) for x in os.environ.get("LOBE_SPP", "64").split(",")):
        t0 = time.process_time()
        r = [_lobe_ours(bpy, scene, tmp_path, spp, s) / ref for s in range(N)]
        _report(f"lobe AREA no_diffuse ours {spp} spp", r,
                (time.process_time() - t0) / N)


@pytest.mark.parametrize("weight, walk, spp", [(1.0, False, 64), (0.5, False, 64),
                                               (1.0, True, 1024)])
def test_sss(fresh_scene, bpy_addon, tmp_path, weight, walk, spp):
    """Per channel (R, G, B) against Cycles at 4096 spp; Cycles at 128 spp, seeds 0-2."""
    import test_subsurface_cycles as S
    from blender_helpers import cycles_plain, read_rgba, render_exr
    bpy = bpy_addon
    scene = fresh_scene
    scene.photonmap.subsurface_walk = walk
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.render.resolution_percentage = 100
    S._ball(bpy, scene, (0.9, 0.6, 0.3), weight)
    scene.render.engine = "CYCLES"
    cyc = {}
    for cspp, seed in ((128, 0), (128, 1), (128, 2), (4096, 0)):
        cycles_plain(scene, cspp, 8).seed = seed
        cyc[cspp, seed] = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "c.exr"))[
            ..., :3].reshape(-1, 3)
    ball = cyc[128, 0].sum(axis=1) > 0
    want = cyc[4096, 0][ball].mean(axis=0)
    c128 = [cyc[128, s][ball].mean(axis=0) / want for s in range(3)]
    print(f"SWEEP sss weight {weight} walk {walk}: Cycles 128 spp seeds 0-2 / 4096 spp "
          f"{np.round(c128, 4).tolist()}")
    t0, r = time.process_time(), []
    for s in range(N):
        scene.photonmap.seed = s
        img = S._render(bpy, scene, tmp_path / "o.exr", "PHOTONMAP", spp)
        r.append(img[ball].mean(axis=0) / want)
    _report(f"sss weight {weight} walk {walk} ours {spp} spp", r,
            (time.process_time() - t0) / N)


@pytest.mark.parametrize("key", ["aniso", "iso"])
def test_vase(bpy_addon, tmp_path, key):
    """The metal vase against its stored Cycles mean (1024 spp)."""
    import test_vase_aniso_cycles as V
    spp = int(os.environ.get("VASE_SPP", V.OUR_SPP))
    want = V._stored_means()[key]
    t0 = time.process_time()
    r = [V._vase_mean(tmp_path, key, "PHOTONMAP", spp=spp, seed=s) / want for s in range(N)]
    _report(f"vase {key} ours {spp} spp", r, (time.process_time() - t0) / N)


@pytest.mark.parametrize("sky_type, sun_disc", [("SINGLE_SCATTERING", True),
                                                ("SINGLE_SCATTERING", False),
                                                ("HOSEK_WILKIE", False)])
def test_sky(fresh_scene, bpy_addon, tmp_path, sky_type, sun_disc):
    """test_sky_cycles.py's ground (the sky pixels are the baked map: no noise) against
    Cycles at 256 spp, seed 0 (its seeds move it 0.03 %)."""
    import test_sky_cycles as K
    from blender_helpers import ROOT, luminance
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    bpy = bpy_addon
    scene = K._scene(bpy, sun_disc, sky_type)
    ref = K._render(bpy, scene, tmp_path / "c.exr", "CYCLES")
    _, ground = K._masks()
    want = luminance(ref[ground]).mean()
    t0, r = time.process_time(), []
    for s in range(N):
        scene.photonmap.seed = s
        r.append(luminance(K._render(bpy, scene, tmp_path / "o.exr", "PHOTONMAP")[ground]).mean()
                 / want)
    _report(f"sky {sky_type} disc {sun_disc} ground, ours 16 spp", r,
            (time.process_time() - t0) / N)


def test_pane_sun(fresh_scene, bpy_addon, tmp_path):
    """test_pane_sun_cycles.py: the floor's mean against Cycles (2048 spp) and the largest
    8 x 8 block's distance from the blocks' mean, ours at 16 spp."""
    import test_pane_sun_cycles as P
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    bpy = bpy_addon
    scene = fresh_scene
    P._scene(bpy, scene)
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 2048, 12).blur_glossy = 1.0
    want = float(read_rgba(bpy, render_exr(bpy, scene, tmp_path / "c.exr"))[..., :3].mean())
    scene.render.engine = "PHOTONMAP"
    spp = int(os.environ.get("PANE_SPP", "16"))
    cheap(scene, spp=spp, photons=100_000, caustic_photons=100_000)
    t0, r = time.process_time(), []
    for s in range(N):
        scene.photonmap.seed = s
        ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "o.exr"))[..., :3]
        blocks = P._blocks(ours.mean(axis=2))
        r.append([float(ours.mean()) / want, float(np.abs(blocks / blocks.mean() - 1).max())])
    _report(f"pane sun ours {spp} spp: [mean / Cycles, max block |b / mean - 1|]", r,
            (time.process_time() - t0) / N)


def _linking_sweep(bpy, scene, tmp_path, name, spp):
    """Each region of test_light_linking_cycles.py against Cycles at 4096 spp: Cycles at
    256 spp seeds 0-3, ours at spp seeds 0..N-1 (direct light)."""
    import test_light_linking_cycles as K
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    regions = K._regions()

    def means(engine, spp, seed):
        scene.render.engine = engine
        if engine == "CYCLES":
            cycles_plain(scene, spp, 0).seed = seed
        else:
            cheap(scene, spp=spp, photons=400_000, caustic_photons=0)
            scene.photonmap.photon_mapping = False
            scene.photonmap.seed = seed
        img = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "i.exr"))[..., :3].mean(axis=2)
        return np.array([img.mean()] + [img[m].mean() for m in regions.values()])

    want = means("CYCLES", 4096, 0)
    print(f"SWEEP {name} regions: image,", ", ".join(regions))
    c = [means("CYCLES", 256, s) / want for s in range(4)]
    _report(f"{name} Cycles 256 spp / 4096", c, 0.0)
    t0 = time.process_time()
    r = [means("PHOTONMAP", spp, s) / want for s in range(N)]
    _report(f"{name} ours {spp} spp / Cycles 4096", r, (time.process_time() - t0) / N)


def test_linking_fog(bpy_addon, tmp_path):
    """test_light_linking_cycles.py's world fog with the lamp unlinked."""
    import test_light_linking_cycles as K
    bpy = bpy_addon
    scene, key = K._scene(bpy)
    bpy.data.objects["Fill"].data.energy = 0.0
    nt = scene.world.node_tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_WORLD")
    fog = nt.nodes.new("ShaderNodeVolumePrincipled")
    fog.inputs["Density"].default_value = 0.15
    nt.links.new(fog.outputs[0], out.inputs["Volume"])
    scene.cycles.volume_bounces = 0
    _linking_sweep(bpy, scene, tmp_path, "linking fog", int(os.environ.get("LINK_SPP", "32")))


def test_linking_bar(bpy_addon, tmp_path):
    """test_light_linking_cycles.py's glowing bar linked to the middle cube."""
    import test_light_linking_cycles as K
    bpy = bpy_addon
    scene, _ = K.glowing_bar_scene(bpy)
    _linking_sweep(bpy, scene, tmp_path, "linking bar", int(os.environ.get("LINK_SPP", "32")))


@pytest.mark.parametrize("scene, fg", [("sharp_floor", 0.3), ("sharp_floor", 1.0),
                                       ("figure6_box", 1.0)])
def test_glossy_split(scene, fg):
    """tests/test_glossy_split.py's Cycles comparisons (split50): the floor's level
    (ours / Cycles at Filter Glossy fg) and ratio ((ours fg / ours 0) / Cycles'; the
    sharp floor's diffuse part's level too, sharpfloor51), one
    seed a draw at SPLIT_SPP (64); SPLIT_GATHER=0 / 1 sets photons.SPLIT_GATHER_PHOTONS,
    BLUR_GATHER=0 / 1 photons.BLUR_GATHER_PHOTONS (unset: the defaults)."""
    from engine import photons
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    sys.path.insert(0, os.path.join(root, "bench"))
    sys.path.insert(0, os.path.join(root, "tests"))
    import bench_glossy_split as bgs
    import test_glossy_split as T
    for var, name in (("SPLIT_GATHER", "SPLIT_GATHER_PHOTONS"),
                      ("BLUR_GATHER", "BLUR_GATHER_PHOTONS")):
        if var in os.environ:
            setattr(photons, name, os.environ[var] == "1")
    spp = int(os.environ.get("SPLIT_SPP", "64"))
    cyc = (T.SHARP_FLOOR_CYCLES if scene == "sharp_floor"
           else dict(zip((0.0, 1.0), T.CYCLES_MEANS[(scene, "Floor")])))
    t0, level, ratio, diffuse = time.process_time(), [], [], []
    for s in range(N):
        m = {}
        for f in (0.0, fg):
            film, _ = bgs.ours(scene, f, spp, s)
            lum = np.asarray(film.combined, np.float64)[..., :3] @ bgs.LUM
            floor = bgs.bfg.regions(scene, lum.shape)["Floor"]
            m[f] = float(lum[floor].mean())
            if scene == "sharp_floor" and f == fg:
                diffuse.append(float((bgs.ours_diffuse(film) @ bgs.LUM)[floor].mean())
                               / T.SHARP_FLOOR_CYCLES_DIFFUSE[fg])
        level.append(m[fg] / cyc[fg])
        ratio.append((m[fg] / m[0.0]) / (cyc[fg] / cyc[0.0]))
    cpu = (time.process_time() - t0) / N
    _report(f"{scene} Floor FG {fg} level, ours {spp} spp", level, cpu)
    _report(f"{scene} Floor FG {fg} ratio", ratio, cpu)
    if diffuse:
        _report(f"{scene} Floor FG {fg} diffuse part (sharpfloor51) level", diffuse, cpu)
