"""Image files: PNG (sRGB, via Pillow), OpenEXR (linear float, via OpenEXR), PPM (the
paper's format, via Pillow). These libraries are needed only for writing files, so they
are imported lazily: the Blender add-on never needs them.

Every image is written to a temporary file in the target's folder and moved over the
target with os.replace (`replacing`), so a failed write (disk full, `ulimit -f`, an
exception, Ctrl-C) leaves the previous file as it was, never a truncated one. Callers
check the output path with `check_writable` before a render starts."""
from __future__ import annotations

import contextlib
import os
import secrets
import sys

import numpy as np

FORMATS = (".png", ".exr", ".ppm", ".npy")


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(np.nan_to_num(x, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def srgb_decode(c: np.ndarray) -> np.ndarray:
    """Cycles' color_srgb_to_linear (util/color.h) elementwise, as its kernels decode an
    image stored sRGB-encoded after the lookup: c / 12.92 below 0.04045 (0 below 0),
    ((c + 0.055) / 1.055)^2.4 above, not clipped above 1 (a float image's encoded values
    may exceed 1). float64 array of c's shape."""
    c = np.asarray(c, np.float64)
    return np.where(c < 0.04045, np.maximum(c, 0.0) / 12.92,
                    ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4)


def srgb_encode(x: np.ndarray) -> np.ndarray:
    """Cycles' color_linear_to_srgb elementwise (srgb_decode's inverse): 12.92 x below
    0.0031308 (0 below 0), 1.055 x^(1/2.4) - 0.055 above, not clipped above 1 (unlike
    linear_to_srgb, the display encoding). float64 array of x's shape."""
    x = np.asarray(x, np.float64)
    return np.where(x < 0.0031308, 12.92 * np.maximum(x, 0.0),
                    1.055 * np.maximum(x, 0.0031308) ** (1.0 / 2.4) - 0.055)


def to_8bit(rgb: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """Linear radiance -> sRGB-encoded 8 bit (clipped, like Blender's 'Standard' view)."""
    scaled = np.asarray(rgb, np.float64) * (2.0 ** exposure)
    return np.round(linear_to_srgb(scaled) * 255.0).astype(np.uint8)


def check_writable(path: str, on_create=None) -> str:
    """Make sure an image can be written at `path` before the work that produces it starts:
    creates missing folders (as Blender does for its output path; on_create(folder) is
    called when it does, so a command line can say so), then creates and removes a probe
    file beside the target. Returns the absolute path. Raises OSError naming the path and
    the reason."""
    full = os.path.abspath(path)
    if os.path.isdir(full):
        raise OSError(f"output '{path}' is a folder, not a file")
    if os.path.exists(full) and not os.access(full, os.W_OK):
        raise OSError(f"output '{path}' is read-only")
    folder = os.path.dirname(full)
    up = folder
    while not os.path.isdir(up):
        if os.path.exists(up):
            raise OSError(f"output '{path}' cannot be written: '{up}' is a file, not a folder")
        up = os.path.dirname(up)
    try:
        if not os.path.isdir(folder):
            os.makedirs(folder, exist_ok=True)
            if on_create is not None:
                on_create(folder)
        with _temporary_beside(full) as probe:
            with open(probe, "wb") as f:
                f.write(b"\0")
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise OSError(f"output '{path}' cannot be written: {reason} ({folder})") from None
    return full


@contextlib.contextmanager
def _temporary_beside(full: str):
    """A fresh, not yet existing file name in full's folder, ending in full's extension
    (Pillow and numpy pick the format from it); removed on exit if it still exists."""
    folder, name = os.path.split(full)
    ext = os.path.splitext(name)[1]
    while True:
        tmp = os.path.join(folder, f".{name}.{secrets.token_hex(4)}.tmp{ext}")
        try:  # O_EXCL: never reuse another writer's file; mode 0666 & umask, as a new file
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            break
        except FileExistsError:
            continue
    try:
        yield tmp
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def truncation(path: str) -> str | None:
    """Why the image file at `path` is incomplete, or None when it is whole as far as its
    format's own structure tells (PNG: ends with the IEND chunk; JPEG: ends with the EOI
    marker; single-part scanline OpenEXR: the last chunk of the offset table ends inside
    the file; PPM and NPY: header size + pixel bytes). Other formats are not checked
    (None). Writers that ignore a failed write (disk full, `ulimit -f`) leave files that
    fail this check. Formats: PNG spec 11.2.5, ITU T.81 B.2, OpenEXR file layout."""
    ext = os.path.splitext(path)[1].lower()
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        if ext == ".png":
            f.seek(max(0, size - 12))
            return None if f.read(12) == b"\0\0\0\0IEND\xaeB`\x82" else "no IEND chunk at the end"
        if ext in (".jpg", ".jpeg"):
            f.seek(max(0, size - 2))
            return None if f.read(2) == b"\xff\xd9" else "no end-of-image marker"
        if ext == ".exr":
            return _exr_truncation(f, size)
        if ext in (".ppm", ".npy"):
            head = f.read(4096)
    if ext == ".ppm":
        parts = head.split(maxsplit=4)
        if len(parts) < 5 or parts[0] != b"P6":
            return "no P6 header"
        w, h, maxval = (int(v) for v in parts[1:4])
        need = len(head) - len(parts[4]) + w * h * 3 * (2 if maxval > 255 else 1)
        return None if size >= need else f"{size} of {need} bytes"
    if ext == ".npy":
        import io
        fh = io.BytesIO(head)
        try:
            version = np.lib.format.read_magic(fh)
            shape, _, dtype = np.lib.format._read_array_header(fh, version)
        except ValueError as exc:
            return f"bad header ({exc})"
        need = fh.tell() + int(np.prod(shape)) * dtype.itemsize
        return None if size >= need else f"{size} of {need} bytes"
    return None


def _exr_truncation(f, size: int) -> str | None:
    import struct
    if f.read(4) != b"\x76\x2f\x31\x01":
        return "no OpenEXR magic number"
    flags = struct.unpack("<I", f.read(4))[0]
    if flags & 0x1A00:  # tiled, deep or multi-part: chunk layouts not checked here
        return None
    while True:  # the header: attributes (name, type, size, value) up to an empty name
        name = _read_cstring(f)
        if name is None:
            return "header cut short"
        if name == b"":
            break
        if _read_cstring(f) is None:
            return "header cut short"
        raw = f.read(4)
        if len(raw) < 4:
            return "header cut short"
        f.seek(struct.unpack("<i", raw)[0], 1)
    table = f.tell()
    raw = f.read(8)
    if len(raw) < 8:
        return "no offset table"
    first = struct.unpack("<Q", raw)[0]  # the first chunk follows the table at once
    count = (first - table) // 8
    if first <= table or first > size or (first - table) % 8:
        return "offset table cut short"
    f.seek(table)
    offsets = np.frombuffer(f.read(8 * count), "<u8")
    if len(offsets) < count:
        return "offset table cut short"
    last = int(offsets.max())
    if last + 8 > size:
        return "last chunk missing"
    f.seek(last + 4)
    chunk = struct.unpack("<i", f.read(4))[0]
    return None if last + 8 + chunk <= size else "last chunk cut short"


def _read_cstring(f, limit: int = 256) -> bytes | None:
    out = bytearray()
    while len(out) <= limit:
        c = f.read(1)
        if not c:
            return None
        if c == b"\0":
            return bytes(out)
        out += c
    return None


@contextlib.contextmanager
def replacing(path: str):
    """Context manager yielding a temporary path in `path`'s folder to write the new file
    to; on a clean exit the file is flushed to disk and moved over `path` with os.replace
    (atomic on POSIX and Windows). On any exception the temporary file is removed and
    `path` is left as it was.

        with replacing("out.png") as tmp:
            image.save(tmp)
    """
    full = os.path.abspath(path)
    os.makedirs(os.path.dirname(full), exist_ok=True)
    with _temporary_beside(full) as tmp:
        yield tmp
        if not os.path.isfile(tmp) or os.path.getsize(tmp) == 0:
            raise OSError(f"writing '{path}' produced no data")
        cut = truncation(tmp)
        if cut:  # some writers (Blender's PNG and EXR, Pillow's PPM) ignore a short write
            raise OSError(f"writing '{path}' was cut short ({cut}): disk full or file size "
                          f"limit?")
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, full)


def write_image(rgb: np.ndarray, path: str, exposure: float = 0.0, alpha: np.ndarray | None = None,
                metadata: dict | None = None):
    """Write an HxWx3 linear image; the format follows the file extension. `metadata`
    (str -> str) goes into PNG text chunks / EXR header attributes (e.g. which effects the
    render simulated and why). The file is written beside the target and moved over it
    (`replacing`): if writing fails, an existing file at `path` is left intact. Raises
    ValueError for an unknown extension or image shape, OSError when writing fails."""
    metadata = {str(k): str(v) for k, v in (metadata or {}).items()}
    ext = os.path.splitext(path)[1].lower()
    if ext not in FORMATS:
        raise ValueError(f"output '{path}': unsupported format '{ext or '(none)'}'; "
                         f"use one of {', '.join(FORMATS)}")
    rgb = np.asarray(rgb, np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"write_image: expected an HxWx3 image, got {rgb.shape}")
    existed = os.path.exists(path)
    try:
        with replacing(path) as tmp:
            _write(rgb, tmp, ext, exposure, alpha, metadata)
    except (OSError, RuntimeError) as exc:  # OpenEXR raises RuntimeError on a failed write
        # e.g. numpy's "9216 requested and 2016 written" when the disk or ulimit is full
        kept = "the previous file is unchanged" if existed else "nothing was written"
        raise OSError(f"writing '{path}' failed: {getattr(exc, 'strerror', None) or exc} "
                      f"(disk full or file size limit?); {kept}") from exc
    return path


def _write(rgb, path, ext, exposure, alpha, metadata):
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


def write_cryptomatte(passes: dict, names: dict, path: str, view_layer: str = "ViewLayer"):
    """Write Cryptomatte layers as one OpenEXR file the Cryptomatte spec describes (and
    Blender, Nuke and Fusion read): channels `<view_layer>.CryptoObject00.r/g/b/a` ..., the
    layers' names and manifests in the header (engine/cryptomatte.metadata). passes: kind
    -> [(H,W,4) float32]; names: kind -> the names the ids hash. Written beside `path`
    and moved over it, as write_image. Raises OSError when writing fails."""
    import OpenEXR

    from .cryptomatte import KINDS, metadata
    channels, header = {}, {"compression": OpenEXR.ZIP_COMPRESSION,
                            "type": OpenEXR.scanlineimage}
    for kind, layers in passes.items():
        for i, rgba in enumerate(layers):
            for c, ch in enumerate("rgba"):
                channels[f"{view_layer}.{KINDS[kind]}{i:02d}.{ch}"] = np.ascontiguousarray(
                    np.asarray(rgba[..., c], np.float32))
        header.update(metadata(view_layer, kind, names.get(kind, ())))
    try:
        with replacing(path) as tmp:
            with OpenEXR.File(header, channels) as f:
                f.write(tmp)
    except (OSError, RuntimeError) as exc:
        raise OSError(f"writing '{path}' failed: {getattr(exc, 'strerror', None) or exc}") \
            from exc
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
    return srgb_decode(arr).astype(np.float32)


def say_created(folder: str) -> None:
    """on_create callback of check_writable for the command lines: one line on stderr."""
    print(f"created folder {folder} for the output", file=sys.stderr)
