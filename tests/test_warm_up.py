"""The compiled kernels' warm-up (engine/jit.py) compiles every variant a render uses:
after ensure_compiled(), a render adds no signature to any kernel (a new signature is a
compile inside the user's first render, seconds to minutes after a new cache)."""
import sys

import numba

from engine import directlight
from engine.api import cornell_box
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings


def _signatures() -> dict:
    out = {}
    for name, module in list(sys.modules.items()):
        if not name.startswith("engine") or module is None:
            continue
        for attr, value in vars(module).items():
            if isinstance(value, numba.core.registry.CPUDispatcher):
                out[f"{value.py_func.__module__}.{value.__name__}"] = len(value.signatures)
    return out


def test_a_render_after_the_warm_up_compiles_no_kernel():
    ensure_compiled()
    before = _signatures()
    # Smooth glass sphere (corner normals: terminator_lift's float32 (T,3,3) table), area
    # light, photons with caustics and final gathering: the default render's kernels.
    render(cornell_box(24, 18), RenderSettings(workers=1, spp=1, photons=3000,
                                               caustic_photons=1000, seed=3))
    after = _signatures()
    added = {k: (before.get(k, 0), v) for k, v in after.items() if v != before.get(k, 0)}
    assert not added, f"kernels compiled inside the render (signatures before, after): {added}"
    assert len(directlight.terminator_lift.signatures) == 1
