"""What the survey wrote in a disc's folder: stage markers with resume keys, and the files each stage wrote.

Every stage of a disc leaves ``survey_stage_<stage>.json`` in the disc's folder: its resume key
(a hash of the configuration sections it depends on and of the data), its status (``running``
while it works, ``done`` when it finished) and the files it wrote with their SHA-256. A stage is
skipped on a rerun when its marker is done with the same key. When the key changed (one disc's
inclination, say), the stage runs again and replaces its earlier outputs — but only files the
survey itself wrote there: a file a marker lists with the same content, or one that a stage
interrupted there wrote (new or changed since that stage began). Any other file in the way (a
scan of another dataset, a file a user put there) stops that disc with a one-line error naming
it; the files a rerun replaced are listed in the stage's marker (``info["replaced"]``) and logged.
"""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path

from ..._provenance import atomic_path, to_json

__all__ = ["ForeignFileError", "begin", "check_folder", "claim", "clear", "done", "file_hash", "mark", "snapshot",
           "superseded", "write_text"]

log = logging.getLogger(__name__)

IGNORED = ("survey_parts",)
"""Sub-folders of a disc's folder the markers do not list (the scan's chunk files, keyed on their own)."""


class ForeignFileError(RuntimeError):
    """A file the survey would replace in a disc's folder was not written by the survey."""


def write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (temporary file, then rename); return the path."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


def file_hash(path) -> str:
    """SHA-256 of a file's bytes (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _marker(out_dir, stage: str) -> Path:
    return Path(out_dir) / f"survey_stage_{stage}.json"


def _read(path: Path) -> dict | None:
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def _markers(out_dir) -> list[dict]:
    return [r for r in (_read(p) for p in sorted(Path(out_dir).glob("survey_stage_*.json"))) if r is not None]


def done(out_dir, stage: str, key: str, *needed: str) -> dict | None:
    """The marker's info when ``stage`` finished with ``key`` and its files ``needed`` are there, else None."""
    out_dir = Path(out_dir)
    record = _read(_marker(out_dir, stage))
    if record is None or not all((out_dir / f).exists() for f in needed):
        return None
    if record.get("status", "done") != "done" or record.get("key") != key:
        return None
    return record.get("info", {})


def snapshot(out_dir) -> dict[str, str]:
    """``{relative path: SHA-256}`` of the files in a disc's folder (markers and ``survey_parts/`` left out)."""
    out_dir = Path(out_dir)
    files = {}
    for path in sorted(out_dir.rglob("*")) if out_dir.is_dir() else ():
        rel = path.relative_to(out_dir)
        if path.is_file() and rel.parts[0] not in IGNORED and not path.name.startswith("survey_stage_"):
            files[rel.as_posix()] = file_hash(path)
    return files


def _owned(name: str, digest: str, markers: list[dict]) -> bool:
    for record in markers:
        files, before = record.get("files") or {}, record.get("before") or {}
        if files.get(name) == digest:
            return True
        if record.get("status") == "running" and before.get(name) != digest:
            return True  # written by a stage that was interrupted here: the survey's own
    return False


def superseded(out_dir, stage: str, key: str) -> bool:
    """Whether ``stage`` ran (or began) in ``out_dir`` with another key than ``key``: its outputs are stale."""
    record = _read(_marker(out_dir, stage))
    return record is not None and record.get("key") != key


def clear(out_dir, folder: str, *, where: str = "[survey] output") -> list[str]:
    """Delete the files under ``out_dir/folder`` after :func:`claim` found them all the survey's; return them."""
    base = Path(out_dir) / folder
    names = [p.relative_to(out_dir).as_posix() for p in sorted(base.rglob("*")) if p.is_file()] if base.is_dir() else []
    for name in claim(out_dir, names, where=where):
        (Path(out_dir) / name).unlink()
    return names


def begin(out_dir, stage: str, key: str) -> dict[str, dict[str, str]]:
    """Mark ``stage`` as running with ``key``; return the folder's files before it (for :func:`mark`).

    The marker keeps the files its earlier run recorded and the folder as it was when the stage
    first started (a retried stage keeps the first attempt's), so that what an interrupted stage
    wrote counts as the survey's and nothing else does.
    """
    path = _marker(out_dir, stage)
    old = _read(path) or {}
    before = snapshot(out_dir)
    if old.get("status") == "running" and isinstance(old.get("before"), dict):
        before = old["before"]
    markers = _markers(out_dir)
    owned = {n: h for n, h in before.items() if _owned(n, h, markers)}
    write_text(path, to_json({"stage": stage, "key": key, "status": "running", "info": {},
                              "files": old.get("files", {}), "before": before, "owned": owned}, indent=1))
    return {"before": before, "owned": owned}


def mark(out_dir, stage: str, key: str, info: dict | None = None, *, since: dict | None = None,
         written=()) -> None:
    """Mark ``stage`` done with ``key``, recording the files it wrote: those named in ``written``, and
    with ``since`` (from :func:`begin`) the files new or changed since then and those the survey owned
    then that are unchanged."""
    out_dir = Path(out_dir)
    files = {n: file_hash(out_dir / n) for n in written}
    if since is not None:
        before, owned = since["before"], since["owned"]
        files |= {n: h for n, h in snapshot(out_dir).items() if before.get(n) != h or owned.get(n) == h}
    write_text(_marker(out_dir, stage), to_json({"stage": stage, "key": key, "status": "done", "info": info or {},
                                                 "files": files}, indent=1))


def claim(out_dir, names, *, where: str = "[survey] output") -> list[str]:
    """Check that the existing files among ``names`` (relative to ``out_dir``) may be replaced; return them.

    Raises
    ------
    ForeignFileError
        One of them was not written by the survey (or changed since): it names the file and the fix.
    """
    out_dir = Path(out_dir)
    existing = [n for n in names if (out_dir / n).is_file()]
    if not existing:
        return []
    markers = _markers(out_dir)
    foreign = [n for n in existing if not _owned(n, file_hash(out_dir / n), markers)]
    if foreign:
        raise ForeignFileError(
            f"{out_dir / foreign[0]} was not written by this survey (or was changed since): the survey replaces "
            f"only its own outputs; move it away or delete it, or choose another {where}")
    return existing


def check_folder(out_dir) -> None:
    """Refuse a disc folder that holds files but no survey marker (another command's or another run's outputs)."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir() or any(out_dir.glob("survey_stage_*.json")):
        return
    found = sorted(p.name for p in out_dir.iterdir())
    if found:
        raise ForeignFileError(
            f"{out_dir} already holds files the survey did not write ({', '.join(found[:3])}"
            f"{', ...' if len(found) > 3 else ''}): move them away or choose another [survey] output")
