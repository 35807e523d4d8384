"""Many lights in the photon pass: lights that get only a few photons each emit together,
as one photon job, so 1000 small lights cost a handful of traced batches instead of 1000
(each batch pays Embree's and numpy's per-call overhead at every bounce).

Only scenes with more than selection.SAMPLE_ALL_UP_TO lights are grouped, so the photons
(and images) of scenes with few lights are exactly as before.
"""
from __future__ import annotations

from ..parallel import MIN_CHUNK
from . import selection
from .base import emit_arrays


class LightGroup:
    """Consecutive lights of equal ray visibility that emit as one photon job: emit_into
    with n = the sum of their photon counts writes each member's photons (each member's
    share summing to its photon_flux, as Light.emit_into), in order."""

    def __init__(self, lights, counts):
        self.lights = list(lights)
        self.counts = [int(c) for c in counts]
        self.ray_kinds = self.lights[0].ray_kinds
        self.name = f"{len(self.lights)} lights from '{self.lights[0].name}'"

    def _check(self, n):
        if n != sum(self.counts):
            raise ValueError(f"{self.name}: a group emits its {sum(self.counts)} photons at once, "
                             f"not {n}")

    def emit_into(self, key, first, n, count, out, start):
        """Light.emit_into for every member in turn (its own count), slots in order."""
        self._check(n)
        for light, c in zip(self.lights, self.counts):
            start = light.emit_into(key, first, c, c, out, start)
            first += c
        return start

    def emit_towards_into(self, key, first, n, count, targets, out, start):
        """Light.emit_towards_into for every member in turn."""
        self._check(n)
        for light, c in zip(self.lights, self.counts):
            start = light.emit_towards_into(key, first, c, c, targets, out, start)
            first += c
        return start

    def emit(self, n: int, rng):
        return emit_arrays(self, n, rng)

    def emit_towards(self, n: int, rng, centers, radii):
        return emit_arrays(self, n, rng, (centers, radii))


def _receivers(light):
    """A light's Light and Shadow Linking (its scene Light's receivers, blockers and
    their non_ lists)."""
    source = getattr(light, "source", None)
    if source is None:
        return None
    recv, block = source.receivers, source.blockers
    return (None if recv is None else tuple(recv), tuple(source.non_receivers),
            None if block is None else tuple(block), tuple(source.non_blockers))


def photon_emitters(lights, counts, chunk_size: int) -> list:
    """[(index of the first light, light or LightGroup, photon count)] for the photon
    pass: every light on its own for scenes with few lights; with many, lights of fewer
    than min(MIN_CHUNK, chunk_size) photons grouped (consecutive, equal ray visibility) up
    to that many photons per group, which parallel.chunk_length keeps in one job."""
    out = []
    if len(lights) <= selection.SAMPLE_ALL_UP_TO:
        return [(li, lights[li], int(c)) for li, c in enumerate(counts)]
    limit = max(1, min(MIN_CHUNK, int(chunk_size)))
    members, member_counts, first = [], [], -1

    def close():
        if len(members) == 1:
            out.append((first, members[0], member_counts[0]))
        elif members:
            out.append((first, LightGroup(members, member_counts), sum(member_counts)))

    for li, c in enumerate(counts):
        c = int(c)
        if c <= 0:
            continue
        light = lights[li]
        small = c < limit
        # (Light Linking: a group's photons end at their first hit by one rule,
        # engine/lightlinking.py, so its members light the same objects.)
        fits = (members and light.ray_kinds == members[0].ray_kinds
                and _receivers(light) == _receivers(members[0])
                and sum(member_counts) + c <= limit)
        if small and fits:
            members.append(light)
            member_counts.append(c)
            continue
        close()
        members, member_counts, first = ([light], [c], li) if small else ([], [], -1)
        if not small:
            out.append((li, light, c))
    close()
    return out
