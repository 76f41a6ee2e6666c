"""Downloading datasets for users with internet access (never called by tests or the study)."""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import tempfile
import time
import urllib.request
import zipfile
import zlib
from pathlib import Path

from tqdm.auto import tqdm

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
#: Default overall deadline of one download, in seconds (a per-read timeout alone lets a server
#: that sends a byte now and then hold the download for ever).
DOWNLOAD_DEADLINE_S = 6 * 3600.0
#: Default bound on what an archive may expand to, in bytes (also never more than the free disk).
MAX_EXTRACT_BYTES = 64 * 2**30
_READ_TIMEOUT_S = 60.0


def _safe_extract(zf: zipfile.ZipFile, dest: Path, max_bytes: int) -> list[str]:
    """Extract ``zf`` into ``dest``: every entry inside ``dest``, the total declared size (which
    :mod:`zipfile` enforces while reading) at most ``max_bytes`` and the free disk space."""
    dest_r = dest.resolve()
    names = zf.namelist()
    for n in names:
        target = (dest / n).resolve()
        if target != dest_r and dest_r not in target.parents:
            raise ValueError(f"refusing to extract {n!r}: it would land outside {dest}.")
    total = sum(info.file_size for info in zf.infolist())
    free = shutil.disk_usage(dest).free
    if total > min(max_bytes, free):
        limit = "the free disk space" if free < max_bytes else f"max_extract_bytes={max_bytes:,}"
        raise ValueError(
            f"refusing to extract {zf.filename}: it expands to {total:,} bytes, more than {limit} "
            f"({min(max_bytes, free):,} bytes); free space or raise max_extract_bytes."
        )
    zf.extractall(dest)
    return names


def download_dataset(
    name: str,
    root: str | os.PathLike,
    url: str | None = None,
    sha256: str | None = None,
    overwrite: bool = False,
    deadline_s: float = DOWNLOAD_DEADLINE_S,
    max_extract_bytes: int = MAX_EXTRACT_BYTES,
) -> Path:
    """Download (and unzip) a dataset for users with internet access.

    Streams ``url`` (default: the :data:`DOWNLOADS` entry of ``name``) into ``root`` with a
    progress bar, checks its SHA-256 (``sha256`` or the registry's; when neither is known the
    computed hash is logged so it can be pinned), extracts a ``.zip`` into ``root`` and removes
    the archive. The body must have the announced ``Content-Length`` and arrive within
    ``deadline_s``; the archive is extracted into a temporary folder first and moved into place
    only when complete; a zip (by name or content) counts as complete only when it opens and
    every member reads (otherwise it is removed). A marker file, written last, records a
    finished download; a second call returns at once unless ``overwrite``. Whatever fails
    leaves no partial file behind.

    Args:
        name: Dataset name (a :data:`DOWNLOADS` key unless ``url`` is given).
        root: Folder to download into (created).
        url: Override the download URL (any ``http(s)://`` or ``file://`` URL).
        sha256: Expected SHA-256 hex digest of the downloaded file.
        overwrite: Download again even if a finished download is recorded.
        deadline_s: Overall time limit of the transfer, in seconds.
        max_extract_bytes: Largest total size the archive may expand to.

    Returns:
        The folder to pass as ``root=`` to :func:`load_dataset`: ``root`` itself, or its single
        top-level folder when the archive holds exactly one.

    Raises:
        ValueError: unknown name without ``url``, a URL not ending in a file name, checksum
            mismatch (the file is removed), a bad deadline, or a truncated, damaged or too
            large archive (nothing is left extracted).
        OSError: network or file-system errors, a body shorter or longer than its
            ``Content-Length``, the deadline passed (with the URL in the message).
    """
    entry = DOWNLOADS.get(name)
    if entry is None and url is None:
        raise ValueError(
            f"no download known for {name!r}; downloadable: {', '.join(DOWNLOADS)}. For other "
            "datasets pass url=..., or download them by hand and use the layout in the loader's "
            "docstring."
        )
    url = url or str(entry["url"])  # type: ignore[index]
    if not isinstance(deadline_s, (int, float)) or not 0 < deadline_s < float("inf"):
        raise ValueError(f"deadline_s must be a finite number of seconds > 0, got {deadline_s!r}.")
    expected = sha256 or (entry or {}).get("sha256") or None
    expected = expected.lower().strip() if expected else None
    root = Path(root).expanduser()
    root.mkdir(parents=True, exist_ok=True)
    marker = root / _MARKER
    if marker.is_file() and not overwrite:
        info = json.loads(marker.read_text())
        done = root / info["top"] if info.get("top") else root
        if done.is_dir():
            log.info("%s already downloaded into %s (overwrite=True to fetch again)", name, root)
            return done
    raw_name = urllib.request.url2pathname(url.split("?")[0].rstrip("/").split("/")[-1])
    fname = Path(raw_name).name or f"{name}.download"
    if fname in (".", "..") or fname != raw_name.strip("/") or "\0" in fname:
        raise ValueError(
            f"the URL {url} ends in the file name {raw_name!r}, which is not a file name of "
            f"its own; pass a URL whose last part names the file (e.g. .../{name}.zip)."
        )
    marker.unlink(missing_ok=True)  # from here until the end, nothing is recorded as done
    part = root / (fname + ".part")
    got = _stream(name, url, part, root, deadline_s)
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
    with open(target, "rb") as f:
        looks_zip = f.read(4) == b"PK\x03\x04" or target.suffix.lower() == ".zip"
    if looks_zip and not zipfile.is_zipfile(target):
        size = target.stat().st_size
        target.unlink()
        raise ValueError(
            f"{target} is not a complete zip archive (truncated or damaged: {size:,} bytes "
            "received, no end of archive); "
            f"it was removed and nothing is recorded as done. Download it again from {url}."
        )
    top = _unzip(name, target, root, max_extract_bytes) if looks_zip else ""
    tmp_marker = marker.with_name(marker.name + ".tmp")
    tmp_marker.write_text(json.dumps({"name": name, "url": url, "sha256": got, "top": top}))
    os.replace(tmp_marker, marker)
    return root / top if top else root


def _stream(name: str, url: str, part: Path, root: Path, deadline_s: float) -> str:
    """Stream ``url`` into ``part`` with a progress bar; return the SHA-256 hex digest.

    The body must match its ``Content-Length`` (when sent) and arrive within ``deadline_s``
    seconds; otherwise ``part`` is removed and OSError raised.
    """
    digest = hashlib.sha256()
    start = time.monotonic()
    received = 0
    try:
        with urllib.request.urlopen(url, timeout=min(_READ_TIMEOUT_S, deadline_s)) as resp:
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
                # read1: whatever has arrived (read() would wait for a full chunk)
                for chunk in iter(lambda: resp.read1(1 << 20), b""):
                    f.write(chunk)
                    digest.update(chunk)
                    received += len(chunk)
                    bar.update(len(chunk))
                    if time.monotonic() - start > deadline_s:
                        raise TimeoutError(
                            f"not finished after {deadline_s:g} s ({received:,} bytes received; "
                            "deadline_s=... allows more)"
                        )
            if total is not None and received != total:
                raise OSError(
                    f"the server sent {received:,} of the {total:,} bytes it announced "
                    "(connection closed early)"
                )
    except (OSError, ValueError) as exc:  # ValueError: http.client's malformed responses
        part.unlink(missing_ok=True)
        raise OSError(
            f"download of {name!r} from {url} failed: {exc}; nothing was kept. Check the URL "
            f"and your connection and retry, or download it by hand into {root}."
        ) from exc
    return digest.hexdigest()


def _unzip(name: str, target: Path, root: Path, max_bytes: int) -> str:
    """Extract the zip ``target`` into ``root`` (via a temporary folder, moved into place when
    complete), remove it; return its single top folder or ""."""
    staging = Path(tempfile.mkdtemp(prefix=".extract-", dir=root))
    try:
        with zipfile.ZipFile(target) as zf:
            names = _safe_extract(zf, staging, max_bytes)
        for entry in staging.iterdir():
            dest = root / entry.name
            if dest.exists() or dest.is_symlink():
                if dest.is_dir() and not dest.is_symlink():
                    shutil.rmtree(dest)
                else:
                    dest.unlink()
            os.replace(entry, dest)
    except (zipfile.BadZipFile, OSError, EOFError, zlib.error, NotImplementedError) as exc:
        target.unlink(missing_ok=True)  # a member does not read: the archive is damaged
        raise ValueError(
            f"{target} could not be extracted ({type(exc).__name__}: {exc}); it was removed and "
            "nothing was kept. Download it again."
        ) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    target.unlink()
    log.info("%s: extracted %d entries into %s", name, len(names), root)
    tops = {n.split("/")[0] for n in names if n.strip("/")}
    if len(tops) == 1 and (root / next(iter(tops))).is_dir():
        return next(iter(tops))
    return ""
