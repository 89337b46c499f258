*****************************************************************************************************************
* kalman_baro.s -- barometer-only steady-state Kalman filter (state altitude, velocity, acceleration) with
* liftoff, barometer over-range, apogee and low-rate apogee prediction.  No Mach lockout: with the barometer as the
* only measurement a lockout would leave X2/X3 coasting uncorrected (docs/firmware-spec.md section 6, history).
* docs/firmware-spec.md section 6; the code is in kalman.inc, shared with kalman_accel.s.
*****************************************************************************************************************
KALMAN_ACCEL    equ     0
        include "fwemu.inc"
        include "kalman.inc"
