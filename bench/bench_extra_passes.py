"""What Ambient Occlusion, Vector and Light Group passes cost (passes41, issue 14): the
same render without them, with AO and Vector (engine/aopass.py, engine/vectorpass.py) and
with 1, 2 and 4 light groups (engine/lightgroups.py: a photon and camera pass of its
own each), wall seconds (best of --repeat), and whether the image's bits stay.

Scene: a grey floor with two boxes, two point lamps, an emissive panel and a grey
world (4 emitters, each in its own group), --size (160x120), --spp 16, 100k photons.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_extra_passes.py [--size 160x120]
        [--spp 16] [--workers 2] [--repeat 2]
"""
from __future__ import annotations

import argparse
import hashlib
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402

from engine import RenderSettings  # noqa: E402
from engine.api import PaperScene  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.scene import Material, Mesh  # noqa: E402
from engine.vectorpass import SceneMotion  # noqa: E402

GROUPS = ("lamp_a", "lamp_b", "panel", "sky")


def _quad(z, half):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]],
                 float)
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def scene(width, height):
    s = PaperScene(width, height, background=(0.2, 0.2, 0.25))
    s.add_material(Material("grey", (0.6, 0.6, 0.6)))
    s.add_material(Material("glow", (0.5, 0.5, 0.5), emission=(4.0, 2.0, 1.0)))
    v, f = _quad(0.0, 4.0)
    s.add_mesh(Mesh("floor", v, f, materials=["grey"]))
    s.add_box((-0.8, 0.3, 0.5), 1.0, "grey", "box_a")
    s.add_box((1.0, 0.8, 0.4), 0.8, "grey", "box_b")
    v, f = _quad(0.0, 0.3)
    panel = Mesh("panel", v + [0.0, 1.8, 0.9], f, materials=["glow"], lightgroup="panel")
    s.add_mesh(panel)
    s.add_point_light((1.5, -1.0, 2.5), power=300.0)
    s.add_point_light((-1.5, 0.5, 2.0), power=150.0)
    s.lights[0].lightgroup, s.lights[1].lightgroup = "lamp_a", "lamp_b"
    s.world_lightgroup = "sky"
    s.set_camera((0.0, -5.5, 2.6), (0.0, 0.6, 0.2), up=(0.0, 0.0, 1.0), view_angle=50)
    shift = np.zeros((3, 4))
    shift[:, :3] = np.eye(3)
    shift[0, 3] = 0.05
    s.vector_motion = SceneMotion(objects={"box_a": (shift, shift)})
    return s


def film_hash(film):
    h = hashlib.sha1()
    for name in ("direct", "indirect", "caustic", "specular", "emission"):
        h.update(np.ascontiguousarray(getattr(film, name)).tobytes())
    return h.hexdigest()[:12]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args(argv)
    w, h = (int(x) for x in args.size.split("x"))
    ensure_compiled()
    cases = [("none", {}), ("ao + vector", dict(data_passes=("ao", "vector"))),
             ("1 light group", dict(light_groups=GROUPS[:1])),
             ("2 light groups", dict(light_groups=GROUPS[:2])),
             ("4 light groups", dict(light_groups=GROUPS))]
    print(f"{'passes':<16} {'seconds':>8} {'x none':>7}  image bits")
    base = None
    for label, kw in cases:
        best, film = float("inf"), None
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            film = render(scene(w, h), RenderSettings(workers=args.workers, spp=args.spp,
                                                      seed=1, photons=100_000,
                                                      caustic_photons=10_000, **kw))
            best = min(best, time.perf_counter() - t0)
        base = best if base is None else base
        print(f"{label:<16} {best:8.2f} {best / base:7.2f}  {film_hash(film)}", flush=True)


if __name__ == "__main__":
    main()
