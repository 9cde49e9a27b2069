/*
 * board.h - the one board-specific piece of the example firmware: a free-running tick counter.
 *
 * MPS2 boards (QEMU mps2-an386, mps2-an500): CMSDK APB timer 0 counting down from 0xFFFFFFFF at
 * the 25 MHz SYSCLK. Under QEMU with "-icount shift=0" one instruction takes 1 ns of virtual time,
 * so one tick is 40 instructions (firmware.c measures this ratio on a loop of known length).
 * On real silicon, use the core's cycle counter instead (DWT->CYCCNT on the Cortex-M4/M7).
 */
#ifndef BOARD_H
#define BOARD_H

#include <stdint.h>

#define TIMER0_CTRL (*(volatile uint32_t *)0x40000000u)
#define TIMER0_VALUE (*(volatile uint32_t *)0x40000004u)
#define TIMER0_RELOAD (*(volatile uint32_t *)0x40000008u)

static inline void ticks_start(void)
{
    TIMER0_RELOAD = 0xFFFFFFFFu;
    TIMER0_VALUE = 0xFFFFFFFFu;
    TIMER0_CTRL = 1u; /* enable */
}

/* Ticks since ticks_start() (wraps after 2^32). */
static inline uint32_t ticks_now(void) { return 0xFFFFFFFFu - TIMER0_VALUE; }

#endif /* BOARD_H */
