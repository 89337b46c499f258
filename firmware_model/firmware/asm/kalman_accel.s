*****************************************************************************************************************
* kalman_accel.s -- barometer + accelerometer steady-state Kalman filter (3x2 gains; the accelerometer innovation
* e2 = ACC_G*(acc - ACC0) - X3), with the flight logic of kalman_baro plus the Mach lockout (seed 002: during
* lockout the barometer correction is skipped and the filter runs as an integrating accelerometer).
* docs/firmware-spec.md section 6; the code is in kalman.inc, shared with kalman_baro.s.
*****************************************************************************************************************
KALMAN_ACCEL    equ     1
        include "fwemu.inc"
        include "kalman.inc"
