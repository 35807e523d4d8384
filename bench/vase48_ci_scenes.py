"""The two scenes that kept turnedglossy.DIFFUSE off (s47's CI), with it on and off.

    PYTHONPATH=$PWD .venv/bin/python bench/vase48_ci_scenes.py

tests/test_scenefile_instances.py's plastic spheres as instances on shared rows
(resources.INSTANCE_BUDGET_FRACTION 0, as the test) against world-space copies: the
ratio of the combined means (the test asks within 0.5 %); tests/test_stability_geometry.py's
quad whose custom normals point into the surface: the direct pass' mean (the test asks
over 0.3 of the ideal rho E / pi). Both scenes are rebuilt from the tests' own helpers.
Prints a Markdown table; docs/accuracy.md, vase48, gives the numbers measured.
"""
import math
import os
import sys
import tempfile
from pathlib import Path

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for sub in ("tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import numpy as np  # noqa: E402

from engine import RenderSettings, resources, turnedglossy  # noqa: E402
from engine.api import PaperScene  # noqa: E402
from engine.scene import Camera, Material  # noqa: E402
from engine.scenefile import load_scene  # noqa: E402
import test_scenefile_instances as instances_test  # noqa: E402
from test_stability_common import run  # noqa: E402


def instances_over_copies(tmp) -> float:
    """The instanced scene's combined mean over its copies' (the test's settings)."""
    scene, _ = load_scene(instances_test._instanced(tmp))
    copies, _ = load_scene(instances_test._copies(tmp))
    settings = RenderSettings(spp=2, photons=20000, caustic_photons=0, seed=3)
    return float(scene.render(settings).combined.mean()
                 / copies.render(settings).combined.mean())


def bad_normals_direct() -> float:
    """The direct pass' mean of test_shading_normals_pointing_below_the_surface's quad."""
    s = PaperScene(width=16, height=16)
    s.add_material(Material("matte", (0.5,) * 3))
    v = np.array([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    n = np.array([[0, 0, -1], [1, 0, 0.01], [0, 0, 0], [0.3, 0.3, -1]], float)
    s.add_triangles(v, f, "matte", name="bad_normals", normals=n)
    s.add_sun((0, 0, -1), strength=1.0)
    s.camera = Camera(position=(0, 0, 3), kind="ORTHO", ortho_scale=3)
    return float(run(s, spp=2).direct.mean())


def main():
    resources.INSTANCE_BUDGET_FRACTION = 0.0
    ideal = 0.5 / math.pi
    print("| turnedglossy.DIFFUSE | instances / copies | bad normals: direct mean "
          f"(ideal {ideal:.4f}, asserted > {0.3 * ideal:.4f}) |")
    print("|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="vase48_") as tmp:
        for diffuse in (True, False):
            turnedglossy.DIFFUSE = diffuse
            ratio = instances_over_copies(Path(tmp))
            print(f"| {diffuse} | {ratio:.4f} | {bad_normals_direct():.4f} |")


if __name__ == "__main__":
    main()
