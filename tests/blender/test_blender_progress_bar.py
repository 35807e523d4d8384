"""The progress bar's stages take shares of the bar in proportion to their work
(engine/stagespans.py): a render's bar moves steadily instead of parking at a fixed
35 % while the camera pass, most of the time, runs (the s29 new user's "35 % ... <00:02"
for 10-18 s of a 48 s render)."""
import pytest

from blender_helpers import cheap, open_blend

pytestmark = pytest.mark.blender


def _contiguous(spans, order):
    end = 0.0
    for stage in order:
        start, width = spans[stage]
        assert start == pytest.approx(end) and width >= 0
        end = start + width
    assert end == pytest.approx(1.0)


def test_spans_cover_the_bar_in_proportion_to_the_work(bpy_addon):
    from addon.engine import EXPORT_SHARE
    from engine.stagespans import stage_spans as spans_of

    def stage_spans(photon_mapping, photons=0, samples=1):
        return {"export": (0.0, EXPORT_SHARE),
                **spans_of(photon_mapping, photons, samples, start=EXPORT_SHARE)}
    # The paper's Figure 6 at the defaults: 600k photons, 320 x 240 x 128 samples; its
    # photons and maps took 1.6 of 27.4 CPU s (docs/performance.md "e2e28"): the share
    # is on the low side of that (engine/stagespans.py PHOTON_COST_PER_SAMPLE: other
    # scenes' camera samples cost up to 50x Figure 6's), never above it.
    spans = stage_spans(True, 600_000, 320 * 240 * 128)
    _contiguous(spans, ("export", "photons", "photon_map", "render"))
    photon_share = spans["photons"][1] + spans["photon_map"][1]
    assert 0.005 < photon_share < 1.6 / 27.4
    assert spans["render"][1] > 0.9
    # Few samples: the photons are most of the work.
    few = stage_spans(True, 600_000, 64 * 48 * 4)
    assert few["photons"][1] + few["photon_map"][1] > 0.9 * (1 - EXPORT_SHARE)
    # No photon mapping: the render takes what the export leaves.
    off = stage_spans(False)
    _contiguous(off, ("export", "render"))
    assert "photons" not in off


def _render_events(bpy, kinds) -> list:
    """[(event, value)] of the add-on's status events of those kinds during one F12."""
    from addon import engine
    events = []
    listener = (lambda event, value: events.append((event, value))
                if event in kinds else None)
    engine.status_listeners.append(listener)
    try:
        bpy.ops.render.render()
    finally:
        engine.status_listeners.remove(listener)
    return events


def test_a_render_reports_progress_that_never_goes_back(bpy_addon):
    bpy = bpy_addon
    scene = open_blend(bpy, "figure6_box.blend")
    cheap(scene, width=48, height=36, pct=100, spp=4, photons=20_000,
          caustic_photons=5_000)
    from addon import engine
    events = _render_events(bpy, ("progress", "stage"))
    values = [v for e, v in events if e == "progress"]
    # Each stage told once, before its first progress (the batch bar's time left is
    # measured in the camera pass alone: engine/eta.py).
    stages = [(i, v) for i, (e, v) in enumerate(events) if e == "stage"]
    assert [v for _, v in stages] == ["photons", "photon_map", "render"], events
    assert all(events[i + 1][0] == "progress" for i, _ in stages), events
    assert len(values) > 3
    assert all(b >= a - 1e-9 for a, b in zip(values, values[1:])), values
    assert values[-1] == pytest.approx(1.0, abs=0.02)
    # 25k photons (5,000 camera samples' worth) against 48 x 36 x 4 = 6912 samples:
    # the photon stages take about 40 % of the bar.
    from engine.stagespans import PHOTON_COST_PER_SAMPLE, stage_spans
    spans = stage_spans(True, 25_000, 48 * 36 * 4, start=engine.EXPORT_SHARE)
    work = 25_000 * PHOTON_COST_PER_SAMPLE
    assert spans["render"][0] == pytest.approx(
        engine.EXPORT_SHARE + (1 - engine.EXPORT_SHARE) * work / (work + 48 * 36 * 4))
    assert 0.3 < spans["render"][0] < 0.6


def test_a_first_render_fills_the_bar_while_the_kernels_compile(bpy_addon, monkeypatch):
    """A first render on a machine compiles the kernels for minutes: the bar's first half
    follows the compile (kernels done / all) and the render's own work the second half,
    never going back (newuser39 watched it at 0 % through the compile); a render with
    the kernels cached starts its work at 0."""
    bpy = bpy_addon
    scene = open_blend(bpy, "figure6_box.blend")
    cheap(scene, width=24, height=18, pct=100, spp=2, photons=5_000, caustic_photons=1_000)
    from addon import engine
    from addon.core import load_engine
    pm = load_engine()

    def compile_steps(progress=None):
        for i in (1, 2, 3, 4):
            progress("compile", i / 4, pm.jit.COMPILE_PROGRESS.format(i, 4))
        return 2.0
    monkeypatch.setattr(pm.jit, "needs_compile", lambda: True)
    monkeypatch.setattr(pm.jit, "ensure_compiled", compile_steps)
    events = _render_events(bpy, ("progress", "stats"))
    values = [v for e, v in events if e == "progress"]
    assert values[:4] == pytest.approx([0.125, 0.25, 0.375, 0.5])
    assert all(b >= a - 1e-9 for a, b in zip(values, values[1:]))
    assert values[-1] == pytest.approx(1.0)
    assert any(e == "stats" and "Compiling kernels 2/4" in str(v) for e, v in events)
    # Cached kernels: the render's work from 0.
    monkeypatch.setattr(pm.jit, "needs_compile", lambda: False)
    monkeypatch.setattr(pm.jit, "ensure_compiled", lambda progress=None: 0.0)
    values = [v for e, v in _render_events(bpy, ("progress",))]
    assert values[0] < 0.1 and values[-1] == pytest.approx(1.0)
