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


def test_renders_of_many_scene_kinds_after_the_warm_up_compile_no_kernel():
    """A fresh process (earlier tests cannot have compiled the variant already) warms up,
    then renders tests/warm_up_scenes.py's scenes: a world HDRI, every light kind (point
    and spot with a radius, sun with an angle, area, an emissive mesh), an image texture
    and a textured roughness, a normal map, instances, data passes, adaptive sampling, a
    transparent film. No kernel may gain a signature: a new one is a compile inside the
    user's first render of such a scene (the new-user trial's "compiling again")."""
    import json
    import os
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=str(root))
    res = subprocess.run([sys.executable, str(root / "tests" / "warm_up_scenes.py")],
                         cwd=root, env=env, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    added = json.loads(res.stdout.strip().splitlines()[-1])
    assert added == {}, f"kernels compiled inside a render, by scene: {added}"
