"""The gather points' secondary-caustic share (GatherMap.secondary_E, regather29) against
the secondary map's own k-NN estimate (photon visibility, its radius) at the same points,
split into points whose estimate disc is whole and boundary points: sum ratio and the
share's part of the points' E. Cornell box with a glass ball, 30k + 10k photons, seed 2.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_secondary_share.py"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from engine import RenderSettings  # noqa: E402
from engine.api import cornell_box  # noqa: E402
from engine.integrator import smooth_min_photons  # noqa: E402
from engine.photonvisibility import visible_irradiance  # noqa: E402
from engine.render import _photon_pass, prepare_context  # noqa: E402


def main():
    ctx = prepare_context(cornell_box(32, 24, glass_sphere=True),
                          RenderSettings(workers=1, photons=30_000, caustic_photons=10_000,
                                         seed=2))
    _photon_pass(ctx, {}, None, None)
    g, s = ctx.gather_map.complete(), ctx.settings  # (every point's estimates: read whole)
    print("| points | count | share / k-NN estimate (sums) | share / the points' E |")
    print("|---|---:|---:|---:|")
    for name, sel in (("disc whole", ~g.boundary), ("boundary", g.boundary)):
        E = visible_irradiance(ctx.regather_secondary[0], ctx.accel, g.position[sel],
                               g.normal[sel], None, ctx.secondary_radius, s.k_nearest,
                               smooth_min_photons(s), s.estimator, limits=s.bounce_limits,
                               geo=ctx.geo)
        share = g.secondary_E[sel]
        print(f"| {name} | {int(sel.sum()):,} | {share.sum() / E.sum():.3f} | "
              f"{share.sum() / g.E[sel].sum():.4f} |")
    ctx.accel.close()


if __name__ == "__main__":
    main()
