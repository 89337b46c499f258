"""Real logs for the reconstruction: the flight record (barometer, axial accelerometer) through the project's
readers, plus the 3-axis IMU where the log has one.

* AltosUI CSV (TeleMega): ``accel_x, accel_y, accel_z`` (m/s^2; x along the rocket's axis, nose up) and
  ``gyro_roll, gyro_pitch, gyro_yaw`` (deg/s; roll about the axis). Body frame here: z along the axis, so body
  (x, y, z) = log (y, z, x) and rates (pitch, yaw, -roll): the roll sign is not documented in the export; of the
  16 orders and signs, this one's tilt agrees best with the log's own ``tilt`` column (Piccard 2021: 5.2 deg rms).
  AltosUI 1.9 writes rows with the TeleMega's seven IMU
  columns (``gyro_roll .. tilt``) under a header that omits their names on some exports (EuRoC 2021 Piccard: 75
  names, 82 fields a row); when the row is exactly seven fields wider and the header lacks the gyro, the names are
  put back after ``accel_z`` (and said in the notes). An IMU block that never reads the pad's 1 g (Prometheus 2022:
  accel_x/y/z ~0, gyro stuck near 64 deg/s) is reported unusable.
* CATS (``*-imu.csv``): ``Ax, Ay, Az`` m/s^2, ``Gx, Gy, Gz`` deg/s on the barometer's clock; the rocket's axis is the
  axis that reads about +-1 g on the pad (:func:`firmware_model.flights.readers.cats.axial_axis`); body z = that
  axis with its sign, x and y completing a right-handed frame.
* CATS raw (``*-imu_raw.csv``): the same frame, from the counts scaled as :mod:`~firmware_model.flights.readers.
  cats_raw` says (1024 counts/g, 16.4 counts/(deg/s): the CATS firmware's ICM-20601 ranges, checked against the
  TeleMega of the same flight), the median of the IMUs (or the one ``--sensor`` names) on the barometer's clock.

GPS columns are not used: the logs at hand update them about once a second with repeated (stale) fixes in flight;
without GPS the reconstruction is the vertical channel only (docs/reconstruction.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.spec.atmosphere import G0
from firmware_model.runtime.errors import UserError
from firmware_model.flights.readers import detect_format, read_flight
from firmware_model.flights.readers import cats as cats_reader
from firmware_model.flights.readers import cats_raw as cats_raw_reader
from firmware_model.flights.readers._common import read_text
from firmware_model.flights.readers.altosui import header_names
from firmware_model.flights.record import FlightRecord

TELEMEGA_IMU = ("gyro_roll", "gyro_pitch", "gyro_yaw", "mag_x", "mag_y", "mag_z", "tilt")


@dataclass
class ImuLog:
    """A log's record plus, on the record's rows, body-frame ``accel`` (n, 3) and ``gyro`` (n, 3, rad/s) or None;
    ``tilt_log`` the flight computer's own tilt (deg) if the log has one; ``notes``."""

    record: FlightRecord
    accel: np.ndarray | None
    gyro: np.ndarray | None
    tilt_log: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)


def _altosui_imu(path: Path, rec: FlightRecord, notes: list[str]) -> tuple[Any, Any, Any]:
    text = read_text(path)
    header: list[str] | None = None
    rows: list[list[str]] = []
    for line in text.splitlines():
        if not line.strip():
            continue
        if line.startswith("#"):
            if line.startswith("#version"):
                header = header_names(line)
            continue
        rows.append(line.split(","))
    if header is None or "accel_x" not in header:
        notes.append("no 3-axis IMU columns in this AltosUI log")
        return None, None, None
    width = max(len(r) for r in rows)
    if "gyro_roll" not in header:
        if width == len(header) + len(TELEMEGA_IMU):
            i = header.index("accel_z") + 1
            header = header[:i] + list(TELEMEGA_IMU) + header[i:]
            notes.append("header lacks the TeleMega's gyro/mag/tilt names but rows are 7 fields wider: names put "
                         "back after accel_z")
        else:
            notes.append("accelerometer axes but no gyroscope columns")
    idx = {n: header.index(n) for n in ("time", "accel_x", "accel_y", "accel_z", *TELEMEGA_IMU) if n in header}
    t = np.array([float(r[idx["time"]]) for r in rows])

    def col(name: str) -> np.ndarray:
        return np.array([float(r[idx[name]]) if len(r) > idx[name] and r[idx[name]].strip() else math.nan
                         for r in rows])

    # the record dropped repeated timestamps: map by time
    keep = np.searchsorted(t, rec.time_s)
    keep = np.clip(keep, 0, t.size - 1)
    acc = np.stack([col("accel_y"), col("accel_z"), col("accel_x")], axis=1)[keep]
    pad = rec.time_s < 0
    mag = np.linalg.norm(acc, axis=1)
    if not np.any(np.abs(mag - G0) < 3.0):
        what = f"median {np.nanmedian(mag):.2f} m/s^2" if np.isfinite(mag).any() else "no numbers in it"
        notes.append(f"IMU block unusable: |accel| never near 1 g ({what})")
        return None, None, None
    gyr = None
    if "gyro_roll" in idx:
        # roll sign: of the 16 axis orders and signs, (pitch, yaw, -roll) is the one whose tilt agrees with the
        # flight computer's own tilt column on Piccard 2021 (5.2 deg rms over 0.5-30 s; the others 6.4-25 deg)
        gyr = np.radians(np.stack([col("gyro_pitch"), col("gyro_yaw"), -col("gyro_roll")], axis=1)[keep])
        notes.append("TeleMega gyro axes: body rates (pitch, yaw, -roll), chosen by agreement with the log's own "
                     "tilt (docs/reconstruction.md)")
    tilt = col("tilt")[keep] if "tilt" in idx else None
    del pad
    return acc, gyr, tilt


def _to_body(t: np.ndarray, ti: np.ndarray, A: np.ndarray, Gd: np.ndarray, axis: str, sign: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """CATS log axes (n, 3) to the body frame, interpolated onto ``t``; ``Gd`` deg/s -> rad/s. Body z = ``sign`` x the
    log's rocket axis ``axis``; body x, y = the next two log axes in cyclic order (the sign on one keeps the frame
    right-handed)."""
    a = ["x", "y", "z"].index(axis[1].lower())
    b, c = (a + 1) % 3, (a + 2) % 3
    body_a = np.stack([A[:, b], sign * A[:, c], sign * A[:, a]], axis=1)
    body_g = np.radians(np.stack([Gd[:, b], sign * Gd[:, c], sign * Gd[:, a]], axis=1))
    out_a = np.stack([np.interp(t, ti, body_a[:, i]) for i in range(3)], axis=1)
    out_g = np.stack([np.interp(t, ti, body_g[:, i]) for i in range(3)], axis=1)
    return out_a, out_g


def _cats_imu(path: Path, rec: FlightRecord, notes: list[str]) -> tuple[Any, Any]:
    imu_path = Path(rec.provenance.get("imu_source") or "")
    if not imu_path.is_file():
        notes.append("no CATS IMU file")
        return None, None
    tab = cats_reader._table(imu_path, cats_reader.IMU_HEADER, ("ts", "Ax", "Ay", "Az", "Gx", "Gy", "Gz"))
    ti = tab["ts"]
    axis, sign, _ = cats_reader.axial_axis(ti, {c: tab[c] for c in ("Ax", "Ay", "Az")})
    A = np.stack([tab["A" + n] for n in ("x", "y", "z")], axis=1)
    Gd = np.stack([tab["G" + n] for n in ("x", "y", "z")], axis=1)
    out_a, out_g = _to_body(rec.time_s, ti, A, Gd, axis, sign)
    notes.append(f"CATS IMU: rocket axis {'+' if sign > 0 else '-'}{axis}")
    return out_a, out_g


def _cats_raw_imu(rec: FlightRecord, notes: list[str]) -> tuple[Any, Any]:
    imu_path = Path(rec.provenance.get("imu_source") or "")
    if not imu_path.is_file():
        notes.append("no CATS raw IMU file")
        return None, None
    origin_s = float(rec.provenance["time_origin_s"])     # the IMU file's times onto the record's axis
    sensor = rec.provenance.get("sensor") or "median"
    imu = cats_raw_reader.read_imu(imu_path, origin_s, sensor)
    ti = imu.time_s
    axis, sign, _ = cats_reader.axial_axis(ti, {c: imu.accel_mps2[:, i] for i, c in enumerate(("Ax", "Ay", "Az"))})
    out_a, out_g = _to_body(rec.time_s, ti, imu.accel_mps2, imu.gyro_dps, axis, sign)
    notes.append(f"CATS raw IMU: rocket axis {'+' if sign > 0 else '-'}{axis}; {imu.notes[0]}; "
                 f"{cats_raw_reader.IMU_COUNTS_PER_G:g} counts/g, {cats_raw_reader.IMU_COUNTS_PER_DPS:g} "
                 "counts/(deg/s)")
    return out_a, out_g


def read_imu_log(path: str | Path, format: str | None = None) -> ImuLog:
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such flight log")
    fmt = format or detect_format(path)
    rec = read_flight(path, fmt)
    notes: list[str] = []
    acc = gyr = tilt = None
    if fmt == "altosui":
        acc, gyr, tilt = _altosui_imu(path, rec, notes)
    elif fmt == "cats":
        acc, gyr = _cats_imu(path, rec, notes)
    elif fmt == "cats_raw":
        acc, gyr = _cats_raw_imu(rec, notes)
    else:
        notes.append(f"{fmt} logs carry no 3-axis IMU here")
    return ImuLog(record=rec, accel=acc, gyro=gyr, tilt_log=tilt, notes=notes)
