"""The progress bars' time left (engine/eta.py): measured after the kernel compile and
the first chunk, so it is right from the first estimate on a machine's first render
(the rate from the start, compile included, made it many times too long)."""
import re

import pytest

from engine.eta import Eta, format_seconds


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def _run(eta, clock, compile_seconds, setup_seconds, work_seconds, steps=20):
    """A render: the compile reports fraction 0, the first chunk (with its one-off
    set-up) ends at 1/steps, then the work goes on at a steady rate. Yields (true
    remaining seconds, estimate) after each report."""
    eta.restart()
    eta.update(0.0)
    clock.t += compile_seconds
    eta.update(0.0)  # the first progress report after the compile: no work done yet
    per_step = work_seconds / steps
    clock.t += setup_seconds + per_step
    eta.update(1 / steps)
    for i in range(2, steps + 1):
        clock.t += per_step
        eta.update(i / steps)
        yield (steps - i) * per_step, eta.remaining()


def test_time_left_after_a_long_compile_is_the_work_rate():
    clock = Clock()
    eta = Eta(clock=clock)
    estimates = list(_run(eta, clock, compile_seconds=60.0, setup_seconds=3.0,
                          work_seconds=20.0))
    for truth, estimate in estimates:  # from the second report after the first chunk
        assert estimate == pytest.approx(truth, abs=1e-9), estimates
    # The rate from the start (tqdm's {remaining}): the first estimates were minutes.
    t_half, f_half = 60.0 + 3.0 + 10.0, 0.5
    naive = (1 - f_half) / (f_half / t_half)
    assert naive > 7 * 10.0


def test_time_left_counts_down_between_reports_and_never_goes_back():
    clock = Clock()
    eta = Eta(clock=clock)
    eta.update(0.1)
    clock.t = 10.0
    eta.update(0.5)  # 0.4 in 10 s: 12.5 s left
    assert eta.remaining() == pytest.approx(12.5)
    clock.t = 15.0
    assert eta.remaining() == pytest.approx(7.5)
    eta.update(0.3)  # a stage reporting its own fraction anew: ignored
    assert eta.remaining() == pytest.approx(7.5)
    clock.t = 40.0
    assert eta.remaining() == 0.0
    eta.update(1.0)
    assert eta.remaining() == 0.0 and eta.text() == "00:00"


def test_no_estimate_without_enough_work():
    clock = Clock()
    eta = Eta(clock=clock)
    assert eta.remaining() is None and eta.text() == "?"
    eta.update(0.2)
    clock.t = 0.2
    eta.update(0.6)  # 0.2 s of work: below min_seconds
    assert eta.remaining() is None
    eta.update(float("nan"))
    assert eta.remaining() is None


def test_format_seconds():
    assert [format_seconds(s) for s in (None, 0, 59.6, 61, 3599, 3600, 7325)] == \
        ["?", "00:00", "01:00", "01:01", "59:59", "1:00:00", "2:02:05"]


def test_cli_bar_shows_the_fraction_of_the_whole_render_and_the_time_left(tmp_path,
                                                                           capsys):
    from engine.cli import main
    from engine.stagespans import StageSpans
    # The stages' own fractions map onto one rising fraction of the render.
    spans = StageSpans(True, 2000, 32 * 24)
    marks = [spans.whole(s, f) for s, f in (("photons", 0.0), ("photons", 1.0),
                                            ("photon_map", 0.0), ("render", 0.5),
                                            ("render", 1.0))]
    assert marks == sorted(marks) and marks[0] == 0.0 and marks[-1] == 1.0
    assert spans.whole("compile", 0.0) is None
    assert StageSpans(False).whole("render", 0.25) == 0.25
    out = tmp_path / "f.png"
    assert main(["render", "scenes/figure3.toml", "-o", str(out), "--width", "32", "--height",
                 "24", "--spp", "1", "--photons", "2000"]) == 0
    err = capsys.readouterr().err
    assert re.search(r"100% \[\d\d:\d\d<00:00\]", err), err[-1500:]


def test_time_left_follows_the_rate_of_the_current_stage():
    """Photons advance the add-on's bar fast (35 % in 10 s), the camera pass slowly (65 %
    in 130 s): the time left within the camera pass follows its own rate, not the
    average since the start (which promised 30 s where 78 s were left)."""
    clock = Clock()
    eta = Eta(clock=clock)
    eta.update(0.0)
    for i in range(1, 36):  # photons: 1 % per 0.29 s
        clock.t = i * 10.0 / 35
        eta.update(i / 100)
    for i in range(1, 66):  # camera pass: 1 % per 2 s
        clock.t = 10.0 + 2.0 * i
        eta.update((35 + i) / 100)
        truth = 2.0 * (65 - i)
        if clock.t > 40.0:  # once the recent window holds only the camera pass
            assert eta.remaining() == pytest.approx(truth, abs=1e-6), (i, eta.remaining())


def _first_render(eta, clock, stages):
    """The first make render of newuser37 (Figure 6, the kernels compiled), as the
    add-on's bar reports it: the compile (5 min, no progress), the export to 2 % of the
    bar, 0.8 s of set-up, the photon stages to 4.5 % in 2 s (the bar's share of them a
    guess: engine/stagespans.py), then the camera pass to 100 % in 47 s at a steady rate.
    Yields (stage, true seconds left, estimate) after each report; stages: tell them."""
    def report(f, stage):
        eta.update(f, stage if stages else None)
    eta.restart()  # "Compiling render kernels" (the batch's printer)
    clock.t = 300.0
    for i in range(1, 10):  # "Exporting i/9 objects", no stage
        clock.t += 0.05
        report(0.02 * i / 9, None)
    clock.t += 0.8
    end = clock.t + 2.0 + 47.0
    for i in range(1, 8):  # tracing photons
        clock.t += 0.1
        report(0.02 + 0.001 * i, "photons")
        yield "photons", end - clock.t, eta.remaining()
    clock.t += 1.3  # building the maps
    report(0.045, "photon_map")
    yield "photon_map", end - clock.t, eta.remaining()
    start = clock.t
    for i in range(1, 101):
        clock.t = start + 0.47 * i
        report(0.045 + 0.955 * i / 100, "render")
        yield "render", end - clock.t, eta.remaining()


def test_no_time_left_before_the_camera_pass_then_the_camera_passs_own_rate():
    """The first make render said "Tracing photons 100k/400k 2% [05:13<11:09]" for 51 s
    of work (newuser37): the rate was the set-up's and the photon stages', whose share of
    the bar is a guess (engine/stagespans.py). Told the stages, the bar shows no time
    left ('?') before the camera pass, then that pass' own rate: right from its second
    report past min_seconds."""
    clock = Clock()
    told = list(_first_render(Eta(clock=clock, final_stage="render"), clock, stages=True))
    assert all(estimate is None for stage, _, estimate in told if stage != "render"), told
    camera = [(truth, estimate) for stage, truth, estimate in told if stage == "render"]
    assert camera[0][1] is None  # its first report is the starting point
    assert all(e is not None for _, e in camera[2:])
    for truth, estimate in camera[2:]:
        assert estimate == pytest.approx(truth, abs=1e-6)
    # Untold (the bar's fraction alone): the photon stages promised up to 15 minutes for
    # 49 s (the set-up and their slow share of the bar in the rate), 1.4x too long still
    # as the camera pass began.
    clock = Clock()
    untold = list(_first_render(Eta(clock=clock, final_stage="render"), clock, stages=False))
    ratios = [e / t for stage, t, e in untold[:9] if e is not None]
    assert len(ratios) == 9 and min(ratios) > 1.3 and max(ratios) > 15, ratios


def test_a_new_stage_starts_the_rate_anew_and_untold_stages_keep_the_window():
    clock = Clock()
    eta = Eta(clock=clock, final_stage="render")
    eta.update(0.1, "render")
    clock.t = 10.0
    eta.update(0.5, "render")  # 0.4 in 10 s
    assert eta.remaining() == pytest.approx(12.5)
    clock.t = 12.0
    eta.update(0.6, "shadow catcher")  # a stage before the final one's end: no estimate
    assert eta.remaining() is None
    clock.t = 13.0
    eta.update(0.7, "render")  # back: its rate from this report
    assert eta.remaining() is None
    clock.t = 15.0
    eta.update(0.8, "render")
    assert eta.remaining() == pytest.approx(0.2 / (0.1 / 2.0))
