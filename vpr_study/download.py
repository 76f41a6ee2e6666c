"""Downloading datasets for users with internet access (never called by tests or the study)."""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import secrets
import shutil
import tempfile
import time
import urllib.request
import zipfile
import zlib
from pathlib import Path

from tqdm.auto import tqdm

from vpr_core import checks, settings, utils

__all__ = ["DOWNLOADS", "DOWNLOAD_DEADLINE_S", "MAX_EXTRACT_BYTES", "download_dataset"]

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
    every member reads (otherwise it is removed). A marker file (``.vpr_download.json``), written
    last, records per URL what each download created (its top-level entries and every file) and
    the archive's sha256; a second call returns at once unless ``overwrite``. Whatever fails
    leaves no partial file behind.

    A download never deletes or overwrites what it did not create itself in an earlier download
    of the same URL: an entry in the way that the marker does not record (a user's folder of the
    archive's top-level name, a file of the URL's file name with other content), or a recorded
    folder that has gained files of someone else's, is refused before anything is moved.
    A download whose completeness cannot be shown (no ``Content-Length``, not chunked, no
    SHA-256 to check and not a zip that verifies) is kept, with a warning, but not recorded
    as finished: the next call fetches it again (pass ``sha256=...`` to make it stick).

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
        FileExistsError: something the download did not create is in the way (the message
            names it and the fix); nothing was changed.
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
    deadline_s = checks.check_range(deadline_s, "deadline_s (seconds)", 0, math.inf, True, True)
    expected = sha256 or (entry or {}).get("sha256") or None
    expected = expected.lower().strip() if expected else None
    root = Path(root).expanduser()
    root.mkdir(parents=True, exist_ok=True)
    marker = root / _MARKER
    records = _read_marker(marker)
    record = records.get(url)
    if record is not None and record.get("complete") and not overwrite:
        done = root / record["top"] if record.get("top") else root
        if done.is_dir() and all((root / c).exists() for c in record.get("created", [])):
            log.info("%s already downloaded into %s (overwrite=True to fetch again)", name, root)
            return done
    raw_name = urllib.request.url2pathname(url.split("?")[0].rstrip("/").split("/")[-1])
    fname = Path(raw_name).name or f"{name}.download"
    if fname in (".", "..") or fname != raw_name.strip("/") or "\0" in fname:
        raise ValueError(
            f"the URL {url} ends in the file name {raw_name!r}, which is not a file name of "
            f"its own; pass a URL whose last part names the file (e.g. .../{name}.zip)."
        )
    target = root / fname
    if target.is_dir() and not target.is_symlink():
        raise _in_the_way(target, url, "a folder of the URL's file name")
    # a name of its own: never a user's file that happens to end in .part
    part = root / f"{fname}.{secrets.token_hex(4)}.part"
    got, length_shown = _stream(name, url, part, root, deadline_s)
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
    if (target.exists() or target.is_symlink()) and not (
        _owns(record, root, fname) or (target.is_file() and utils.file_sha256(target) == got)
    ):
        part.unlink(missing_ok=True)  # the same bytes may replace it; other bytes may not
        raise _in_the_way(target, url, "a file of the URL's file name with other content")
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
    if looks_zip:
        top, created, files = _unzip(name, target, root, max_extract_bytes, url, record, marker)
    else:
        top, created, files = "", [fname], [fname]
    complete = looks_zip or length_shown or expected is not None
    records = _read_marker(marker)
    records[url] = {
        "name": name,
        "url": url,
        "sha256": got,
        "top": top,
        "created": created,
        "files": files,
        "complete": complete,
    }
    _write_marker(marker, records)
    if not complete:
        log.warning(
            "%s: %s arrived without a Content-Length and no SHA-256 is known, so its "
            "completeness cannot be shown: it is kept at %s but not recorded as finished (the "
            "next call downloads it again). Pass sha256=%s if that is the published hash.",
            name,
            url,
            target,
            got,
        )
    return root / top if top else root


def _read_marker(marker: Path) -> dict[str, dict]:
    """The marker's records by URL (``{}`` when absent or unreadable; a record of the older
    format, without the list of what it created, proves no ownership)."""
    try:
        data = json.loads(marker.read_text())
    except (OSError, ValueError):
        return {}
    if isinstance(data, dict) and isinstance(data.get("downloads"), dict):
        return {k: v for k, v in data["downloads"].items() if isinstance(v, dict)}
    if isinstance(data, dict) and isinstance(data.get("url"), str):  # the format before records
        return {data["url"]: {**data, "created": [], "files": [], "complete": True}}
    return {}


def _write_marker(marker: Path, records: dict[str, dict]) -> None:
    """Write the records atomically (a unique temporary file, then a rename); no file when
    there is no record."""
    if not records:
        marker.unlink(missing_ok=True)
        return
    tmp = marker.with_name(f"{marker.name}.{secrets.token_hex(4)}.tmp")
    try:
        tmp.write_text(json.dumps({"format": 2, "downloads": records}, indent=1))
        os.replace(tmp, marker)
    finally:
        tmp.unlink(missing_ok=True)


def _owns(record: dict | None, root: Path, entry: str) -> bool:
    """Whether ``root/entry`` is what an earlier download (``record``) created: a recorded
    top-level entry, and every file under it one the download extracted."""
    if not record or entry not in record.get("created", ()):
        return False
    files = set(record.get("files", ()))
    path = root / entry
    if path.is_symlink() or not path.is_dir():
        return entry in files
    return all(
        (Path(d) / f).relative_to(root).as_posix() in files
        for d, dirs, names in os.walk(path)
        for f in [*names, *(x for x in dirs if (Path(d) / x).is_symlink())]
    )


def _in_the_way(path: Path, url: str, what: str) -> FileExistsError:
    """The error for an entry a download would replace but did not create."""
    return FileExistsError(
        f"{path} is in the way of the download from {url}: {what}, not created by an earlier "
        "download of this URL (or holding files added since), so it is left untouched and "
        f"nothing was changed. Move or rename {path}, or pass another root= (an empty folder)."
    )


def _stream(name: str, url: str, part: Path, root: Path, deadline_s: float) -> tuple[str, bool]:
    """Stream ``url`` into ``part`` with a progress bar; return the SHA-256 hex digest and
    whether the body's length was shown complete (``Content-Length`` matched, or a chunked body
    ended by its last chunk; a ``file://`` URL's length is the file's).

    The body must match its ``Content-Length`` (when sent) and arrive within ``deadline_s``
    seconds; otherwise ``part`` is removed and OSError raised.
    """
    digest = hashlib.sha256()
    start = time.monotonic()
    received = 0
    try:
        with urllib.request.urlopen(url, timeout=min(_READ_TIMEOUT_S, deadline_s)) as resp:
            total = int(resp.headers.get("Content-Length") or 0) or None
            chunked = "chunked" in str(resp.headers.get("Transfer-Encoding", "")).lower()
            with (
                open(part, "xb") as f,
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
    return digest.hexdigest(), total is not None or chunked


def _unzip(
    name: str,
    target: Path,
    root: Path,
    max_bytes: int,
    url: str,
    record: dict | None,
    marker: Path,
) -> tuple[str, list[str], list[str]]:
    """Extract the zip ``target`` into ``root`` (via a temporary folder, moved into place when
    complete), remove it; return its single top folder (or ""), the top-level entries created
    and every file extracted (relative to ``root``).

    An entry in the way that ``record`` (the earlier download of ``url``) did not create is
    refused before anything is moved (:class:`FileExistsError`, the archive removed)."""
    staging = Path(tempfile.mkdtemp(prefix=".extract-", dir=root))
    try:
        with zipfile.ZipFile(target) as zf:
            names = _safe_extract(zf, staging, max_bytes)
        entries = sorted(e.name for e in staging.iterdir())
        files = sorted(
            (Path(d) / f).relative_to(staging).as_posix()
            for d, _, found in os.walk(staging)
            for f in found
        )
        for entry in entries:
            dest = root / entry
            if (dest.exists() or dest.is_symlink()) and not _owns(record, root, entry):
                raise _in_the_way(dest, url, "an entry of the archive's top level")
        if record is not None and any((root / e).exists() for e in entries):
            # replacing what the earlier download made: not finished until the end
            _write_marker(marker, {**_read_marker(marker), url: {**record, "complete": False}})
        for entry in entries:
            dest = root / entry
            if dest.is_dir() and not dest.is_symlink():
                shutil.rmtree(dest)
            elif dest.exists() or dest.is_symlink():
                dest.unlink()
            os.replace(staging / entry, dest)
    except (zipfile.BadZipFile, OSError, EOFError, zlib.error, NotImplementedError) as exc:
        target.unlink(missing_ok=True)  # a member does not read: the archive is damaged
        if isinstance(exc, FileExistsError):
            raise
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
        return next(iter(tops)), entries, files
    return "", entries, files
