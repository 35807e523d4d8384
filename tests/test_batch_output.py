"""The batch command's output (addon/batch.py, _StatusPrinter): warnings start on a line
of their own and the progress bar continues below them, also when stdout and stderr share
one file (`python -m addon.batch ... > log 2>&1`, where Blender's warnings were glued to
the bar's line: new-user trial, s17). No Blender needed: the printer is fed the engine's
events and Blender's stdout print as the render operator makes them."""
import io
import sys

import pytest

from addon import batch

WARNINGS = ["material 'toon': shader 'Toon BSDF' (BSDF_TOON) is not supported; "
            "approximated by a Diffuse BSDF of its Color",
            "mesh 'NaNMesh': dropped 4 zero-area faces"]


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def _run(shared):
    """A render's events as addon/engine.py sends them, the bar and the warnings into
    one stream `shared`, Blender's reports printed on sys.stdout as bpy.ops does when the
    render operator returns (inside beside_bar); returns the text written."""
    printer = batch._StatusPrinter(stream=shared, out=shared)
    with printer.beside_bar():
        printer("stats", "Exporting 1/7 objects")
        printer("progress", 0.01)
        printer("warning", WARNINGS[0])  # the export's: before the long render
        printer("stats", "Tracing photons 16k/20k")
        printer("progress", 0.3)
        printer("stats", "Rendering 43%")
        printer("progress", 0.9)
        printer("warning", WARNINGS[1])  # the engine's own, after the render
        printer("stats", "Done: 4454 triangles, 1 light, 0.5 s")
        printer("progress", 1.0)
        printer("effects", ["caustics: off - nothing focuses light"])
        printer("finished", "done")
        for w in WARNINGS:  # Blender's print of the operator's reports, sys.stdout
            print(f"Warning: Photon Mapping: {w}")
        print("Info: another report")
    printer.close()
    return shared.getvalue()


def _check(text):
    lines = text.split("\n")  # a line in a log file: \r does not start one there
    for w in WARNINGS:
        where = [i for i, line in enumerate(lines) if w in line]
        assert len(where) == 1, (w, text)  # said once: Blender's repeat is left out
        line = lines[where[0]].rsplit("\r", 1)[-1]
        assert line == f"Warning: Photon Mapping: {w}", repr(lines[where[0]])
    # Each at the start of its line (no bar drawn before it on that line), the bar below.
    first = next(i for i, line in enumerate(lines) if WARNINGS[0] in line)
    assert lines[first].startswith("Warning: ") or lines[first].startswith("\r"), text
    assert "Tracing photons" in "\n".join(lines[first + 1:]), text  # the bar continues
    assert any(line.split("\r")[-1] == "Info: another report" for line in lines), text
    assert lines.index("Done: 4454 triangles, 1 light, 0.5 s") > first
    assert "  caustics: off - nothing focuses light" in lines


def test_warnings_in_a_shared_log_file_start_on_a_line_of_their_own():
    text = _run(io.StringIO())
    _check(text)
    for w in WARNINGS:  # a file keeps what \r would wipe: a real line start, not a \r
        line = next(line for line in text.split("\n") if w in line)
        assert line.startswith("Warning: "), repr(line)


def test_warnings_on_a_terminal_clear_the_bar_and_it_is_redrawn_below():
    text = _run(_Terminal())
    _check(text)
    before, after = text.split(f"Warning: Photon Mapping: {WARNINGS[0]}\n")
    assert before.endswith("\r"), repr(before[-80:])  # the bar's line cleared first
    assert after.startswith("\r") and "% [" in after.split("\n")[0], repr(after[:200])


def test_quiet_leaves_blenders_print_alone():
    """--quiet prints no warning itself: Blender's print of each report passes through
    as it is, except its two prints of a failure, which the run's "render failed" line
    says (newuser42: a memory refusal read three times)."""
    shared = io.StringIO()
    printer = batch._StatusPrinter(quiet=True, stream=shared, out=shared)
    with printer.beside_bar():
        printer("warning", WARNINGS[0])
        print(f"Warning: Photon Mapping: {WARNINGS[0]}")
        printer("finished", "error: Photon Mapping: not rendered: too big")
        print("Error: Photon Mapping: not rendered: too big")
        print("Error: Photon Mapping: not rendered: too big")
    printer.close()
    assert shared.getvalue() == f"Warning: Photon Mapping: {WARNINGS[0]}\n", shared.getvalue()
    assert printer.warnings == [WARNINGS[0]]


def test_more_warnings_than_blender_reports_are_each_printed_once():
    """Past the add-on's MAX_REPORTED_WARNINGS the rest are printed by the add-on
    ("Photon Mapping warning: ...") and one report points at "the system console", which
    for the batch is this output: both left out, every warning said once when it came."""
    shared = io.StringIO()
    printer = batch._StatusPrinter(stream=shared, out=shared)
    with printer.beside_bar():
        printer("stats", "Rendering 1%")
        for w in WARNINGS:
            printer("warning", w)
        print(f"Photon Mapping warning: {WARNINGS[1]}")  # during the render
        print(f"Warning: Photon Mapping: {WARNINGS[0]}")  # when the operator returns
        print("Warning: Photon Mapping: 1 more warnings (see the system console)")
        print("half a line", end="")
    printer.close()
    text = shared.getvalue()
    for w in WARNINGS:
        assert text.count(w) == 1, text
    assert "system console" not in text and "Photon Mapping warning:" not in text
    assert "\nhalf a line" in text


def _frame_report(previous, effects):
    shared = io.StringIO()
    printer = batch._StatusPrinter(stream=shared, out=shared, previous_effects=previous)
    printer("stats", "Done: 12 triangles, 1 light, 0.1 s")
    printer("effects", effects)
    printer("finished", "done")
    printer.close()
    return shared.getvalue()


def test_an_animations_later_frame_repeats_no_unchanged_effect_report():
    """--frames: each frame printed the whole effect report again (s23's trial); a frame
    that simulates what the frame before did says so in one line, a changed one its
    changed lines only (newuser42: a moving ring changed one count a frame and the batch
    printed the whole report each time)."""
    report = ["caustics: on - 'Glass' focuses light", "final gather: on"]
    first = _frame_report(None, report)
    assert all(f"  {line}" in first for line in report)
    same = _frame_report(list(report), list(report))
    assert "Effects as the previous frame" in same and "except" not in same
    assert not any(line in same for line in report)
    changed = _frame_report(report, ["caustics: off - nothing focuses light",
                                      "final gather: on"])
    assert "Effects as the previous frame, except:" in changed
    assert "  caustics: off - nothing focuses light" in changed
    assert "final gather: on" not in changed


def test_the_bar_redraws_its_clock_through_the_kernel_compile():
    """newuser24 watched "Compiling render kernels (first render only): 0%" for an hour:
    the module count was cut off by the bar's 46 characters and nothing redrew the bar
    between two modules. The count's text fits, and the bar redraws every second while
    the compile runs, as through any step that reports nothing (a slow estimator chunk,
    newuser42), until the bar closes."""
    import time

    from engine.jit import COMPILE_MESSAGE, COMPILE_PROGRESS
    assert len(COMPILE_PROGRESS.format(14, 14)) <= 42
    shared = _Terminal()
    printer = batch._StatusPrinter(stream=shared, out=shared)
    printer("stats", COMPILE_MESSAGE)
    printer("stats", COMPILE_PROGRESS.format(1, 14))
    before = shared.getvalue().count("\r")
    time.sleep(2.5)
    during = shared.getvalue().count("\r")
    assert during >= before + 2, (before, during)
    assert "Compiling kernels 1/14, first render only" in shared.getvalue()
    printer("stats", "Exporting 1/4 objects")
    settled = shared.getvalue().count("\r")
    time.sleep(2.5)
    assert shared.getvalue().count("\r") >= settled + 2
    printer("finished", "done")
    printer.close()
    closed = shared.getvalue()
    time.sleep(1.5)
    assert shared.getvalue() == closed  # the ticker stopped with the bar


def _frames(text):
    """Each frame the bar drew and each other line, in a file's text, the clock aside."""
    import re
    return [re.sub(r"\s*\[[^\[\]]*\]\s*$", "", f).rstrip()
            for f in re.split(r"[\r\n]", text) if f.strip()]


def test_a_cancelled_render_in_a_log_file_says_each_state_once():
    """In a log file (stderr redirected, a pipe) "Cancelled" and each progress state
    were drawn twice (s30): a stage's text and its first progress step drew one state in
    two frames, and closing the bar drew its last state again below Blender's report."""
    shared = io.StringIO()  # a file: every frame stays in the text
    printer = batch._StatusPrinter(stream=shared, out=shared)
    with printer.beside_bar():
        printer("stats", "Loading engine")
        printer("stats", "Exporting 1/4 objects")
        printer("progress", 0.005)  # 0 % still: the same state
        printer("stats", "Exporting 4/4 objects")
        printer("progress", 0.02)
        printer("stats", "Rendering pixels 512/5k")
        printer("progress", 0.41)
        printer("stats", "Cancelled")
        printer("finished", "cancelled")
        # Blender's print of the engine's report when the render operator returns
        print("Info: Photon Mapping: render cancelled (12 triangles, 1 light, 0.5 s)")
    printer.close()
    frames = _frames(shared.getvalue())
    assert sum(f.startswith("Cancelled") for f in frames) == 1, frames
    assert len(frames) == len(set(frames)), frames  # no state drawn twice
    # Each stage's first state and, when it moved on within LOG_FRAME_SECONDS, its last
    # one before the next stage (no line per step between).
    bar = [f for f in frames if "%" in f]
    assert [f.split("  ")[0] + " " + f.split()[-1] for f in bar] == [
        "Starting 0%", "Loading engine 0%", "Exporting 1/4 objects 0%",
        "Exporting 4/4 objects 0%", "Rendering pixels 512/5k 2%", "Cancelled 41%"], bar
    assert "\r" not in shared.getvalue()  # each frame a line of its own in a log
    assert frames[-1].startswith("Info: Photon Mapping: render cancelled"), frames
    assert shared.getvalue().endswith("s)\n")  # the bar's line ended, nothing after


def test_a_finished_render_in_a_log_file_draws_its_last_state_once():
    shared = io.StringIO()
    printer = batch._StatusPrinter(stream=shared, out=shared)
    printer("stats", "Rendering pixels 5k/5k")
    printer("progress", 1.0)
    printer("stats", "Done: 12 triangles, 1 light, 0.1 s")
    printer("finished", "done")
    printer.close()
    frames = _frames(shared.getvalue())
    assert sum(f.startswith("Done ") for f in frames) == 1, frames
    assert "Done: 12 triangles, 1 light, 0.1 s" in frames  # close()'s summary line


def test_on_a_terminal_the_bar_still_redraws_an_unchanged_state():
    """A terminal overwrites each frame: there every draw is kept (the clock moves)."""
    shared = _Terminal()
    printer = batch._StatusPrinter(stream=shared, out=shared)
    printer("stats", "Exporting 1/4 objects")
    printer("progress", 0.005)
    printer("stats", "Cancelled")
    printer("finished", "cancelled")
    printer.close()
    assert shared.getvalue().count("Cancelled") >= 2  # its frame, then tqdm's closing one


def test_the_time_left_waits_for_the_camera_pass_the_engine_names():
    """The add-on tells each stage before its progress ("stage" events); the batch's bar
    shows no time left before the camera pass (engine/eta.py: the photon stages' rate
    promised 11:09 for 51 s, newuser37), then the pass' own rate."""
    clock = [0.0]
    printer = batch._StatusPrinter(stream=io.StringIO(), out=io.StringIO())
    printer("stats", "Exporting 1/1 objects")
    printer.eta.clock = lambda: clock[0]
    printer("progress", 0.02)
    for stage, t, f in (("photons", 1.0, 0.021), ("photons", 2.0, 0.022),
                        ("photon_map", 3.0, 0.03), ("render", 4.0, 0.1),
                        ("render", 6.0, 0.3), ("render", 8.0, 0.5)):
        clock[0] = t
        printer("stage", stage)
        printer("progress", f)
        assert (printer.eta.remaining() is None) == (t < 6.0), (stage, t)
    assert printer.eta.remaining() == pytest.approx(0.5 / 0.1)  # 10 %/s in the pass
    assert printer.eta.text() == "00:05"
    printer("finished", "done")
    printer.close()
