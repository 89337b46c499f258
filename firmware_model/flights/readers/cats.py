"""CATS flight computer exports: a barometer file and an IMU file on one clock (``hedy-baro.csv`` +
``hedy-imu.csv``).

* baro: header ``ts,id,T,P``: ``ts`` s, ``id`` sensor name, ``T`` degC, ``P`` Pa.
* imu: header ``ts,id,Ax,Ay,Az,Gx,Gy,Gz``: ``ts`` s, ``A*`` m/s^2 (specific force), ``G*`` deg/s.

Either file may be passed; its partner is the same name with ``baro`` and ``imu`` swapped. A baro file without a
partner gives a record without accelerometer (said in the provenance); an IMU file without its baro partner is an
error (no pressure). The record's time axis is the barometer's; the IMU is interpolated linearly onto it (on the
shared log the two clocks are identical and the interpolation is exact).

**Axial axis, decided from the data**: the axis whose pad mean (samples before liftoff, at least the first 0.3 s)
has the largest magnitude is the rocket's axis, with the sign that makes the pad read +1 g. On ``hedy`` that is
``-Ay`` (pad -9.9 m/s^2 on Ay; Ax, Az under 1 m/s^2; during boost -Ay reads +55..+68 m/s^2). The reader also
checks that the chosen axis reads more than +2 g at some point (a boost); otherwise it says so in the provenance.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from firmware_model.flights.readers._common import check_time, fail, licence_of, parse_float, read_text, show
from firmware_model.flights.record import FlightRecord
from firmware_model.spec.atmosphere import G0

BARO_HEADER: tuple[str, ...] = ("ts", "id", "T", "P")
IMU_HEADER: tuple[str, ...] = ("ts", "id", "Ax", "Ay", "Az", "Gx", "Gy", "Gz")


def _first_line(text: str) -> list[str]:
    for line in text.splitlines():
        if line.strip():
            return [c.strip() for c in line.split(",")]
    return []


def kind_of(text: str) -> str | None:
    """``"baro"`` / ``"imu"`` when the text is a CATS baro / IMU export, else None."""
    head = _first_line(text)
    if tuple(head[:4]) == BARO_HEADER:
        return "baro"
    if tuple(head[:5]) == IMU_HEADER[:5]:
        return "imu"
    return None


def looks_like(text: str) -> bool:
    return kind_of(text) is not None


def partner(path: Path, kind: str) -> Path:
    """The other file of the pair: ``baro`` <-> ``imu`` in the file name (last occurrence)."""
    a, b = ("baro", "imu") if kind == "baro" else ("imu", "baro")
    name = path.name
    i = name.rfind(a)
    if i < 0:
        return path.with_name(re.sub(a, b, name, flags=re.I))
    return path.with_name(name[:i] + b + name[i + len(a):])


def _table(path: Path, columns: tuple[str, ...], numeric: tuple[str, ...]) -> dict[str, np.ndarray]:
    text = read_text(path)
    lines = text.splitlines()
    header: list[str] | None = None
    header_line = 0
    out: dict[str, list[float]] = {c: [] for c in numeric}
    line_of: list[int] = []
    idx: dict[str, int] = {}
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        fields = line.split(",")
        if header is None:
            header, header_line = [c.strip() for c in fields], number
            missing = [c for c in columns if c not in header]
            if missing:
                raise fail(path, number, f"missing column(s) {', '.join(missing)}")
            idx = {c: header.index(c) for c in columns}
            continue
        if len(fields) != len(header):
            raise fail(path, number, f"{len(fields)} fields, the header has {len(header)}")
        for c in numeric:
            out[c].append(parse_float(path, number, c, fields[idx[c]]))
        line_of.append(number)
    if header is None or not line_of:
        raise fail(path, header_line or 1, "no data rows")
    arrays = {c: np.asarray(v, dtype=np.float64) for c, v in out.items()}
    check_time(path, line_of, arrays["ts"], drop_repeats=False)
    arrays["_lines"] = np.asarray(line_of)
    return arrays


def axial_axis(t: np.ndarray, acc: dict[str, np.ndarray]) -> tuple[str, float, dict[str, float]]:
    """(axis name, sign, pad means) of the axial axis, decided from the pad (see the module docstring)."""
    total = np.sqrt(sum(a * a for a in acc.values()))
    # pad: before the total specific force first exceeds 2 g for 5 samples in a row, and at least 0.3 s
    above = total > 2.0 * G0
    run = np.convolve(above.astype(int), np.ones(5, dtype=int), mode="valid") == 5
    lift = int(np.argmax(run)) if run.any() else t.shape[0]
    pad = t < max(t[0] + 0.3, t[lift] - 0.2 if lift < t.shape[0] else t[-1])
    pad[: min(30, t.shape[0])] = True
    means = {name: float(np.mean(a[pad])) for name, a in acc.items()}
    axis = max(means, key=lambda n: abs(means[n]))
    return axis, (1.0 if means[axis] > 0 else -1.0), means


def read(path: Path) -> FlightRecord:
    """Read a CATS pair (pass either file)."""
    text = read_text(path)
    kind = kind_of(text)
    if kind is None:
        raise fail(path, 1, f"not a CATS export (header must start with {','.join(BARO_HEADER)} "
                            f"or {','.join(IMU_HEADER[:5])})")
    other = partner(path, kind)
    baro_path, imu_path = (path, other) if kind == "baro" else (other, path)
    notes: list[str] = []
    if not baro_path.exists():
        raise fail(path, 1, f"CATS IMU file without its barometer partner {baro_path.name} (no pressure)")
    baro = _table(baro_path, BARO_HEADER, ("ts", "T", "P"))
    bad = np.nonzero(~(baro["P"] > 0))[0]
    if bad.size:
        raise fail(baro_path, int(baro["_lines"][bad[0]]), f"P: {show(baro['P'][bad[0]])} Pa is not positive")
    t = baro["ts"]
    accel = None
    axis_info: dict[str, object] = {}
    if imu_path.exists():
        imu = _table(imu_path, IMU_HEADER[:5], ("ts", "Ax", "Ay", "Az"))
        ti = imu["ts"]
        acc = {c: imu[c] for c in ("Ax", "Ay", "Az")}
        axis, sign, means = axial_axis(ti, acc)
        a = sign * acc[axis]
        outside = (t < ti[0]) | (t > ti[-1])
        accel = np.interp(t, ti, a)
        accel[outside] = np.nan
        if outside.any():
            notes.append(f"{int(outside.sum())} barometer rows outside the IMU's time span: accel NaN there")
        same = ti.shape == t.shape and np.array_equal(ti, t)
        notes.append("IMU on the barometer's clock: " + ("identical timestamps" if same else
                                                            "interpolated linearly onto the barometer's times"))
        axis_info = {"axis": ("-" if sign < 0 else "+") + axis, "pad_means_mps2": means,
                     "max_axial_mps2": float(np.max(a))}
        if np.max(a) < 2.0 * G0:
            notes.append(f"axial axis {axis_info['axis']} never reads above 2 g: is this a flight?")
    else:
        notes.append(f"no IMU partner {imu_path.name}: record without accelerometer")
    lic_b = licence_of(baro_path)
    provenance = {
        "source": str(baro_path), "imu_source": str(imu_path) if accel is not None else None, "format": "cats",
        "licence": lic_b[0], "origin": lic_b[1], "rows": int(t.shape[0]), "axial": axis_info, "notes": notes,
        "baro_sensor_hint": "pascal" if np.all(baro["P"] == np.rint(baro["P"])) else "unknown",
    }
    name = re.sub(r"[-_]?baro$", "", baro_path.stem) or baro_path.stem
    return FlightRecord(name=name, time_s=t, pressure_pa=baro["P"], accel_mps2=accel, temperature_c=baro["T"],
                        provenance=provenance)
