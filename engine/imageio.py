"""Image files: PNG (sRGB, via Pillow), OpenEXR (linear float, via OpenEXR), PPM (the
paper's format, via Pillow). These libraries are needed only for writing files, so they
are imported lazily: the Blender add-on never needs them."""
from __future__ import annotations

import os

import numpy as np

FORMATS = (".png", ".exr", ".ppm", ".npy")


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(np.nan_to_num(x, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, np.float64)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def to_8bit(rgb: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """Linear radiance -> sRGB-encoded 8 bit (clipped, like Blender's 'Standard' view)."""
    scaled = np.asarray(rgb, np.float64) * (2.0 ** exposure)
    return np.round(linear_to_srgb(scaled) * 255.0).astype(np.uint8)


def write_image(rgb: np.ndarray, path: str, exposure: float = 0.0, alpha: np.ndarray | None = None,
                metadata: dict | None = None):
    """Write an HxWx3 linear image; the format follows the file extension. `metadata`
    (str -> str) goes into PNG text chunks / EXR header attributes (e.g. which effects the
    render simulated and why)."""
    metadata = {str(k): str(v) for k, v in (metadata or {}).items()}
    ext = os.path.splitext(path)[1].lower()
    if ext not in FORMATS:
        raise ValueError(f"output '{path}': unsupported format '{ext or '(none)'}'; "
                         f"use one of {', '.join(FORMATS)}")
    rgb = np.asarray(rgb, np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"write_image: expected an HxWx3 image, got {rgb.shape}")
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    if ext == ".npy":
        np.save(path, rgb)
    elif ext == ".exr":
        import OpenEXR
        channels = {"RGB": np.ascontiguousarray(rgb)}
        if alpha is not None:
            channels["A"] = np.ascontiguousarray(np.asarray(alpha, np.float32))
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
                  **metadata}
        with OpenEXR.File(header, channels) as f:
            f.write(path)
    else:
        from PIL import Image, PngImagePlugin
        img8 = to_8bit(rgb, exposure)
        extra = {}
        if ext == ".png" and metadata:
            info = PngImagePlugin.PngInfo()
            for k, v in metadata.items():
                info.add_itxt(k, v)
            extra["pnginfo"] = info
        if ext == ".png" and alpha is not None:
            a8 = np.round(np.clip(alpha, 0, 1) * 255).astype(np.uint8)
            Image.fromarray(np.dstack([img8, a8]), "RGBA").save(path, **extra)
        else:
            Image.fromarray(img8, "RGB").save(path, **extra)
    return path


def read_image(path: str) -> np.ndarray:
    """Read an image as linear float32 HxWx3 (EXR/NPY as stored; PNG/PPM decoded from sRGB)."""
    ext = os.path.splitext(path)[1].lower()
    if ext == ".npy":
        return np.load(path).astype(np.float32)
    if ext == ".exr":
        import OpenEXR
        with OpenEXR.File(path) as f:
            ch = f.channels()
            if "RGB" in ch:
                return np.asarray(ch["RGB"].pixels, np.float32)[..., :3]
            if "RGBA" in ch:
                return np.asarray(ch["RGBA"].pixels, np.float32)[..., :3]
            names = [n for n in ("R", "G", "B") if n in ch]
            if len(names) == 3:
                return np.dstack([np.asarray(ch[n].pixels, np.float32) for n in names])
            raise ValueError(f"{path}: no RGB channels (found {', '.join(ch)})")
    from PIL import Image
    arr = np.asarray(Image.open(path).convert("RGB"), np.float64) / 255.0
    return srgb_to_linear(arr).astype(np.float32)
