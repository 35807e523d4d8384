"""The stratified sampler's cell shift, A/B per seed (glossy02, issue 14): the camera
pass's light-point and final-gather dimensions on the linear shift (A, as before glossy02:
StratifiedSampler.uv patched to ask for no scramble for those keys) or scrambled (B, this
code). Same seed => same photon maps and pixel jitter, so the per-seed difference is the
pairing's alone. Prints per seed the pass's image mean in A and B, then the means, the
ratio A / B and the paired difference in standard errors.

usage: PYTHONPATH=. python bench/bench_cell_shift.py SCENE SPP SEED0 NSEEDS WIDTH
  SCENE: ball (a Principled ball of roughness 0.2 close up on a rough floor under one
  area light, photon mapping off, direct pass) | room (the same with a wall behind,
  photon mapping on, indirect pass)."""
import sys

import numpy as np

import engine.sampling as sampling
from engine.api import PaperScene
from engine.scene import Material
from engine.settings import RenderSettings

LINEAR = [False]
_uv = sampling.StratifiedSampler.uv


def _patched(self, key, rng=None, scrambled=True):
    # read once per call on the calling thread; the flag is set between renders only
    if LINEAR[0] and key[0] in ("light", "gather"):
        scrambled = False
    return _uv(self, key, rng=rng, scrambled=scrambled)


def scene(kind, width):
    s = PaperScene(width=width, height=width)
    s.add_material(Material("ball", (0.8, 0.3, 0.2), roughness=0.2, specular=1.0))
    s.add_material(Material("floor", (0.5, 0.5, 0.5), roughness=0.7))
    s.add_sphere((0, 0, 0.5), 0.5, "ball", name="ball")
    s.add_plane((0, 0, 0), (0, 0, 1), 12.0, "floor", name="floor")
    if kind == "room":
        s.add_material(Material("wall", (0.2, 0.6, 0.3)))
        s.add_plane((0.7, 0, 1.0), (-1, 0, 0), 4.0, "wall", name="wall")
    s.add_rect_area_light((-0.5, -0.8, 2.0), size=(0.4, 0.4), power=200.0,
                          direction=(0.25, 0.4, -0.75))
    s.set_camera((-1.6, 0.0, 0.9), (0.0, 0.0, 0.5), up=(0, 0, 1), view_angle=35.0)
    return s


def main():
    kind, spp, s0, ns, width = sys.argv[1], *map(int, sys.argv[2:6])
    sampling.StratifiedSampler.uv = _patched
    sc = scene(kind, width)
    kw = (dict(photon_mapping=False) if kind == "ball"
          else dict(photons=20000, caustic_photons=2000))
    name = "direct" if kind == "ball" else "indirect"
    rows = []
    for seed in range(s0, s0 + ns):
        row = []
        for linear in (True, False):
            LINEAR[0] = linear
            film = sc.render(RenderSettings(spp=spp, seed=seed, workers=1, **kw))
            row.append(float(np.asarray(getattr(film, name), np.float64).mean()))
        rows.append(row)
        print(seed, *("%.6f" % v for v in row), flush=True)
    a = np.array(rows)
    d = a[:, 0] - a[:, 1]
    se = d.std(ddof=1) / np.sqrt(len(d))
    print(f"{kind} {name} {spp} spp, {ns} seeds: linear {a[:, 0].mean():.5f} scrambled "
          f"{a[:, 1].mean():.5f} ratio {a[:, 0].mean() / a[:, 1].mean():.5f} "
          f"diff {d.mean():.2e} +- {se:.2e} ({d.mean() / se:.1f} SE), "
          f"linear lower in {(d < 0).sum()} seeds")


if __name__ == "__main__":
    main()
