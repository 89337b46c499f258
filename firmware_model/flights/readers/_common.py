"""Shared parts of the flight-log readers: reading text, one-line errors naming file and line, number parsing,
the licence table of known logs, repeated-timestamp handling.

Every reader reports a bad file as one :class:`~firmware_model.runtime.errors.UserError` ``"<file>:<line>: <what>"`` (line
numbers are 1-based physical lines of the file) and never returns half a record.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from firmware_model.runtime.errors import UserError

#: Licence of the logs the project knows by name (../shared/flights/README.md says which is which). A file not
#: listed here gets ``"unknown"`` unless it states its own (generic CSV: a ``# licence: ...`` comment line).
KNOWN_LICENCES: tuple[tuple[str, str, str], ...] = (
    # (file-name regex, licence, origin)
    (r"^prometheus-2022-06-24-tele(metrum|mega)\.csv$", "MIT", "RocketPy (github.com/RocketPy-Team/RocketPy) test data"),
    (r"^hedy-(baro|imu)\.csv$", "MIT", "RocketPy (github.com/RocketPy-Team/RocketPy) test data, CATS flight computer"),
    (r"^2012-\d\d-\d\d-serial-\d+-flight-\d+\.csv$", "GPL-2.0-or-later", "AltOS source tree (altusmetrum.org)"),
)


def licence_of(path: Path) -> tuple[str, str]:
    """(licence, origin) of a known shared log by its file name, else ("unknown", "")."""
    for pattern, licence, origin in KNOWN_LICENCES:
        if re.match(pattern, path.name):
            return licence, origin
    return "unknown", ""


def read_text(path: Path) -> str:
    """The file's text, or a UserError naming it (missing, unreadable, not text, empty)."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: no such flight log") from None
    except IsADirectoryError:
        raise UserError(f"{path}: is a directory, not a flight log") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot read: {exc.strerror}") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise UserError(f"{path}:{line}: not a text file (byte 0x{data[exc.start]:02x} is not UTF-8)") from None
    if not text.strip():
        raise UserError(f"{path}:1: empty file")
    return text


def fail(path: Path, line: int, what: str) -> UserError:
    """The one error type of the readers: ``file:line: what``."""
    return UserError(f"{path}:{line}: {what}")


def parse_float(path: Path, line: int, column: str, text: str, *, allow_empty: bool = False) -> float:
    """One number. An empty field is NaN if ``allow_empty`` (a missing value), else an error; literal NaN/inf and
    anything unparseable are errors naming the column and the text."""
    s = text.strip()
    if not s:
        if allow_empty:
            return math.nan
        raise fail(path, line, f"{column}: empty field")
    try:
        value = float(s)
    except ValueError:
        raise fail(path, line, f"{column}: cannot parse {s!r} as a number") from None
    if not math.isfinite(value):
        raise fail(path, line, f"{column}: {s!r} is not a finite number")
    return value


def check_time(path: Path, lines: list[int], t: np.ndarray, *, drop_repeats: bool) -> tuple[np.ndarray, int]:
    """Check a time column for strict increase. Returns (keep mask, number of repeated timestamps dropped).

    With ``drop_repeats`` a row whose time equals the previous kept row's is dropped (the caller decides whether
    the rows were identical); a time that goes backwards is always an error naming the line."""
    keep = np.ones(t.shape[0], dtype=bool)
    last = -math.inf
    dropped = 0
    for i in range(t.shape[0]):
        if t[i] > last:
            last = t[i]
            continue
        if t[i] == last and drop_repeats:
            keep[i] = False
            dropped += 1
            continue
        raise fail(path, lines[i], f"time does not increase ({last!r} -> {t[i]!r})")
    if int(keep.sum()) < 2:
        raise fail(path, lines[-1] if lines else 1, f"a flight needs at least 2 samples, got {int(keep.sum())}")
    return keep, dropped
