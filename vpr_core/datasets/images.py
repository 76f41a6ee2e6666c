"""Image files: which files are images, how they are listed, and how one is read; damaged,
truncated, oversized and tiny images are refused by name (:func:`read_image`)."""

from __future__ import annotations

import os
import re
import struct
import sys
import tempfile
import threading
import unicodedata
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from ..checks import check_file
from ..notices import notice

__all__ = [
    "IMAGE_EXTENSIONS",
    "MAX_IMAGE_PIXELS",
    "MIN_IMAGE_SIDE",
    "check_folder",
    "list_images",
    "read_image",
    "scan_images",
]

#: Every 8-bit format OpenCV's ``imread`` decodes (other files in an image folder are skipped
#: with a warning naming them).
IMAGE_EXTENSIONS = (
    ".jpg",
    ".jpeg",
    ".jpe",
    ".png",
    ".bmp",
    ".dib",
    ".tif",
    ".tiff",
    ".webp",
    ".gif",
    ".jp2",
    ".avif",
    ".ppm",
    ".pgm",
    ".pbm",
    ".pnm",
    ".sr",
    ".ras",
)

#: Smallest accepted short side of an image, in pixels. Below it the landmark stages degenerate
#: (Edge Boxes finds no boxes on 8x8 images; dense sampling makes 3-pixel boxes that blank images
#: "match"), so such images are refused instead of scored. 32 keeps the standard 64x32 (W x H)
#: SeqSLAM-style Nordland frames loadable: their smallest dense landmark (area ratio 0.16) is
#: still about 26x13 pixels.
MIN_IMAGE_SIDE = 32
#: Largest accepted image, in pixels (W x H), checked in the file's header before decoding:
#: 100 megapixels (300 MB as RGB); VPR datasets' images are far smaller.
MAX_IMAGE_PIXELS = 100_000_000


_JPEG_SOI, _JPEG_SOS, _JPEG_EOI = b"\xff\xd8", b"\xff\xda", b"\xff\xd9"
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PIL_LOCK = threading.Lock()


def _header_size(path: Path) -> tuple[int, int] | None:
    """``(W, H)`` the file's header claims, read by Pillow's lazy open (nothing decoded), or
    None when Pillow does not know the format. Pillow's own bomb limit is lifted meanwhile (under
    a lock) so that the size is known and :data:`MAX_IMAGE_PIXELS` decides."""
    with _PIL_LOCK:
        limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
        try:
            with Image.open(path) as im:
                return im.size
        except (OSError, SyntaxError, ValueError, struct.error, IndexError, EOFError):
            return None  # not a format Pillow reads (or a damaged header): left to OpenCV
        finally:
            Image.MAX_IMAGE_PIXELS = limit


def _check_image_file(path: str | os.PathLike) -> bool:
    """Raise if a JPEG or PNG file is truncated or claims too many pixels (no decoding).

    A JPEG must hold a start-of-scan marker and, after the last one, the end-of-image marker
    (inside entropy-coded data ``0xFF`` is always followed by ``0x00`` or a restart marker, so the
    marker cannot appear by chance). A PNG must start with the PNG signature and hold an ``IEND``
    chunk. The size in the file's header (any format Pillow reads, by its lazy open) must not
    exceed :data:`MAX_IMAGE_PIXELS` (checked before anything is allocated).

    Args:
        path: The image file.

    Returns:
        True when the file is a JPEG.

    Raises:
        ValueError: the file is damaged or too large; the message names it and the fix.
    """
    path = Path(path)
    data = path.read_bytes()
    problem = None
    size = _header_size(path)
    if size is not None and size[0] * size[1] > MAX_IMAGE_PIXELS:
        raise ValueError(
            f"{path} claims {size[0]} x {size[1]} pixels (W x H) in a {len(data)}-byte file, "
            f"more than MAX_IMAGE_PIXELS = {MAX_IMAGE_PIXELS:,}: refused before decoding. "
            "Downscale the image or remove it from the dataset."
        )
    if data[:2] == _JPEG_SOI:
        sos = data.rfind(_JPEG_SOS)
        if sos < 0:
            problem = "a JPEG without image data (no start-of-scan marker)"
        elif data.rfind(_JPEG_EOI) < sos:
            problem = "a truncated JPEG (no end-of-image marker after the image data)"
    elif data[:8] == _PNG_SIGNATURE and data.rfind(b"IEND") < 0:
        problem = "a truncated PNG (no IEND chunk)"
    if problem is not None:
        raise ValueError(
            f"{path} is {problem}, {len(data)} bytes: it would decode partly grey and change the "
            "results. Re-download the file or remove it from the dataset."
        )
    return data[:2] == _JPEG_SOI


#: libjpeg's warnings that mean lost image data (printed to stderr; the decode still "succeeds"):
#: more than 2 extraneous bytes before the end-of-image marker are scan data the decoder could
#: not place (random bytes inside the scan); 1-2 are encoder padding, and bytes before other
#: markers are harmless.
_JPEG_DAMAGE = re.compile(
    r"Corrupt JPEG data(?!: \d+ extraneous bytes)|Premature end of JPEG|Huffman|Invalid SOS"
    r"|Inconsistent progression|Bogus|(?:[3-9]|\d\d+) extraneous bytes before marker 0xd9"
)
_DECODE_LOCK = threading.Lock()


def _imread_jpeg(path: Path) -> tuple[np.ndarray | None, str]:
    """``cv2.imread`` of a JPEG with libjpeg's stderr captured (fd 2, serialised by a lock).

    Returns:
        The BGR image (or None) and libjpeg's damage warnings (``""`` when clean); any other
        text printed meanwhile is passed on to stderr.
    """
    with _DECODE_LOCK, tempfile.TemporaryFile() as capture:
        sys.stderr.flush()
        saved = os.dup(2)
        try:
            os.dup2(capture.fileno(), 2)
            img = cv2.imread(str(path), cv2.IMREAD_COLOR)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        capture.seek(0)
        text = capture.read().decode("utf-8", "replace")
    damage = [line for line in text.splitlines() if _JPEG_DAMAGE.search(line)]
    other = [line for line in text.splitlines() if line and line not in damage]
    if other:
        print("\n".join(other), file=sys.stderr)
    return img, "; ".join(damage)


def read_image(path: str | os.PathLike, min_side: int = MIN_IMAGE_SIDE) -> np.ndarray:
    """Read an image file as ``uint8 (H, W, 3)`` RGB (grey images are expanded to 3 channels).

    The pixels are OpenCV's (``cv2.imread``, BGR -> RGB); before decoding, JPEG and PNG files are
    checked for truncation (:func:`_check_image_file`), and a JPEG whose decoding makes libjpeg
    report damaged data (corrupt scan data, a premature end) is refused.

    Args:
        path: The image file.
        min_side: Smallest accepted ``min(H, W)`` in pixels (default :data:`MIN_IMAGE_SIDE`;
            pass 1 to accept any size).

    Returns:
        ``uint8 (H, W, 3)`` RGB image.

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: OpenCV cannot decode it, it is truncated or damaged, too many pixels
            (:func:`_check_image_file`), or it is smaller than ``min_side``.
    """
    path = Path(path)
    if not check_file(path, "image"):
        raise FileNotFoundError(f"image file not found: {path}")
    is_jpeg = _check_image_file(path)
    damage = ""
    try:
        if is_jpeg:
            img, damage = _imread_jpeg(path)
        else:
            img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    except cv2.error as exc:  # e.g. OpenCV's own pixel limit in a header it parses
        reason = str(exc).strip().splitlines()[-1][-160:]
        raise ValueError(
            f"{path} cannot be decoded by OpenCV ({reason}); replace or remove the file."
        ) from None
    if damage:
        raise ValueError(
            f"{path} is a damaged JPEG (the decoder reports: {damage[:200]}): it would decode "
            "with grey or garbled areas and change the results. Re-download the file or remove "
            "it from the dataset."
        )
    if img is None:
        raise ValueError(
            f"{path} is not a readable image (OpenCV could not decode it; the file may be "
            "corrupt, truncated or in an unsupported format): replace or remove the file."
        )
    h, w = img.shape[:2]
    if min(h, w) < min_side:
        raise ValueError(
            f"{path} is too small: {w}x{h} pixels (W x H), but images need at least {min_side} "
            f"pixels on the short side (MIN_IMAGE_SIDE; landmarks degenerate below it). Use the "
            "full-resolution images, or remove this one from the dataset."
        )
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def _natural_key(name: str) -> list:
    """Sort key that orders digit runs by value: ``2.jpg`` before ``10.jpg`` (runs of any length
    or script: compared as digit strings, never through ``int()``)."""
    key: list = []
    for i, t in enumerate(re.split(r"(\d+)", name)):
        if i % 2:  # a run of decimal digits
            digits = "".join(str(unicodedata.decimal(c)) for c in t).lstrip("0")
            key.append((0, len(digits), digits, t))
        else:
            key.append((1, 0, t.lower(), t))
    return key


def _broken_link(p: Path) -> str | None:
    """How a symlink is broken (``"a symlink loop"`` / ``"a dangling symlink ..."``), or None."""
    if not p.is_symlink():
        return None
    try:
        p.resolve(strict=True)
    except FileNotFoundError:
        return f"a dangling symlink (it points to {os.readlink(p)}, which does not exist)"
    except (RuntimeError, OSError):  # RuntimeError: Python < 3.13's "Symlink loop"
        return "a symlink loop (following it leads back to itself)"
    return None


def check_folder(folder: Path, what: str, fix: str) -> Path:
    """Return ``folder`` if it is a folder; else a FileNotFoundError naming ``what``, why (a
    broken symlink, or the folders beside it) and ``fix``."""
    if not folder.is_dir():
        broken = _broken_link(folder)
        if broken is not None:
            why = f"it is {broken}"
        elif folder.parent.is_dir():
            beside = sorted(p.name for p in folder.parent.iterdir() if p.is_dir())
            why = f"no such folder (folders beside it: {', '.join(beside) or 'none'})"
        else:
            why = f"{folder.parent} does not exist either"
        raise FileNotFoundError(f"{what} {folder} not found: {why}; {fix}")
    return folder


def scan_images(
    folder: str | os.PathLike, what: str = "image folder"
) -> tuple[list[Path], list[Path]]:
    """Image files directly inside ``folder`` (naturally sorted) and the other files it skipped.

    Images are files with an extension of :data:`IMAGE_EXTENSIONS` (any case); hidden files and
    sub-folders are ignored, except a folder named like an image (``1.jpg/``), which is returned as
    skipped like every other file.

    Raises:
        FileNotFoundError: ``folder`` does not exist or is not a folder.
        ValueError: it holds no image file, or an image name is a broken symlink (named as a
            symlink loop or a dangling symlink).
    """
    folder = check_folder(
        Path(folder),
        what,
        "create it and put the images there, or point `root` at the folder that contains it.",
    )
    files, skipped = [], []
    for p in folder.iterdir():
        if p.name.startswith("."):
            continue
        is_image = p.suffix.lower() in IMAGE_EXTENSIONS
        broken = _broken_link(p)
        if broken and is_image:
            raise ValueError(f"{what}: {p} is {broken}; fix or remove the link.")
        if is_image and not p.is_dir():
            check_file(p, f"{what}: image")  # a FIFO or a device named like an image
        if p.is_file() and is_image:
            files.append(p)
        elif p.is_file() or broken or (is_image and p.is_dir()):
            skipped.append(p)  # a folder named like an image is reported, never used
    if not files:
        raise ValueError(
            f"{what} {folder} contains no images (looked for {', '.join(IMAGE_EXTENSIONS)}, "
            "any case); copy the images there or point `root` at the right folder."
        )

    def key(p):
        return _natural_key(p.name)

    return sorted(files, key=key), sorted(skipped, key=key)


def list_images(folder: str | os.PathLike, what: str = "image folder") -> list[Path]:
    """Image files directly inside ``folder``, naturally sorted (``2.jpg`` before ``10.jpg``).

    Extensions (case-insensitive): :data:`IMAGE_EXTENSIONS`. Hidden files are ignored; any other
    file is skipped with a warning naming it (:func:`~vpr_core.notices.notice`).

    Args:
        folder: The folder.
        what: How to call the folder in error messages.

    Returns:
        The image files, naturally sorted by name.

    Raises:
        FileNotFoundError: ``folder`` does not exist or is not a folder.
        ValueError: it holds no image file, or an image name is a broken symlink.
    """
    files, skipped = scan_images(folder, what)
    if skipped:
        names = ", ".join(p.name for p in skipped[:10]) + (" ..." if len(skipped) > 10 else "")
        notice(
            f"{what} {folder}: skipped {len(skipped)} file(s) that are not images OpenCV "
            f"reads ({names}); they are not part of the dataset."
        )
    return files
