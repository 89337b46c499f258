/*
 * startup.c -- reset handler and vector table for the Cortex-M golden-vector runs under qemu-system-arm.
 *
 * The vector table sits at address 0 (section .vectors, see the board linker scripts): initial stack pointer, then
 * the reset handler.  Reset copies .data from its load address in flash to RAM (the micro:bit has flash at 0 and
 * RAM at 0x20000000; on the MPS2 boards the same copy is harmless), then enters newlib's semihosting start-up
 * (_start of rdimon-crt0: clears .bss, runs constructors, calls main and exits with main's return value through
 * semihosting, which becomes QEMU's exit status).  Any fault handler prints one line and exits with status 3.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

extern uint32_t __data_load__, __data_start__, __data_end__, __stack_top__;
extern void _start(void);

void Reset_Handler(void);
void Fault_Handler(void);

void Reset_Handler(void)
{
    uint32_t *src = &__data_load__;
    uint32_t *dst = &__data_start__;
    if (src != dst) {
        while (dst < &__data_end__) {
            *dst++ = *src++;
        }
    }
    _start();
    for (;;) {
    }
}

void Fault_Handler(void)
{
    printf("fault: the core took an exception (HardFault/NMI/MemManage/BusFault/UsageFault)\n");
    exit(3);
}

typedef void (*vector_fn)(void);

/* Initial SP, Reset, NMI, HardFault, MemManage, BusFault, UsageFault (the last three reserved on v6-M). */
__attribute__((section(".vectors"), used)) const vector_fn fwv_vectors[7] = {
    (vector_fn)(uintptr_t)&__stack_top__, Reset_Handler, Fault_Handler, Fault_Handler,
    Fault_Handler, Fault_Handler, Fault_Handler,
};
