"""How often a photon's stored reverse pdf through rough glass decides Filter Glossy's
split otherwise than the photon's own forward pdf did (docs/compatibility.md
"splitmaps47"): random refraction pairs through a Principled glass (IOR 1.5) from
outside in and inside out, at several roughnesses; the pdf the camera side takes
(principled.reverse_transmission_pdf, Cycles' bsdf_microfacet.h seen from the far side)
against the forward one (transmission_pdf: what photonkernels.reverse_pdf stored before
splitmaps47). Per case: the median ratio reverse / forward over the valid pairs, and the
share of them whose decision (pdf >= Filter Glossy) differs at 0.1, 0.3 and 1.

    PYTHONPATH=$PWD .venv/bin/python bench/splitmaps47_reverse.py
"""
from __future__ import annotations

import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from engine.closures import principled as pr  # noqa: E402
from engine.geometry import closure_params  # noqa: E402
from engine.scene import Material  # noqa: E402


def hemisphere(rng, n, min_z=0.02):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + min_z
    return v / np.linalg.norm(v, axis=1)[:, None]


def main():
    rng = np.random.default_rng(0)
    n = 20_000
    print("| roughness | side | valid pairs | median reverse / forward | decisions differing at FG 0.1 / 0.3 / 1 |")
    print("|---:|---|---:|---:|---|")
    for rough in (0.1, 0.3, 0.5, 0.7):
        m = Material("glass", (1.0, 1.0, 1.0), transmission=1.0, roughness=rough, ior=1.5)
        for front, side in ((True, "outside in"), (False, "inside out")):
            prm, w = pr.setup_np(closure_params([m]), np.zeros(1, np.int64),
                                 np.asarray([m.base_color], np.float64), np.full(1, 0.6),
                                 np.full(1, front))
            sel = np.zeros((1, pr.N_LOBES))
            sel[0, pr.L_GLASS_R] = sel[0, pr.L_GLASS_T] = 0.5
            came, left = hemisphere(rng, n), -hemisphere(rng, n)
            fwd = np.array([pr.transmission_pdf(prm, sel, 0, *came[j], *left[j])
                            for j in range(n)])
            rev = np.array([pr.reverse_transmission_pdf(prm, sel, 0, *came[j], *left[j])
                            for j in range(n)])
            ok = (fwd > 0) & (rev > 0)
            ratio = np.median(rev[ok] / fwd[ok])
            flips = " / ".join(f"{100 * np.mean((fwd[ok] >= fg) != (rev[ok] >= fg)):.1f} %"
                               for fg in (0.1, 0.3, 1.0))
            print(f"| {rough} | {side} | {int(ok.sum())} | {ratio:.3f} | {flips} |")


if __name__ == "__main__":
    main()
