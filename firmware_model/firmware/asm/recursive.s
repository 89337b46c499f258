*****************************************************************************************************************
* recursive.s -- D. Schultz's shift-and-add recursive altitude filter with barometric apogee detection behind an
* accelerometer velocity gate (Schultz 2002, "Filtering the Data" and "Algorithm Testing").
*
*   EST += (z << (8-S)) - rs(EST, S)          EST is Q24.8; weight 2^-S
*   VEL += acc - ACC0                          velocity in accel counts x samples (ACC0 = pad reading = 1 g)
*   LIFTOFF when VEL > V_LIFT; GATE_HIGH when (after liftoff) VEL > V_GATE; ARMED when, on a later sample,
*   VEL has come back below V_GATE ("Velocity Gate Off": apogee detection enabled once the accelerometer velocity
*   is below ~200 ft/s after burnout); EXT follows the maximum of EST; APOGEE when armed and EXT - EST >= THR.
*   A flight whose VEL never exceeds V_GATE is never armed: this program then never declares apogee.
*
* Field-ready logic (spec section 5): ACC0 averaged over 2^CAL_P pad samples; a barometer rate gate (a sample
* more than E_GATE counts from the last used one is not used, for up to GATE_N samples: BARO_REJECT; then EST
* and EXT are re-based by the shift and it is used); ACC_CLIP
* latched when the accelerometer reads its rail (32767) for CLIP_N consecutive samples in BOOST (CLP counts them),
* after which no apogee evidence counts until CLIP_CLEAR (the drag reading acc - ACC0 >= -A_DRAG for 2^K
* consecutive samples in COAST, CLP again) and APOGEE then needs APO_N samples.
*
* Contract: docs/firmware-spec.md section 5.  Constants (S, THR, V_LIFT, V_GATE, ROUND, BARO_SIGN, CAL_P, E_GATE,
* GATE_N, APO_N, K, A_COAST, COAST_N, V_DESC, A_DRAG, CLIP_N) come from the build.  Entry points: init, step (JSR/RTS).  Uses D0-D7; no stack beyond the
* return address.
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
* init -- EST = EXT = z << 8; VEL = 0; ACC0 = acc; EVENTS = 0; ZL = z; SUMA = 0; CAL = REJ = NEG = 0;
* PHASE = PAD; CST = CLP = 0.
*****************************************************************************************************************
init    READZS  d0,0                    ; z
        move.l  d0,(ZL).w
        lsl.l   #8,d0                   ; z << 8
        move.l  d0,(EST).w
        move.l  d0,(EXT).w
        clr.l   (VEL).w
        move.w  (ACCEL_ADC).w,d0
        ext.l   d0
        move.l  d0,(ACC0).w             ; pad reading until the calibration replaces it
        clr.w   (EVENTS).w
        clr.l   (SUMA).w
        clr.w   (CAL).w
        clr.w   (REJ).w
        clr.w   (NEG).w
        clr.w   (PHASE).w               ; PH_PAD
        clr.w   (CST).w
        clr.w   (CLP).w
        rts

*****************************************************************************************************************
* step -- one sample.  Register use: d1 = VEL, d2 = EST, d6 = acc, d7 = EVENTS, d4 = 0 (rounding), d0/d3/d5
* scratch.
*****************************************************************************************************************
*---- 0. per-sample bits cleared ----------------------------------------------------------------------------------
step    move.w  (EVENTS).w,d7
        andi.w  #EV_LATCHED,d7
        moveq   #0,d4                   ; zero for the rounding ADDX
        move.w  (ACCEL_ADC).w,d6
        ext.l   d6                      ; d6 = acc

*---- 1. pad calibration while CAL < 2^CAL_P: SUMA += acc; ACC0 = rs(SUMA, CAL_P) on the last one ---------------
        move.w  (CAL).w,d0
        cmpi.w  #1<<CAL_P,d0
        bcc.s   .run                    ; calibrated
        add.l   d6,(SUMA).w             ; |SUMA| <= 2^23: exact
        addq.w  #1,d0
        move.w  d0,(CAL).w
        cmpi.w  #1<<CAL_P,d0
        bne     .baro
        move.l  (SUMA).w,d1
        RSHIFT  d1,CAL_P,d5,d4          ; ACC0 = rs(SUMA, CAL_P)
        move.l  d1,(ACC0).w
        bra     .baro                   ; steps 2-4 skipped during calibration

*---- 2. VEL += acc - ACC0 (wraps); liftoff: not LIFTOFF and VEL > V_LIFT -----------------------------------------
.run    move.l  d6,d1
        sub.l   (ACC0).w,d1             ; acc - ACC0 (exact: |ACC0| <= 2^15)
        add.l   (VEL).w,d1
        move.l  d1,(VEL).w
        moveq   #EV_LIFTOFF,d0
        and.w   d7,d0
        bne.s   .phase
        cmpi.l  #V_LIFT,d1
        ble.s   .phase
        ori.w   #EV_LIFTOFF,d7
        move.w  #PH_BOOST,(PHASE).w
*---- phases: BOOST: CST counts acc - ACC0 < -A_COAST, COAST_N -> COAST; COAST after ACC_CLIP, not CLIP_CLEAR: CLP
*     counts acc - ACC0 >= -A_DRAG, 2^K -> CLIP_CLEAR; APOGEE and VEL < -V_DESC: DESCENT ------------------------------
*     (step 3 runs only with PHASE == BOOST after this, so only the BOOST branch that stays in BOOST falls into it)
.phase  move.w  (PHASE).w,d0
        cmpi.w  #PH_BOOST,d0
        bne.s   .coast
        move.l  d6,d3
        sub.l   (ACC0).w,d3             ; acc - ACC0 (exact)
        cmpi.l  #-A_COAST,d3
        bge.s   .cst0
        move.w  (CST).w,d3
        addq.w  #1,d3
        move.w  d3,(CST).w
        cmpi.w  #COAST_N,d3
        bcs.s   .clip
        move.w  #PH_COAST,(PHASE).w
        bra.s   .gate                   ; PHASE is COAST now: no step 3
.cst0   clr.w   (CST).w
*---- 3. PHASE == BOOST and not ACC_CLIP: CLP counts acc == 32767 (the rail); CLIP_N of them set ACC_CLIP, CLP = 0 ---
.clip   move.w  d7,d0
        andi.w  #EV_ACC_CLIP,d0
        bne.s   .gate
        cmpi.w  #32767,d6
        bne.s   .clpr0                  ; off the rail: the count starts again
        move.w  (CLP).w,d0
        addq.w  #1,d0
        cmpi.w  #CLIP_N,d0
        bcc.s   .clpset
        move.w  d0,(CLP).w
        bra.s   .gate
.clpset ori.w   #EV_ACC_CLIP,d7         ; CLIP_N samples at the rail: set ACC_CLIP, CLP = 0
.clpr0  clr.w   (CLP).w
        bra.s   .gate
*---- (phases, continued: not BOOST)
.coast  cmpi.w  #PH_COAST,d0
        bne.s   .desc
        move.w  d7,d3
        andi.w  #EV_ACC_CLIP|EV_CLIP_CLEAR,d3
        cmpi.w  #EV_ACC_CLIP,d3         ; equal only for "ACC_CLIP and not CLIP_CLEAR"
        bne.s   .gate                   ; (PHASE is COAST: the DESCENT test below cannot fire)
        move.l  d6,d3
        sub.l   (ACC0).w,d3             ; acc - ACC0 (exact)
        cmpi.l  #-A_DRAG,d3
        blt.s   .clp0                   ; drag high: the count starts again
        move.w  (CLP).w,d3
        addq.w  #1,d3
        move.w  d3,(CLP).w
        cmpi.w  #1<<K,d3
        bcs.s   .gate
        ori.w   #EV_CLIP_CLEAR,d7       ; 2^K drag-low samples in coast: the speed is known again
        bra.s   .gate
.clp0   clr.w   (CLP).w
        bra.s   .gate
.desc   cmpi.w  #PH_APOGEE,d0
        bne.s   .gate
        cmpi.l  #-V_DESC,d1
        bge.s   .gate
        move.w  #PH_DESCENT,(PHASE).w
*---- 4a. GATE_HIGH and not ARMED and VEL < V_GATE: set ARMED -------------------------------------------------------
*     (GATE_HIGH as it was before 4b of this sample: the sample that sets GATE_HIGH cannot also set ARMED)
.gate   moveq   #EV_GATE_HIGH|EV_ARMED,d0
        and.w   d7,d0
        cmpi.w  #EV_GATE_HIGH,d0        ; equal only for "GATE_HIGH and not ARMED"
        bne.s   .gateb
        cmpi.l  #V_GATE,d1
        bge.s   .baro                   ; VEL >= V_GATE: 4b could only set GATE_HIGH again
        ori.w   #EV_ARMED,d7
        bra.s   .baro                   ; VEL < V_GATE: 4b cannot fire
*---- 4b. LIFTOFF and VEL > V_GATE: set GATE_HIGH -------------------------------------------------------------------
.gateb  moveq   #EV_LIFTOFF,d0
        and.w   d7,d0
        beq.s   .baro
        cmpi.l  #V_GATE,d1
        ble.s   .baro
        ori.w   #EV_GATE_HIGH,d7

*---- 5. rate gate: d = z - ZL inside [-E_GATE, E_GATE] -> use; else reject for up to GATE_N samples --------------
.baro   READZS  d0,0                    ; z
        move.l  d0,d3
        sub.l   (ZL).w,d3               ; d = z - ZL (32-bit; exact for every ADC word and sane pascal word)
        cmpi.l  #E_GATE,d3
        bgt.s   .out
        cmpi.l  #-E_GATE,d3
        blt.s   .out
        clr.w   (REJ).w                 ; inside the gate
        bra.s   .use
.out    move.w  (REJ).w,d5
        cmpi.w  #GATE_N,d5
        bcc.s   .rebase                 ; closed for GATE_N samples in a row: a lasting shift
        addq.w  #1,d5
        move.w  d5,(REJ).w
        ori.w   #EV_BARO_REJECT,d7
        move.l  (EST).w,d2              ; not used: EST unchanged
        bra.s   .ext
.rebase lsl.l   #8,d3                   ; d << 8 (wraps as the spec's wrap32 sum does)
        add.l   d3,(EST).w              ; re-base: EST and EXT move with the shift (wrap)
        add.l   d3,(EXT).w
*---- EST = EST + (z << (8-S)) - rs(EST, S) -----------------------------------------------------------------------
.use    move.l  d0,(ZL).w
        if      8-S>0
        lsl.l   #8-S,d0                 ; z << (8-S): the ADC lined up with EST's binary point, divided by 2^S
        endif
        move.l  (EST).w,d2
        move.l  d2,d3
        RSHIFT  d3,S,d1,d4              ; rs(EST, S)   (S <= 8: never uses the count register d1)
        sub.l   d3,d2                   ; EST - EST/2^S
        add.l   d0,d2                   ;   + ADC/2^S   (the Schultz 2002 listing has it backwards)
        move.l  d2,(EST).w

*---- 6. extreme and apogee (no evidence while ACC_CLIP and not CLIP_CLEAR; N = APO_N after ACC_CLIP, else 1) -----
.ext    move.l  (EXT).w,d0
        cmp.l   d0,d2
        ble.s   .notnew
        move.l  d2,(EXT).w              ; new extreme
        clr.w   (NEG).w
        move.w  d7,(EVENTS).w
        rts

.notnew moveq   #EV_ARMED|EV_APOGEE,d1
        and.w   d7,d1
        subq.w  #EV_ARMED,d1            ; zero only for "ARMED and not APOGEE"
        bne.s   .done
        sub.l   d2,d0                   ; EXT - EST: exact as an UNSIGNED long, since 0 <= EXT - EST < 2^32 here
        cmpi.l  #THR,d0
        bcs.s   .reset                  ; unsigned below the threshold: no evidence
        move.w  d7,d3
        andi.w  #EV_ACC_CLIP|EV_CLIP_CLEAR,d3
        cmpi.w  #EV_ACC_CLIP,d3
        beq.s   .reset                  ; clipped, the speed not known again yet: no evidence
        move.w  (NEG).w,d1
        addq.w  #1,d1                   ; NEG < APO_N <= 32767 here: no overflow
        move.w  d1,(NEG).w
        moveq   #1,d0                   ; N = 1 ...
        andi.w  #EV_ACC_CLIP,d3
        beq.s   .cmpn
        move.w  #APO_N,d0               ; ... or APO_N after a clip
.cmpn   cmp.w   d0,d1
        bcs.s   .done                   ; NEG < N
        ori.w   #EV_APOGEE,d7
        move.w  #PH_APOGEE,(PHASE).w
        bra.s   .done
.reset  clr.w   (NEG).w
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
ACC0:   ds.l    1                       ; pad accelerometer reading (1 g), averaged over 2^CAL_P samples
EVENTS: ds.w    1                       ; event bits (fwemu.inc EV_*)
ZL:     ds.l    1                       ; the last barometer sample z the filter used (rate gate)
SUMA:   ds.l    1                       ; sum of pad accelerometer readings
CAL:    ds.w    1                       ; pad samples summed so far
REJ:    ds.w    1                       ; consecutive rejected barometer samples
NEG:    ds.w    1                       ; consecutive armed samples with EXT - EST >= THR
PHASE:  ds.w    1                       ; flight phase PH_* (fwemu.inc; reported, not used by the apogee logic)
CST:    ds.w    1                       ; consecutive BOOST samples with acc - ACC0 < -A_COAST
CLP:    ds.w    1                       ; clip counter: rail samples in BOOST (0..CLIP_N), then after ACC_CLIP
*                                         drag-low samples in COAST (0..2^K)
