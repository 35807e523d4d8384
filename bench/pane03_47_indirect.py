"""Where ours' light of a rough pane under a sun goes past Cycles' at Filter Glossy 1
(pane03_47; docs/accuracy.md "pane03_47"). The scene of
bench/bench_split_rough_glass.py pane R GGX (tests/blender/test_pane_sun_cycles.py's, the
pane made rough); Cycles 2048 spp, ours 16 spp, 100k / 100k photons, seed 0, clamps off,
both at Filter Glossy 1. Prints one line per render (ours with its passes).

    PYTHONPATH=$PWD .venv/bin/python bench/pane03_47_indirect.py [ROUGH ...]
        Cycles at Light Paths > Diffuse 4 and 1; ours: full, Diffuse 1, the photons of
        kinds INDIRECT and CAUSTIC_DIFFUSE with a glossy count (all of them here: they
        reflected off the pane's underside) at power 0 before render._build_maps, and
        glossysplit.ENABLED off
    PYTHONPATH=$PWD .venv/bin/python bench/pane03_47_indirect.py limits
        both engines at Diffuse 1-4, roughness 0.3 and 0.6; the global shot's photons by
        kind and (diffuse, glossy, transmission) count
    PYTHONPATH=$PWD .venv/bin/python bench/pane03_47_indirect.py kinds
        Cycles' own passes at 0.3; ours with the INDIRECT, then the CAUSTIC_DIFFUSE
        (secondary map) photons alone at power 0, at 0.3 and 0.6
    PYTHONPATH=$PWD .venv/bin/python bench/pane03_47_indirect.py fg0
        both engines at Filter Glossy 0, Diffuse 1 and 4, 0.3 and 0.6; ours also with the
        CAUSTIC_DIFFUSE photons at power 0
    PYTHONPATH=$PWD .venv/bin/python bench/pane03_47_indirect.py cuts
        ours at 0.3, Diffuse 1-3, nothing / CAUSTIC_DIFFUSE (3) / INDIRECT (2) at power 0
"""
import os
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))


def main():
    import bpy
    import addon
    import blender_helpers as bh
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    from engine import glossysplit
    from engine.photonkernels import CAUSTIC_DIFFUSE, INDIRECT
    rd = sys.modules["engine.render"]
    orig_bm = rd._build_maps
    tmp = tempfile.mkdtemp(prefix="pane03_")
    import test_pane_sun_cycles as ps

    def build(rough):
        bpy.ops.wm.read_homefile(use_empty=True)
        s = bpy.context.scene
        ps._scene(bpy, s)
        s.cycles.pixel_filter_type, s.cycles.filter_width = "BOX", 1.0
        g = bpy.data.materials["Glass"].node_tree.nodes["Glass BSDF"]
        g.inputs["Roughness"].default_value = rough
        g.distribution = "GGX"
        return s

    def mean(s, engine, name, passes=False):
        s.render.engine = engine
        path = bh.render_exr(bpy, s, os.path.join(tmp, name), multilayer=passes)
        if passes:
            L = bh.read_layers(path)
            return (float(L["Combined"][..., :3].mean()),
                    {k: round(float(v[..., :3].mean()), 4) for k, v in L.items()
                     if k not in ("Combined", "Photon Hits")})
        return float(bh.read_rgba(bpy, path)[..., :3].mean())

    cut_kinds = [(INDIRECT, CAUSTIC_DIFFUSE)]

    def no_reflected(ctx, shot, *a, **kw):
        b = np.asarray(shot.bounces, np.int64)
        gm = np.isin(shot.kind, cut_kinds[0])
        cut = gm & (b[:, 2] > 0)
        p = shot.power.astype(np.float64).sum(axis=1)
        print(f"  gather-kind photons reflected off the pane: {100 * p[cut].sum() / max(p[gm].sum(), 1e-30):.1f} % of their power", flush=True)
        shot.power[cut] = 0
        return orig_bm(ctx, shot, *a, **kw)

    def stats(ctx, shot, *a, **kw):
        b = np.asarray(shot.bounces, np.int64)
        p = shot.power.astype(np.float64).sum(axis=1)
        rows = {}
        for k, d, g, t in zip(shot.kind, b[:, 1], b[:, 2], b[:, 3]):
            key = (int(k), int(d), int(g), int(t))
            rows[key] = rows.get(key, 0) + 1
        tot = p.sum()
        for key in sorted(rows):
            sel = ((shot.kind == key[0]) & (b[:, 1] == key[1]) & (b[:, 2] == key[2])
                   & (b[:, 3] == key[3]))
            print(f"  kind {key[0]} (diffuse, glossy, transmission) {key[1:]}: "
                  f"{rows[key]} photons, {100 * p[sel].sum() / tot:.2f} % of power", flush=True)
        return orig_bm(ctx, shot, *a, **kw)

    if sys.argv[1:2] == ["fg0"]:
        def cut3(ctx, shot, *a, **kw):
            shot.power[shot.kind == CAUSTIC_DIFFUSE] = 0
            return orig_bm(ctx, shot, *a, **kw)
        for rough in (0.3, 0.6):
            for db in (1, 4):
                s = build(rough)
                c = bh.cycles_plain(s, 2048, 12)
                c.diffuse_bounces = db
                cy = mean(s, "CYCLES", f"f{rough}{db}.exr")
                out = []
                for v in ("full", "cut"):
                    s = build(rough)
                    s.cycles.blur_glossy = 0.0
                    s.cycles.sample_clamp_indirect = s.cycles.sample_clamp_direct = 0.0
                    s.cycles.diffuse_bounces = db
                    bh.cheap(s, spp=16, photons=100_000, caustic_photons=100_000)
                    s.photonmap.seed = 0
                    rd._build_maps = cut3 if v == "cut" else orig_bm
                    try:
                        out.append(mean(s, "PHOTONMAP", f"f{rough}{db}{v}.exr", passes=True))
                    finally:
                        rd._build_maps = orig_bm
                print(f"rough {rough} FG 0 Diffuse {db}: Cycles {cy:.4f}, ours {out[0][0]:.4f} "
                      f"({out[0][0] / cy:.4f}) {out[0][1]}; CAUSTIC_DIFFUSE at power 0: "
                      f"{out[1][0]:.4f} {out[1][1]}", flush=True)
        return
    if sys.argv[1:2] == ["cuts"]:
        def cut(ctx, shot, *a, **kw):
            shot.power[np.isin(shot.kind, cut_kinds[0])] = 0
            return orig_bm(ctx, shot, *a, **kw)
        for db in (1, 2, 3):
            for kinds in ((), (CAUSTIC_DIFFUSE,), (INDIRECT,)):
                cut_kinds[0] = kinds
                s = build(0.3)
                s.cycles.blur_glossy = 1.0
                s.cycles.sample_clamp_indirect = s.cycles.sample_clamp_direct = 0.0
                s.cycles.diffuse_bounces = db
                bh.cheap(s, spp=16, photons=100_000, caustic_photons=100_000)
                s.photonmap.seed = 0
                rd._build_maps = cut
                try:
                    o, passes = mean(s, "PHOTONMAP", f"x{db}{kinds}.exr", passes=True)
                finally:
                    rd._build_maps = orig_bm
                print(f"rough 0.3 ours Diffuse {db}, kinds {kinds} at power 0: {o:.4f} "
                      f"{passes}", flush=True)
        return
    if sys.argv[1:2] == ["kinds"]:
        s = build(0.3)
        c = bh.cycles_plain(s, 2048, 12)
        c.blur_glossy = 1.0
        vl = s.view_layers[0]
        vl.use_pass_diffuse_direct = vl.use_pass_diffuse_indirect = True
        vl.use_pass_transmission_direct = vl.use_pass_transmission_indirect = True
        vl.use_pass_glossy_direct = vl.use_pass_glossy_indirect = True
        cy, cp = mean(s, "CYCLES", "kc.exr", passes=True)
        print(f"rough 0.3 Cycles FG 1: {cy:.4f} {cp}", flush=True)
        for name, kinds in (("INDIRECT", (INDIRECT,)), ("CAUSTIC_DIFFUSE", (CAUSTIC_DIFFUSE,))):
            cut_kinds[0] = kinds
            for rough in (0.3, 0.6):
                s = build(rough)
                s.cycles.blur_glossy = 1.0
                s.cycles.sample_clamp_indirect = s.cycles.sample_clamp_direct = 0.0
                bh.cheap(s, spp=16, photons=100_000, caustic_photons=100_000)
                s.photonmap.seed = 0
                rd._build_maps = no_reflected
                try:
                    o, passes = mean(s, "PHOTONMAP", f"k{rough}{name}.exr", passes=True)
                finally:
                    rd._build_maps = orig_bm
                print(f"rough {rough} ours, kind {name} photons' power 0: {o:.4f} {passes}",
                      flush=True)
        return
    if sys.argv[1:2] == ["limits"]:
        for rough in (0.3, 0.6):
            line = []
            for db in (1, 2, 3, 4):
                s = build(rough)
                c = bh.cycles_plain(s, 2048, 12)
                c.blur_glossy = 1.0
                c.diffuse_bounces = db
                cy = mean(s, "CYCLES", f"lc{rough}_{db}.exr")
                s = build(rough)
                s.cycles.blur_glossy = 1.0
                s.cycles.sample_clamp_indirect = s.cycles.sample_clamp_direct = 0.0
                s.cycles.diffuse_bounces = db
                bh.cheap(s, spp=16, photons=100_000, caustic_photons=100_000)
                s.photonmap.seed = 0
                rd._build_maps = stats if db == 4 else orig_bm
                try:
                    o, passes = mean(s, "PHOTONMAP", f"lo{rough}_{db}.exr", passes=True)
                finally:
                    rd._build_maps = orig_bm
                line.append((db, cy, o, passes))
                print(f"rough {rough} Diffuse {db}: Cycles {cy:.4f}, ours {o:.4f} "
                      f"({o / cy:.4f}) {passes}", flush=True)
        return
    for rough in [float(x) for x in (sys.argv[1:] or ["0.3", "0.6"])]:
        C = {}
        for db in (4, 1):
            s = build(rough)
            c = bh.cycles_plain(s, 2048, 12)
            c.blur_glossy = 1.0
            c.diffuse_bounces = db
            C[db] = mean(s, "CYCLES", f"c{rough}_{db}.exr")
        print(f"rough {rough} Cycles FG 1: Diffuse 4 {C[4]:.4f}, Diffuse 1 {C[1]:.4f}, "
              f"difference {C[4] - C[1]:.4f}", flush=True)
        for v in ("full", "diffuse1", "noreflected", "splitoff"):
            s = build(rough)
            s.cycles.blur_glossy = 1.0
            s.cycles.sample_clamp_indirect = s.cycles.sample_clamp_direct = 0.0
            if v == "diffuse1":
                s.cycles.diffuse_bounces = 1
            bh.cheap(s, spp=16, photons=100_000, caustic_photons=100_000)
            s.photonmap.seed = 0
            rd._build_maps = no_reflected if v == "noreflected" else orig_bm
            glossysplit.ENABLED = v != "splitoff"
            try:
                o, passes = mean(s, "PHOTONMAP", f"o{rough}_{v}.exr", passes=True)
            finally:
                rd._build_maps = orig_bm
                glossysplit.ENABLED = True
            ref = C[1] if v == "diffuse1" else C[4]
            print(f"rough {rough} ours {v}: {o:.4f} ({o / ref:.4f} of Cycles "
                  f"{'Diffuse 1' if v == 'diffuse1' else 'Diffuse 4'}) {passes}", flush=True)


if __name__ == "__main__":
    main()
