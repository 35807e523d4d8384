"""`python -m addon.batch ... > log 2>&1`: the warnings in the shared log start on lines of
their own, once each, with the progress bar continuing below (Blender printed them glued to
the bar's line: new-user trial, s17). tests/test_batch_output.py checks the printer alone."""
import os
import re
import subprocess

import pytest

from blender_helpers import BLENDS, PYTHON, ROOT

pytestmark = pytest.mark.blender


def test_batch_warnings_in_a_shared_log_start_on_their_own_line(tmp_path):
    log = tmp_path / "log"
    # Max Ray Depth 1 below Glossy 4 with the glossy sphere in view: the effect analysis
    # warns (engine/effects.py, _warn_max_ray_depth).
    with open(log, "wb") as f:
        res = subprocess.run([PYTHON, "-m", "addon.batch",
                              os.path.join(BLENDS, "figure3_sphere.blend"),
                              "-o", str(tmp_path / "f3.png"), "--samples", "2",
                              "--photons", "5000", "--caustic-photons", "2000",
                              "--resolution-percentage", "25", "--max-depth", "1"],
                             cwd=ROOT, stdout=f, stderr=subprocess.STDOUT, timeout=300)
    text = log.read_text()
    assert res.returncode == 0, text[-3000:]
    lines = text.split("\n")
    warned = [i for i, line in enumerate(lines)
              if "Max Ray Depth 1 stops camera paths after" in line]
    assert len(warned) == 1, text[-3000:]
    assert lines[warned[0]].startswith("Warning: Photon Mapping: Max Ray Depth 1"), \
        repr(lines[warned[0]][:300])
    assert all(line.startswith("Warning: ") for line in lines if "Warning: " in line), text
    # The bar continues below the warning, and the report follows the closed bar.
    below = "\n".join(lines[warned[0] + 1:])
    assert re.search(r"Done +\S+\| 100%", below), below[:1000]
    assert re.search(r"^Done: \d+ triangles", below, re.M), below[:1000]
    assert re.search(r"^  specular reflection / refraction: on - up to 1 bounce \(", below,
                     re.M), below[-3000:]
