"""Output integrity (issue 16): images replace the target only when completely written,
the output path is checked before the render starts, and Ctrl-C never leaves a broken
frame (the CLI keeps the finished part only with --keep-partial)."""
import os
import resource
import signal
import subprocess
import sys

import numpy as np
import pytest

from helpers import ROOT
from process_helpers import Watched
from engine.imageio import check_writable, read_image, replacing, truncation, write_image

SCENE = os.path.join(ROOT, "scenes", "figure3.toml")
OLD = b"the previous frame, which must survive"


def _cli(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "engine.cli", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=300, **kwargs)


def _main(capsys, monkeypatch, *args):
    """engine.cli.main in this process (cwd = ROOT): (exit code, stderr); the path and
    error handling of `python -m engine.cli` without a Python start and engine import
    (~1.5 CPU s) per call (test_input.py runs the process's exit codes)."""
    from engine import cli
    monkeypatch.chdir(ROOT)
    capsys.readouterr()
    code = cli.main(list(args))
    return code, capsys.readouterr().err


def _leftovers(folder, keep):
    return sorted(n for n in os.listdir(folder) if n not in keep)


@pytest.mark.parametrize("ext", [".png", ".exr", ".npy", ".ppm"])
def test_failed_write_leaves_the_previous_file(tmp_path, monkeypatch, ext):
    """A writer that dies half way (disk full) leaves the old file byte for byte."""
    target = tmp_path / f"out{ext}"
    target.write_bytes(OLD)
    import engine.imageio as imageio
    real = imageio._write

    def dies_mid_write(rgb, path, *args):
        real(rgb, path, *args)  # the new image lands in the temporary file ...
        with open(path, "r+b") as f:
            f.truncate(10)  # ... and the disk fills up
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(imageio, "_write", dies_mid_write)
    with pytest.raises(OSError, match="No space"):
        write_image(np.ones((4, 5, 3)), str(target))
    assert target.read_bytes() == OLD
    assert _leftovers(tmp_path, {target.name}) == []


def test_successful_write_replaces_and_keeps_nothing_else(tmp_path):
    target = tmp_path / "out.npy"
    target.write_bytes(OLD)
    img = np.random.default_rng(1).random((6, 7, 3)).astype(np.float32)
    write_image(img, str(target))
    assert np.array_equal(read_image(str(target)), img)
    assert _leftovers(tmp_path, {target.name}) == []
    umask = os.umask(0)
    os.umask(umask)
    assert (target.stat().st_mode & 0o777) == (0o666 & ~umask)  # as a new file, not 0600


def test_replacing_removes_the_temporary_file_on_an_exception(tmp_path):
    target = tmp_path / "a.png"
    target.write_bytes(OLD)
    with pytest.raises(KeyboardInterrupt):
        with replacing(str(target)) as tmp:
            with open(tmp, "wb") as f:
                f.write(b"half")
            raise KeyboardInterrupt
    assert target.read_bytes() == OLD
    assert _leftovers(tmp_path, {target.name}) == []


@pytest.mark.parametrize("ext", [".png", ".jpg", ".exr", ".ppm", ".npy"])
def test_truncation_finds_a_file_cut_anywhere(tmp_path, ext):
    """Writers that ignore a short write (Blender's PNG and EXR, Pillow's PPM) leave files
    cut at a block boundary: each cut is told from the whole file by its own structure."""
    img = np.random.default_rng(2).random((48, 64, 3)).astype(np.float32)
    whole = tmp_path / f"whole{ext}"
    if ext == ".jpg":
        from PIL import Image
        Image.fromarray((img * 255).astype(np.uint8)).save(whole)
    else:
        write_image(img, str(whole))
    data = whole.read_bytes()
    assert truncation(str(whole)) is None
    cut = tmp_path / f"cut{ext}"
    for n in {len(data) // 2, len(data) - 1, len(data) - 20, min(4096, len(data) - 2)}:
        cut.write_bytes(data[:n])
        assert truncation(str(cut)), (ext, n, len(data))


def test_a_writer_that_ignores_a_short_write_keeps_the_old_file(tmp_path, monkeypatch):
    """Blender's save_render reports success on a full disk: the cut file never replaces
    the previous frame."""
    target = tmp_path / "out.png"
    target.write_bytes(OLD)
    import engine.imageio as imageio
    real = imageio._write

    def cut_silently(rgb, path, *args):
        real(rgb, path, *args)
        with open(path, "r+b") as f:
            f.truncate(os.path.getsize(path) - 100)

    monkeypatch.setattr(imageio, "_write", cut_silently)
    with pytest.raises(OSError, match="cut short.*unchanged"):
        write_image(np.random.default_rng(3).random((40, 50, 3)), str(target))
    assert target.read_bytes() == OLD
    assert _leftovers(tmp_path, {target.name}) == []


SMALL_RENDER = ("render", SCENE, "--width", "64", "--height", "48", "--spp", "1",
                "--photons", "2000", "--caustic-photons", "1000", "--quiet")


@pytest.fixture(scope="module")
def warm_cli(tmp_path_factory):
    """The small render once without a file size limit, for the module: kernels the cache
    lacks would be written under the limit too (and fail for that reason, not the
    image's). One process for the three formats below (they ran one each)."""
    warm = tmp_path_factory.mktemp("warm") / "w.npy"
    assert _cli(*SMALL_RENDER, "-o", str(warm)).returncode == 0


@pytest.mark.parametrize("ext", [".npy", ".ppm", ".exr"])
def test_write_beyond_the_file_size_limit_keeps_the_old_file(tmp_path, ext, warm_cli):
    """`ulimit -f`: the CLI's write fails (EFBIG, or a writer that ignores it and leaves a
    cut file); the old image stays, one-line error."""
    target = tmp_path / f"out{ext}"  # 64x48: npy 36 KB, ppm 9 KB, exr > 8 KB
    target.write_bytes(OLD)

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of being killed
        resource.setrlimit(resource.RLIMIT_FSIZE, (8192, 8192))

    res = _cli(*SMALL_RENDER, "-o", str(target), preexec_fn=limit)
    assert res.returncode == 1, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and target.name in lines[0] and "unchanged" in lines[0], res.stderr
    assert target.read_bytes() == OLD
    assert _leftovers(tmp_path, {target.name}) == []


def test_check_writable_refuses_before_anything_is_written(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_bytes(b"x")
    with pytest.raises(OSError, match="is a file, not a folder"):
        check_writable(str(blocker / "sub" / "out.png"))
    with pytest.raises(OSError, match="is a folder"):
        check_writable(str(tmp_path))
    ok = tmp_path / "new" / "dir" / "out.png"
    created = []
    assert check_writable(str(ok), on_create=created.append) == str(ok)
    assert ok.parent.is_dir() and os.listdir(ok.parent) == []  # the probe is gone
    assert created == [str(ok.parent)]  # said once, so the command line can tell the user
    check_writable(str(ok), on_create=created.append)
    assert created == [str(ok.parent)]  # an existing folder is not announced


def test_cli_checks_the_output_path_before_rendering(tmp_path, capsys, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_bytes(b"x")
    code, err = _main(capsys, monkeypatch, "render", SCENE, "-o", str(blocker / "out.png"),
                      "--spp", "64")
    assert code == 1
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and str(blocker) in lines[0], err  # no progress bar first


def test_a_folder_as_the_output_is_named_as_such(tmp_path, capsys, monkeypatch):
    for command in ("render", "compare"):
        code, err = _main(capsys, monkeypatch, command, SCENE, "-o", str(tmp_path), "--spp", "1")
        assert code == 1
        assert err.strip() == (f"photonmap: error: --output '{tmp_path}' is a folder: "
                               f"give an image file, e.g. '{tmp_path / 'render.png'}'"), err
    assert os.listdir(tmp_path) == []


def _interrupted_cli(tmp_path, *extra, sig=signal.SIGINT):
    target = tmp_path / "out.png"
    target.write_bytes(OLD)
    # A grey background: every finished pixel is non-zero, every unfinished one zero.
    with open(SCENE, encoding="utf-8") as f:
        text = f.read().replace("background = [0, 0, 0]", "background = [0.2, 0.2, 0.2]")
    assert "0.2, 0.2, 0.2" in text
    scene = tmp_path / "grey.toml"
    scene.write_text(text, encoding="utf-8")
    with Watched([sys.executable, "-m", "engine.cli", "render", str(scene), "-o", str(target),
                  "--width", "160", "--height", "120", "--spp", "256", "--photons", "20000",
                  "--caustic-photons", "10000", *extra], cwd=ROOT) as w:
        # Interrupt once some of the camera pass is finished (the bar shows 'Rendering
        # pixels N/M' after each chunk).
        assert w.wait_for(r"Rendering pixels \d+k?/"), w.stderr[-2000:]
        w.proc.send_signal(sig)
        return target, w.finish(), w.stderr


def test_cli_ctrl_c_leaves_the_target_untouched(tmp_path):
    target, rc, err = _interrupted_cli(tmp_path)
    assert rc == 130, err[-2000:]
    assert target.read_bytes() == OLD
    assert "interrupted while rendering" in err and "left untouched" in err
    assert "Traceback" not in err
    assert _leftovers(tmp_path, {target.name, "grey.toml"}) == []


def test_cli_ctrl_c_with_keep_partial_writes_the_finished_part_marked(tmp_path):
    from PIL import Image
    target, rc, err = _interrupted_cli(tmp_path, "--keep-partial")
    assert rc == 130, err[-2000:]
    assert "wrote the partial image" in err and "Traceback" not in err
    with Image.open(target) as im:
        note = im.text.get("photonmap:partial", "")
        img = np.asarray(im.convert("RGB"), np.float64)
    assert note.startswith("interrupted:") and "rows" in note, note
    rows = int(note.split("the top ")[1].split(" of ")[0])
    assert 0 < rows < 120
    # Finished pixels run row by row from the top: rows above `rows` are complete (no
    # black pixel), rows below it untouched (black).
    assert img[:rows].sum(axis=2).min() > 0 and img[rows + 1:].max() == 0


def test_cli_sigterm_is_a_cancel_as_ctrl_c(tmp_path):
    """A job's timeout (`timeout 600 photonmap ...`) or a render farm's cancel sends
    SIGTERM: the render is cancelled as by Ctrl-C (--keep-partial writes the finished
    part), exit status 143; the process was killed mid-render before, keeping nothing."""
    from PIL import Image
    target, rc, err = _interrupted_cli(tmp_path, "--keep-partial", sig=signal.SIGTERM)
    assert rc == 143, err[-2000:]
    assert "wrote the partial image" in err and "Traceback" not in err
    with Image.open(target) as im:
        assert im.text.get("photonmap:partial", "").startswith("interrupted:")
    assert _leftovers(tmp_path, {target.name, "grey.toml"}) == []


def test_cli_ctrl_c_in_a_progressive_render_keeps_the_finished_passes(tmp_path):
    from PIL import Image
    target = tmp_path / "prog.png"
    target.write_bytes(OLD)
    with Watched([sys.executable, "-m", "engine.cli", "render", SCENE, "-o", str(target),
                  "--width", "64", "--height", "48", "--spp", "2", "--photons", "20000",
                  "--caustic-photons", "5000", "--passes", "500", "--keep-partial"],
                 cwd=ROOT) as w:
        assert w.wait_for(r"Pass 3: "), w.stderr[-2000:]  # passes 1 and 2 are finished
        w.proc.send_signal(signal.SIGINT)
        rc = w.finish()
    assert rc == 130, w.stderr[-2000:]
    with Image.open(target) as im:
        note = im.text.get("photonmap:partial", "")
        img = np.asarray(im.convert("RGB"))
    assert note.startswith("interrupted: ") and "complete pass(es)" in note, note
    passes = int(note.split()[1])
    assert 2 <= passes < 500
    assert img.max() > 0  # the average of the finished passes, not a black frame


def test_cli_writes_alpha_for_a_transparent_film_and_holdouts(tmp_path, capsys, monkeypatch):
    """photonmap render: film_transparent / holdout objects give an RGBA PNG and an EXR
    with an A channel, alpha 0 where the background or a holdout is seen."""
    from PIL import Image
    scene = tmp_path / "t.toml"
    scene.write_text("""
[render]
width = 24
height = 16
spp = 1
photons = 2000
caustic_photons = 0
film_transparent = true

[camera]
position = [0, -4, 1]
look_at = [0, 0, 0.5]
fov = 40

[[objects]]
type = "plane"
center = [0, 0, 0]
size = 20

[[objects]]
type = "box"
center = [0, 0, 0.5]
size = [0.5, 0.5, 0.5]
holdout = true

[[lights]]
type = "point"
position = [0, -1, 3]
power = 300
""")
    for ext in (".png", ".exr"):
        out = tmp_path / f"o{ext}"
        code, err = _main(capsys, monkeypatch, "render", str(scene), "-o", str(out), "--quiet")
        assert code == 0, err
        if ext == ".png":
            img = np.asarray(Image.open(out))
            assert img.shape == (16, 24, 4)
            alpha = img[..., 3] / 255.0
        else:
            import OpenEXR
            with OpenEXR.File(str(out), separate_channels=True) as f:
                alpha = np.asarray(f.channels()["A"].pixels)
        assert alpha[0].max() == 0.0           # sky above the plane: transparent
        assert alpha[-1].min() == 1.0          # the plane in front of the box: opaque
        assert alpha[8, 12] == 0.0             # the holdout box in the middle: a hole


def _ctrl_c_into_a_silent_step(monkeypatch, capsys, command, target, compiling):
    """Run the CLI's `command` with the kernels' compile (compiling) or cached load
    simulated by a 60 s step that polls nothing, and a Ctrl-C 0.3 s into it; returns
    (exit status, seconds, stderr). Python's own Ctrl-C handler is installed, as an
    interactive start has it (a CI job started in the background inherits SIGINT ignored;
    the CLI then restores that instead), and put back after."""
    import importlib
    import threading
    import time

    from engine import jit
    from engine.cli import main
    render_module = importlib.import_module("engine.render")
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))

    def silent_step(progress=None):
        if compiling:
            progress("compile", 0.0, jit.COMPILE_MESSAGE)
        timer.start()
        end = time.monotonic() + 60
        while time.monotonic() < end:
            time.sleep(0.01)  # a signal handler's exception lands here
        return 60.0

    monkeypatch.setattr(render_module, "ensure_compiled", silent_step)
    started_with = signal.signal(signal.SIGINT, signal.default_int_handler)
    target.write_bytes(OLD)
    t0 = time.monotonic()
    try:
        rc = main([command, SCENE, "-o", str(target), "--width", "32", "--height", "24",
                   "--spp", "1", "--photons", "2000"])
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, started_with)
    return rc, time.monotonic() - t0, capsys.readouterr().err


def test_cli_ctrl_c_during_the_kernel_compile_stops_at_once(tmp_path, monkeypatch, capsys):
    """The first render on a machine compiles the kernels for about a minute, polling
    nothing: a Ctrl-C then stops at once (nothing is finished to keep; the cache is
    written only after a complete compile) instead of waiting out the compile silently."""
    target = tmp_path / "out.png"
    for command, said in (("render", "interrupted while compiling the render kernels"),
                          ("compare", "interrupted")):
        rc, seconds, err = _ctrl_c_into_a_silent_step(monkeypatch, capsys, command, target,
                                                      compiling=True)
        assert rc == 130 and seconds < 20, (command, rc, seconds, err[-1500:])
        assert said in err and "left untouched" in err and "Traceback" not in err, err
        assert target.read_bytes() == OLD


def test_cli_ctrl_c_while_the_cached_kernels_load_stops_at_once(tmp_path, monkeypatch,
                                                                 capsys):
    """Loading the cached kernels reports no progress and polls nothing (2-3 s idle, 20 s
    on a loaded machine: newuser42's Ctrl-C took 20 s "while preparing"). Until the engine
    first polls should_cancel a Ctrl-C stops at once; after that it cancels as before
    (test_cli_ctrl_c_leaves_the_target_untouched)."""
    target = tmp_path / "out.png"
    rc, seconds, err = _ctrl_c_into_a_silent_step(monkeypatch, capsys, "render", target,
                                                  compiling=False)
    assert rc == 130 and seconds < 20, (rc, seconds, err[-1500:])
    assert "interrupted while preparing" in err and "left untouched" in err, err
    assert "Traceback" not in err and target.read_bytes() == OLD


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_cli_ctrl_c_while_the_command_loads_stops_without_a_traceback(tmp_path):
    """Ctrl-C in the `photonmap` command's first moment (numpy, numba, Embree still
    importing): exit 130 and one line, never a KeyboardInterrupt traceback."""
    import time
    launcher = tmp_path / "photonmap"  # what pip's console script does, from this checkout
    started = tmp_path / "started"  # (written once Python's start-up is over)
    launcher.write_text(f"import sys\nsys.path.insert(0, {ROOT!r})\n"
                        f"open({str(started)!r}, 'w').close()\n"
                        "from engine.cli import main\nsys.exit(main())\n")
    target = tmp_path / "out.png"
    # A user's shell starts the command with Ctrl-C at its default; a background job of a
    # non-interactive shell (a CI run started with '&') inherits it ignored, and Python
    # then rightly keeps ignoring it: start the child as the shell would.
    proc = subprocess.Popen([sys.executable, str(launcher), "render", SCENE, "-o", str(target),
                             "--width", "32", "--height", "24", "--spp", "1", "--quiet"],
                            cwd=ROOT, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    # After Python's own start-up (before it, SIGINT kills the process: no handler yet)
    # and engine/__init__.py's first lines (its quiet handler), while numpy, numba and
    # Embree import (a second or more). A fixed 0.3 s from the start came too early at
    # load 20.
    deadline = time.monotonic() + 60
    while not started.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    err = proc.communicate(timeout=120)[1]
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupt" in err, err
    assert not target.exists()
