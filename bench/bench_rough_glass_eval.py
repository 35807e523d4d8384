"""A sun through one rough glass interface, seen from the dense side (the pane tests' floor
under a single-plane pane): the refraction's directional transmittance
integral of f |cos_o| |cos_i| over the camera's hemisphere (midpoint quadrature, 400 x 800
cells), by Cycles' bsdf_microfacet_eval (written out in
tests/test_rough_glass_cycles_eval.py), by ours' principled.eval_transmission_many, and
over Walter et al.'s valid pairs alone (ours before roughglass47; the photons' sampler).
Prints one line per roughness and sun angle (docs/accuracy.md "roughglass47").

    PYTHONPATH=$PWD .venv/bin/python bench/bench_rough_glass_eval.py
"""
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))


def main():
    from engine.closures import principled as pr
    import test_rough_glass_cycles_eval as t
    n = 400
    u = (np.arange(n) + 0.5) / n
    th = np.arccos(1.0 - u)
    ph = 2 * math.pi * (np.arange(2 * n) + 0.5) / (2 * n)
    T, P = np.meshgrid(th, ph, indexing="ij")
    wi = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)],
                  -1).reshape(-1, 3)
    dw = 2 * math.pi / (n * 2 * n)
    eta = 1.0 / 1.5
    print("roughness  sun  Cycles  ours   valid pairs  valid / Cycles")
    for rough in (0.3, 0.6, 0.7, 1.0):
        prm = np.repeat(t._packed(rough, 1.5, 1.0, False), len(wi), axis=0)
        for sun in (0.0, 30.0, 60.0):
            s = math.radians(sun)
            wo = np.tile([math.sin(s), 0.0, -math.cos(s)], (len(wi), 1))
            ev = np.empty((len(wi), 4))
            pr.eval_transmission_many(prm, np.tile([0.0, 0.0, 1.0], (len(wi), 1)), wi, wo,
                                      ev)
            f, _ = t.cycles_refraction_eval(wi, wo, rough ** 2, eta)
            c = float((f * wi[:, 2]).sum() * dw)
            o = float((ev[:, 0] * wi[:, 2]).sum() * dw)
            v = float((np.where(t._valid(wi, wo, eta), f, 0.0) * wi[:, 2]).sum() * dw)
            print(f"{rough:9.1f} {sun:4.0f}  {c:.4f}  {o:.4f}  {v:.4f}       {v / c:.4f}")


if __name__ == "__main__":
    main()
