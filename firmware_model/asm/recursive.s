*****************************************************************************************************************
* recursive.s -- D. Schultz's shift-and-add recursive altitude filter with barometric apogee detection behind an
* accelerometer velocity gate (seed 000, "Filtering the Data" and "Algorithm Testing").
*
*   EST += (z << (8-S)) - rs(EST, S)          EST is Q24.8; weight 2^-S
*   VEL += acc - ACC0                          velocity in accel counts x samples (ACC0 = pad reading = 1 g)
*   LIFTOFF when VEL > V_LIFT; GATE_HIGH when (after liftoff) VEL > V_GATE; ARMED when, on a later sample,
*   VEL has come back below V_GATE ("Velocity Gate Off": apogee detection enabled once the accelerometer velocity
*   is below ~200 ft/s after burnout); EXT follows the maximum of EST; APOGEE when armed and EXT - EST >= THR.
*   A flight whose VEL never exceeds V_GATE is never armed: this program then never declares apogee.
*
* Contract: docs/firmware-spec.md section 5.  Constants (S, THR, V_LIFT, V_GATE, ROUND, BARO_SIGN) come from the
* build.  Entry points: init, step (JSR/RTS).  Uses D0-D4, D7; no stack beyond the return address.
*****************************************************************************************************************
        include "fwemu.inc"

        section code
*---- reset vectors: initial SSP and PC (a real board would enter reset, which samples forever) ------------------
vectors dc.l    STACK_TOP
        dc.l    reset

reset   lea     STACK_TOP,sp
        jsr     init
.loop   jsr     step                    ; (real firmware: wait for the sample timer here)
        bra.s   .loop

*****************************************************************************************************************
* init -- EST = EXT = z << 8; VEL = 0; ACC0 = acc; EVENTS = 0.
*****************************************************************************************************************
init    READZS  d0,8                    ; z << 8
        move.l  d0,(EST).w
        move.l  d0,(EXT).w
        clr.l   (VEL).w
        move.w  (ACCEL_ADC).w,d0
        ext.l   d0
        move.l  d0,(ACC0).w             ; pad reading: 1 g, the velocity integrator's offset
        clr.w   (EVENTS).w
        rts

*****************************************************************************************************************
* step -- one sample.  Register use: d1 = VEL, d2 = EST, d7 = EVENTS, d4 = 0 (rounding), d0/d3 scratch.
* The only per-sample event bits (MACH_LOCKOUT, BARO_INVALID) are never set by this program, so EVENTS is not
* masked at entry.  Event bits used: LIFTOFF, GATE_HIGH, ARMED, APOGEE (all latched).
*****************************************************************************************************************
step    move.w  (ACCEL_ADC).w,d1
        ext.l   d1
        sub.l   (ACC0).w,d1             ; acc - ACC0 (exact: both are sign-extended words)
        add.l   (VEL).w,d1              ; 1. VEL += acc - ACC0 (wraps)
        move.l  d1,(VEL).w
        move.w  (EVENTS).w,d7

*---- 2. liftoff: not LIFTOFF and VEL > V_LIFT ----------------------------------------------------------------------
        moveq   #EV_LIFTOFF,d0
        and.w   d7,d0
        bne.s   .gate
        cmpi.l  #V_LIFT,d1
        ble.s   .gate
        ori.w   #EV_LIFTOFF,d7
*---- 3a. GATE_HIGH and not ARMED and VEL < V_GATE: set ARMED -------------------------------------------------------
*     (GATE_HIGH as it was before 3b of this sample: the sample that sets GATE_HIGH cannot also set ARMED)
.gate   moveq   #EV_GATE_HIGH|EV_ARMED,d0
        and.w   d7,d0
        cmpi.w  #EV_GATE_HIGH,d0        ; equal only for "GATE_HIGH and not ARMED"
        bne.s   .gateb
        cmpi.l  #V_GATE,d1
        bge.s   .est                    ; VEL >= V_GATE: 3b could only set GATE_HIGH again
        ori.w   #EV_ARMED,d7
        bra.s   .est                    ; VEL < V_GATE: 3b cannot fire
*---- 3b. LIFTOFF and VEL > V_GATE: set GATE_HIGH -------------------------------------------------------------------
.gateb  moveq   #EV_LIFTOFF,d0
        and.w   d7,d0
        beq.s   .est
        cmpi.l  #V_GATE,d1
        ble.s   .est
        ori.w   #EV_GATE_HIGH,d7

*---- 4. EST = EST + (z << (8-S)) - rs(EST, S) ---------------------------------------------------------------------
.est    READZS  d0,8-S                  ; z << (8-S): the ADC lined up with EST's binary point, divided by 2^S
        move.l  (EST).w,d2
        move.l  d2,d3
        moveq   #0,d4                   ; zero for the rounding ADDX
        RSHIFT  d3,S,d1,d4              ; rs(EST, S)   (S <= 8: never uses the count register d1)
        sub.l   d3,d2                   ; EST - EST/2^S
        add.l   d0,d2                   ;   + ADC/2^S   (the seed's listing has this subtraction backwards)
        move.l  d2,(EST).w

*---- 5. extreme and apogee ----------------------------------------------------------------------------------------
        move.l  (EXT).w,d0
        cmp.l   d0,d2
        ble.s   .notnew
        move.l  d2,(EXT).w              ; new extreme
        move.w  d7,(EVENTS).w
        rts

.notnew moveq   #EV_ARMED|EV_APOGEE,d1
        and.w   d7,d1
        subq.w  #EV_ARMED,d1            ; zero only for "ARMED and not APOGEE"
        bne.s   .done
        sub.l   d2,d0                   ; EXT - EST: exact as an UNSIGNED long, since 0 <= EXT - EST < 2^32 here
        cmpi.l  #THR,d0
        bcs.s   .done                   ; unsigned below the threshold
        ori.w   #EV_APOGEE,d7
.done   move.w  d7,(EVENTS).w
        rts

*****************************************************************************************************************
* RAM variables
*****************************************************************************************************************
        section bss
        org     RAM_START               ; variables from the bottom of RAM
EST:    ds.l    1                       ; Q24.8 filtered altitude (barometer counts x BARO_SIGN)
EXT:    ds.l    1                       ; Q24.8 extreme (maximum) of EST so far
VEL:    ds.l    1                       ; velocity, accel counts x samples
ACC0:   ds.l    1                       ; pad accelerometer reading (1 g)
EVENTS: ds.w    1                       ; event bits (fwemu.inc EV_*)
