"""The add-on's report of a render: the effect report reaches last_render and the
stats carry the real kernel-compile time (docs/design.md, Bounce limits; issue 14)."""
import re

import pytest

from blender_helpers import cheap

pytestmark = pytest.mark.blender


def test_stats_carry_the_compile_time_under_one_name(open_ground, monkeypatch):
    """The add-on loads (or compiles) the kernels before the export, so the engine's own
    time_compile read 0.0 while last_render kept the real number apart as compile_time:
    now stats['time_compile'] is the add-on's number (one name), and compile_time is
    gone."""
    import bpy

    from addon import engine
    from addon.core import load_engine
    pm = load_engine()
    monkeypatch.setattr(pm.jit, "ensure_compiled", lambda progress=None: 1.25)
    cheap(open_ground, width=16, height=12, spp=1, photons=2000, caustic_photons=500)
    bpy.ops.render.render()
    last = engine.last_render
    assert "compile_time" not in last
    assert last["stats"]["time_compile"] >= 1.25
    lines = last["stats"]["effects"]
    # The open ground's rough grey floor and ball: matte, and nothing focuses light.
    caustics = next(x for x in lines if x.startswith("caustics:"))
    assert caustics.startswith("caustics: off - nothing focuses light"), caustics
    bounces = next(x for x in lines if x.startswith("bounce limits:"))
    assert bounces.endswith("camera paths stop at these too, as in Cycles"), bounces


def test_adaptive_render_reports_its_samples(open_ground):
    """A render with Noise Threshold on: the stats carry the mean samples a pixel took,
    between the first check (16 past Min Samples 4) and Samples."""
    import bpy

    from addon import engine
    cheap(open_ground, width=16, height=12, spp=32, photons=2000, caustic_photons=500)
    pm = open_ground.photonmap
    pm.use_adaptive_sampling, pm.adaptive_threshold, pm.adaptive_min_samples = True, 0.05, 4
    try:
        bpy.ops.render.render()
    finally:
        for name in ("use_adaptive_sampling", "adaptive_threshold", "adaptive_min_samples"):
            pm.property_unset(name)
    stats = engine.last_render["stats"]
    assert 16 <= stats["adaptive_mean_spp"] <= 32
    assert stats["adaptive_spp"] == 32


def test_the_next_frame_prints_an_unchanged_effect_report_once(open_ground, capsys):
    """Ctrl+F12 printed the whole effect report to the console once a frame (s23's trial):
    a render that simulates what the one before did prints one line instead."""
    import bpy

    from addon import engine
    cheap(open_ground, width=16, height=12, spp=1, photons=2000, caustic_photons=500)
    engine._printed_effects = []
    bpy.ops.render.render()
    first = capsys.readouterr().out
    report = engine.last_render["stats"]["effects"]
    assert all(f"Photon Mapping: {line}" in first for line in report), first
    open_ground.frame_set(open_ground.frame_current + 1)
    bpy.ops.render.render()
    second = capsys.readouterr().out
    assert "Photon Mapping: effects as the previous render" in second, second
    assert not any(f"Photon Mapping: {line}" in second for line in report), second


def test_the_next_frame_reports_only_new_warnings(open_ground):
    """Ctrl+F12 reported every warning again on every frame: the frame after the last one
    rendered reports only what is new and counts the rest in one line; rendering a frame
    again (or one that does not follow) reports them all. The render's own list keeps
    them all."""
    import bpy

    from addon import engine
    toon = bpy.data.materials.new("Toon")
    if bpy.app.version < (5, 0, 0):
        toon.use_nodes = True
    nt = toon.node_tree
    bsdf = nt.nodes.new("ShaderNodeBsdfToon")
    nt.links.new(bsdf.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    bpy.data.objects["Ball"].data.materials.clear()
    bpy.data.objects["Ball"].data.materials.append(toon)
    cheap(open_ground, width=16, height=12, spp=1, photons=2000, caustic_photons=500)
    events = []
    listener = lambda event, value: events.append((event, value))  # noqa: E731

    def render(frame):
        open_ground.frame_set(frame)
        events.clear()
        engine.status_listeners.append(listener)
        try:
            bpy.ops.render.render()
        finally:
            engine.status_listeners.remove(listener)
        told = [v for e, v in events if e == "warning"]
        repeated = [v for e, v in events if e == "warnings_repeated"]
        return told, repeated

    told, repeated = render(1)
    toon_warnings = [w for w in told if "Toon" in w]
    assert toon_warnings and not repeated, told
    told, repeated = render(2)  # the next frame: nothing new to say
    assert not [w for w in told if "Toon" in w] and repeated and repeated[0] >= 1, events
    assert any("Toon" in w for w in engine.last_render["warnings"])
    told, repeated = render(2)  # the same frame again: a user fixing what was warned
    assert [w for w in told if "Toon" in w] == toon_warnings and not repeated
    told, repeated = render(5)  # not the next frame
    assert [w for w in told if "Toon" in w] == toon_warnings and not repeated


def test_a_moving_animation_prints_its_effect_report_once(open_ground, capsys):
    """s26's trial: a 2-frame animation of a turning bottle printed the whole report on
    both frames, as the photons stored (and the search radius) differ a little when
    anything moves. Lines whose words are unchanged are not printed again."""
    import bpy

    from addon import engine
    cheap(open_ground, width=16, height=12, spp=1, photons=2000, caustic_photons=500)
    engine._printed_effects = []
    ball = bpy.data.objects["Ball"]
    start = ball.location.copy()
    try:
        bpy.ops.render.render()
        first_report = engine.last_render["stats"]["effects"]
        capsys.readouterr()
        ball.location.x += 0.7  # the ball moves: other photon counts, the same effects
        bpy.ops.render.render()
        second = capsys.readouterr().out
    finally:
        ball.location = start
    report = engine.last_render["stats"]["effects"]
    assert report != first_report  # the numbers moved (else the s23 test covers it)
    # (the report's lines, not the background progress lines "Photon Mapping: 24% ...")
    printed = [x for x in second.splitlines() if x.startswith("Photon Mapping: ")
               and not re.match(r"Photon Mapping: \d+% ", x)]
    assert printed[0].startswith("Photon Mapping: effects as the previous render"), second
    words = engine._NUMBER.sub
    same = [line for line, old in zip(report, first_report)
            if words("#", line) == words("#", old)]
    assert len(same) >= len(report) - 1, (report, first_report)  # the photon maps line at most
    assert not any(x.endswith(line) for x in printed for line in same), second
    changed = [line for line in report if line not in same]
    assert printed[1:len(changed) + 1] == [f"Photon Mapping: {x}" for x in changed], second


def test_a_changed_effect_line_is_printed_after_the_unchanged_ones():
    """Only lines whose words changed are printed again; all changed (or another number of
    lines): the whole report."""
    from addon.engine import effect_lines_to_print
    before = ["caustics: off - nothing focuses light", "photon maps: on - 1,200 photons"]
    moved = ["caustics: off - nothing focuses light", "photon maps: on - 1,250 photons"]
    assert effect_lines_to_print(moved, before) == ["effects as the previous render"]
    switched = ["caustics: on - 500 photons aimed at 'Glass'", "photon maps: on - 1,250 photons"]
    assert effect_lines_to_print(switched, before) == [
        "effects as the previous render, except:", "caustics: on - 500 photons aimed at 'Glass'"]
    assert effect_lines_to_print(before, []) == before
    assert effect_lines_to_print(before[:1], before) == before[:1]
    other = ["caustics: on - 9 photons", "photon maps: off - no lights"]
    assert effect_lines_to_print(other, before) == other


def test_a_background_render_prints_its_progress(open_ground, capsys):
    """newuser56: a script's bpy.ops.render.render() sat silent for minutes (no bar in
    the background, and Blender 5 prints no stats line): a line each tenth of the bar,
    rising, with the stats text; none at the end (the report follows)."""
    import bpy
    # (enough pixels for several camera chunks: the bar moves in steps)
    cheap(open_ground, width=64, height=48, spp=96, photons=2000, caustic_photons=500)
    bpy.ops.render.render()
    out = capsys.readouterr().out
    shares = [int(m) for m in re.findall(r"^Photon Mapping: (\d+)% \S", out, re.M)]
    assert len(shares) >= 3, out
    assert shares == sorted(shares) and len(set(s // 10 for s in shares)) == len(shares)
    assert 0 < shares[0] and shares[-1] < 100
