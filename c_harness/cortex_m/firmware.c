/*
 * firmware.c - example firmware: replay a recorded trajectory through a generated observer on a
 * Cortex-M and print the estimates through semihosting (QEMU mps2 boards, or a debug probe).
 *
 * Input: the host file "obs_in.bin" (semihosting, relative to the host's working folder): rows
 * of NY + NU reals (y, u) in the target's real type, little-endian. The observer starts from the
 * first row's y with default parameters and a zero estimate, then steps once per row.
 * Output, one line per step and a summary:
 *   e <hex> <hex> ...      the estimate, each real as its IEEE-754 bit pattern (exact)
 *   done steps=N status=S ticks=T max_ticks=M calib_ticks=C calib_insns=I stack=B stack_size=Z
 * ticks: sum over the steps of the board's tick counter around <prefix>_step only; calib_*: the
 * ticks of a loop of exactly calib_insns instructions (ticks -> instructions); stack: deepest
 * stack use of the whole run (bytes, painted stack).
 * Exit: 0 when every step returned OK, else 1.
 */
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "obs_bind.h"
#include "semihost.h"
#include "startup.h"

#define CALIB_LOOPS 100000u /* 2 instructions per loop */

static OBS_STATE state;
static OBS_REAL row[OBS_LEN(OBS_NY + OBS_NU)];
static OBS_REAL est[OBS_LEN(OBS_NEST)];

/* "subs; bne": exactly 2 instructions per iteration */
static void __attribute__((noinline)) spin(uint32_t n)
{
    __asm__ volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
}

static char *put_hex(char *p, uint32_t v, int digits)
{
    static const char hex[] = "0123456789abcdef";
    int i;
    for (i = digits - 1; i >= 0; --i) *p++ = hex[(v >> (4 * i)) & 0xFu];
    return p;
}

static char *put_dec(char *p, const char *key, unsigned long v)
{
    char tmp[12];
    int n = 0;
    while (*key) *p++ = *key++;
    do tmp[n++] = (char)('0' + v % 10u); while ((v /= 10u) != 0u);
    while (n > 0) *p++ = tmp[--n];
    return p;
}

/* "e <hex> ..." for one estimate: the bit pattern of each real */
static void print_estimate(void)
{
    char line[4 + (int)OBS_LEN(OBS_NEST) * 18];
    char *p = line;
    int i;
    *p++ = 'e';
    for (i = 0; i < (int)OBS_NEST; ++i) {
        *p++ = ' ';
        if (sizeof(OBS_REAL) == 8) {
            uint64_t b;
            memcpy(&b, &est[i], 8);
            p = put_hex(p, (uint32_t)(b >> 32), 8);
            p = put_hex(p, (uint32_t)b, 8);
        } else {
            uint32_t b;
            memcpy(&b, &est[i], 4);
            p = put_hex(p, b, 8);
        }
    }
    *p++ = '\n';
    *p = '\0';
    sh_write0(line);
}

int main(void)
{
    char line[200], *p = line;
    unsigned long steps = 0, ticks = 0, max_ticks = 0, calib;
    uint32_t t0;
    int status = 0;
    int32_t in = sh_open("obs_in.bin", SH_MODE_RB);
    if (in < 0) {
        sh_write0("cannot open obs_in.bin\n");
        return 1;
    }
    ticks_start();
    t0 = ticks_now();
    spin(CALIB_LOOPS);
    calib = ticks_now() - t0;
    if (sh_read(in, row, sizeof row) == 0)
        status = OBS_FN(init)(&state, NULL, row, NULL);
    else
        status = -1;
    if (status == 0) {
        do {
            uint32_t dt;
            t0 = ticks_now();
            status = OBS_FN(step)(&state, row, row + OBS_NY, est);
            dt = ticks_now() - t0;
            if (status != 0) break;
            ticks += dt;
            if (dt > max_ticks) max_ticks = dt;
            ++steps;
            print_estimate();
        } while (sh_read(in, row, sizeof row) == 0);
    }
    sh_close(in);
    if (status > 0) {
        sh_write0("error: ");
        sh_write0(obs_status_name(status));
        sh_write0("\n");
    }
    p = put_dec(p, "done steps=", steps);
    p = put_dec(p, " status=", (unsigned long)(status < 0 ? 255 : status));
    p = put_dec(p, " ticks=", ticks);
    p = put_dec(p, " max_ticks=", max_ticks);
    p = put_dec(p, " calib_ticks=", calib);
    p = put_dec(p, " calib_insns=", 2ul * CALIB_LOOPS);
    p = put_dec(p, " stack=", stack_peak());
    p = put_dec(p, " stack_size=", stack_size());
    *p++ = '\n';
    *p = '\0';
    sh_write0(line);
    return status != 0 || steps == 0;
}
