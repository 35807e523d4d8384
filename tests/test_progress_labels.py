"""The progress text names each photon shot as the effect report names what it holds: the
glow shot (light off rough specular layers first, engine/render.py GLOW_SHOT) is named by
the surfaces the light comes off ("glossy photons"), not "caustic photons", which beside
the report's "caustics: off - nothing focuses light" read as a contradiction (newuser33: a
room lit by a lamp in a frosted shade showed "Tracing caustic photons 2156k/2156k"), nor
"glow photons", which said nothing to a user (newuser37); the maps line says what they
carry."""
import pytest

from engine import RenderSettings
from engine.render import render
from test_leak_lampshade import lamp_scene


def test_glow_shot_is_traced_as_glow_photons_when_caustics_are_off():
    texts = []
    film = render(lamp_scene(24, 18),
                  RenderSettings(spp=1, photons=20_000, caustic_photons=5_000, seed=1,
                                 workers=1),
                  progress=lambda stage, fraction, text: texts.append(text))
    report = "\n".join(film.stats["effects"])
    assert "caustics: off" in report, report
    assert film.stats.get("glow_photons_emitted", 0) > 0, film.stats  # the shot ran
    tracing = [t for t in texts if t.startswith("Tracing")]
    assert any(t.startswith("Tracing glossy photons ") for t in tracing), tracing
    assert not any("caustic photons" in t for t in tracing), tracing
    # The report says what they were: the soft glow of the rough metal shade and plaster.
    maps = next(line for line in film.stats["effects"] if line.startswith("photon maps"))
    assert (f"glossy photons: {film.stats['glow_photons_emitted']:,} traced for the soft "
            "glow off rough specular layers (the light those surfaces") in maps, maps
    # The global shot keeps its name.
    assert any(t.startswith("Tracing photons ") for t in tracing), tracing



def test_photon_progress_moves_once_through_all_shots():
    """The photon stage's fraction rises steadily over the global and the glow shot and
    ends at 1 (each shot ran 0 -> 1 on its own: the glow shot, several times the global
    one here, held the bar at the end of the photon span; newuser33)."""
    seen = []
    render(lamp_scene(24, 18),
           RenderSettings(spp=1, photons=20_000, caustic_photons=5_000, seed=1, workers=1),
           progress=lambda stage, fraction, text: seen.append((stage, fraction, text)))
    photons = [(f, t) for stage, f, t in seen if stage == "photons"]
    fractions = [f for f, _ in photons]
    assert any(t.startswith("Tracing glossy photons") for _, t in photons)
    assert all(b >= a for a, b in zip(fractions, fractions[1:])), fractions
    assert abs(fractions[-1] - 1.0) < 1e-9, fractions[-1]
    first_glow = next(f for f, t in photons if t.startswith("Tracing glossy photons"))
    assert 0.0 < first_glow < 1.0, first_glow


def test_the_render_tells_its_photon_plan_before_tracing_and_the_bar_follows_it():
    """on_plan is told the photons of every shot (the glow shot included) before the first
    is traced; StageSpans re-sized by it gives the photon stage its real share (the
    settings' global + caustic counts left out a glow shot several times their size:
    newuser33's bar crawled through the photon span, then jumped)."""
    from engine.stagespans import StageSpans
    settings = RenderSettings(spp=1, photons=20_000, caustic_photons=5_000, seed=1,
                              workers=1)
    samples = 24 * 18 * settings.spp
    spans = StageSpans(True, settings.photons + settings.caustic_photons, samples)
    before = spans.spans["photons"]
    events = []

    def on_plan(work):
        events.append(("plan", work["photons"]))
        spans.plan(work)

    film = render(lamp_scene(24, 18), settings, on_plan=on_plan,
                  progress=lambda stage, fraction, text: events.append(
                      (stage, spans.whole(stage, fraction))))
    st = film.stats
    # Caustics off: the glow shot is the caustic map (its photons counted once).
    assert "caustics: off" in "\n".join(st["effects"])
    emitted = st["photons_emitted"] + st["glow_photons_emitted"]
    plans = [e for e in events if e[0] == "plan"]
    assert len(plans) == 1 and plans[0][1] == emitted, (plans, emitted)
    assert st["photons_emitted_all"] == emitted  # (the teaching tiles' count)
    assert st["glow_photons_emitted"] > settings.photons  # the shot the settings miss
    first_photon = next(i for i, e in enumerate(events) if e[0] == "photons")
    assert events.index(plans[0]) < first_photon
    # The bar: rising, 0 -> 1, the photon stage's share by the plan's count.
    marks = [w for stage, w in events if stage != "plan" and w is not None]
    assert all(b >= a - 1e-12 for a, b in zip(marks, marks[1:])), marks
    assert marks[-1] == 1.0
    from engine.stagespans import PHOTON_COST_PER_SAMPLE
    work = emitted * PHOTON_COST_PER_SAMPLE
    assert spans.spans["render"][0] == pytest.approx(work / (work + samples))
    assert spans.spans["photons"][1] > before[1]
