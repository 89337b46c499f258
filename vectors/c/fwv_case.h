/*
 * fwv_case.h -- the descriptor of one golden-vector case as the harness sees it (the generated cases.h /
 * cases_avr.h fill a table of these from the per-case headers in vectors/cases/).
 *
 * On an MCU with separate program memory, define FWV_ROM (e.g. PROGMEM) and the FWV_RD_* / FWV_COPY accessors
 * before including this file; on a host they are plain reads.
 */
#ifndef FWV_CASE_H
#define FWV_CASE_H

#include <stdint.h>
#include <string.h>
#include "fw.h"

#ifndef FWV_ROM
#define FWV_ROM
#endif
#ifndef FWV_RD_U16
#define FWV_RD_U16(p) (*(p))
#endif
#ifndef FWV_RD_I16
#define FWV_RD_I16(p) (*(p))
#endif
#ifndef FWV_RD_I32
#define FWV_RD_I32(p) (*(p))
#endif
#ifndef FWV_COPY
#define FWV_COPY(dst, src, n) memcpy((dst), (src), (n))
#endif

typedef struct {
    const char *name;         /* case name (file stem in vectors/cases/) */
    fw_program program;
    fw_consts consts;
    int32_t n_samples;
    int32_t n_words;
    const uint16_t *adc;      /* [n_samples] raw barometer ADC (NULL for a pascal case) */
    const int16_t *acc;       /* [n_samples] accelerometer counts */
    const int32_t *init;      /* [n_words] state after init */
    const int32_t *expected;  /* [n_samples * n_words] state after each step, row-major */
    const int32_t *pa;        /* [n_samples] the pascal kind's signed 32-bit barometer word (NULL for an ADC case) */
} fwv_case;

#endif /* FWV_CASE_H */
