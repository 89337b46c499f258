"""CATS flight computer **raw** per-sensor exports (the EuRoC 2021 "piccard-cats-*" files): one CSV per kind of
data, written from pandas (a first, unnamed index column).

What the reader relies on (docs/flights.md, "CATS raw"):

* ``*baro_raw.csv``: ``,ts,id,T,P``: ``ts`` **ms** since power-on, ``id`` ``BARO0``..``BARO2`` (three MS5607
  barometers, one row each per 10 ms, interleaved), ``T`` 0.01 degC, ``P`` Pa (integer).
* ``*imu_raw.csv``: ``,ts,id,Gx,Gy,Gz,Ax,Ay,Az``: ``id`` ``IMU0``..``IMU2`` (three ICM-20601), raw counts, the
  registers as read (no offset removed). **Scales** (docs/reconstruction.md, "Piccard (CATS)"):
  accelerometer :data:`IMU_COUNTS_PER_G` = 1024 counts/g (+-32 g), gyroscope :data:`IMU_COUNTS_PER_DPS` = 16.4
  counts/(deg/s) (+-2000 deg/s). Source: the CATS firmware of 2020-11 to 2021-12 (catsystems/cats-embedded,
  ``boards/cats_rev1/Core/Src/config/globals.c``: ``ICM20601_ACCEL_RANGE_32G``, ``ICM20601_GYRO_RANGE_2000_DPS`` on
  all three chips in every commit of that span; ``task_imu_read.c`` records ``icm20601_read_accel_raw`` /
  ``_gyro_raw``; ``get_accel_sensitivity`` 1024, ``get_gyro_sensitivity`` 16.4). Checked on the EuRoC 2021 Piccard
  log: the boost and coast (-0.2..30 s) against the TeleMega's pad-calibrated axial accelerometer give 997-999
  counts/g for each IMU; the vertical velocity closing to zero at the apogee (36.3-37.1 s) gives 1001-1026 counts/g;
  the roll rate against the TeleMega's gyro_roll gives 16.55 counts/(deg/s) over 0-30 s (max 562 deg/s). The first
  0.07 s read 1,186-1,197 counts (|a|) on each IMU: not a pad (the log starts 0.32 s before EV_LIFTOFF, the CATS
  recorder keeping only its last queue entries before liftoff, with the motor already pushing: 1.16 g at 1024/g; the
  TeleMega's first row, 0.3 s before its own liftoff, reads 1.41 g), so no scale is derived from it, and the
  accelerometer is not re-based on it. The axial axis is decided from the first samples as for the CATS pair
  (:func:`.cats.axial_axis`): ``-Ax`` on Piccard. The ``sensor_info`` file flags ``imu_0`` and ``imu_2`` on every
  row; their data agree with ``IMU1`` (scales above), so the flags are not used.
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
from dataclasses import dataclass
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
#: ICM-20601 at +-32 g (the CATS firmware's ``ICM20601_ACCEL_RANGE_32G``; module docstring for the evidence).
IMU_COUNTS_PER_G: float = 1024.0
#: ICM-20601 at +-2000 deg/s (the CATS firmware's ``ICM20601_GYRO_RANGE_2000_DPS``).
IMU_COUNTS_PER_DPS: float = 16.4
IMU_AXES: tuple[str, ...] = ("Ax", "Ay", "Az", "Gx", "Gy", "Gz")


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


@dataclass
class ImuData:
    """A CATS raw IMU file in physical units: ``time_s`` (s on the record's axis), ``accel_mps2`` (n, 3) log axes
    x, y, z (specific force), ``gyro_dps`` (n, 3) deg/s, ``sensor`` (``median`` or ``IMUn``), ``notes``."""

    time_s: np.ndarray
    accel_mps2: np.ndarray
    gyro_dps: np.ndarray
    sensor: str
    notes: list[str]


def read_imu(imu_path: Path, origin_s: float, sensor: str = "median") -> ImuData:
    """The IMU file of a CATS raw flight, scaled by :data:`IMU_COUNTS_PER_G` and :data:`IMU_COUNTS_PER_DPS`, on the
    time axis of :func:`read` (``origin_s``: the EV_LIFTOFF time, s since power-on). ``sensor``: ``median`` (of the
    IMUs at each timestamp) or a barometer or IMU name whose digit picks the IMU."""
    it = Table(imu_path, read_text(imu_path), ",", min_rows=2)
    ti_ms, imus, ilines = _by_sensor(imu_path, it, IMU_AXES, "IMU")
    check_time(imu_path, ilines, ti_ms, drop_repeats=False)
    inames = sorted(imus)
    if sensor == "median":
        raw = {c: np.median(np.stack([imus[n][c] for n in inames]), axis=0) for c in IMU_AXES}
        notes = [f"accelerometer and gyroscope: median of {', '.join(inames)}"]
    else:
        iname = "IMU" + sensor.removeprefix("BARO").removeprefix("IMU")
        if iname not in imus:
            raise fail(imu_path, it.header_line, f"no {iname} for --sensor {sensor}")
        raw = dict(imus[iname])
        notes = [f"accelerometer and gyroscope: {iname}"]
    acc = np.stack([raw[c] for c in ("Ax", "Ay", "Az")], axis=1) / IMU_COUNTS_PER_G * G0
    gyr = np.stack([raw[c] for c in ("Gx", "Gy", "Gz")], axis=1) / IMU_COUNTS_PER_DPS
    return ImuData(time_s=ti_ms / 1000.0 - origin_s, accel_mps2=acc, gyro_dps=gyr, sensor=sensor, notes=notes)


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
        imu = read_imu(imu_path, origin_s, chosen)
        notes += imu.notes
        ti = imu.time_s
        acc = {c: imu.accel_mps2[:, i] for i, c in enumerate(("Ax", "Ay", "Az"))}
        axis, sign, means = axial_axis(ti, acc)
        a = sign * acc[axis]
        accel = np.interp(t, ti, a, left=np.nan, right=np.nan)
        first = ti < ti[0] + 0.1
        pad_g = float(np.mean(a[first])) / G0
        axis_info = {"axis": ("-" if sign < 0 else "+") + axis, "pad_means_mps2": means}
        notes.append(f"axial axis {axis_info['axis']}, nominal calibration (the CATS firmware's ICM-20601 "
                     f"ranges): {IMU_COUNTS_PER_G:g} counts/g (+-32 g), {IMU_COUNTS_PER_DPS:g} counts/(deg/s) "
                     f"(+-2000 deg/s), zero offset; the first 0.1 s reads {pad_g:.2f} g"
                     + (" (the log starts with the motor already burning)" if pad_g > 1.2 else ""))
    else:
        notes.append(f"no IMU file {imu_path.name}: record without accelerometer")
    if "own_apogee" not in events:
        notes.append("no EV_APOGEE: CATS's own apogee unknown")
    notes += gaps_note(t, lines)
    licence, origin = licence_of(baro_path)
    provenance = {"source": str(baro_path), "format": "cats_raw",
                  "imu_source": str(imu_path) if imu_path.exists() else None, "time_origin_s": origin_s,
                  "licence": licence, "origin": origin,
                  "rows": len(bt.rows), "sensor": chosen, "sensors": names, "axial": axis_info,
                  "own_computer": "CATS", "baro_sensor_hint": "pascal", "notes": notes}
    name = re.sub(r"[-_]?baro_raw$", "", baro_path.stem) or baro_path.stem
    return FlightRecord(name=name, time_s=t, pressure_pa=p, accel_mps2=accel, temperature_c=temp, events=events,
                        provenance=provenance, row_lines=np.asarray(lines))
