"""Shared parts of the flight-log readers: reading text, one-line errors naming file and line, number parsing,
the licence table of known logs, repeated-timestamp handling.

Every reader reports a bad file as one :class:`~firmware_model.runtime.errors.UserError`
``"<file>:<line>: <what>"`` (line numbers are 1-based physical lines of the file) and never returns half a record.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
import stat
import re
from pathlib import Path

import numpy as np

from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import pressure_pa

#: Licence of the logs the project knows by name (../shared/flights/README.md says which is which). A file not
#: listed here gets ``"unknown"`` unless it states its own (generic CSV: a ``# licence: ...`` comment line).
KNOWN_LICENCES: tuple[tuple[str, str, str], ...] = (
    # (file-name regex, licence, origin)
    (r"^prometheus-2022-06-24-tele(metrum|mega)\.csv$", "MIT",
     "RocketPy (github.com/RocketPy-Team/RocketPy) test data"),
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
    """The file's text, or a UserError naming it (missing, a folder, a FIFO or device, unreadable, not text,
    empty). Only a regular file is opened: reading a FIFO would block until a writer comes (issue 33)."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise UserError(f"{path}: no such flight log") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot read: {exc.strerror}") from None
    if stat.S_ISDIR(mode):
        raise UserError(f"{path}: is a directory, not a flight log")
    if not stat.S_ISREG(mode):
        kind = "a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "a device"
        raise UserError(f"{path}: is {kind}, not a flight log file (give a regular file)")
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
    if not text or text.isspace():     # (not text.strip(): that copies a whole log ending in a newline)
        raise UserError(f"{path}:1: empty file")
    return text


def iter_lines(text: str, limit: int | None = None) -> Iterator[str]:
    """The lines of ``text`` one at a time (``str.splitlines`` without building the list: a 200 MiB log's list of
    lines took more memory than its text; issue 33), at most ``limit`` of them."""
    if "\r" in text and "\n" not in text:            # old Mac line ends: rare and small
        yield from text.splitlines()[:limit]
        return
    start, n, size = 0, 0, len(text)
    while start < size and (limit is None or n < limit):
        end = text.find("\n", start)
        if end < 0:
            end = size
        line = text[start:end]
        yield line[:-1] if line.endswith("\r") else line
        start, n = end + 1, n + 1


def fail(path: Path, line: int, what: str) -> UserError:
    """The one error type of the readers: ``file:line: what``, ``what`` cut to :data:`MAX_WHAT_CHARS` (issue 33:
    a 5 MB unparseable field was echoed as a 5,000,109-byte error line)."""
    if len(what) > MAX_WHAT_CHARS:
        what = what[:MAX_WHAT_CHARS - 30] + f"...({len(what):,} chars)"
    return UserError(f"{path}:{line}: {what}")


#: The longest reason a reader's error line carries (a field's text in it is cut).
MAX_WHAT_CHARS: int = 300


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
        raise fail(path, lines[i], f"time does not increase ({show(last)} -> {show(t[i])})")
    if int(keep.sum()) < 2:
        raise fail(path, lines[-1] if lines else 1, f"a flight needs at least 2 samples, got {int(keep.sum())}")
    return keep, dropped


# ---------------------------------------------------------------------------------------------------- tables
def show(value: object) -> str:
    """A value as a user would write it in an error text: ``0.01``, not ``np.float64(0.01)``."""
    if isinstance(value, (float, np.floating)):
        x = float(value)
        return repr(int(x)) if x.is_integer() and abs(x) < 1e15 else repr(x)
    if isinstance(value, np.integer):
        return str(int(value))
    return str(value)


def header_fields(text: str, delimiter: str = ",", skip_comments: bool = True) -> list[str]:
    """The stripped fields of the first non-blank line (lines starting with ``#`` skipped when asked), with
    trailing empty fields removed (RRC3 ends every line with a ``;``); empty list for no such line."""
    for line in text.splitlines():
        if not line.strip() or (skip_comments and line.startswith("#")):
            continue
        fields = [f.strip() for f in line.split(delimiter)]
        while fields and not fields[-1]:
            fields.pop()
        return fields
    return []


class Table:
    """A delimited text table: ``header`` (stripped names, trailing empty names removed), ``header_line``,
    ``rows`` = [(line number, fields)], ``notes`` (rows skipped and why).

    * blank lines and, before the header, ``#`` comment lines are skipped;
    * a row whose fields are all empty (RRC3 writes ``;;;;;;;`` at the end) is skipped and noted;
    * a row with fewer fields than the header is an error naming the line, **unless** it is the last line of a
      file that does not end with a newline (a log cut off mid-row): that row is dropped and noted;
    * a row with more fields than the header is accepted only when the extra fields are empty.
    """

    def __init__(self, path: Path, text: str, delimiter: str = ",", min_rows: int = 1,
                 comments: bool = True, allow_duplicates: bool = False) -> None:
        self.path = path
        self.notes: list[str] = []
        self.header: list[str] = []
        self.header_line = 0
        self.rows: list[tuple[int, list[str]]] = []
        lines = text.splitlines()
        ends_cleanly = text.endswith(("\n", "\r"))
        empty_rows = 0
        for number, line in enumerate(lines, start=1):
            if not line.strip():
                continue
            if not self.header:
                if comments and line.startswith("#"):
                    continue
                fields = [f.strip() for f in line.split(delimiter)]
                while fields and not fields[-1]:
                    fields.pop()
                self.header, self.header_line = fields, number
                continue
            fields = line.split(delimiter)
            if not any(f.strip() for f in fields):
                empty_rows += 1
                continue
            n = len(self.header)
            if len(fields) < n:
                if number == len(lines) and not ends_cleanly:
                    self.notes.append(f"line {number}: last row cut short ({len(fields)} of {n} fields, no newline "
                                      "at the end of the file): dropped")
                    continue
                raise fail(path, number, f"{len(fields)} fields, the header (line {self.header_line}) names {n}")
            if len(fields) > n and any(f.strip() for f in fields[n:]):
                raise fail(path, number, f"{len(fields)} fields, the header (line {self.header_line}) names {n}")
            self.rows.append((number, fields[:n]))
        if not self.header:
            raise fail(path, max(1, len(lines)), "no header line")
        if empty_rows:
            self.notes.append(f"{empty_rows} rows with every field empty skipped")
        if len(self.rows) < min_rows:
            raise fail(path, self.header_line, f"{len(self.rows)} data rows (need at least {min_rows})")
        dup = sorted({c for c in self.header if c and self.header.count(c) > 1})
        if dup and not allow_duplicates:
            raise fail(path, self.header_line, f"column(s) named twice: {', '.join(dup)}")

    @property
    def lines(self) -> list[int]:
        return [num for num, _ in self.rows]

    def index(self, name: str) -> int:
        """Column index of ``name`` (exact), or an error naming the header line."""
        if name not in self.header:
            raise fail(self.path, self.header_line, f"missing column {name!r} (columns: {', '.join(self.header)})")
        return self.header.index(name)

    def floats(self, name: str, *, decimal_comma: bool = False, allow_empty: bool = False) -> np.ndarray:
        """Column ``name`` as float64; errors name the file, line, column and the text as written."""
        j = self.index(name)
        out = np.empty(len(self.rows))
        for i, (num, fields) in enumerate(self.rows):
            s = fields[j]
            if decimal_comma:
                s = s.replace(",", ".")
            try:
                out[i] = parse_float(self.path, num, name, s, allow_empty=allow_empty)
            except UserError:
                if decimal_comma:   # name the field as the user wrote it
                    raise parse_error(self.path, num, name, fields[j], allow_empty) from None
                raise
        return out

    def strings(self, name: str) -> list[str]:
        j = self.index(name)
        return [fields[j].strip() for _, fields in self.rows]


def parse_error(path: Path, line: int, column: str, text: str, allow_empty: bool) -> UserError:
    s = text.strip()
    if not s and not allow_empty:
        return fail(path, line, f"{column}: empty field")
    return fail(path, line, f"{column}: cannot parse {s!r} as a number")


def gaps_note(t: np.ndarray, lines: list[int], limit_s: float = 1.0) -> list[str]:
    """Notes for intervals longer than ``limit_s`` between rows (line numbers as in the file)."""
    d = np.diff(t)
    big = np.nonzero(d > limit_s)[0]
    out = [f"gap of {show(round(float(d[i]), 6))} s between line {lines[i]} and line {lines[i + 1]}"
           for i in big[:5]]
    if big.size > 5:
        out.append(f"... {big.size - 5} more gaps over {show(limit_s)} s")
    return out


#: The altitudes a log may hold (m above its pad or sea level): the standard atmosphere this package uses ends
#: near 32 km and is extended; past 100 km (the Karman line) a barometric altitude is not a reading (issue 33:
#: an altitude of 1e308 ft reached liftoff detection as "pressure must be > 0 Pa").
ALTITUDE_RANGE_M: tuple[float, float] = (-1000.0, 100_000.0)


def check_altitude(path: Path, lines: list[int], altitude_m: np.ndarray, column: str, unit: str = "m",
                   scale: float = 1.0) -> None:
    """A UserError ``FILE:LINE: COLUMN: VALUE UNIT is out of range; allowed: ...`` for the first altitude outside
    :data:`ALTITUDE_RANGE_M` (``altitude_m`` in metres; ``scale`` metres per ``unit`` for the message)."""
    lo, hi = ALTITUDE_RANGE_M
    bad = np.nonzero(np.isfinite(altitude_m) & ((altitude_m < lo) | (altitude_m > hi)))[0]
    if bad.size:
        i = int(bad[0])
        raise fail(path, lines[i], f"{column}: {show(float(altitude_m[i]) / scale)} {unit} is out of range; "
                                   f"allowed: {show(round(lo / scale))}..{show(round(hi / scale))} {unit} "
                                   "(a barometric altitude)")


#: Site altitude (m above sea level) assumed for an altitude-only log when none is given: sea level.
DEFAULT_SITE_ALTITUDE_M: float = 0.0


def synthetic_pressure(altitude_agl_m: np.ndarray, site_altitude_m: float | None, source: str = "given"
                       ) -> tuple[np.ndarray, str]:
    """Pressure (Pa) a barometer would have read at ``altitude_agl_m`` above a site at ``site_altitude_m`` (None:
    :data:`DEFAULT_SITE_ALTITUDE_M`) through the standard atmosphere, and the note that says so."""
    site = DEFAULT_SITE_ALTITUDE_M if site_altitude_m is None else float(site_altitude_m)
    if not math.isfinite(site) or not -500.0 <= site <= 10000.0:
        raise UserError(f"site altitude {show(site)} m: must be a number between -500 and 10000 m")
    p = np.asarray(pressure_pa(np.asarray(altitude_agl_m, dtype=np.float64) + site), dtype=np.float64)
    how = source if site_altitude_m is not None else "the default, sea level: give the site altitude to change it"
    return p, (f"SYNTHETIC BAROMETER: the log has altitude, not pressure; pressure = standard atmosphere at "
               f"altitude + site altitude {site:.1f} m ({how})")
