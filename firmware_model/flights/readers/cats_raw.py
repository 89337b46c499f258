"""CATS flight computer **raw** per-sensor exports (the EuRoC 2021 "piccard-cats-*" files): one CSV per kind of
data, written from pandas (a first, unnamed index column).

What the reader relies on (docs/flights.md, "CATS raw"):

* ``*baro_raw.csv``: ``,ts,id,T,P``: ``ts`` **ms** since power-on, ``id`` ``BARO0``..``BARO2`` (three MS5607
  barometers, one row each per 10 ms, interleaved), ``T`` 0.01 degC, ``P`` Pa (integer).
* ``*imu_raw.csv``: ``,ts,id,Gx,Gy,Gz,Ax,Ay,Az``: ``id`` ``IMU0``..``IMU2`` (three ICM-20601), raw counts.
  Accelerometer: the ICM-20601's **nominal** calibration, +-32 g, 1024 counts/g, zero offset. It is not re-based
  on the pad: the shared log starts 0.33 s before CATS's liftoff event with the motor already burning (1.3 g in
  the first 0.1 s, 3.3 g by 0.1 s before EV_LIFTOFF); with the nominal calibration the coast reads -1.3 m/s^2
  and the boost ~105 m/s^2, as the TeleMega on the same flight (-2.1 and ~108). The axial axis is decided from
  the first samples as for the CATS pair (:func:`.cats.axial_axis`).
* ``*event_info_raw.csv``: ``,ts,event,out_idx``: ``EV_LIFTOFF``, ``EV_APOGEE`` (**CATS's own apogee**), ...
* ``*flight_states_raw.csv`` (``,ts,state``) and ``*sensor_info_raw.csv`` (sensor fault flags): companions, not
  logs; reading one of them names the barometer file to read instead.
* The record's time axis: the barometer timestamps, in s **from EV_LIFTOFF** when the events file has it (else
  from the first row), so the three computers of one flight share an origin up to their own liftoff detection.
* Several sensors: ``sensor=None`` takes the **median** of the barometers (and of the IMUs) at each timestamp,
  ``sensor="BARO1"`` one barometer (its IMU: the same digit). Which one is in the notes.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from firmware_model.spec.atmosphere import G0
from firmware_model.flights.readers._common import Table, check_time, fail, gaps_note, licence_of, read_text
from firmware_model.flights.readers.cats import axial_axis
from firmware_model.flights.record import FlightRecord

HEADERS: dict[str, tuple[str, ...]] = {
    "baro": ("", "ts", "id", "T", "P"),
    "imu": ("", "ts", "id", "Gx", "Gy", "Gz", "Ax", "Ay", "Az"),
    "event_info": ("", "ts", "event", "out_idx"),
    "flight_states": ("", "ts", "state"),
}
#: ICM-20601 at +-32 g.
IMU_COUNTS_PER_G: float = 1024.0


def kind_of(text: str) -> str | None:
    """``baro``, ``imu``, ``event_info``, ``flight_states``, ``sensor_info`` or None."""
    head = tuple(_raw_header(text))
    for kind, want in HEADERS.items():
        if head == want:
            return kind
    if len(head) >= 3 and head[:2] == ("", "ts") and all(re.fullmatch(r"(imu|baro)_\d", h) for h in head[2:]):
        return "sensor_info"
    return None


def _raw_header(text: str) -> list[str]:
    for line in text.splitlines():
        if line.strip():
            return [f.strip() for f in line.split(",")]
    return []


def looks_like(text: str) -> bool:
    return kind_of(text) in ("baro", "imu")


def companion_reason(text: str) -> str | None:
    """Why a companion file is not a log (None for a baro/IMU file or a file of another format)."""
    kind = kind_of(text)
    if kind in ("event_info", "flight_states", "sensor_info"):
        return f"a CATS raw {kind.replace('_', ' ')} file (read the *baro_raw.csv of the same flight)"
    return None


def sibling(path: Path, kind: str) -> Path:
    """The file of ``kind`` of the same flight: the name with its ``baro_raw`` / ``imu_raw`` / ... part replaced."""
    m = re.search(r"(baro|imu|event_info|flight_states|sensor_info)_raw", path.name)
    if m is None:
        return path.with_name(f"{kind}_raw.csv")
    return path.with_name(path.name[:m.start()] + f"{kind}_raw" + path.name[m.end():])


def _by_sensor(path: Path, table: Table, columns: tuple[str, ...], prefix: str
               ) -> tuple[np.ndarray, dict[str, dict[str, np.ndarray]], list[int]]:
    """Per-timestamp values of each sensor id: (ts, {id: {column: values}}, first line of each ts). Every
    timestamp must have every sensor once (an error names the line otherwise)."""
    ids = table.strings("id")
    ts = table.floats("ts")
    vals = {c: table.floats(c) for c in columns}
    names = sorted(set(ids))
    bad = [n for n in names if not re.fullmatch(prefix + r"\d+", n)]
    if bad:
        i = ids.index(bad[0])
        raise fail(path, table.rows[i][0], f"id: {bad[0]!r} is not {prefix}<n>")
    k = len(names)
    if len(ids) % k:
        raise fail(path, table.rows[-1][0], f"{len(ids)} rows is not a whole number of {k}-sensor groups")
    n = len(ids) // k
    out = {name: {c: np.empty(n) for c in columns} for name in names}
    t = np.empty(n)
    lines = []
    for g in range(n):
        base = g * k
        t[g] = ts[base]
        lines.append(table.rows[base][0])
        seen = set()
        for r in range(base, base + k):
            if ts[r] != t[g] or ids[r] in seen:
                raise fail(path, table.rows[r][0], f"rows of timestamp {t[g]:.0f} are not one row per sensor "
                                                   f"({', '.join(names)})")
            seen.add(ids[r])
            for c in columns:
                out[ids[r]][c][g] = vals[c][r]
    return t, out, lines


def _events(path: Path) -> tuple[dict[str, float], list[str]]:
    ev_path = sibling(path, "event_info")
    if not ev_path.exists():
        return {}, [f"no events file {ev_path.name}: CATS's own apogee unknown"]
    table = Table(ev_path, read_text(ev_path), ",", min_rows=0)
    ts = table.floats("ts")
    names = table.strings("event")
    events: dict[str, float] = {}
    for t, name in zip(ts, names):
        events.setdefault(name, float(t) / 1000.0)
    return events, []


def read(path: Path, sensor: str | None = None) -> FlightRecord:
    """Read a CATS raw flight from its barometer file (or its IMU file: the barometer file is found beside it)."""
    text = read_text(path)
    kind = kind_of(text)
    if kind not in ("baro", "imu"):
        why = companion_reason(text) if kind else None
        raise fail(path, 1, why or "not a CATS raw export (header ,ts,id,T,P or ,ts,id,Gx,...)")
    baro_path = path if kind == "baro" else sibling(path, "baro")
    if not baro_path.exists():
        raise fail(path, 1, f"CATS raw IMU file without its barometer file {baro_path.name} (no pressure)")
    btext = text if baro_path == path else read_text(baro_path)
    bt = Table(baro_path, btext, ",", min_rows=2)
    t_ms, baros, lines = _by_sensor(baro_path, bt, ("T", "P"), "BARO")
    notes = list(bt.notes)
    names = sorted(baros)
    if sensor is None:
        p = np.median(np.stack([baros[n]["P"] for n in names]), axis=0)
        temp = np.median(np.stack([baros[n]["T"] for n in names]), axis=0) / 100.0
        notes.append(f"barometer: median of {', '.join(names)} at each timestamp (choose one with --sensor)")
        chosen = "median"
    else:
        if sensor not in baros:
            raise fail(baro_path, bt.header_line, f"--sensor {sensor!r}: this log has {', '.join(names)}")
        p, temp = baros[sensor]["P"], baros[sensor]["T"] / 100.0
        notes.append(f"barometer: {sensor} (of {', '.join(names)})")
        chosen = sensor
    bad = np.nonzero(~(p > 0))[0]
    if bad.size:
        raise fail(baro_path, lines[int(bad[0])], f"P: {p[bad[0]]:g} Pa is not positive")
    check_time(baro_path, lines, t_ms, drop_repeats=False)
    events_ms, ev_notes = _events(baro_path)
    notes += ev_notes
    origin_s = events_ms.get("EV_LIFTOFF", float(t_ms[0]) / 1000.0)
    t = t_ms / 1000.0 - origin_s
    notes.append("time: s from EV_LIFTOFF" if "EV_LIFTOFF" in events_ms else "time: s from the first row")
    events = {f"cats_{k.lower().removeprefix('ev_')}": v - origin_s for k, v in events_ms.items()}
    if "cats_apogee" in events:
        events["own_apogee"] = events["cats_apogee"]
    accel = None
    axis_info: dict[str, object] = {}
    imu_path = sibling(baro_path, "imu")
    if imu_path.exists():
        it = Table(imu_path, read_text(imu_path), ",", min_rows=2)
        ti_ms, imus, ilines = _by_sensor(imu_path, it, ("Ax", "Ay", "Az"), "IMU")
        check_time(imu_path, ilines, ti_ms, drop_repeats=False)
        inames = sorted(imus)
        if chosen == "median":
            acc = {c: np.median(np.stack([imus[n][c] for n in inames]), axis=0) for c in ("Ax", "Ay", "Az")}
            notes.append(f"accelerometer: median of {', '.join(inames)}")
        else:
            iname = "IMU" + chosen.removeprefix("BARO")
            if iname not in imus:
                raise fail(imu_path, it.header_line, f"no {iname} for --sensor {chosen}")
            acc = dict(imus[iname])
            notes.append(f"accelerometer: {iname}")
        ti = ti_ms / 1000.0 - origin_s
        axis, sign, means = axial_axis(ti, {c: v / IMU_COUNTS_PER_G * G0 for c, v in acc.items()})
        a = sign * acc[axis] / IMU_COUNTS_PER_G * G0
        accel = np.interp(t, ti, a, left=np.nan, right=np.nan)
        first = ti < ti[0] + 0.1
        pad_g = float(np.mean(a[first])) / G0
        axis_info = {"axis": ("-" if sign < 0 else "+") + axis, "pad_means_mps2": means}
        notes.append(f"axial axis {axis_info['axis']}, nominal calibration: {IMU_COUNTS_PER_G:g} counts/g "
                     f"(ICM-20601 +-32 g), zero offset; the first 0.1 s reads {pad_g:.2f} g"
                     + (" (the log starts with the motor already burning)" if pad_g > 1.2 else ""))
    else:
        notes.append(f"no IMU file {imu_path.name}: record without accelerometer")
    if "own_apogee" not in events:
        notes.append("no EV_APOGEE: CATS's own apogee unknown")
    notes += gaps_note(t, lines)
    licence, origin = licence_of(baro_path)
    provenance = {"source": str(baro_path), "format": "cats_raw", "licence": licence, "origin": origin,
                  "rows": len(bt.rows), "sensor": chosen, "sensors": names, "axial": axis_info,
                  "own_computer": "CATS", "baro_sensor_hint": "pascal", "notes": notes}
    name = re.sub(r"[-_]?baro_raw$", "", baro_path.stem) or baro_path.stem
    return FlightRecord(name=name, time_s=t, pressure_pa=p, accel_mps2=accel, temperature_c=temp, events=events,
                        provenance=provenance, row_lines=np.asarray(lines))
