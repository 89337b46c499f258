/*
 * fw.c -- portable C99 port of the fwemu rocket apogee filters (see fw.h and docs/firmware-spec.md).
 */
#include "fw.h"

int32_t fw_wrap32(int64_t x)
{
    /* Conversion to uint32_t is defined (reduction modulo 2^32); convert back without implementation-defined
       behaviour by splitting on the sign bit. */
    uint32_t w = (uint32_t)x;
    if (w & UINT32_C(0x80000000)) {
        return -(int32_t)(~w) - 1; /* ~w <= 0x7FFFFFFF */
    }
    return (int32_t)w;
}

static int64_t floor_shift(int64_t x, int32_t s)
{
    /* floor(x / 2^s) without right-shifting a negative value: for x < 0, ~x = -x - 1 >= 0 and
       floor(x / 2^s) = ~(floor(~x / 2^s)). */
    if (s <= 0) {
        return x;
    }
    if (x >= 0) {
        return x >> s;
    }
    return ~((~x) >> s);
}

int64_t fw_rs(int64_t x, int32_t s, int32_t mode)
{
    if (s <= 0) {
        return x;
    }
    if (mode) {
        return floor_shift(x + ((int64_t)1 << (s - 1)), s);
    }
    return floor_shift(x, s);
}

int32_t fw_mulg(int64_t e, fw_gain g, int32_t mode)
{
    return fw_wrap32(fw_rs(e * (int64_t)g.m, g.s, mode));
}

/* x << s for s >= 0 as an exact multiplication (never shifts a negative value). */
static int64_t ls(int64_t x, int32_t s)
{
    return x * ((int64_t)1 << s);
}

int32_t fw_alt(const fw_consts *c, int32_t adc)
{
    /* docs/firmware-spec.md 2a: ALT[i] + rs((ALT[i+1] - ALT[i]) * f, ALT_SHIFT, mode), product exact in int64;
       called for a valid word only (0 <= adc <= BARO_MAX < 2^17) */
    int32_t s = c->ALT_SHIFT;
    int32_t i = (int32_t)((uint32_t)adc >> s);
    int64_t f = (int64_t)((uint32_t)adc & ((UINT32_C(1) << s) - 1u));
    int64_t lo = FW_ALT_READ(&c->ALT[i]);
    int64_t hi = FW_ALT_READ(&c->ALT[i + 1]);
    return fw_wrap32(lo + fw_rs((hi - lo) * f, s, c->ROUND));
}

static int baro_valid(const fw_consts *c, int32_t adc)
{
    return adc >= c->BARO_MIN && adc <= c->BARO_MAX;
}

static int64_t baro_z(const fw_consts *c, int32_t adc)
{
    /* int64: the pascal kind's word may be -2^31, whose negation does not fit int32 (a negation, not a 64-bit
       multiplication, which costs an 8-bit MCU ~150 cycles) */
    return c->BARO_SIGN < 0 ? -(int64_t)adc : (int64_t)adc;
}

void fw_init(fw_program prog, const fw_consts *c, fw_state *st, int32_t adc, int16_t acc)
{
    int32_t z8 = fw_wrap32(ls(baro_z(c, adc), 8));
    st->EST = st->EXT = st->VEL = 0;
    st->ZL = 0;
    st->X1 = st->X2 = st->X3 = 0;
    st->ACC0 = 0;
    st->EVENTS = 0;
    st->APFRAC = 0;
    st->GND = st->SUMZ = st->SUMA = 0;
    st->CAL = st->REJ = st->NEG = 0;
    st->PHASE = FW_PH_PAD;
    st->CST = st->DLY = st->LOCK = 0;
    st->VB = 0;
    st->CLP = 0;
    st->E0 = 0;
    st->HMAX = 0;
    st->HT = 0;
    st->HP = 0;
    switch (prog) {
    case FW_RECURSIVE:
        st->EST = z8;
        st->EXT = z8;
        st->VEL = 0;
        st->ACC0 = acc;
        st->ZL = fw_wrap32(baro_z(c, adc));
        break;
    case FW_RECURSIVE_SEED_LITERAL:
        st->EST = z8;
        break;
    case FW_KALMAN_ACCEL:
        st->ACC0 = acc;
        /* fall through */
    case FW_KALMAN_BARO:
        st->X1 = baro_valid(c, adc) ? fw_alt(c, adc) : 0;
        st->GND = st->X1;
        st->HMAX = st->X1;
        st->HP = st->X1;
        break;
    }
}

/* ACC_CLIP and not CLIP_CLEAR: after an accelerometer clip, before the speed is known again (spec sections 5, 6:
   no apogee evidence, no prediction; kalman_accel keeps the barometer out) */
#define FW_CLIPPED(events) (((events) & (FW_EV_ACC_CLIP | FW_EV_CLIP_CLEAR)) == FW_EV_ACC_CLIP)

/* spec sections 5 step 3 and 6 step 7 (the accelerometer programs): in boost and before ACC_CLIP, CLP counts
   consecutive samples at the accelerometer's rail (32767); the CLIP_N-th sets ACC_CLIP and CLP = 0. A macro on
   the state's fields (st->CLP, st->EVENTS), so a port that keeps other types for them still compiles it. */
#define RAIL_COUNT(st, acc, clip_n)                                        \
    do {                                                                   \
        if ((st)->PHASE == FW_PH_BOOST && !((st)->EVENTS & FW_EV_ACC_CLIP)) { \
            if ((acc) == 32767) {                                          \
                (st)->CLP = (uint16_t)((st)->CLP + 1u);                    \
                if ((int32_t)(st)->CLP >= (clip_n)) {                      \
                    (st)->EVENTS |= FW_EV_ACC_CLIP;                        \
                    (st)->CLP = 0;                                         \
                }                                                          \
            } else {                                                       \
                (st)->CLP = 0;                                             \
            }                                                              \
        }                                                                  \
    } while (0)

static void step_recursive(const fw_consts *c, fw_state *st, int32_t adc, int16_t acc)
{
    int64_t z = baro_z(c, adc);
    int32_t zw = fw_wrap32(z);
    int32_t d;
    int use = 1;
    st->EVENTS &= (uint16_t)~FW_EV_PER_SAMPLE;
    if ((int32_t)st->CAL < (1 << c->CAL_P)) {
        /* 1. pad calibration of ACC0 (|SUMA| <= 2^23: exact); steps 2-4 skipped */
        st->SUMA = (int32_t)((int64_t)st->SUMA + acc);
        st->CAL = (uint16_t)(st->CAL + 1u);
        if ((int32_t)st->CAL == (1 << c->CAL_P)) {
            st->ACC0 = (int32_t)fw_rs(st->SUMA, c->CAL_P, c->ROUND);
        }
    } else {
        /* 2. velocity: running sum of (acc - ACC0); liftoff */
        st->VEL = fw_wrap32((int64_t)st->VEL + ((int64_t)acc - (int64_t)st->ACC0));
        if (!(st->EVENTS & FW_EV_LIFTOFF) && st->VEL > c->V_LIFT) {
            st->EVENTS |= FW_EV_LIFTOFF;
            st->PHASE = FW_PH_BOOST;
        }
        /* phases: coast after COAST_N samples with acc - ACC0 < -A_COAST; descent after apogee */
        if (st->PHASE == FW_PH_BOOST) {
            if ((int64_t)acc - (int64_t)st->ACC0 < -(int64_t)c->A_COAST) {
                st->CST = (uint16_t)(st->CST + 1u);
                if ((int32_t)st->CST >= c->COAST_N) {
                    st->PHASE = FW_PH_COAST;
                }
            } else {
                st->CST = 0;
            }
        } else if (st->PHASE == FW_PH_COAST && FW_CLIPPED(st->EVENTS)) {
            /* after a clip: CLIP_CLEAR once the drag reading acc - ACC0 >= -A_DRAG for 2^K coast samples in a row */
            if ((int64_t)acc - (int64_t)st->ACC0 >= -(int64_t)c->A_DRAG) {
                st->CLP = (uint16_t)(st->CLP + 1u);
                if ((int32_t)st->CLP >= ((int32_t)1 << c->K)) {
                    st->EVENTS |= FW_EV_CLIP_CLEAR;
                }
            } else {
                st->CLP = 0;
            }
        } else if (st->PHASE == FW_PH_APOGEE && (int64_t)st->VEL < -(int64_t)c->V_DESC) {
            st->PHASE = FW_PH_DESCENT;
        }
        /* 3. the accelerometer at its rail (32767) for CLIP_N samples in a row in boost: VEL underestimates from
              now on */
        RAIL_COUNT(st, acc, c->CLIP_N);
        /* 4. velocity gate: a. armed when VEL is back below the gate (GATE_HIGH from an earlier sample);
              b. GATE_HIGH once VEL exceeds the gate after liftoff */
        if ((st->EVENTS & FW_EV_GATE_HIGH) && !(st->EVENTS & FW_EV_ARMED) && st->VEL < c->V_GATE) {
            st->EVENTS |= FW_EV_ARMED;
        }
        if ((st->EVENTS & FW_EV_LIFTOFF) && st->VEL > c->V_GATE) {
            st->EVENTS |= FW_EV_GATE_HIGH;
        }
    }
    /* 5. barometer rate gate; EST += (z << (8 - S)) - rs(EST, S) for a used sample */
    d = fw_wrap32((int64_t)zw - (int64_t)st->ZL); /* SUB.L */
    if (d >= -(int64_t)c->E_GATE && d <= (int64_t)c->E_GATE) {
        st->REJ = 0;
    } else if ((int32_t)st->REJ < c->GATE_N) {
        st->REJ = (uint16_t)(st->REJ + 1u);
        st->EVENTS |= FW_EV_BARO_REJECT;
        use = 0;
    } else {
        /* the gate opens on a lasting shift: EST and EXT move with it (re-base) */
        st->EST = fw_wrap32((int64_t)st->EST + ls(d, 8));
        st->EXT = fw_wrap32((int64_t)st->EXT + ls(d, 8));
    }
    if (use) {
        st->ZL = zw;
        st->EST = fw_wrap32((int64_t)st->EST + ls(z, 8 - c->S) - fw_rs(st->EST, c->S, c->ROUND));
    }
    /* 6. extreme and apogee (after ACC_CLIP: no evidence until CLIP_CLEAR, then APO_N samples of it) */
    if (st->EST > st->EXT) {
        st->EXT = st->EST;
        st->NEG = 0;
    } else if ((st->EVENTS & FW_EV_ARMED) && !(st->EVENTS & FW_EV_APOGEE)) {
        if ((int64_t)st->EXT - (int64_t)st->EST >= (int64_t)c->THR && !FW_CLIPPED(st->EVENTS)) {
            int32_t need = (st->EVENTS & FW_EV_ACC_CLIP) ? c->APO_N : 1;
            st->NEG = (uint16_t)(st->NEG + 1u);
            if ((int32_t)st->NEG >= need) {
                st->EVENTS |= FW_EV_APOGEE;
                st->PHASE = FW_PH_APOGEE;
            }
        } else {
            st->NEG = 0;
        }
    }
}

static void step_seed_literal(const fw_consts *c, fw_state *st, int32_t adc)
{
    int64_t z = baro_z(c, adc);
    /* Schultz 2002's listing, subtraction backwards: EST += rs(EST, S) - (z << (8 - S)) */
    st->EST = fw_wrap32((int64_t)st->EST + fw_rs(st->EST, c->S, c->ROUND) - ls(z, 8 - c->S));
}

static void step_kalman(const fw_consts *c, fw_state *st, int32_t adc, int16_t acc, int with_accel)
{
    const int32_t mode = c->ROUND;
    const int32_t K = c->K;
    const int32_t ncal = (int32_t)1 << c->CAL_P;
    int64_t t1, t2;
    int32_t h = 0, e1 = 0, e2 = 0, a = 0;
    int baro_ok, steady = 0, use, locked = 0, rebase = 0;
    int64_t c1_1 = 0, c1_2 = 0, c1_3 = 0, c2_1 = 0, c2_2 = 0, c2_3 = 0;

    /* 0. per-sample bits, barometer range, h = alt(adc) for a valid sample */
    st->EVENTS &= (uint16_t)~FW_EV_PER_SAMPLE;
    baro_ok = baro_valid(c, adc);
    if (!baro_ok) {
        st->EVENTS |= FW_EV_BARO_INVALID;
    } else {
        h = fw_alt(c, adc);
    }
    /* 1. pad calibration */
    if ((int32_t)st->CAL < ncal) {
        if (baro_ok) {
            st->SUMZ = fw_wrap32((int64_t)st->SUMZ + h);
            if (with_accel) {
                st->SUMA = fw_wrap32((int64_t)st->SUMA + acc);
            }
            st->CAL = (uint16_t)(st->CAL + 1u);
            if ((int32_t)st->CAL == ncal) {
                st->GND = fw_wrap32(fw_rs(st->SUMZ, c->CAL_P, mode));
                st->X1 = st->GND;
                st->HMAX = st->GND;
                if (with_accel) {
                    st->ACC0 = fw_wrap32(fw_rs(st->SUMA, c->CAL_P, mode));
                }
            }
        }
        return;
    }
    /* 2. predict */
    t1 = fw_rs(st->X2, K, mode) + fw_rs(st->X3, 2 * K + 1, mode);
    t2 = fw_rs(st->X3, K, mode);
    st->X1 = fw_wrap32((int64_t)st->X1 + t1);
    st->X2 = fw_wrap32((int64_t)st->X2 + t2);
    /* 3. accelerometer innovation (kalman_accel) */
    if (with_accel) {
        a = fw_mulg((int64_t)acc - (int64_t)st->ACC0, c->ACC_G, mode);
        e2 = fw_wrap32((int64_t)a - (int64_t)st->X3);
        c2_1 = fw_mulg(e2, c->G12, mode);
        c2_2 = fw_mulg(e2, c->G22, mode);
        c2_3 = fw_mulg(e2, c->G32, mode);
    }
    /* 4. Mach lockout (kalman_accel): after ACC_CLIP no barometer until a 2^(K+1)-sample drag-low coast window
          re-bases X2 from the innovation drift (second half minus first half, over 1 s); else no barometer while
          X2 > MACH_VLO and MACH_N samples after; then re-base. Only a steady sample (within H_STEP of the previous
          valid one: |h|, |HP| <= 2^30, so the difference is exact) counts for the window or re-bases. */
    if (with_accel) {
        const int64_t dh = (int64_t)h - (int64_t)st->HP;
        steady = baro_ok && dh >= -(int64_t)c->H_STEP && dh <= (int64_t)c->H_STEP;
        if (FW_CLIPPED(st->EVENTS)) {
            locked = 1;
            st->LOCK = (uint16_t)c->MACH_N;
            if (st->PHASE == FW_PH_COAST && (int64_t)a >= -(int64_t)c->A_DRAG && steady) {
                int64_t e = fw_wrap32((int64_t)h - (int64_t)st->X1); /* X1 predicted */
                st->CLP = (uint16_t)(st->CLP + 1u);
                if ((int32_t)st->CLP <= ((int32_t)1 << K)) {
                    st->E0 = fw_wrap32((int64_t)st->E0 - e);
                } else {
                    st->E0 = fw_wrap32((int64_t)st->E0 + e);
                }
                if ((int32_t)st->CLP == ((int32_t)2 << K)) {
                    st->X2 = fw_wrap32((int64_t)st->X2 + fw_rs(st->E0, K, mode));
                    st->VB = st->X2;
                    st->LOCK = 0;
                    st->EVENTS |= FW_EV_CLIP_CLEAR;
                    locked = 0;
                    rebase = 1;
                }
            } else {
                st->CLP = 0;
                st->E0 = 0;
            }
        } else if (((st->EVENTS & FW_EV_LIFTOFF) && st->X2 > c->MACH_VLO)
                   || ((c->GUARDS & 1) && (st->PHASE == FW_PH_BOOST
                                           || (st->PHASE == FW_PH_PAD && (int64_t)a > (int64_t)c->A_COAST)))) {
            /* above the Mach threshold, or (thrust guard) BOOST, or the pad with a thrust reading: no barometer */
            st->LOCK = (uint16_t)c->MACH_N;
            locked = 1;
        } else if (st->LOCK > 1u) {
            st->LOCK = (uint16_t)(st->LOCK - 1u);
            locked = 1;
        } else if (st->LOCK == 1u) {
            if (steady) {
                st->LOCK = 0;
                rebase = 1;
            } else {
                locked = 1;
            }
        }
        if (locked) {
            st->EVENTS |= FW_EV_MACH_LOCKOUT;
        }
    }
    /* 5. innovation and gate (a re-base takes X1 = h and no barometer correction) */
    use = 0;
    if (baro_ok && !locked) {
        if (rebase) {
            st->X1 = h;
            st->REJ = 0;
        } else {
            e1 = fw_wrap32((int64_t)h - (int64_t)st->X1);
            if ((int64_t)e1 >= -(int64_t)c->E_GATE && (int64_t)e1 <= (int64_t)c->E_GATE) {
                st->REJ = 0;
                use = 1;
            } else if ((int32_t)st->REJ < c->GATE_N) {
                st->REJ = (uint16_t)(st->REJ + 1u);
                st->EVENTS |= FW_EV_BARO_REJECT;
            } else {
                use = 1;
            }
        }
    }
    /* 6. correct (locked out: X1, X2 only predicted, X3 = a, the accelerometer alone) */
    if (locked) {
        st->X3 = fw_wrap32((int64_t)st->X3 + e2);
    } else {
        if (use) {
            c1_1 = fw_mulg(e1, c->G11, mode);
            c1_2 = fw_mulg(e1, c->G21, mode);
            c1_3 = fw_mulg(e1, c->G31, mode);
        }
        st->X1 = fw_wrap32((int64_t)st->X1 + c1_1 + c2_1);
        st->X2 = fw_wrap32((int64_t)st->X2 + c1_2 + c2_2);
        st->X3 = fw_wrap32((int64_t)st->X3 + c1_3 + c2_3);
    }
    /* 7. liftoff and Mach delay */
    if (st->EVENTS & FW_EV_LIFTOFF) {
        if (st->DLY > 0u) {
            st->DLY = (uint16_t)(st->DLY - 1u);
        }
    } else if (st->X2 > c->V_LIFT) {
        st->EVENTS |= FW_EV_LIFTOFF;
        st->PHASE = FW_PH_BOOST;
        st->DLY = (uint16_t)c->DLY_N;
    }
    /* 7b. kalman_accel: the accelerometer at its rail (32767) for CLIP_N samples in a row in boost */
    if (with_accel) {
        RAIL_COUNT(st, acc, c->CLIP_N);
    }
    /* 8. plausibility bound VB = min(max(X2, VB - DV), VB + DU), exact in int64 (the result is an int32) */
    {
        /* gravity guard: at or below zero VB falls by DG (g dt) only */
        int64_t vb = (int64_t)st->VB - (int64_t)(((c->GUARDS & 2) && st->VB <= 0) ? c->DG : c->DV);
        int64_t up = (int64_t)st->VB + (int64_t)c->DU;
        if (vb < (int64_t)st->X2) {
            vb = st->X2;
        }
        if (vb > up) {
            vb = up;
        }
        st->VB = (int32_t)vb;
    }
    /* 8b. descent record: the highest valid barometric altitude, and how many valid samples it is old */
    if (baro_ok) {
        if (h > st->HMAX) {
            st->HMAX = h;
            st->HT = 0;
        } else if ((int32_t)st->HT < c->DESC_N) {
            st->HT = (uint16_t)(st->HT + 1u);
        }
        if (with_accel) {
            st->HP = h;
        }
    }
    /* 9. phases and apogee */
    if (st->PHASE == FW_PH_BOOST) {
        if ((int64_t)st->X3 < -(int64_t)c->A_COAST) {
            st->CST = (uint16_t)(st->CST + 1u);
            if ((int32_t)st->CST >= c->COAST_N) {
                st->PHASE = FW_PH_COAST;
            }
        } else if (st->CST > 0u) {
            st->CST = (uint16_t)(st->CST - 1u);   /* issue 30: a sample at or above -A_COAST takes one back */
        }
    }
    if (st->PHASE == FW_PH_COAST) {
        /* gravity guard: X2 - VB >= -V_FALL; floor guard: X1 and (valid) h >= GND + H_FLOOR (exact in int64) */
        const int64_t fl = (int64_t)st->GND + (int64_t)c->H_FLOOR;
        const int phys = !(c->GUARDS & 2) || (int64_t)st->X2 - (int64_t)st->VB >= -(int64_t)c->V_FALL;
        const int high = !(c->GUARDS & 4) || ((int64_t)st->X1 >= fl && (!baro_ok || (int64_t)h >= fl));
        /* descent guard: the barometer reads below its highest, or that reading is DESC_N samples old */
        const int down = !(c->GUARDS & 8) || !baro_ok || h < st->HMAX || (int32_t)st->HT >= c->DESC_N;
        if (st->DLY == 0u && st->VB < 0 && !FW_CLIPPED(st->EVENTS) && phys && high) {
            if (down) {   /* the descent guard pauses the count, it does not restart it */
                st->NEG = (uint16_t)(st->NEG + 1u);
                if ((int32_t)st->NEG >= c->APO_N) {
                    st->EVENTS |= FW_EV_APOGEE;
                    st->PHASE = FW_PH_APOGEE;
                }
            }
        } else {
            st->NEG = 0;
        }
    } else if (st->PHASE == FW_PH_APOGEE && (int64_t)st->X2 < -(int64_t)c->V_DESC) {
        st->PHASE = FW_PH_DESCENT;
    }
    /* 10. low-rate apogee prediction (in coast) */
    if (st->PHASE == FW_PH_COAST && !(st->EVENTS & FW_EV_APOGEE_PREDICTED) && st->X2 > 0
        && !FW_CLIPPED(st->EVENTS)) {
        int64_t d = -fw_rs(st->X3, K, mode);
        if ((int64_t)st->X2 < d) {
            int64_t v = st->X2; /* 0 < v < d */
            int64_t q;
            st->EVENTS |= FW_EV_APOGEE_PREDICTED;
            while (d >= 32768) {
                d >>= 1; /* both positive: plain shifts are floor */
                v >>= 1;
            }
            q = (v * 65536) / d;
            st->APFRAC = (uint16_t)(q > 65535 ? 65535 : q);
        }
    }
}

void fw_step(fw_program prog, const fw_consts *c, fw_state *st, int32_t adc, int16_t acc)
{
    switch (prog) {
    case FW_RECURSIVE:
        step_recursive(c, st, adc, acc);
        break;
    case FW_RECURSIVE_SEED_LITERAL:
        step_seed_literal(c, st, adc);
        break;
    case FW_KALMAN_BARO:
        step_kalman(c, st, adc, acc, 0);
        break;
    case FW_KALMAN_ACCEL:
        step_kalman(c, st, adc, acc, 1);
        break;
    }
}

int fw_words(fw_program prog, const fw_state *st, int32_t out[FW_MAX_WORDS])
{
    switch (prog) {
    case FW_RECURSIVE:
        out[0] = st->EST; out[1] = st->EXT; out[2] = st->VEL; out[3] = st->ACC0; out[4] = st->EVENTS;
        out[5] = st->ZL; out[6] = st->SUMA; out[7] = st->CAL; out[8] = st->REJ; out[9] = st->NEG;
        out[10] = st->PHASE; out[11] = st->CST; out[12] = st->CLP;
        return 13;
    case FW_RECURSIVE_SEED_LITERAL:
        out[0] = st->EST;
        return 1;
    case FW_KALMAN_BARO:
        out[0] = st->X1; out[1] = st->X2; out[2] = st->X3; out[3] = st->EVENTS; out[4] = st->APFRAC;
        out[5] = st->GND; out[6] = st->SUMZ; out[7] = st->CAL; out[8] = st->REJ; out[9] = st->NEG;
        out[10] = st->PHASE; out[11] = st->CST; out[12] = st->DLY; out[13] = st->VB; out[14] = st->HMAX;
        out[15] = st->HT;
        return 16;
    case FW_KALMAN_ACCEL:
        out[0] = st->X1; out[1] = st->X2; out[2] = st->X3; out[3] = st->ACC0; out[4] = st->EVENTS;
        out[5] = st->APFRAC; out[6] = st->GND; out[7] = st->SUMZ; out[8] = st->SUMA; out[9] = st->CAL;
        out[10] = st->REJ; out[11] = st->NEG; out[12] = st->PHASE; out[13] = st->CST; out[14] = st->DLY;
        out[15] = st->VB; out[16] = st->LOCK; out[17] = st->CLP; out[18] = st->E0; out[19] = st->HMAX;
        out[20] = st->HT; out[21] = st->HP;
        return 22;
    }
    return 0;
}

const char *fw_word_name(fw_program prog, int i)
{
    static const char *const rec[] = {"EST", "EXT", "VEL", "ACC0", "EVENTS", "ZL", "SUMA", "CAL", "REJ", "NEG",
                                      "PHASE", "CST", "CLP"};
    static const char *const lit[] = {"EST"};
    static const char *const kb[] = {"X1", "X2", "X3", "EVENTS", "APFRAC", "GND", "SUMZ", "CAL", "REJ", "NEG",
                                     "PHASE", "CST", "DLY", "VB", "HMAX", "HT"};
    static const char *const ka[] = {"X1", "X2", "X3", "ACC0", "EVENTS", "APFRAC", "GND", "SUMZ", "SUMA", "CAL",
                                     "REJ", "NEG", "PHASE", "CST", "DLY", "VB", "LOCK", "CLP", "E0", "HMAX",
                                     "HT", "HP"};
    switch (prog) {
    case FW_RECURSIVE:
        return (i >= 0 && i < 13) ? rec[i] : "?";
    case FW_RECURSIVE_SEED_LITERAL:
        return (i == 0) ? lit[0] : "?";
    case FW_KALMAN_BARO:
        return (i >= 0 && i < 16) ? kb[i] : "?";
    case FW_KALMAN_ACCEL:
        return (i >= 0 && i < 22) ? ka[i] : "?";
    }
    return "?";
}
