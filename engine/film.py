"""Film: per-effect radiance buffers whose sum is the combined image.

Rows run top to bottom (image convention); Blender's bottom-to-top rows are the add-on's
business. All buffers are linear float32.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

EFFECTS = ("direct", "indirect", "caustic", "specular", "emission")


@dataclass
class Film:
    width: int
    height: int
    direct: np.ndarray = None
    indirect: np.ndarray = None
    caustic: np.ndarray = None
    specular: np.ndarray = None     # everything seen through mirrors and glass
    emission: np.ndarray = None     # emitters and background seen directly
    photon_hits: np.ndarray = None  # photon-hit view: dots by photon kind on black (Fig. 6 left)
    alpha: np.ndarray = None        # coverage: 1 where a camera ray hit geometry
    holdout: np.ndarray = None      # fraction of camera samples that met a holdout surface
    depth: np.ndarray = None        # view-axis depth (m) of the surface each pixel's first
                                    # sample ended on (Cycles' Depth: sample 0); inf = none
    normal: np.ndarray = None       # world-space shading normal of the first hit
    # Camera samples each pixel took (H,W) float32, Cycles' "Sample Count" debug pass:
    # set by adaptive sampling only (engine/adaptive.py; None: every pixel took spp)
    sample_count: np.ndarray = None
    # Cycles' data passes the settings asked for (engine/datapasses.py): key ->
    # (H,W,3) or (H,W) float32 per-sample averages (Denoising Normal / Albedo / Depth,
    # Diffuse / Glossy / Transmission Color)
    data: dict = field(default_factory=dict)
    # Cryptomatte ID mattes the settings asked for (engine/cryptomatte.py): kind ->
    # [(H,W,4) float32 passes, two ranks each], and kind -> the names its ids hash
    # (the manifest)
    cryptomatte: dict = field(default_factory=dict)
    cryptomatte_names: dict = field(default_factory=dict)
    # Shadow catchers (engine/shadowcatcher.py; None: the scene has none): per-sample
    # means "light" (H,W,3) of the camera samples whose first hit is a catcher,
    # "coverage" (H,W) their share, "background" (H,W,3) the world behind the catchers
    # (without a transparent film), "alone" (H,W,3) / "alone_coverage" (H,W) the
    # catcher-only render's radiance and coverage
    catcher: dict | None = None
    show_photons: bool = False
    stats: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)

    def __post_init__(self):
        shape3 = (self.height, self.width, 3)
        for name in EFFECTS + ("photon_hits", "normal"):
            if getattr(self, name) is None:
                setattr(self, name, np.zeros(shape3, np.float32))
        if self.alpha is None:
            self.alpha = np.zeros((self.height, self.width), np.float32)
        if self.holdout is None:
            self.holdout = np.zeros((self.height, self.width), np.float32)
        if self.depth is None:
            self.depth = np.full((self.height, self.width), np.inf, np.float32)

    @property
    def combined(self) -> np.ndarray:
        """Sum of the effect buffers; with show_photons the photon-hit view instead (the
        paper's Fig. 6, left: dots on black), never dots painted over the render."""
        if self.show_photons:
            return self.photon_hits.astype(np.float32, copy=True)
        return sum(getattr(self, name) for name in EFFECTS).astype(np.float32)

    def passes(self) -> dict[str, np.ndarray]:
        out = {"combined": self.combined, **{n: getattr(self, n) for n in EFFECTS},
               "photon_hits": self.photon_hits, "depth": self.depth,
               "normal": self.normal, "alpha": self.alpha}
        if self.sample_count is not None:
            out["sample_count"] = self.sample_count
        # (self.data, Cycles' data passes, stays apart: the add-on writes them into
        # Blender's render result; --save-passes writes them by write_data_passes.)
        return out

    def write_passes(self, root: str, ext: str, exposure: float = 0.0,
                     spp: int | None = None) -> list[str]:
        """--save-passes of both front ends (engine/cli.py, addon/batch.py): each effect
        pass, the photon-hit view and, with adaptive sampling, the sample count (grey: the
        share of `spp` a pixel took) as `root.<name><ext>` at `exposure` stops, then the
        data passes (write_data_passes). Returns the paths written. Raises OSError when a
        file cannot be written."""
        from .imageio import write_image
        paths = []
        for name, img in self.passes().items():
            if name in ("combined", "depth", "alpha", "normal"):
                continue
            path = f"{root}.{name}{ext}"
            if name == "sample_count":
                if not spp:
                    continue
                write_image(np.repeat((img / spp)[..., None], 3, axis=2), path)
            else:
                write_image(img, path, exposure)
            paths.append(path)
        return paths + self.write_data_passes(root)

    def write_data_passes(self, root: str) -> list[str]:
        """Write each of Cycles' data passes made (self.data) as linear OpenEXR
        `root.<key>.exr` (one-channel passes as grey RGB); returns the paths. They are data
        (signed camera-space normals, depths in metres, albedos), so linear float whatever
        the image's own format, as Blender's multilayer EXR keeps them."""
        from .imageio import write_image
        from .lightpasses import shown
        paths = []
        # (The light passes as Blender shows them: Direct / Indirect divided by Color.)
        from .vectorpass import KEYS as VECTOR_KEYS, shown as vector_shown
        vec = vector_shown(self.data)
        made = {k: v for k, v in self.data.items() if k not in VECTOR_KEYS}
        if vec is not None:  # (pixels a frame as Blender shows them: x, y, 0 each)
            for key, xy in zip(VECTOR_KEYS, (vec[..., :2], vec[..., 2:])):
                made[key] = np.concatenate([xy, np.zeros_like(xy[..., :1])], axis=2)
        for key, img in {**made, **shown(self.data)}.items():
            rgb = img if img.ndim == 3 else np.repeat(img[..., None], 3, axis=2)
            # (a Shader AOV's key holds its name: any character but a file name's kept)
            paths.append(f"{root}.{re.sub(r'[^0-9A-Za-z_.-]', '_', key)}.exr")
            write_image(rgb, paths[-1])
        return paths
