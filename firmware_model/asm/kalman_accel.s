*****************************************************************************************************************
* kalman_accel.s -- barometer + accelerometer steady-state Kalman filter (3x2 gains; the accelerometer innovation
* e2 = ACC_G*(acc - ACC0) - X3), with the same flight logic as kalman_baro.
* docs/firmware-spec.md section 6; the code is in kalman.inc, shared with kalman_baro.s.
*****************************************************************************************************************
KALMAN_ACCEL    equ     1
        include "fwemu.inc"
        include "kalman.inc"
