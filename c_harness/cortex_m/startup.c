/*
 * startup.c - minimal Cortex-M startup: vector table, reset handler, stack painting.
 *
 * Reset: enable the FPU (CPACR), copy .data from flash, zero .bss, paint the free stack with
 * STACK_PAINT, call main(), report its result through semihosting (exit 0 when main returns 0).
 * A fault also ends the run through semihosting (exit 1) instead of hanging.
 * stack_peak() gives the deepest stack use so far: the painted words no longer intact.
 * Symbols come from the linker script (mps2.ld).
 */
#include <stdint.h>

#include "semihost.h"
#include "startup.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _sstack, _estack;

int main(void);
void Reset_Handler(void);
void Fault_Handler(void);

#define STACK_PAINT 0xDEADBEEFu /* not a repeated byte: the paint loop never becomes memset */
#define CPACR (*(volatile uint32_t *)0xE000ED88u)

typedef void (*handler)(void);
typedef union {
    handler fn;
    uint32_t *sp;
} vector;

__attribute__((section(".vectors"), used)) const vector vectors[16] = {
    {.sp = &_estack},     {.fn = Reset_Handler}, {.fn = Fault_Handler}, {.fn = Fault_Handler},
    {.fn = Fault_Handler}, {.fn = Fault_Handler}, {.fn = Fault_Handler}, {.fn = 0},
    {.fn = 0},             {.fn = 0},             {.fn = 0},             {.fn = Fault_Handler},
    {.fn = Fault_Handler}, {.fn = 0},             {.fn = Fault_Handler}, {.fn = Fault_Handler},
};

void Fault_Handler(void)
{
    sh_write0("fault\n");
    sh_exit(0);
}

void Reset_Handler(void)
{
    uint32_t *src = &_sidata, *dst, *sp;
    CPACR |= 0xFu << 20; /* CP10, CP11: full access to the FPU */
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    for (dst = &_sdata; dst < &_edata;) *dst++ = *src++;
    for (dst = &_sbss; dst < &_ebss;) *dst++ = 0;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    for (dst = &_sstack; dst < sp - 16;) *dst++ = STACK_PAINT; /* all but this frame's 64 bytes */
    sh_exit(main() == 0);
}

unsigned long stack_peak(void)
{
    const uint32_t *p = &_sstack;
    while (p < &_estack && *p == STACK_PAINT) ++p;
    return (unsigned long)((uintptr_t)&_estack - (uintptr_t)p);
}

unsigned long stack_size(void) { return (unsigned long)((uintptr_t)&_estack - (uintptr_t)&_sstack); }
