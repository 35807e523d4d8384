"""The CLI's output with stdout and stderr in one pipe (`photonmap render ... > log 2>&1`,
a CI log): each warning - the scene's, the effect analysis', and Python warnings raised
inside the render on the main thread and on the engine's worker threads - is printed once,
when it arises, on a line of its own before the closing summary, and the progress bar's
text is never broken by it (engine/console.py; the batch command's twin is
tests/blender/test_blender_batch_warnings.py). The Python warnings come from a child
script that patches the engine before it runs the CLI's main(). A hand-set search radius
that does wrong (`--radius`, known once the photon maps are built) is said before the camera
pass, once, also over progressive passes and from a Dask cluster's workers. The last tests
check the engine's side alone: render()'s and render_progressive()'s on_warning, which both
front ends print from."""
import os
import re
import subprocess
import sys

import pytest

from helpers import ROOT

# A tiny scene that warns: a base colour above 1 and a zero-area face (the scene's, known
# when it loads), and a mirror in view cut by --max-depth 1 (the effect analysis', known
# before the photons are shot).
SCENE = """
background = [0, 0, 0]

[render]
width = 24
height = 18
photons = 2000
caustic_photons = 1000
spp = 1

[camera]
position = [0, -6, 2.5]
look_at = [0, 0, 0.8]
up = [0, 0, 1]
fov = 40

[materials.hot]
base_color = [2.0, 0.5, 0.5]

[materials.mirror]
base_color = [0.9, 0.9, 0.9]
metallic = 1.0
roughness = 0.0

[[objects]]
type = "plane"
name = "floor"
center = [0, 0, 0]
normal = [0, 0, 1]
size = 10
material = "hot"

[[objects]]
type = "sphere"
name = "ball"
center = [0, 0, 1]
radius = 1
material = "mirror"

[[objects]]
type = "mesh"
name = "Sliver"
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]]
faces = [[0, 1, 2], [0, 1, 3]]
material = "hot"

[[lights]]
type = "area"
name = "area"
position = [0, 0, 4]
direction = [0, 0, -1]
size = [1.5, 1.5]
power = 400
"""

# Runs engine.cli.main with the engine patched to warn as numpy, scipy or numba would:
# a UserWarning on the main thread as the render prepares, numpy's RuntimeWarning in every
# chunk on the worker threads (engine/parallel.py), each from one place (Python's default
# filter prints it once). Prints how many worker chunks warned, after the CLI's output.
# The patches that make a render warn (shared with the batch command's test,
# tests/blender/test_blender_batch_warnings.py).
WARNING_PATCHES = """
parallel = importlib.import_module("engine.parallel")
render_module = importlib.import_module("engine.render")  # engine.render is the function

on_workers = []
_with_flag = parallel._with_flag


def with_flag(job, flag):
    run = _with_flag(job, flag)

    def warned(*args):
        on_workers.append(threading.current_thread() is not threading.main_thread())
        np.log(np.zeros(1))  # numpy warns: divide by zero
        return run(*args)
    return warned


parallel._with_flag = with_flag
_prepare = render_module.prepare_context


def prepare_context(*args, **kwargs):
    warnings.warn("a warning raised inside the render", UserWarning)
    return _prepare(*args, **kwargs)


render_module.prepare_context = prepare_context
"""
CHILD = """
import importlib, sys, threading, warnings
sys.path.insert(0, {root!r})
import numpy as np
""" + WARNING_PATCHES + """from engine.cli import main
if __name__ == "__main__":  # not in --dask's worker processes, which import this file
    rc = main(sys.argv[1:])
    print(f"worker chunks warned: {{sum(on_workers)}}")
    sys.exit(rc)
"""

ENGINE_WARNINGS = ["material 'hot': base colour [2.0, 0.5, 0.5] above 1",
                   "mesh 'Sliver': dropped 1 zero-area faces",
                   "Max Ray Depth 1 stops camera paths after 1 mirror / glass bounce"]
PYTHON_WARNINGS = ["UserWarning: a warning raised inside the render",
                   "RuntimeWarning: divide by zero encountered in log"]
# A whole bar as engine/cli.py draws it: description, bar, percentage, [elapsed<left].
WHOLE_BAR = re.compile(r"^.{42}.*\| *\d{1,3}% \[[0-9:]+<[^\]]*\]$")


def _run(tmp_path, *extra):
    scene = tmp_path / "warns.toml"
    scene.write_text(SCENE, encoding="utf-8")
    child = tmp_path / "child.py"
    child.write_text(CHILD.format(root=str(ROOT)), encoding="utf-8")
    # PYTHONPATH: --dask's worker processes import the engine too.
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p))
    res = subprocess.run([sys.executable, str(child), "render", str(scene), "-o",
                          str(tmp_path / "out.png"), "--max-depth", "1", "--workers", "2",
                          *extra], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, timeout=600, env=env)
    return res.returncode, res.stdout.decode("utf-8", "replace")


def _own_line(lines, text, where):
    """The index of the one line that holds `text`, checked to hold nothing of the bar."""
    found = [i for i, line in enumerate(lines) if text in line]
    assert len(found) == 1, (text, where)  # printed once
    line = lines[found[0]]
    assert "\r" not in line and "% [" not in line, repr(line)  # on a line of its own
    return found[0]


# --radius 0.01 m: far below the spacing of the scene's 2000 global photons (~0.2 m), known
# once the photon maps are built (engine/render.py, radius_warnings).
RADIUS = ("--radius", "0.01")
RADIUS_WARNING = "search radius 0.01 m is below the photon spacing"


@pytest.fixture(scope="module")
def radius_run(tmp_path_factory):
    """_run with RADIUS: (return code, text, its tmp_path). One process for the two tests
    that read a plain run's pipe (its warnings, bar and the radius warning's place; they
    ran one each)."""
    tmp_path = tmp_path_factory.mktemp("radius_run")
    return (*_run(tmp_path, *RADIUS), tmp_path)


def test_cli_warnings_each_on_a_line_of_their_own_in_a_shared_pipe(radius_run):
    rc, text, tmp_path = radius_run
    assert rc == 0, text[-3000:]
    lines = text.split("\n")  # in a log file \r starts no line
    summary = next(i for i, line in enumerate(lines) if line.startswith("wrote "))
    first_photons = next(i for i, line in enumerate(lines) if "Tracing photons" in line)
    for w in ENGINE_WARNINGS:
        i = _own_line(lines, w, text)
        assert lines[i].startswith(f"photonmap: warning: {w}"), repr(lines[i])
        # When it arose: the scene's and the effect analysis' before the photons.
        assert i < first_photons, text
    for w in PYTHON_WARNINGS:
        i = _own_line(lines, w, text)
        assert i < summary, text
        assert lines[i].startswith(str(tmp_path / "child.py")), repr(lines[i])
    # Worker chunks warned from many chunks on worker threads; printed once above.
    workers = int(re.search(r"^worker chunks warned: (\d+)$", text, re.M).group(1))
    assert workers >= 2, text
    # The bar's text whole: every drawing of it (between \r and the line's end or the
    # next \r) is a complete bar, nothing glued before or after it.
    drawings = [seg for line in lines for seg in line.split("\r") if "% [" in seg]
    assert len(drawings) >= 3, text
    for seg in drawings:
        assert WHOLE_BAR.match(seg), repr(seg)


def test_cli_quiet_prints_the_warnings_without_a_bar(tmp_path):
    rc, text = _run(tmp_path, "--quiet")
    assert rc == 0, text[-3000:]
    assert "% [" not in text and "\r" not in text, text
    lines = text.split("\n")
    for w in ENGINE_WARNINGS + PYTHON_WARNINGS:
        _own_line(lines, w, text)


def test_render_tells_each_warning_once_when_it_arises(tmp_path):
    """engine.render's on_warning, which both front ends print from: each of
    film.warnings once; the scene's and the effect analysis' before the first photon is
    traced (the progress callback's first 'photons' stage)."""
    from engine import RenderSettings, render
    from engine.scenefile import load_scene
    path = tmp_path / "warns.toml"
    path.write_text(SCENE, encoding="utf-8")
    scene, overrides = load_scene(str(path))
    events = []
    film = render(scene, RenderSettings(**dict(overrides, max_depth=1, workers=1)),
                  progress=lambda stage, fraction, text: events.append(("stage", stage)),
                  on_warning=lambda text: events.append(("warning", text)))
    told = [text for kind, text in events if kind == "warning"]
    assert sorted(told) == sorted(set(film.warnings)) and len(told) == len(set(told))
    first_photons = events.index(("stage", "photons"))
    for w in ENGINE_WARNINGS:
        where = next(i for i, (kind, text) in enumerate(events) if w in text)
        assert where < first_photons, events


def _first(lines, text):
    return next(i for i, line in enumerate(lines) if text in line)


def test_cli_radius_warning_before_the_camera_pass(radius_run):
    """Said once its photon maps are built: on a line of its own before the camera pass's
    first bar (`Rendering NN%`), once (it came after the whole camera pass)."""
    rc, text, _ = radius_run
    assert rc == 0, text[-3000:]
    lines = text.split("\n")
    i = _own_line(lines, RADIUS_WARNING, text)
    assert lines[i].startswith(f"photonmap: warning: {RADIUS_WARNING}"), repr(lines[i])
    assert _first(lines, "Building photon map") < i < _first(lines, "Rendering "), text


def test_cli_progressive_radius_warning_once_before_the_first_camera_pass(tmp_path):
    """Every pass stores its own photons and words the warning with its own count: said
    once, with pass 1's maps, before pass 1's camera pass (progressive passes dropped it)."""
    rc, text = _run(tmp_path, *RADIUS, "--passes", "2")
    assert rc == 0, text[-3000:]
    lines = text.split("\n")
    i = _own_line(lines, RADIUS_WARNING, text)
    assert i < _first(lines, "Pass 1: Rendering ") and i < _first(lines, "pass 1: "), text
    for w in ENGINE_WARNINGS:
        assert _own_line(lines, w, text) < _first(lines, "Tracing photons"), text
    # The summary counts the passes' samples (it said one pass' spp).
    summary = lines[_first(lines, "wrote ")]
    assert re.search(r", 2 passes x \d+ spp, ", summary), summary


def test_cli_dask_warnings_once_as_the_workers_find_them(tmp_path):
    """--dask local:1, 3 passes: the scene's before anything is sent, the effect analysis'
    and the search radius' as the worker finds them, each once (not once per pass), before
    the first pass's bar (`Pass 1 done`) and its `pass 1:` line (they came after the last
    pass)."""
    pytest.importorskip("distributed")
    rc, text = _run(tmp_path, *RADIUS, "--passes", "3", "--dask", "local:1")
    assert rc == 0, text[-3000:]
    lines = text.split("\n")
    first_pass = min(_first(lines, "Pass 1 done"), _first(lines, "pass 1: "))
    for w in ENGINE_WARNINGS + [RADIUS_WARNING]:
        i = _own_line(lines, w, text)
        assert lines[i].startswith(f"photonmap: warning: {w}"), repr(lines[i])
        assert i < first_pass, text
    assert _own_line(lines, "pass 3: ", text) < _first(lines, "wrote "), text


def _stages_and_warnings(call, **settings):
    """(events, film) of call(scene, settings, progress=..., on_warning=...) for the
    warning scene with `settings`: events in order, ("stage", stage) or ("warning", text)."""
    import tempfile

    from engine import RenderSettings
    from engine.scenefile import load_scene
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "warns.toml")
        with open(path, "w", encoding="utf-8") as f:
            f.write(SCENE)
        scene, overrides = load_scene(path)
    events = []
    film = call(scene, RenderSettings(**dict(overrides, max_depth=1, workers=1, **settings)),
                progress=lambda stage, fraction, text: events.append(("stage", stage)),
                on_warning=lambda text: events.append(("warning", text)))
    return events, film


def test_render_and_passes_tell_the_radius_warning_before_the_camera_pass():
    """render(): told between the photon map's build and the camera pass's first
    progress; render_progressive() over 3 passes: told once, in pass 1 before its camera
    pass, listed once in film.warnings."""
    from engine import render
    from engine.progressive import Budget, render_progressive
    def passes(*args, **kw):
        return render_progressive(*args, budget=Budget(passes=3), **kw)
    for call in (render, passes):
        events, film = _stages_and_warnings(call, radius=0.01)
        told = [i for i, (kind, text) in enumerate(events)
                if kind == "warning" and text.startswith(RADIUS_WARNING)]
        assert len(told) == 1, events
        assert events.index(("stage", "photon_map")) < told[0] < events.index(("stage", "render"))
        assert sum(w.startswith(RADIUS_WARNING) for w in film.warnings) == 1, film.warnings
        said = [text for kind, text in events if kind == "warning"]
        assert sorted(said) == sorted(film.warnings), (said, film.warnings)
