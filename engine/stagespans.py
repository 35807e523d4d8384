"""The progress bar's share of each stage of a render, for the CLI's bar (engine/cli.py)
and Blender's (addon/engine.py).

A render reports progress(stage, fraction, text) with each stage's own fraction 0..1
(engine.render). A bar over the whole render gives each stage a span (start, width) in
proportion to its work: the photon pass and the photon maps' build by the photons emitted,
the camera pass by its samples (pixels x spp). Fixed shares were far off: 35 % of the bar
for photons that took 3-7 % of the time left the bar parked there while the pixels
rendered (newuser29). The photons emitted are known exactly only once the effect analysis
has planned the shots (a glow shot can be several times the global one: newuser33's bar
crawled through the photon span and then jumped), so the spans start from the settings'
counts and are re-sized by `StageSpans.plan` when the render tells its plan
(engine.render's on_plan), before any photon is traced: nothing past the start has been
shown yet, so the bar never moves back.
"""
from __future__ import annotations

# CPU per emitted photon (tracing and the maps' build) over CPU per camera sample. It
# differs by scene far more than by photon: the paper's Figure 6 at the defaults 1.0
# (docs/performance.md "e2e28": 1.6 s for 600k photons, 25.8 s for 320 x 240 x 128
# samples), newuser29's room ~0.2 (5 % of its time on photons where 1.0 said 20 %),
# newuser34's lamp-and-window room 0.012 (1.6 us a photon, 3.3M of them with the glow
# shot, against 132 us a camera sample: 1.0 put the bar at 57 % after 6 of 332 s). A
# photon share too small only hurries the bar through a short stage; one too large parks
# it for minutes: the low side, 0.2.
PHOTON_COST_PER_SAMPLE = 0.2
# The photon stage's split between tracing and building the maps (Figure 6: 0.6 s
# tracing, 1.0 s maps).
TRACE_SHARE = 0.6
# The shadow catcher's second, catcher-only pass (engine/shadowcatcher.py) at the end of
# a render whose scene has a catcher: its share of the render's span (measured 20 % and
# 23 % of the render time on newuser37's opaque and transparent catcher scenes). Without
# a span of its own the bar sat near 100 % while that pass ran (polish38).
CATCHER_SHARE = 0.2


def stage_spans(photon_mapping: bool, photons: int = 0, samples: int = 1,
                start: float = 0.0, catcher: bool = False, groups: int = 0) -> dict:
    """{stage: (start, width)} covering [start, 1] of the bar: "photons", "photon_map"
    and "render" in proportion to their work, or "render" alone without photon mapping
    (or no photons); with catcher, "shadow catcher" (the catcher-only pass) takes the
    last CATCHER_SHARE of it; with groups > 0 light groups to render after it
    (engine/lightgroups.py: each a render of its own emitters, about the main one's
    work), "light groups" takes the last groups / (groups + 1) of the bar (newuser41b:
    it sat at 100 % through four groups' renders). photons: emitted over every shot;
    samples: the camera samples of the render (pixels x spp); start: the share taken
    before the render (the add-on's export)."""
    rest = 1.0 - start
    out = {}
    if groups > 0:
        share = rest * groups / (groups + 1.0)
        out["light groups"] = (1.0 - share, share)
        rest -= share
    if catcher:
        out["shadow catcher"] = (start + (1.0 - CATCHER_SHARE) * rest, CATCHER_SHARE * rest)
        rest -= CATCHER_SHARE * rest
    if not photon_mapping or photons <= 0:
        out["render"] = (start, rest)
        return out
    work = photons * PHOTON_COST_PER_SAMPLE
    share = rest * work / (work + max(samples, 1))
    trace, build = TRACE_SHARE * share, (1.0 - TRACE_SHARE) * share
    out.update({"photons": (start, trace), "photon_map": (start + trace, build),
                "render": (start + share, rest - share)})
    return out


class StageSpans:
    """A render's spans (stage_spans), re-sized when the render tells its photon plan.

    spans = StageSpans(photon_mapping, photons, samples, start); spans.plan(work) as the
    render's on_plan; spans.whole(stage, fraction) -> the bar's position, None for a
    stage outside the render's work (the kernel compile)."""

    def __init__(self, photon_mapping: bool, photons: int = 0, samples: int = 1,
                 start: float = 0.0):
        self.photon_mapping, self.samples, self.start = photon_mapping, samples, start
        self.photons, self.catcher, self.groups = photons, False, 0
        self.spans = stage_spans(photon_mapping, photons, samples, start)

    def plan(self, work: dict) -> None:
        """engine.render's on_plan: {"photons": n} emitted over every shot, {"catcher_pass":
        True} when a catcher-only pass follows the main one, {"light_groups": n} the light
        groups rendered after it (each key as it is known)."""
        self.photons = int(work.get("photons", self.photons))
        self.catcher = bool(work.get("catcher_pass", self.catcher))
        self.groups = int(work.get("light_groups", self.groups))
        self.spans = stage_spans(self.photon_mapping, self.photons, self.samples,
                                 self.start, self.catcher, self.groups)

    def whole(self, stage: str, fraction: float) -> float | None:
        if stage not in self.spans:
            return None
        base, span = self.spans[stage]
        return min(1.0, max(0.0, base + span * min(max(float(fraction), 0.0), 1.0)))
