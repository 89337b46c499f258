"""The CATS raw IMU scales (readers/cats_raw.py: 1024 counts/g, 16.4 counts/(deg/s)) checked against the TeleMega
that flew beside it (EuRoC 2021 Piccard), and the 3-axis IMU the reconstruction reads from the raw files.

The old reading of the log ("1,199 counts on the pad": a scale of ~1,190 counts/g from the first samples) would put
the CATS boost 16 % below the TeleMega's and fail the first test; a gyroscope at any other ICM-20601 range (32.8,
65.5, 8.2 counts/(deg/s)) fails the second by a factor of two or more.
"""

from __future__ import annotations

import numpy as np
import pytest

from firmware_model.flights.readers import cats_raw, read_flight
from firmware_model.flights.reconstruct.logs import read_imu_log
from tests.flights.test_readers import SHARED, needs_shared

EUROC = SHARED / "euroc21"
#: CATS time = TeleMega time + this (s): the best fit of the CATS barometric altitude to the TeleMega's over 1-30 s
#: (0.032-0.034 s) and of the two axial accelerometers over the boost and coast (0.054-0.056 s); the 10 Hz low-pass
#: of the ICM-20601 delays the CATS accelerometer by ~0.02 s.
SHIFT_S = 0.045


def _ratio(x: np.ndarray, y: np.ndarray) -> float:
    """Least-squares k in x ~ k y."""
    return float(np.sum(x * y) / np.sum(y * y))


@needs_shared
def test_cats_raw_accelerometer_scale_matches_the_telemega() -> None:
    cats = read_flight(EUROC / "piccard-cats-baro_raw.csv")
    mega = read_flight(EUROC / "piccard-telemega-serial-6733-flight-0004.eeprom")   # pad-calibrated (+-1 g)
    fm = mega.specific_force_mps2()
    m = (mega.time_s > -0.2) & (mega.time_s < 30.0)
    fc = np.interp(mega.time_s[m] + SHIFT_S, cats.time_s, cats.accel_mps2)
    k = _ratio(fc, fm[m])
    assert abs(k - 1.0) < 0.04, k                  # 1.024 measured; 1,190 counts/g gives 0.84
    # the first samples are not a pad: 1.16-1.3 g (motor already pushing), so they do not give a scale
    first = cats.time_s < cats.time_s[0] + 0.1
    assert 1.1 < float(np.nanmean(cats.accel_mps2[first])) / 9.80665 < 1.4
    assert "1024 counts/g" in " ".join(cats.provenance["notes"])
    assert cats_raw.IMU_COUNTS_PER_G == 1024.0


@needs_shared
def test_cats_raw_gyro_scale_matches_the_telemega_roll_rate() -> None:
    cats = read_imu_log(EUROC / "piccard-cats-baro_raw.csv")
    mega = read_imu_log(EUROC / "piccard-telemega.csv")
    assert cats.gyro is not None and cats.accel is not None
    m = (mega.record.time_s > 0.0) & (mega.record.time_s < 30.0)
    roll_c = np.interp(mega.record.time_s[m] + SHIFT_S, cats.record.time_s, cats.gyro[:, 2])   # about the axis
    roll_m = mega.gyro[m, 2]
    assert np.degrees(np.max(np.abs(roll_m))) > 300.0          # the rocket spun: the scale is well exercised
    k = _ratio(roll_c, roll_m)
    # |k| = 0.99 (16.55 counts/(deg/s) against 16.4); the sign: the TeleMega's body z rate is -gyro_roll
    # (chosen by tilt agreement, reconstruct/logs.py), the CATS's is right-handed from the ICM-20601's own axes
    assert 0.96 < abs(k) < 1.04, k
    # the pad-free start: the body z axis (the rocket's, -Ax on this board) reads the boost
    assert float(np.median(cats.accel[(cats.record.time_s > 1.0) & (cats.record.time_s < 5.0), 2])) > 5 * 9.80665


@needs_shared
def test_cats_raw_read_imu_single_sensor_and_units() -> None:
    rec = read_flight(EUROC / "piccard-cats-baro_raw.csv", sensor="BARO1")
    imu = cats_raw.read_imu(EUROC / "piccard-cats-imu_raw.csv", float(rec.provenance["time_origin_s"]), "BARO1")
    assert imu.sensor == "BARO1" and imu.notes == ["accelerometer and gyroscope: IMU1"]
    assert imu.accel_mps2.shape == imu.gyro_dps.shape == (imu.time_s.size, 3)
    assert abs(imu.time_s[0] - rec.time_s[0]) < 0.05          # both on the EV_LIFTOFF axis
    with pytest.raises(Exception, match="no IMU7"):
        cats_raw.read_imu(EUROC / "piccard-cats-imu_raw.csv", 0.0, "BARO7")
