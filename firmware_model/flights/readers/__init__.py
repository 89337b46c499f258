"""Flight-log readers: every format in, one :class:`~firmware_model.flights.record.FlightRecord` out.

``read_flight(path, format=None)`` detects the format from the file's content (``format`` overrides it):

* ``altosui``: AltosUI CSV v5/v6 (a ``#version,...`` column line) — :mod:`.altosui`;
* ``cats``: CATS baro + IMU pair (``ts,id,T,P`` / ``ts,id,Ax,...``; pass either file) — :mod:`.cats`;
* ``rdas``: RDAS text export of the seeds (whitespace-separated ``time accel pressure [digital]``) — :mod:`.rdas`;
* ``generic``: CSV with unit-named columns (``time_s``, ``pressure_pa`` ...) — :mod:`.generic`.

Bad files raise one :class:`~firmware_model.runtime.errors.UserError` naming the file and line (docs/flights.md).
"""

from __future__ import annotations

from pathlib import Path

from firmware_model.flights.readers import altosui, cats, generic, rdas
from firmware_model.flights.readers._common import read_text
from firmware_model.flights.readers.generic import write_generic
from firmware_model.flights.record import FlightRecord
from firmware_model.runtime.errors import UserError

#: Known formats, in detection order.
FORMATS: tuple[str, ...] = ("altosui", "cats", "rdas", "generic")
_MODULES = {"altosui": altosui, "cats": cats, "rdas": rdas, "generic": generic}


def detect_format(path: str | Path) -> str:
    """The format of ``path`` judged by its content; UserError naming the file when none fits."""
    path = Path(path)
    text = read_text(path)
    for name in ("altosui", "cats", "generic", "rdas"):
        if _MODULES[name].looks_like(text):
            return name
    raise UserError(f"{path}:1: unknown flight log format (not {', '.join(FORMATS)}); "
                    "name it with format= / --format")


def read_flight(path: str | Path, format: str | None = None) -> FlightRecord:  # noqa: A002 (the CLI's --format)
    """Read one flight log. ``format``: one of :data:`FORMATS` to skip detection, or None to detect."""
    path = Path(path)
    if format is None:
        format = detect_format(path)
    elif format not in FORMATS:
        raise UserError(f"{path}: unknown format {format!r}; known: {', '.join(FORMATS)}")
    return _MODULES[format].read(path)


__all__ = ["FORMATS", "detect_format", "read_flight", "write_generic"]
