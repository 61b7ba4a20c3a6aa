"""What a certificate is made from (:func:`load_sources`): the result JSON read (not yet
checked) and hashed, the log it names found and hashed, ``<stem>.holdout.csv`` beside it; and
the nominal given to ``dhlog report`` (:class:`Nominal`)."""

from __future__ import annotations

import hashlib
import json
import stat
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dhlog.errors import InputError
from dhlog.present.certificate.holdout import CSV_REMEDY
from dhlog.present.certificate.read import ResultFileError

if TYPE_CHECKING:
    from dhlog.model.dh import StandardDH

#: Largest result file read (a result of a 6-joint robot is about 50 kB).
MAX_RESULT_BYTES = 64 << 20


@dataclass(frozen=True)
class LogCheck:
    """The log the result names: where it was looked for, where it was found (None: not
    found) and its SHA-256 there."""

    name: str
    recorded_sha256: str
    path: Path | None
    sha256: str | None
    searched: tuple[Path, ...]


@dataclass(frozen=True)
class Sources:
    """Everything a certificate is made from, read by :func:`load_sources`: the result document
    (untrusted, checked by :func:`~dhlog.present.certificate.page.certificate_html`), the result
    file's own SHA-256 and time, the log's check, and the held-out CSV's text (None when it is
    not beside the result)."""

    result_path: Path
    document: Any
    result_sha256: str
    result_modified: datetime
    log: LogCheck
    holdout_path: Path
    holdout_text: str | None

    @property
    def inputs(self) -> list[Path]:
        """Every file read, so that an output may refuse to replace one."""
        found = [self.result_path]
        if self.log.path is not None:
            found.append(self.log.path)
        if self.holdout_text is not None:
            found.append(self.holdout_path)
        return found


@dataclass(frozen=True)
class Nominal:
    """The nominal table given to ``dhlog report`` (the result JSON does not record it) and the
    name it was given by."""

    name: str
    table: StandardDH


def _stem(path: Path) -> str:
    name = path.name
    for suffix in (".dh.json", ".json"):
        if name.endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)]
    return path.stem


def holdout_csv_path(result_path: Path) -> Path:
    """``<stem>.holdout.csv`` beside ``<stem>.dh.json``."""
    return result_path.with_name(f"{_stem(result_path)}.holdout.csv")


def _sha256_of(path: Path) -> str:
    from dhlog.io.writer import sha256_of

    return sha256_of(path)


def load_sources(result_path: Path, *, log: Path | None = None) -> Sources:
    """Read ``result_path`` (JSON, not yet checked), its SHA-256 and modification time; the log
    it names (``source.path``): ``log`` when given, else looked for beside the result and in
    the current folder, hashed where found; and ``<stem>.holdout.csv`` beside it."""
    name = str(result_path)
    try:
        mode = result_path.stat().st_mode
        if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):  # a pipe would wait, a device stream
            raise InputError(
                f"{name}: is not a regular file (a device, pipe or socket); dhlog report reads a "
                "result only from a regular file: save it to one first."
            )
        with open(result_path, "rb") as f:
            data = f.read(MAX_RESULT_BYTES + 1)
        modified = datetime.fromtimestamp(result_path.stat().st_mtime, tz=UTC)
    except OSError as exc:
        raise InputError(
            f"{name}: cannot be read ({exc.strerror or exc}); give the <stem>.dh.json that "
            "dhlog process wrote."
        ) from None
    if len(data) > MAX_RESULT_BYTES:
        raise ResultFileError(name, "the file", f"is larger than {MAX_RESULT_BYTES >> 20} MiB")
    try:
        document = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ResultFileError(name, "the file", f"is not UTF-8 text (byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise ResultFileError(
            name, "the file", f"is not valid JSON ({exc.msg} at line {exc.lineno})"
        ) from None
    except ValueError as exc:  # an integer beyond Python's digit limit
        raise ResultFileError(name, "the file", f"is not valid JSON ({exc})") from None
    except RecursionError:
        raise ResultFileError(name, "the file", "nests too deeply to be a result") from None
    source = document.get("source") if isinstance(document, dict) else None
    log_name = source.get("path") if isinstance(source, dict) else None
    recorded = source.get("sha256") if isinstance(source, dict) else None
    log_check = _find_log(
        result_path,
        log_name if isinstance(log_name, str) else "",
        recorded if isinstance(recorded, str) else "",
        log,
    )
    csv_path = holdout_csv_path(result_path)
    holdout_text = None
    if csv_path.is_file():
        try:
            holdout_text = csv_path.read_bytes().decode("utf-8")
        except OSError as exc:
            raise InputError(f"{csv_path}: cannot be read ({exc.strerror or exc}).") from None
        except UnicodeDecodeError as exc:
            raise ResultFileError(
                str(csv_path), "the file", f"is not UTF-8 text (byte {exc.start})", CSV_REMEDY
            ) from None
    return Sources(
        result_path,
        document,
        hashlib.sha256(data).hexdigest(),
        modified,
        log_check,
        csv_path,
        holdout_text,
    )


def _is_log(path: Path) -> bool:
    """A file, or a folder (a rosbag2 bag): never a device, a pipe or a socket."""
    try:
        return path.is_file() or path.is_dir()
    except (OSError, ValueError):
        return False


def _find_log(result_path: Path, name: str, recorded: str, given: Path | None) -> LogCheck:
    """The log: ``given``, else the file ``name`` (its last part only: ``process`` records the
    name alone, and the JSON is untrusted) beside the result or in the current folder."""
    if given is not None:
        if not _is_log(given):
            raise InputError(f"{given}: no such log; give the log the result was computed from.")
        try:
            return LogCheck(name, recorded, given, _sha256_of(given), (given,))
        except OSError as exc:
            raise InputError(f"{given}: cannot be read ({exc.strerror or exc}).") from None
    base = Path(name.replace("\\", "/")).name if "\x00" not in name else ""
    if base in ("", ".", ".."):
        return LogCheck(name, recorded, None, None, ())
    searched = tuple(dict.fromkeys((result_path.parent / base, Path.cwd() / base)))
    for candidate in searched:
        if _is_log(candidate):
            try:
                return LogCheck(name, recorded, candidate, _sha256_of(candidate), searched)
            except OSError:
                continue
    return LogCheck(name, recorded, None, None, searched)
