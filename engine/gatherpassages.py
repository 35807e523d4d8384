"""Gather rays through window glass and transparent passes: which of a final gather's
rays reached their current hit by nothing but the surfaces shadow rays cross.

Shadow rays cross flat passages (thin glass slabs, window glass) and transparent passes
(docs/design.md, Transparent shadows), and photons leave them as the path they entered.
So the light of an emitter seen through a window is direct light: D's shadow rays carry
the sides they sample, and its photons are direct-kind, out of the caustic map. The
sides no shadow ray samples (a material's Emission Sampling None / Front / Back, Cycles'
SD_MIS_FRONT / SD_MIS_BACK unset) reach a diffuse surface only by the level-0 gather
rays that meet them (integrator.unsampled_emission), and a regather level's surfaces
take every emissive mesh that way (their direct light skips the meshes). A gather ray
counted that emission at its own first hit only, so behind a window it was lost: a
floor under a 1 cm slab lit by a panel of Emission Sampling None read 0.027 for Cycles'
1.468, 0 behind a card of alpha 0.5, and a room under such a card 0.47 of the open room
where 0.5 is exact (its corners' regathers lost the panel; issue 14,
docs/compatibility.md "passages48"). GatherPassages tells the continued rays that
crossed only such surfaces, whose emission then counts as at the first hit: Cycles'
path meets that emitter past the glass's refractions (no MIS for an unsampled side)
with the glass's weight, which the continuation's throughput carries.

The state is the camera paths' (shadowtransmittance.camera_passage, CameraPassages'
tables): a refraction into window glass remembers the ray's state before it, the
refraction out through the parallel face (photonkernels.flat_exit) gives it back, a
straight pass through a transparent material keeps it; any other continuation (a
reflection, a glass that is no passage, a glossy lobe) ends it. Here the state is one
number per ray, 1 while every surface so far was crossed, 0 after anything else or
inside the glass.
"""
from __future__ import annotations

import numpy as np

from .shadowtransmittance import CameraPassages, camera_passage


class GatherPassages:
    """Per gathering hit row (n of them, one ray each at a time), whether the ray's way
    from the gathering hit crossed only window passages and transparent passes (clear)
    and, inside window glass, the glass it entered and the state before it."""

    @classmethod
    def for_context(cls, ctx, n: int):
        """None for a scene whose shadow rays cross no surface (CameraPassages.for_context:
        no flat passage nor transparent pass; then no ray is ever clear past its first
        hit), else the state of n gathering hits."""
        shadow = getattr(ctx, "shadow", None)
        self = cls()
        self.tables = self.mat_pass = None
        if shadow is not None and shadow.shared:
            # Shared instance rows (engine/sharedrows.py) have no (T,) columns for the
            # kernel, and their shadow rays cross transparent passes only (no flat
            # passages: pk.flat_tables): the same rule on the hits' rows, so instances
            # count what their expansion counts (tests/test_instancing.py).
            self.geo = ctx.geo
            self.mat_pass = np.asarray(shadow.transparent_materials(ctx.table), bool)
            if not self.mat_pass.any():
                return None
        else:
            camera = CameraPassages.for_context(ctx, 0)
            if camera is None:
                return None
            self.tables = camera.tables
        self.clear = np.zeros(n)  # 1.0: clear (a float: camera_passage's pdf slot)
        self.entry = np.full(n, -1, np.int64)
        self.pre = np.zeros(n)
        # Whether the ray entered window glass since its hit (a clear ray then crossed a
        # window passage; else transparent passes alone: passes_only).
        self.glass = np.zeros(n, bool)
        return self

    def start(self, idx) -> None:
        """The gather rays of hit rows idx (K,) leave their hit: clear, outside glass."""
        self.clear[idx] = 1.0
        self.entry[idx] = -1
        self.pre[idx] = 0.0
        self.glass[idx] = False

    def end(self, idx) -> None:
        """The rays of hit rows idx (K,) went on by no passage (outside every glass)."""
        self.clear[idx] = 0.0
        self.entry[idx] = -1
        self.pre[idx] = 0.0

    def clear_rows(self, idx) -> np.ndarray:
        """(K',) int64: the rows of idx (K,) (a step's rays, by hit row) whose ray met its
        current hit across passages alone (outside every window glass)."""
        return np.flatnonzero(np.take(self.clear, idx) > 0.0)

    def passes_only(self, idx) -> np.ndarray:
        """(K,) bool: per hit row of idx (K,), whether its ray met its current hit across
        transparent passes alone (clear, no window glass entered): the surfaces a next-event
        pane's shadow rays cross before the pane (panelight._past_passes)."""
        return (np.take(self.clear, idx) > 0.0) & ~np.take(self.glass, idx)

    def at_passage(self, idx) -> np.ndarray:
        """(K,) bool: per hit row of idx (K,), whether its ray met its current hit across
        passages alone or inside window glass it entered so (a refraction there out
        through the parallel face ends a passage: step makes the ray clear again)."""
        return ((np.take(self.clear, idx) > 0.0)
                | ((np.take(self.entry, idx) >= 0) & (np.take(self.pre, idx) > 0.0)))

    def step(self, prim, d_in, p, idx, keep, d_out) -> None:
        """After continue_specular at hits prim (M,) (triangle rows; arriving directions
        d_in (M,3), points p (M,3)) of the rays of hit rows idx (M,): the rows keep (K,)
        of them went on along d_out (K,3) (at most once each). Their state becomes clear
        again where they left window glass through a flat passage entered while clear,
        stays clear through a transparent pass, and is 0 after anything else."""
        c = np.ascontiguousarray
        keep = c(keep, np.int64)
        M, K = len(prim), len(keep)
        if K == 0:
            return
        clear_in = c(np.take(self.clear, idx), np.float64)
        entry_in = c(np.take(self.entry, idx), np.int64)
        pre_in = c(np.take(self.pre, idx), np.float64)
        if self.tables is None:
            self._step_shared(prim, d_in, idx, keep, d_out, clear_in, entry_in, pre_in)
            return
        zeros_m = np.zeros((M, 3))
        clear_out = np.zeros(K)
        entry_out = np.empty(K, np.int64)
        pre_out = np.empty(K)
        scratch = [np.zeros((K, 3)) for _ in range(4)]
        camera_passage(*self.tables, c(prim, np.int64), c(d_in, np.float64),
                       c(p, np.float64), keep, c(d_out, np.float64), clear_in, zeros_m,
                       zeros_m, entry_in, pre_in, zeros_m, zeros_m, clear_out, scratch[0],
                       scratch[1], entry_out, pre_out, scratch[2], scratch[3])
        rows = np.take(idx, keep)
        glass = np.take(self.glass, rows) | (entry_out >= 0)
        self.clear[rows] = clear_out
        self.entry[rows] = entry_out
        self.pre[rows] = pre_out
        self.glass[rows] = glass

    def _step_shared(self, prim, d_in, idx, keep, d_out, clear_in, entry_in, pre_in):
        """step on shared instance rows: camera_passage's transparent-pass rule (a
        continuation straight on through a material of mat_pass keeps the state; anything
        else ends it) on the kept hits' rows alone."""
        t = np.asarray(prim, np.int64)[keep]
        hit = t >= 0
        passed = np.zeros(len(keep), bool)
        passed[hit] = self.mat_pass[np.asarray(self.geo.material[t[hit]], np.int64)]
        a = np.asarray(d_in, np.float64)[keep]
        b = np.asarray(d_out, np.float64)
        straight = (np.einsum("ij,ij->i", a, b)
                    >= (1.0 - 1e-12) * np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        passed &= straight
        rows = np.take(idx, keep)
        self.clear[rows] = np.where(passed, clear_in[keep], 0.0)
        self.entry[rows] = np.where(passed, entry_in[keep], -1)
        self.pre[rows] = np.where(passed, pre_in[keep], 0.0)
