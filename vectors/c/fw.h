/*
 * fw.h -- portable C99 port of the fwemu rocket apogee filters.
 *
 * Written from docs/firmware-spec.md (the integer contract), independently of the Python model and of the 68000
 * assembly.  Every state word is a signed 32-bit two's complement integer in Q24.8 unless noted; the event and
 * apogee-fraction words are unsigned 16-bit.  No implementation-defined or undefined behaviour is relied upon:
 *   - right shifts of negative values go through fw_rs() (floor or half-up, exact, on int64_t);
 *   - left shifts are multiplications by a power of two on int64_t (never shift a negative value);
 *   - every store to a 32-bit state word is fw_wrap32() of an exact int64_t sum (wrap via uint32_t).
 * Constants come in an fw_consts struct filled from a golden-vector header (FWV_<CASE>_<NAME> macros).
 */
#ifndef FW_H
#define FW_H

#include <stdint.h>

/* Programs (docs/firmware-spec.md sections 5 and 6). */
typedef enum {
    FW_RECURSIVE = 0,
    FW_KALMAN_BARO = 1,
    FW_KALMAN_ACCEL = 2,
    FW_RECURSIVE_SEED_LITERAL = 3
} fw_program;

/* Event bits of the EVENTS word (docs/firmware-spec.md section 4). */
#define FW_EV_LIFTOFF          0x0001u /* latched */
#define FW_EV_ARMED            0x0002u /* latched (recursive: VEL back below V_GATE after GATE_HIGH) */
#define FW_EV_APOGEE           0x0004u /* latched */
#define FW_EV_MACH_LOCKOUT     0x0008u /* this sample only */
#define FW_EV_BARO_INVALID     0x0010u /* this sample only */
#define FW_EV_APOGEE_PREDICTED 0x0020u /* latched */
#define FW_EV_GATE_HIGH        0x0040u /* latched (recursive: VEL has exceeded V_GATE since liftoff) */
#define FW_EV_BARO_REJECT      0x0080u /* this sample only (Kalman: innovation outside the gate, not used) */
#define FW_EV_ACC_CLIP         0x0100u /* latched: the accelerometer read its rail CLIP_N samples in a row in boost */
#define FW_EV_CLIP_CLEAR       0x0200u /* latched: after ACC_CLIP, the drag reading was low long enough in coast
                                          (recursive 2^K samples; kalman_accel 2^(K+1), with the velocity re-base) */
#define FW_EV_PER_SAMPLE       (FW_EV_MACH_LOCKOUT | FW_EV_BARO_INVALID | FW_EV_BARO_REJECT)

/* The altitude table lives in program memory on an AVR (PROGMEM); FW_ALT_READ reads one node. */
#if defined(__AVR__)
#include <avr/pgmspace.h>
#define FW_ALT_READ(p) ((int32_t)pgm_read_dword(p))
#else
#define FW_ALT_READ(p) (*(p))
#endif

/* A quantized gain g = m / 2^s: m signed 16-bit mantissa, 0 <= s <= 47. */
typedef struct {
    int32_t m;
    int32_t s;
} fw_gain;

/* Build constants (docs/firmware-spec.md section 3).  Unused fields of a program may be left 0. */
typedef struct {
    int32_t K;          /* sample period dt = 2^-K s, 0..10 */
    int32_t ROUND;      /* 0 = floor, 1 = half_up (every right shift) */
    int32_t BARO_SIGN;  /* +1 or -1: z = BARO_SIGN * adc (the pascal kind: -1) */
    int32_t S;          /* recursive weight 2^-S, 1..8 */
    int32_t THR;        /* recursive apogee threshold, Q24.8 units */
    int32_t V_LIFT;     /* liftoff velocity: recursive accel counts x samples; Kalman Q24.8 units/s */
    int32_t V_GATE;     /* recursive velocity gate, accel counts x samples */
    fw_gain G11, G21, G31; /* Kalman gains on the barometer innovation */
    fw_gain G12, G22, G32; /* kalman_accel gains on the accelerometer innovation */
    fw_gain ACC_G;         /* accelerometer counts -> Q24.8 m/s^2 */
    fw_gain G11T, G21T, G31T; /* kalman_accel transonic barometer gains */
    int32_t MACH_VLO;   /* kalman_accel: above it (after liftoff) the transonic gains are used, Q24.8 m/s */
    int32_t MACH_VHI;   /* unused since the field-ready change (lockout window of Schultz n.d.) */
    int32_t MACH_E;     /* unused since the field-ready change */
    int32_t BARO_MIN;   /* valid raw range, inclusive: ADC counts, or pascals (the pascal kind) */
    int32_t BARO_MAX;
    int32_t ALT_SHIFT;  /* Kalman: altitude-table segment width 2^ALT_SHIFT counts or Pa (1..15) */
    int32_t ALT_N;      /* number of table nodes */
    int32_t CAL_P;      /* pad calibration over 2^CAL_P valid samples (0..8) */
    int32_t E_GATE;     /* Kalman: innovation gate, Q24.8 m; recursive: barometer rate gate, counts */
    int32_t GATE_N;     /* gated samples in a row after which the gate opens */
    int32_t APO_N;      /* consecutive samples of apogee evidence (Kalman: coast, DLY = 0, VB < 0; recursive: after
                           ACC_CLIP) */
    int32_t MACH_N;     /* kalman_accel: barometer unused MACH_N samples after X2 falls back to MACH_VLO (settling) */
    int32_t DLY_N;      /* Kalman: Mach delay, samples after liftoff without apogee */
    int32_t DV;         /* Kalman: plausibility bound VB falls by at most DV per sample, Q24.8 m/s */
    int32_t A_COAST;    /* coast: acceleration below -A_COAST (Kalman X3, Q24.8 m/s^2; recursive acc - ACC0, counts) */
    int32_t COAST_N;    /* coast: consecutive samples below -A_COAST */
    int32_t V_DESC;     /* descent: after apogee, velocity below -V_DESC (Kalman X2; recursive VEL) */
    int32_t DU;         /* Kalman: the plausibility bound VB rises by at most DU per sample, Q24.8 m/s */
    int32_t A_DRAG;     /* clip clear: drag reading at or above -A_DRAG (recursive acc - ACC0, counts; kalman_accel
                           the accelerometer reading a, Q24.8 m/s^2) */
    int32_t CLIP_N;     /* ACC_CLIP after CLIP_N rail samples (acc = 32767) in a row in boost */
    int32_t GUARDS;     /* Kalman: physical guards of issue 30, bit mask: 1 thrust (kalman_accel: no barometer in
                           BOOST), 2 gravity (VB falls by DG at or below 0; evidence needs X2 >= VB - V_FALL), 4 floor
                           (evidence needs X1 and h >= GND + H_FLOOR), 8 descent (evidence needs h < HMAX or
                           HT >= DESC_N) */
    int32_t DG;         /* Kalman gravity guard: VB falls by at most DG = g dt per sample at or below 0, Q24.8 m/s */
    int32_t V_FALL;     /* Kalman gravity guard: evidence needs X2 - VB >= -V_FALL, Q24.8 m/s */
    int32_t H_FLOOR;    /* Kalman floor guard: evidence needs X1 and h at least H_FLOOR above GND, Q24.8 m */
    int32_t DESC_N;     /* Kalman descent guard: evidence needs h < HMAX, or HMAX to be DESC_N valid samples old */
    int32_t H_STEP;     /* kalman_accel: only a steady sample, |h - HP| <= H_STEP, re-bases X1, Q24.8 m */
    const int32_t *ALT; /* [ALT_N] table nodes, Q24.8 m (FW_ALT_READ) */
} fw_consts;

/* The state of any program (the words each program uses are listed in fw_words()). */
typedef struct {
    int32_t EST, EXT, VEL;  /* recursive: Q24.8 units, Q24.8 units, accel counts x samples */
    int32_t X1, X2, X3;     /* Kalman: Q24.8 units, units/s, units/s^2 */
    int32_t ACC0;           /* pad accelerometer reading, counts */
    uint16_t EVENTS;        /* event bits */
    uint16_t APFRAC;        /* unsigned Q0.16 fraction of a sample period */
    int32_t GND, SUMZ, SUMA; /* Kalman pad calibration: ground (Q24.8 m), sums of altitudes and accel counts */
    uint16_t CAL, REJ, NEG;  /* counters: pad samples, gated samples in a row, apogee evidence samples in a row */
    int32_t ZL;              /* recursive: the last barometer sample z used (rate gate) */
    uint16_t PHASE, CST;     /* flight phase (FW_PH_*) and consecutive coast samples */
    uint16_t DLY, LOCK;      /* Kalman: Mach delay countdown; kalman_accel: Mach lockout / settling countdown */
    int32_t VB;              /* Kalman: plausibility bound max(X2, VB - DV), Q24.8 m/s */
    uint16_t CLP;            /* rail samples in a row in boost; after ACC_CLIP, drag-low coast samples in a row */
    int32_t E0;              /* kalman_accel: innovation drift over the clip-clear window (second half minus first
                                half), Q24.8 m */
    int32_t HMAX;            /* Kalman: the highest valid barometric altitude h since the pad calibration, Q24.8 m */
    uint16_t HT;             /* Kalman: valid samples since HMAX last rose, 0..DESC_N */
    int32_t HP;              /* kalman_accel: h of the last valid sample (the re-base's steady test), Q24.8 m */
} fw_state;

/* Flight phases of the PHASE word (docs/firmware-spec.md section 4a). */
#define FW_PH_PAD     0u
#define FW_PH_BOOST   1u
#define FW_PH_COAST   2u
#define FW_PH_APOGEE  3u
#define FW_PH_DESCENT 4u

/* Maximum number of output words of any program. */
#define FW_MAX_WORDS 22

/* Exact helpers (exposed for unit tests). */
int32_t fw_wrap32(int64_t x);                      /* x reduced to int32 two's complement */
int64_t fw_rs(int64_t x, int32_t s, int32_t mode); /* rounding right shift, mode 0 floor / 1 half_up */
int32_t fw_mulg(int64_t e, fw_gain g, int32_t mode); /* wrap32(rs(e * m, s, mode)), exact 48-bit product */
int32_t fw_alt(const fw_consts *c, int32_t adc);     /* alt(adc) of a valid word: table + interpolation, Q24.8 m */

/* init: state after the first sample.  adc: the barometer word of the build's kind (docs/firmware-spec.md 2):
   an ADC's unsigned 16-bit count (zero-extended) or the pascal kind's signed 32-bit word; acc signed 16-bit. */
void fw_init(fw_program prog, const fw_consts *c, fw_state *st, int32_t adc, int16_t acc);
/* step: one sample through the program. */
void fw_step(fw_program prog, const fw_consts *c, fw_state *st, int32_t adc, int16_t acc);
/* The output words of prog in docs/firmware-spec.md section 7 order (.w words zero-extended); returns the count. */
int fw_words(fw_program prog, const fw_state *st, int32_t out[FW_MAX_WORDS]);
/* Name of output word i of prog ("EST", "X1", ...), or "?" when out of range. */
const char *fw_word_name(fw_program prog, int i);

#endif /* FW_H */
