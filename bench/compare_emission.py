"""Photon emission: this checkout's kernels against an older checkout's numpy emission
(before engine/lights/emission.py, e.g. 19b2e00), fed the same uniform numbers.

    .venv/bin/python bench/compare_emission.py OLD_CHECKOUT

Runs itself twice: in this checkout (the kernels' photons and every slot's emission
numbers, saved to a temporary .npz) and, in a child process, with OLD_CHECKOUT first on
sys.path (its lights' numpy _emit / emit_towards, handed those numbers in the order they
drew them). Prints per light kind and mode (natural, aimed) the share of rows whose
float32 origins and float64 directions are bitwise equal, the largest relative power
difference and the relative difference of the summed power. Table in
docs/performance.md, "Fourth slice: photon emission".
"""
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

NPZ = os.path.join(tempfile.gettempdir(), f"compare_emission_{os.getuid() if hasattr(os, 'getuid') else 0}.npz")

N = 20000
TARGETS = (np.array([[0.3, 0.1, 0.4], [-0.5, 0.2, 0.6]]), np.array([0.25, 0.4]))


def scene_lights():
    from engine.geometry import prepare
    from engine.lights import prepare_lights
    from engine.scene import Light, Material
    from engine.lights.environment import Environment
    from helpers import top_down_plane
    out = {}
    def add(name, light=None, env=None, emissive=False, background=None):
        s = top_down_plane()
        if light is not None:
            s.add_light(light)
        if env is not None:
            s.environment = env
        if background is not None:
            s.background = background
        if emissive:
            s.add_material(Material("glow", (0.5, 0.5, 0.5), emission=(2.0, 1.5, 1.0)))
            s.add_sphere((0.2, -0.3, 0.8), 0.3, "glow", name="lamp", segments=8)
        s.validate()
        geo, table = prepare(s)
        lights = prepare_lights(s, geo, table)
        out[name] = lights[0] if light is not None else lights[-1]
    add("point", Light("p", "POINT", 100.0, position=(0.1, 0.2, 2.0)))
    add("point_r", Light("p", "POINT", 100.0, position=(0.1, 0.2, 2.0), radius=0.3))
    frame = np.stack([np.array([1.0, 0, 0]) / 2.0, np.array([0, 1.0, 0]) / 0.5, np.array([0, 0, -1.0])])
    add("spot", Light("s", "SPOT", 100.0, position=(0, 0, 3), direction=(0, 0, -1),
                      spot_size=math.radians(40), spot_blend=0.3))
    add("spot_r_scaled", Light("s", "SPOT", 100.0, position=(0, 0, 3), direction=(0.2, 0, -1),
                               spot_size=math.radians(40), spot_blend=0.2, radius=0.2, spot_frame=frame))
    add("area_rect", Light("a", "AREA", 50.0, position=(0, 0, 2), direction=(0.1, 0, -1), size_x=1.0, size_y=0.5))
    add("area_disk", Light("a", "AREA", 50.0, position=(0, 0, 2), direction=(0, 0, -1), size_x=1.0, size_y=1.0, shape="DISK"))
    add("area_ellipse_spread", Light("a", "AREA", 50.0, position=(0, 0, 2), direction=(0, 0, -1), size_x=1.0, size_y=0.4,
                                     shape="DISK", spread=math.radians(40)))
    v = np.array([math.cos(math.radians(60)), math.sin(math.radians(60)), 0.0])
    add("area_sheared", Light("a", "AREA", 50.0, position=(0, 0, 2), direction=(0, 0, -1), size_x=1.0, size_y=0.5, skew_axis_v=v))
    add("sun", Light("sun", "SUN", 3.0, direction=(0.3, 0.2, -1)))
    add("sun_angle", Light("sun", "SUN", 3.0, direction=(0.3, 0.2, -1), angle=math.radians(10)))
    add("mesh", emissive=True)
    add("world", background=(0.2, 0.3, 0.4))
    rng = np.random.default_rng(3)
    px = rng.random((12, 24, 3)) ** 3
    px[2, 5] = 300.0
    add("world_env", env=Environment(px, 1.3, None, "Linear"))
    return out


def step_new():
    from engine.lights.emission import EmissionBuffers, emission_uniforms
    key = np.uint64(0x1234567890ABCDEF)
    res = {}
    for name, light in scene_lights().items():
        u = emission_uniforms(key, np.arange(N), 7)
        res[name + "/u"] = u
        for aimed in (False, True):
            out = EmissionBuffers(N)
            m = (light.emit_towards_into(key, 0, N, N, TARGETS, out, 0) if aimed
                 else light.emit_into(key, 0, N, N, out, 0))
            o32, d32, d, power, slot = out.head(m)
            tag = f"{name}/{'aimed' if aimed else 'natural'}"
            res[tag + "/o32"], res[tag + "/d"], res[tag + "/power"], res[tag + "/slot"] = o32, d, power, slot
    np.savez(NPZ, **res)


class FakeRng:
    """Hands the old emission code the kernels' numbers: random() the next dimension in
    the order the old code drew them, choice() the target choice as numpy's Generator
    makes it (searchsorted on the normalised CDF)."""
    def __init__(self, seq, choice):
        self.seq, self.choice_u = list(seq), choice
    def random(self, n=None):
        return self.seq.pop(0)
    def choice(self, K, size=None, p=None):
        cdf = np.cumsum(p); cdf /= cdf[-1]
        return cdf.searchsorted(self.choice_u, side="right")


ORDER = {  # (natural random sequence, aimed sequence, aimed choice dim) in old draw order
    "point": ([0, 1, 2, 3], [1, 2, 3, 4], 0), "spot": ([0, 1, 2, 3], [1, 2, 3, 4, 5, 6], 0),
    "area": ([0, 1, 2, 3], [1, 2, 3, 4], 0), "sun": ([0, 1, 2, 3], [0, 1, 3, 4], 2),
    "mesh": ([1, 2, 3, 4, 0, 5], [1, 2, 3, 4, 0], 5), "world": ([0, 1, 2, 3], [0, 1, 3, 4], 2)}


def step_base():
    new = np.load(NPZ)
    lights = scene_lights()
    print(f"{'light':22s} {'mode':8s} {'rows':>6s} {'o32 equal':>10s} {'d equal':>8s} {'max |d|':>9s} {'power max rel':>13s} {'flux rel':>9s}")
    for name, light in lights.items():
        kind = name.split("_")[0]
        u = new[name + "/u"]
        for aimed in (False, True):
            tag = f"{name}/{'aimed' if aimed else 'natural'}"
            nat, aim_seq, cdim = ORDER[kind]
            if not aimed:
                rng = FakeRng([u[:, k] for k in nat], None)
                u1, u2, u3, u4 = (rng.random(N) for _ in range(4))
                o, d, power = light._emit(N, rng, u1, u2, u3, u4)
            else:
                rng = FakeRng([u[:, k] for k in aim_seq], u[:, cdim])
                o, d, power = light.emit_towards(N, rng, *TARGETS)
            live = np.maximum(np.maximum(power[:, 0], power[:, 1]), power[:, 2]) > 0
            o, d, power = o[live], d[live], power[live]
            slot = np.nonzero(live)[0]
            ko, kd, kp, ks = (new[tag + "/" + k] for k in ("o32", "d", "power", "slot"))
            same_rows = len(ks) == len(slot) and np.array_equal(ks, slot)
            if not same_rows:
                common = np.intersect1d(ks, slot)
                print(f"  {tag}: rows differ: kernel {len(ks)} numpy {len(slot)} common {len(common)}")
                ki = np.searchsorted(ks, common); ni = np.searchsorted(slot, common)
                ko, kd, kp = ko[ki], kd[ki], kp[ki]; o, d, power = o[ni], d[ni], power[ni]
            o_eq = np.mean(ko == o.astype(np.float32))
            d_eq = np.mean(kd == d)
            dmax = np.abs(kd - d).max() if len(d) else 0
            prel = (np.abs(kp - power) / np.maximum(np.abs(power), 1e-300)).max() if len(d) else 0
            frel = abs(kp.sum() - power.sum()) / max(abs(power.sum()), 1e-300)
            print(f"{name:22s} {'aimed' if aimed else 'natural':8s} {len(kp):6d} {o_eq:10.4f} {d_eq:8.4f} {dmax:9.2e} {prel:13.2e} {frel:9.2e}")


if __name__ == "__main__":
    if len(sys.argv) == 3:  # the child: python compare_emission.py ROOT base
        root = os.path.abspath(sys.argv[1])
        sys.path.insert(0, os.path.join(root, "tests"))
        sys.path.insert(0, root)
        step_base()
    else:
        here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        sys.path.insert(0, os.path.join(here, "tests"))
        sys.path.insert(0, here)
        step_new()
        subprocess.run([sys.executable, os.path.abspath(__file__), sys.argv[1], "base"],
                       check=True)
