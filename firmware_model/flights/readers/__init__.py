"""Flight-log readers: every format in, one :class:`~firmware_model.flights.record.FlightRecord` out.

``read_flight(path, format=None, **options)`` detects the format from the file's content (``format`` overrides
it). One module per format (docs/flights.md has each format's facts):

* ``altosui``: AltosUI CSV v5/v6, with or without the ``#version`` comment line — :mod:`.altosui`;
* ``eeprom``: AltOS ``.eeprom`` raw flash logs of every family (log formats 1, 5-8, 10, 12, 14-16, 19, 21, 22, 24,
  25; JSON or old text style) — :mod:`.altos_eeprom` (formats 7 and 19 in JSON through :mod:`.eeprom`);
* ``cats``: CATS baro + IMU pair (``ts,id,T,P`` / ``ts,id,Ax,...``) — :mod:`.cats`;
* ``cats_raw``: CATS raw per-sensor files (``,ts,id,T,P`` ...; three barometers, events file) — :mod:`.cats_raw`;
* ``rrc3``: Missile Works RRC3 export — :mod:`.rrc3`; ``eggtimer``: Eggtimer flight CSV — :mod:`.eggtimer`;
* ``raven``: Featherweight Raven export — :mod:`.raven`;
* ``board``: a team board's ``time,pressure`` sensor file + its state file — :mod:`.board`;
* ``columns``: any CSV through a column map (built-in maps detected by their columns) — :mod:`.columns`;
* ``rdas``: RDAS text export of the seeds — :mod:`.rdas`; ``generic``: our unit-named CSV — :mod:`.generic`;
* ``perfectflite``: PerfectFlite .pf2 / DataCap CSV / StratoLogger rows — :mod:`.perfectflite`; ``raven_fip``:
  Featherweight Raven FIP export — :mod:`.raven_fip`; ``blueraven``: Blue Raven app low/high-rate pair —
  :mod:`.blueraven`; ``aim``: Entacore AIM export — :mod:`.aim`; ``altimetercloud``: AltimeterCloud (Rocketry Ltd
  Mercury) — :mod:`.altimetercloud`.

``options`` (each passed only to the formats that take it; a format that does not is an error):
``sensor`` (cats_raw: ``BARO0``..; default the median), ``columns`` (a column map: forces ``columns``),
``site_altitude_m`` (altitude-only logs), ``flight`` (eeprom: the flight number in the file).

:func:`not_a_log` says why a file is not a flight log (README, LICENSE, an Eggtimer info text, a CATS events
file, a board's state file, a Blue Raven summary) so that a folder can be read file by file. Bad files raise one
:class:`~firmware_model.runtime.errors.UserError` naming the file and line (docs/flights.md).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from firmware_model.flights.readers import (aim, altimetercloud, altos_eeprom, altosui, blueraven, board, cats,
                                            cats_raw, columns, eggtimer, generic, perfectflite, raven, raven_fip, rdas,
                                            rrc3)
from firmware_model.flights.readers._common import read_text
from firmware_model.flights.readers.generic import write_generic
from firmware_model.flights.record import FlightRecord
from firmware_model.runtime.errors import UserError

#: Known formats.
FORMATS: tuple[str, ...] = ("altosui", "eeprom", "cats", "cats_raw", "rrc3", "eggtimer", "raven", "board",
                            "columns", "rdas", "generic", "perfectflite", "raven_fip", "blueraven", "aim",
                            "altimetercloud")
_MODULES = {"altosui": altosui, "eeprom": altos_eeprom, "cats": cats, "cats_raw": cats_raw, "rrc3": rrc3,
            "eggtimer": eggtimer, "raven": raven, "board": board, "columns": columns, "rdas": rdas,
            "generic": generic, "perfectflite": perfectflite, "raven_fip": raven_fip,
            "blueraven": blueraven, "aim": aim, "altimetercloud": altimetercloud}
#: Detection order: the strict header tests first, RDAS (a majority of numeric lines) last.
_DETECT: tuple[str, ...] = ("eeprom", "altosui", "cats", "cats_raw", "rrc3", "eggtimer", "raven", "board",
                            "columns", "perfectflite", "raven_fip", "blueraven", "aim", "altimetercloud",
                            "generic", "rdas")
#: Which reader takes which option.
OPTIONS: dict[str, tuple[str, ...]] = {"sensor": ("cats_raw",), "columns": ("columns",),
                                       "site_altitude_m": ("eggtimer", "raven", "columns", "perfectflite",
                                                                           "altimetercloud"), "flight": ("eeprom",)}


#: Detection reads at most this many characters of a log (whole lines): every format names itself in its first
#: lines (a header, a JSON head), and a test that splits the whole text took 2.6x a 200 MiB log's size.
DETECT_CHARS: int = 4 << 20


def _matches(text: str) -> list[str]:
    return [name for name in _DETECT if _MODULES[name].looks_like(text)]


def not_a_log(path: str | Path) -> str | None:
    """Why ``path`` is not a flight log (a readable reason), or None when it is one or might be one."""
    path = Path(path)
    text = read_text(path)
    if _matches(text):
        return None
    for module in (cats_raw, board, blueraven):
        why = module.companion_reason(text)
        if why:
            return why
    first = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    name = path.name.lower()
    if path.suffix.lower() in (".md", ".txt", ".rst") or name.startswith(("license", "licence", "readme", "copying")):
        return f"a text document ({first[:40]!r}), not a log"
    return None


def detect_format(path: str | Path) -> str:
    """The format of ``path`` judged by its content; UserError naming the file when none fits."""
    path = Path(path)
    text = read_text(path)
    if len(text) > DETECT_CHARS:   # judge a big log by its head: several tests split every line (issue 33)
        text = text[:text.rfind("\n", 0, DETECT_CHARS) + 1] or text[:DETECT_CHARS]
    hit = next((name for name in _DETECT if _MODULES[name].looks_like(text)), None)   # the first, as _matches
    if hit is not None:
        return hit
    why = not_a_log(path)
    if why:
        raise UserError(f"{path}:1: not a flight log: {why}")
    raise UserError(f"{path}:1: unknown flight log format (not {', '.join(FORMATS)}); "
                    "name it with format= / --format, or map its columns with --columns")


def read_flight(path: str | Path, format: str | None = None,  # the CLI's --format
                **options: Any) -> FlightRecord:
    """Read one flight log. ``format``: one of :data:`FORMATS` to skip detection, or None to detect.
    ``options``: see the module docstring (None values are ignored)."""
    path = Path(path)
    options = {k: v for k, v in options.items() if v is not None}
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise UserError(f"{path}: unknown reader option(s) {', '.join(unknown)}")
    if "columns" in options and format is None:
        format = "columns"
    if format is None:
        format = detect_format(path)
    elif format not in FORMATS:
        raise UserError(f"{path}: unknown format {format!r}; known: {', '.join(FORMATS)}")
    for key in options:
        if format not in OPTIONS[key]:
            flag = "--" + key.replace("_", "-").replace("-m", "")
            raise UserError(f"{path}: {flag} does not apply to a {format} log (only to {', '.join(OPTIONS[key])})")
    return _MODULES[format].read(path, **options)


__all__ = ["FORMATS", "OPTIONS", "detect_format", "not_a_log", "read_flight", "write_generic"]
