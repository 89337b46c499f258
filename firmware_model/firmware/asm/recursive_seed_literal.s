*****************************************************************************************************************
* recursive_seed_literal.s -- seed 000's pseudo-listing of the recursive filter, transcribed as written:
*
*       move.l ESTALT,D0 ; shr.l #5,D0 ; move.l ADCCNT,D1 ; shl.l #3,D1 ; sub.l D1,D0 ; add.l D0,ESTALT
*
* i.e. EST += rs(EST, S) - (z << (8-S)), with the subtraction backwards (the correct filter subtracts EST/2^S and
* adds the sample).  Kept to show that it diverges (docs/firmware-spec.md section 5).  Differences from the seed
* that the spec requires: the shift of EST is the spec's rounding shift rs (ASR, plus ADDX for half_up) rather than
* the seed's logical SHR, and the sample is z = BARO_SIGN * adc.  No flight logic.
*****************************************************************************************************************
        include "fwemu.inc"

        section code
vectors dc.l    STACK_TOP
        dc.l    reset

reset   lea     STACK_TOP,sp
        jsr     init
.loop   jsr     step
        bra.s   .loop

* init -- EST = z << 8
init    READZS  d0,8
        move.l  d0,(EST).w
        rts

* step -- EST += rs(EST, S) - (z << (8-S))   (sic)
step    move.l  (EST).w,d0              ; get a copy of the old altitude estimate
        moveq   #0,d2
        RSHIFT  d0,S,d3,d2              ; divide it by 2^S
        READZS  d1,8-S                  ; the new ADC count, lined up with the binary point
        sub.l   d1,d0                   ; subtract ADCCNT from ESTALT (backwards)
        add.l   d0,(EST).w              ; update altitude estimate
        rts

        section bss
        org     RAM_START               ; variables from the bottom of RAM
EST:    ds.l    1                       ; Q24.8 "filtered" altitude
