/*
 * harness.c -- runs the C99 port (fw.c) on every golden-vector case listed in FWV_CASES_FILE (default
 * "cases.h") and checks every word of every sample, bit for bit.
 *
 * Output: for each failing case its first mismatch, as
 *     case <name> sample <i> word <NAME>: expected <x> got <y>
 * (sample -1 is the state after init), then a summary "N passed, M failed".  Exit status 1 when any case fails.
 * With FWV_CYCLES defined (the AVR build) it also reports the cycles per step measured by the target.
 */
#include <stdio.h>

#ifdef __AVR__
#include <avr/io.h>
#include <avr/interrupt.h>
#include <avr/pgmspace.h>
#include <avr/sleep.h>
#define FWV_ROM PROGMEM
#define FWV_RD_U16(p) ((uint16_t)pgm_read_word(p))
#define FWV_RD_I16(p) ((int16_t)pgm_read_word(p))
#define FWV_RD_I32(p) ((int32_t)pgm_read_dword(p))
#define FWV_COPY(dst, src, n) memcpy_P((dst), (src), (n))
#endif

#include "fwv_case.h"

#ifndef FWV_CASES_FILE
#define FWV_CASES_FILE "cases.h"
#endif
#include FWV_CASES_FILE

#ifdef __AVR__
/* stdout on USART0 (simavr prints what the simulated UART sends). */
static int uart_putchar(char ch, FILE *f)
{
    (void)f;
    while (!(UCSR0A & (1 << UDRE0))) {
    }
    UDR0 = (uint8_t)ch;
    return 0;
}
static FILE uart_out = FDEV_SETUP_STREAM(uart_putchar, NULL, _FDEV_SETUP_WRITE);

/* Timer1 at the CPU clock (prescaler 1) times each fw_step; OVERHEAD is the cost of the timing code itself. */
static uint16_t timer_overhead;
#define TIMER_START() do { TCNT1 = 0; TIFR1 = (1 << TOV1); } while (0)
#define TIMER_READ() (TCNT1)
#define TIMER_OVERFLOWED() (TIFR1 & (1 << TOV1))

typedef struct {
    uint32_t n;
    uint32_t sum_lo;   /* sum of cycles (32-bit is enough for the AVR subset) */
    uint16_t min, max;
    uint8_t overflow;
} cyc_stats;
static cyc_stats cycles[4];
#endif

static int run_case(const fwv_case *cs)
{
    fw_state st;
    int32_t got[FW_MAX_WORDS];
    int32_t i, j, nw;
    uint16_t adc0 = FWV_RD_U16(&cs->adc[0]);
    int16_t acc0 = FWV_RD_I16(&cs->acc[0]);

    fw_init(cs->program, &cs->consts, &st, adc0, acc0);
    nw = fw_words(cs->program, &st, got);
    if (nw != cs->n_words) {
        printf("case %s: program has %ld words, vectors have %ld\n", cs->name, (long)nw, (long)cs->n_words);
        return 0;
    }
    for (j = 0; j < nw; j++) {
        int32_t want = FWV_RD_I32(&cs->init[j]);
        if (got[j] != want) {
            printf("case %s sample -1 word %s: expected %ld got %ld\n", cs->name, fw_word_name(cs->program, (int)j),
                   (long)want, (long)got[j]);
            return 0;
        }
    }
    for (i = 0; i < cs->n_samples; i++) {
        uint16_t adc = FWV_RD_U16(&cs->adc[i]);
        int16_t acc = FWV_RD_I16(&cs->acc[i]);
#ifdef __AVR__
        uint16_t t;
        uint8_t ovf;
        TIMER_START();
        fw_step(cs->program, &cs->consts, &st, adc, acc);
        t = TIMER_READ();
        ovf = TIMER_OVERFLOWED() ? 1 : 0;
        {
            cyc_stats *cy = &cycles[cs->program];
            t = (uint16_t)(t - timer_overhead);
            if (cy->n == 0 || t < cy->min) cy->min = t;
            if (cy->n == 0 || t > cy->max) cy->max = t;
            cy->sum_lo += t;
            cy->n++;
            cy->overflow |= ovf;
        }
#else
        fw_step(cs->program, &cs->consts, &st, adc, acc);
#endif
        fw_words(cs->program, &st, got);
        for (j = 0; j < nw; j++) {
            int32_t want = FWV_RD_I32(&cs->expected[(int32_t)i * nw + j]);
            if (got[j] != want) {
                printf("case %s sample %ld word %s: expected %ld got %ld\n", cs->name, (long)i,
                       fw_word_name(cs->program, (int)j), (long)want, (long)got[j]);
                return 0;
            }
        }
    }
    return 1;
}

int main(void)
{
    long passed = 0, failed = 0;
    unsigned k;
    fwv_case cs;
#ifdef __AVR__
    UCSR0B = (1 << TXEN0);
    stdout = &uart_out;
    TCCR1A = 0;
    TCCR1B = (1 << CS10);
    TIMER_START();
    timer_overhead = TIMER_READ();
#endif
    for (k = 0; k < FWV_N_CASES; k++) {
        FWV_COPY(&cs, &fwv_cases[k], sizeof cs);
        if (run_case(&cs)) {
            passed++;
        } else {
            failed++;
        }
    }
#ifdef __AVR__
    for (k = 0; k < 4; k++) {
        if (cycles[k].n) {
            printf("cycles program %u: samples %lu min %u mean %lu max %u%s\n", k, (unsigned long)cycles[k].n,
                   cycles[k].min, (unsigned long)(cycles[k].sum_lo / cycles[k].n), cycles[k].max,
                   cycles[k].overflow ? " OVERFLOW" : "");
        }
    }
#endif
    printf("%ld passed, %ld failed\n", passed, failed);
#ifdef __AVR__
    printf("done\n");
    cli();
    sleep_mode();
#endif
    return failed ? 1 : 0;
}
