"""The gather map's float32 levels and narrow neighbour tables against another checkout's
films (docs/performance.md "hdri52"): tools/film_hashes.py's renders (80 x 60, 16 spp, 1
worker, default settings) of each blend, BASE's in a child process (its own engine) and
this checkout's here. Prints both films' hashes and the change of the summed passes:
relMSE (mean (new - base)^2 / (base^2 + 0.01)), max abs, mean abs over the mean, and the
largest change relative to the pixel (|new - base| / base where base > 1e-3).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_level_films.py BASE \\
        [figure3_sphere,figure6_box,figure7_blocker,figure8_caustic,hdri_sphere]

(BASE: e.g. `git worktree add --detach /tmp/base main`; the blends' exports are the ones
tools/film_hashes.py writes into $TMPDIR/film_hashes/.)
"""
import os
import pickle
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "tools"), os.path.join(ROOT, "bench")]

import numpy as np  # noqa: E402

import film_hashes as fh  # noqa: E402
from bench_kernels import exported  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

CHILD = r"""
import pickle, sys
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
ensure_compiled()
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = 80, 60
film = render(scene, RenderSettings(workers=1, spp=16))
np.savez(OUT, **{p: np.asarray(getattr(film, p)) for p in PASSES})
"""


def base_passes(base, pickle_path, out):
    code = (f"ROOT={base!r}; PICKLE={pickle_path!r}; OUT={out!r}; "
            f"PASSES={fh.PASSES!r}\n" + CHILD)
    subprocess.run([sys.executable, "-c", code], check=True)
    with np.load(out) as z:
        return {p: z[p] for p in fh.PASSES}


def passes_hash(passes) -> str:
    import hashlib
    h = hashlib.sha1()
    for p in fh.PASSES:
        h.update(np.ascontiguousarray(passes[p]).tobytes())
    return h.hexdigest()


def main(base, blends):
    ensure_compiled()
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    print("| blend | base | this | relMSE | max abs | mean abs / mean | max rel |")
    print("|---|---|---|---:|---:|---:|---:|")
    for name in blends.split(","):
        path = exported(name, where)
        old = base_passes(os.path.abspath(base), path, os.path.join(where, name + ".base.npz"))
        with open(path, "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = 80, 60
        film = render(scene, RenderSettings(workers=1, spp=16))
        new = {p: np.asarray(getattr(film, p)) for p in fh.PASSES}
        a = sum(np.asarray(old[p], np.float64) for p in fh.PASSES)
        b = sum(np.asarray(new[p], np.float64) for p in fh.PASSES)
        rel = np.mean((b - a) ** 2 / (a * a + 1e-2))
        lit = a > 1e-3
        max_rel = float((np.abs(b - a)[lit] / a[lit]).max()) if lit.any() else 0.0
        print(f"| {name} | {passes_hash(old)[:8]} | {fh.film_hash(film)[:8]} | {rel:.2e} | "
              f"{np.abs(b - a).max():.2e} | {np.abs(b - a).mean() / a.mean():.2e} | "
              f"{max_rel:.2e} |", flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else
         "figure3_sphere,figure6_box,figure7_blocker,figure8_caustic,hdri_sphere")
