"""Downloading datasets for users with internet access (never called by tests or the study)."""

from __future__ import annotations

import hashlib
import json
import logging
import os
import urllib.request
import zipfile
from pathlib import Path

from .. import settings

__all__ = ["DOWNLOADS", "download_dataset"]

log = logging.getLogger("vpr_core")

DOWNLOADS: dict[str, dict[str, str | None]] = {
    "gardens_point": {
        # Zenodo record of Gardens Point Walking (doi 10.5281/zenodo.4590133).
        "url": "https://zenodo.org/records/4590133/files/GardensPointWalking.zip?download=1",
        # SHA-256 not known to us (no network when this was written): the download prints the
        # computed hash; put it here once it has been checked against Zenodo's listed checksum.
        "sha256": None,
    },
}

_MARKER = ".vpr_download.json"


def _safe_extract(zf: zipfile.ZipFile, dest: Path) -> list[str]:
    dest_r = dest.resolve()
    names = zf.namelist()
    for n in names:
        target = (dest / n).resolve()
        if target != dest_r and dest_r not in target.parents:
            raise ValueError(f"refusing to extract {n!r}: it would land outside {dest}.")
    zf.extractall(dest)
    return names


def download_dataset(
    name: str,
    root: str | os.PathLike,
    url: str | None = None,
    sha256: str | None = None,
    overwrite: bool = False,
) -> Path:
    """Download (and unzip) a dataset for users with internet access.

    Streams ``url`` (default: the :data:`DOWNLOADS` entry of ``name``) into ``root`` with a
    progress bar, checks its SHA-256 (``sha256`` or the registry's; when neither is known the
    computed hash is logged so it can be pinned), extracts a ``.zip`` into ``root`` and removes
    the archive. A marker file records a finished download; a second call returns at once
    unless ``overwrite``.

    Args:
        name: Dataset name (a :data:`DOWNLOADS` key unless ``url`` is given).
        root: Folder to download into (created).
        url: Override the download URL (any ``http(s)://`` or ``file://`` URL).
        sha256: Expected SHA-256 hex digest of the downloaded file.
        overwrite: Download again even if a finished download is recorded.

    Returns:
        The folder to pass as ``root=`` to :func:`load_dataset`: ``root`` itself, or its single
        top-level folder when the archive holds exactly one.

    Raises:
        ValueError: unknown name without ``url``, checksum mismatch (the file is removed), or a
            bad archive.
        OSError: network or file-system errors (with the URL in the message).
    """
    entry = DOWNLOADS.get(name)
    if entry is None and url is None:
        raise ValueError(
            f"no download known for {name!r}; downloadable: {', '.join(DOWNLOADS)}. For other "
            "datasets pass url=..., or download them by hand and use the layout in the loader's "
            "docstring."
        )
    url = url or str(entry["url"])  # type: ignore[index]
    expected = sha256 or (entry or {}).get("sha256") or None
    expected = expected.lower().strip() if expected else None
    root = Path(root).expanduser()
    root.mkdir(parents=True, exist_ok=True)
    marker = root / _MARKER
    if marker.is_file() and not overwrite:
        info = json.loads(marker.read_text())
        log.info("%s already downloaded into %s (overwrite=True to fetch again)", name, root)
        return root / info.get("top", "") if info.get("top") else root
    fname = Path(urllib.request.url2pathname(url.split("?")[0].rstrip("/").split("/")[-1])).name
    fname = fname or f"{name}.download"
    part = root / (fname + ".part")
    got = _stream(name, url, part, root)
    if expected is not None and got != expected:
        part.unlink(missing_ok=True)
        raise ValueError(
            f"SHA-256 mismatch for {url}: expected {expected}, got {got}; the file was removed. "
            "Retry (the download may be truncated) or check the URL / the expected hash."
        )
    if expected is None:
        log.warning(
            "%s: no SHA-256 known for %s; computed sha256=%s (pass sha256=... to verify next time)",
            name,
            url,
            got,
        )
    target = root / fname
    os.replace(part, target)
    top = _unzip(name, target, root) if zipfile.is_zipfile(target) else ""
    marker.write_text(json.dumps({"name": name, "url": url, "sha256": got, "top": top}))
    return root / top if top else root


def _stream(name: str, url: str, part: Path, root: Path) -> str:
    """Stream ``url`` into ``part`` with a progress bar; return the SHA-256 hex digest."""
    from tqdm.auto import tqdm

    digest = hashlib.sha256()
    try:
        with urllib.request.urlopen(url, timeout=60) as resp:
            total = int(resp.headers.get("Content-Length") or 0) or None
            with (
                open(part, "wb") as f,
                tqdm(
                    total=total,
                    unit="B",
                    unit_scale=True,
                    desc=f"download {name}",
                    leave=False,
                    disable=settings.progress_disabled(),
                ) as bar,
            ):
                for chunk in iter(lambda: resp.read(1 << 20), b""):
                    f.write(chunk)
                    digest.update(chunk)
                    bar.update(len(chunk))
    except OSError as exc:
        part.unlink(missing_ok=True)
        raise OSError(
            f"download of {name!r} from {url} failed: {exc}; check the URL and your "
            f"connection, or download it by hand into {root}."
        ) from exc
    return digest.hexdigest()


def _unzip(name: str, target: Path, root: Path) -> str:
    """Extract the zip ``target`` into ``root``, remove it; return its single top folder or ""."""
    try:
        with zipfile.ZipFile(target) as zf:
            names = _safe_extract(zf, root)
    except zipfile.BadZipFile as exc:
        raise ValueError(
            f"{target} is not a valid zip archive ({exc}); download it again with overwrite=True."
        ) from None
    target.unlink()
    log.info("%s: extracted %d entries into %s", name, len(names), root)
    tops = {n.split("/")[0] for n in names if n.strip("/")}
    if len(tops) == 1 and (root / next(iter(tops))).is_dir():
        return next(iter(tops))
    return ""
