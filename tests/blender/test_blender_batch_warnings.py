"""`python -m addon.batch ... > log 2>&1`: the warnings in the shared log start on lines of
their own, once each, with the progress bar continuing below (Blender printed them glued to
the bar's line: new-user trial, s17). tests/test_batch_output.py checks the printer alone."""
import os
import re
import subprocess

import pytest

from blender_helpers import BLENDS, PYTHON, ROOT
from test_cli_output import WARNING_PATCHES, _own_line

pytestmark = pytest.mark.blender


RADIUS_WARNING = "search radius 0.01 m is below the photon spacing"
BATCH_ARGS = ["-o", "f3.png", "--samples", "1", "--photons", "2000", "--caustic-photons", "1000",
              "--resolution-percentage", "10", "--max-depth", "1", "--radius", "0.01"]


@pytest.fixture(scope="module")
def shared_log(tmp_path_factory):
    """The batch command on figure3_sphere.blend with Max Ray Depth 1 below Glossy 4 with
    the glossy sphere in view (the effect analysis warns: engine/effects.py,
    _warn_max_ray_depth) and a search radius of 0.01 m (the photon pass warns), stdout
    and stderr into one log file: (return code, text). One Blender process for the
    tests that read a log (they ran one each)."""
    tmp = tmp_path_factory.mktemp("shared_log")
    log = tmp / "log"
    args = [str(tmp / a) if a == "f3.png" else a for a in BATCH_ARGS]
    with open(log, "wb") as f:
        res = subprocess.run([PYTHON, "-m", "addon.batch",
                              os.path.join(BLENDS, "figure3_sphere.blend"), *args],
                             cwd=ROOT, stdout=f, stderr=subprocess.STDOUT, timeout=300)
    return res.returncode, log.read_text()


def test_batch_warnings_in_a_shared_log_start_on_their_own_line(shared_log):
    rc, text = shared_log
    assert rc == 0, text[-3000:]
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


# Opens figure3_sphere.blend, gives the floor's material a Toon BSDF (not supported: the
# export warns), saves it, and runs the batch command on it with the engine patched to warn
# as numpy, scipy or numba would: a UserWarning on the main thread as the render prepares,
# numpy's RuntimeWarning in every chunk on the worker threads (engine/parallel.py). Prints
# how many worker chunks warned, after the command's output.
CHILD = """
import importlib, os, sys, threading, warnings
sys.path.insert(0, {root!r})
import numpy as np
import bpy
bpy.ops.wm.open_mainfile(filepath=os.path.join({blends!r}, "figure3_sphere.blend"))
tree = bpy.data.objects["Floor"].active_material.node_tree
toon = tree.nodes.new("ShaderNodeBsdfToon")
out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
tree.links.new(toon.outputs[0], out.inputs["Surface"])
bpy.ops.wm.save_as_mainfile(filepath={blend!r})
""" + WARNING_PATCHES + """from addon import batch
rc = batch.main(sys.argv[1:])
print(f"worker chunks warned: {{sum(on_workers)}}")
sys.exit(rc)
"""
PYTHON_WARNINGS = ["UserWarning: a warning raised inside the render",
                   "RuntimeWarning: divide by zero encountered in log"]
# A whole bar as addon/batch.py draws it: description, bar, percentage, [elapsed<left].
WHOLE_BAR = re.compile(r"^.{46}.*\| *\d{1,3}% \[[0-9:]+<[^\]]*\]$")


def test_batch_python_warnings_from_the_render_threads_on_their_own_lines(tmp_path):
    """A Toon BSDF (the export's warning), Max Ray Depth 1 (the effect analysis'), and
    Python warnings raised inside the render on the main and the worker threads: each
    once, on a line of its own before the closing `wrote ...` line, the bar whole."""
    child = tmp_path / "child.py"
    child.write_text(CHILD.format(root=ROOT, blends=BLENDS, blend=str(tmp_path / "toon.blend")),
                     encoding="utf-8")
    res = subprocess.run([PYTHON, str(child), str(tmp_path / "toon.blend"),
                          "-o", str(tmp_path / "f3.png"), "--samples", "1",
                          "--photons", "2000", "--caustic-photons", "1000", "--threads", "2",
                          "--resolution-percentage", "10", "--max-depth", "1"],
                         cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         timeout=300)
    text = res.stdout.decode("utf-8", "replace")
    assert res.returncode == 0, text[-3000:]
    lines = text.split("\n")
    summary = next(i for i, line in enumerate(lines) if line.startswith("wrote "))
    first_photons = next(i for i, line in enumerate(lines) if "Tracing photons" in line)
    toon = _own_line(lines, "Toon BSDF", text)
    depth = _own_line(lines, "Max Ray Depth 1 stops camera paths after", text)
    for i in (toon, depth):  # when they arose: before the photons are shot
        assert lines[i].startswith("Warning: Photon Mapping: ") and i < first_photons, text
    for w in PYTHON_WARNINGS:
        i = _own_line(lines, w, text)
        assert lines[i].startswith(str(child)) and i < summary, repr(lines[i])
    workers = int(re.search(r"^worker chunks warned: (\d+)$", text, re.M).group(1))
    assert workers >= 2, text
    drawings = [seg for line in lines for seg in line.split("\r") if "% [" in seg]
    assert len(drawings) >= 3, text
    for seg in drawings:
        assert WHOLE_BAR.match(seg), repr(seg)


def _batch_log(tmp_path, *extra):
    """The shared log's command (BATCH_ARGS) with `extra` options, stdout and stderr in
    one pipe: its lines."""
    args = [str(tmp_path / a) if a == "f3.png" else a for a in BATCH_ARGS]
    res = subprocess.run([PYTHON, "-m", "addon.batch",
                          os.path.join(BLENDS, "figure3_sphere.blend"), *args, *extra],
                         cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         timeout=600)
    text = res.stdout.decode("utf-8", "replace")
    assert res.returncode == 0, text[-3000:]
    return text.split("\n"), text


def _first(lines, text):
    return next(i for i, line in enumerate(lines) if text in line)


def test_batch_radius_warning_before_the_camera_pass(shared_log):
    """The search radius' warning once, on a line of its own, when the photon maps are
    built: before the camera pass's first bar (`Rendering NN%`); it came after the
    render."""
    rc, text = shared_log
    assert rc == 0, text[-3000:]
    lines = text.split("\n")
    i = _own_line(lines, RADIUS_WARNING, text)
    assert lines[i].startswith(f"Warning: Photon Mapping: {RADIUS_WARNING}"), repr(lines[i])
    assert i < _first(lines, "Rendering "), text


def test_batch_on_a_scheduler_says_the_workers_warnings_once_before_pass_1(tmp_path):
    """--dask with a scheduler of 1 worker process, 16 passes: the effect analysis' and
    the search radius' warnings (found on the worker) each once, before the first pass's
    bar; they came at the end (the effect analysis' never)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        lines, text = _batch_log(tmp_path, "--dask", cluster.scheduler_address)
    first_pass = _first(lines, "Pass 1")
    for w in ("Max Ray Depth 1 stops camera paths after", RADIUS_WARNING):
        i = _own_line(lines, w, text)
        assert lines[i].startswith("Warning: Photon Mapping: ") and i < first_pass, text
