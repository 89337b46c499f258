/*
 * harness.c -- runs the C99 port (fw.c) on every golden-vector case listed in FWV_CASES_FILE (default
 * "cases.h") and checks every word of every sample, bit for bit.
 *
 * Output: for each failing case its first mismatch, as
 *     case <name> sample <i> word <NAME>: expected <x> got <y>
 * (sample -1 is the state after init), then a summary "N passed, M failed".  Exit status 1 when any case fails.
 * On the AVR it also reports the cycles per step measured with Timer1; with FWV_ICOUNT on a Cortex-M under
 * qemu-system-arm -icount shift=0 (one instruction = 1 ns of virtual time) the instructions per step counted with
 * SysTick: each step runs FWV_TICK_NS_NUM x FWV_ICOUNT_OVERSAMPLE times on a copy of the state, so that the
 * elapsed SysTick ticks (one tick = FWV_TICK_NS_NUM / FWV_TICK_NS_DEN ns) are a whole multiple of the instruction
 * count, minus the same loop around an empty function (one instruction, its return).  Counted: every instruction from fw_step's entry to its return.
 * Both report per program "min mean max at <case> sample <i>" (the input that gave the maximum).
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

#endif

#if defined(__AVR__) || defined(FWV_ICOUNT)
#define FWV_STATS 1
typedef struct {
    uint32_t n;
    uint32_t sum_lo;   /* sum of cycles / instructions (32 bits are enough for the MCU subsets) */
    uint32_t min, max;
    const char *max_case;
    int32_t max_sample;
    uint8_t overflow;
} cyc_stats;
static cyc_stats cycles[4];

static void stats_add(cyc_stats *cy, uint32_t t, uint8_t ovf, const char *name, int32_t sample)
{
    if (cy->n == 0 || t < cy->min) cy->min = t;
    if (cy->n == 0 || t > cy->max) {
        cy->max = t;
        cy->max_case = name;
        cy->max_sample = sample;
    }
    cy->sum_lo += t;
    cy->n++;
    cy->overflow |= ovf;
}
#endif

#ifdef FWV_ICOUNT
#ifndef FWV_TICK_NS_NUM
#error "FWV_ICOUNT needs FWV_TICK_NS_NUM / FWV_TICK_NS_DEN (the SysTick period in ns as a fraction)"
#endif
#ifndef FWV_ICOUNT_OVERSAMPLE
#define FWV_ICOUNT_OVERSAMPLE 1
#endif
#define FWV_REPS (FWV_TICK_NS_NUM * FWV_ICOUNT_OVERSAMPLE)
#define FWV_TICKS_PER_INSN (FWV_TICK_NS_DEN * FWV_ICOUNT_OVERSAMPLE)
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
typedef void (*fwv_step_fn)(fw_program, const fw_consts *, fw_state *, int32_t, int16_t);

static void empty_step(fw_program prog, const fw_consts *c, fw_state *st, int32_t adc, int16_t acc)
{
    (void)prog; (void)c; (void)st; (void)adc; (void)acc;
}

/* 100 NOPs and the return: 101 instructions, to check the counting itself. */
__attribute__((naked, noinline)) static void known_101(fw_program prog, const fw_consts *c, fw_state *st,
                                                        int32_t adc, int16_t acc)
{
    (void)prog; (void)c; (void)st; (void)adc; (void)acc;
    __asm__ volatile(".rept 100\n\tnop\n\t.endr\n\tbx lr\n");
}

static fwv_step_fn volatile step_fn = fw_step, empty_fn = empty_step, known_fn = known_101;

/* SysTick ticks of FWV_REPS calls of f, each on a fresh copy of *st; *st gets the result. */
static uint32_t ticks_of(fwv_step_fn f, fw_program prog, const fw_consts *c, fw_state *st, int32_t adc,
                         int16_t acc)
{
    fw_state tmp = *st;
    uint32_t r, t0, t1;
    /* start on a tick edge: the reading's phase then does not depend on how many instructions ran before (the
       start-up code's .data/.bss loops grow with the port's state; a phase shift once made the calibration 102) */
    t0 = SYST_CVR;
    while (SYST_CVR == t0) {
    }
    t0 = SYST_CVR;
    for (r = 0; r < FWV_REPS; r++) {
        tmp = *st;
        f(prog, c, &tmp, adc, acc);
    }
    t1 = SYST_CVR;
    *st = tmp;
    return (t0 - t1) & 0xFFFFFFu;
}

static uint8_t icount_inexact;

/* Instructions of one call of f: (ticks(f) - ticks(empty)) / FWV_TICKS_PER_INSN + 1, rounded to the nearest
 * (QEMU's timer may land one tick either side when a tick is not a whole number of ns: with the oversampling a
 * count stays exact while each reading is within a tick; a larger residual is reported); *st advanced by f. */
static uint32_t instructions_of(fwv_step_fn f, fw_program prog, const fw_consts *c, fw_state *st, int32_t adc,
                                int16_t acc)
{
    fw_state scratch = *st;
    uint32_t base = ticks_of(empty_fn, prog, c, &scratch, adc, acc);
    uint32_t full = ticks_of(f, prog, c, st, adc, acc);
    uint32_t d = full - base, n = (d + FWV_TICKS_PER_INSN / 2) / FWV_TICKS_PER_INSN;
    uint32_t res = d > n * FWV_TICKS_PER_INSN ? d - n * FWV_TICKS_PER_INSN : n * FWV_TICKS_PER_INSN - d;
    if (FWV_TICKS_PER_INSN == 1 ? 0 : res > 2) icount_inexact = 1;
    return n + 1;
}
#endif

#ifdef FWV_HAS_CHECK_FROM
#define FWV_CHECK_FROM(k) fwv_check_from[k]
#else
#define FWV_CHECK_FROM(k) 0
#endif

/* Run case cs; check (and time) the samples from `from` on (0 = all, and the state after init); the expected
 * rows start at sample `from` (a slice of a case split to fit a small MCU, see mcu/batches.py). */
/* The barometer word of sample i: the pascal word, or the ADC count zero-extended. */
#define FWV_BARO(cs, i) ((cs)->pa ? FWV_RD_I32(&(cs)->pa[(i)]) : (int32_t)FWV_RD_U16(&(cs)->adc[(i)]))

static int run_case(const fwv_case *cs, int32_t from)
{
    fw_state st;
    int32_t got[FW_MAX_WORDS];
    int32_t i, j, nw;
    int32_t adc0 = FWV_BARO(cs, 0);
    int16_t acc0 = FWV_RD_I16(&cs->acc[0]);

    fw_init(cs->program, &cs->consts, &st, adc0, acc0);
    nw = fw_words(cs->program, &st, got);
    if (nw != cs->n_words) {
        printf("case %s: program has %ld words, vectors have %ld\n", cs->name, (long)nw, (long)cs->n_words);
        return 0;
    }
    for (j = 0; j < nw && from == 0; j++) {
        int32_t want = FWV_RD_I32(&cs->init[j]);
        if (got[j] != want) {
            printf("case %s sample -1 word %s: expected %ld got %ld\n", cs->name, fw_word_name(cs->program, (int)j),
                   (long)want, (long)got[j]);
            return 0;
        }
    }
    for (i = 0; i < cs->n_samples; i++) {
        int32_t adc = FWV_BARO(cs, i);
        int16_t acc = FWV_RD_I16(&cs->acc[i]);
        if (i < from) {
            fw_step(cs->program, &cs->consts, &st, adc, acc);
            continue;
        }
        {
#if defined(__AVR__)
        uint16_t t;
        uint8_t ovf;
        TIMER_START();
        fw_step(cs->program, &cs->consts, &st, adc, acc);
        t = TIMER_READ();
        ovf = TIMER_OVERFLOWED() ? 1 : 0;
        stats_add(&cycles[cs->program], (uint16_t)(t - timer_overhead), ovf, cs->name, i);
#elif defined(FWV_ICOUNT)
        stats_add(&cycles[cs->program], instructions_of(step_fn, cs->program, &cs->consts, &st, adc, acc), 0,
                  cs->name, i);
#else
        fw_step(cs->program, &cs->consts, &st, adc, acc);
#endif
        }
        fw_words(cs->program, &st, got);
        for (j = 0; j < nw; j++) {
            int32_t want = FWV_RD_I32(&cs->expected[(int32_t)(i - from) * nw + j]);
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
#ifdef FWV_ICOUNT
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0;
    SYST_CSR = 5u; /* enable, processor clock, no interrupt */
    {
        fw_state scratch;
        uint32_t n;
        memset(&scratch, 0, sizeof scratch);
        n = instructions_of(known_fn, FW_RECURSIVE, NULL, &scratch, 0, 0);
        printf("calibration: known 101 instructions counted as %lu\n", (unsigned long)n);
        if (n != 101u) {
            printf("icount: the calibration is wrong: the instruction counts below are meaningless "
                   "(QEMU not run with -icount shift=0, or another SysTick clock)\n");
            failed++;
        }
    }
#endif
    for (k = 0; k < FWV_N_CASES; k++) {
        FWV_COPY(&cs, &fwv_cases[k], sizeof cs);
        if (run_case(&cs, FWV_CHECK_FROM(k))) {
            passed++;
        } else {
            failed++;
        }
    }
#ifdef FWV_STATS
    for (k = 0; k < 4; k++) {
        if (cycles[k].n) {
#ifdef __AVR__
            printf("cycles program %u: samples %lu min %lu mean %lu max %lu at %s sample %ld%s\n", k,
#else
            printf("icount program %u: samples %lu min %lu mean %lu max %lu at %s sample %ld%s\n", k,
#endif
                   (unsigned long)cycles[k].n, (unsigned long)cycles[k].min,
                   (unsigned long)(cycles[k].sum_lo / cycles[k].n), (unsigned long)cycles[k].max,
                   cycles[k].max_case, (long)cycles[k].max_sample, cycles[k].overflow ? " OVERFLOW" : "");
        }
    }
#endif
#ifdef FWV_ICOUNT
    if (icount_inexact) {
        printf("icount: a tick count was off by more than two ticks (QEMU not run with -icount shift=0?)\n");
        failed++;
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
