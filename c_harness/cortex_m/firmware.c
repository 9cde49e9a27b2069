/*
 * firmware.c - example firmware: replay a recorded trajectory through a generated observer on a
 * Cortex-M and print the estimates through semihosting (QEMU mps2 boards, or a debug probe).
 *
 * Input: the host file "obs_in.bin" (semihosting, relative to the host's working folder): rows
 * of NY + NU reals (y, u) in the target's real type, little-endian. The observer starts from the
 * first row's y with default parameters and a zero estimate, then steps once per row.
 * Optional "obs_dt.bin": one real per row, the elapsed time of that row (a jittered loop); the
 * rows are then replayed a second time from init with <prefix>_step_dt (the first row's dt is
 * not used by a first-order hold).
 * Output, one line per step and a summary per pass:
 *   e <hex> <hex> ...      the estimate, each real as its IEEE-754 bit pattern (exact)
 *   done steps=N status=S ticks=T max_ticks=M calib_ticks=C calib_insns=I stack=B stack_size=Z
 *   d <hex> <hex> ...      (obs_dt.bin) the estimates of the step_dt pass
 *   done_dt steps=N status=S ticks=T max_ticks=M stack=B
 * ticks: sum over the steps of the board's tick counter around <prefix>_step (_step_dt) only;
 * calib_*: the ticks of a loop of exactly calib_insns instructions (ticks -> instructions);
 * stack: deepest stack use so far (bytes, painted stack): of the step pass, then of both passes
 * (an elapsed time above DT_MAX is split in a loop of kernel calls).
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
static OBS_REAL elapsed;   /* the elapsed time of a row (obs_dt.bin) */

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

/* "<tag> <hex> ..." for one estimate: the bit pattern of each real */
static void print_estimate(char tag)
{
    char line[4 + (int)OBS_LEN(OBS_NEST) * 18];
    char *p = line;
    int i;
    *p++ = tag;
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

/* The second pass (obs_dt.bin present): init again, step_dt over the rows with their elapsed
   times; prints "d ..." per step and the done_dt line. Returns the first non-zero status, -1 on
   an input error, 0 when there is no obs_dt.bin. */
static int replay_dt(void)
{
    char line[120], *p = line;
    unsigned long steps = 0, ticks = 0, max_ticks = 0;
    uint32_t t0, dticks;
    int status;
    int32_t in, din = sh_open("obs_dt.bin", SH_MODE_RB);
    if (din < 0) return 0;
    in = sh_open("obs_in.bin", SH_MODE_RB);
    if (in < 0 || sh_read(in, row, sizeof row) != 0) {
        sh_close(din);
        return -1;
    }
    status = OBS_FN(init)(&state, NULL, row, NULL);
    while (status == 0) {
        if (sh_read(din, &elapsed, sizeof elapsed) != 0) {
            status = -1;
            break;
        }
        t0 = ticks_now();
        status = OBS_FN(step_dt)(&state, elapsed, row, row + OBS_NY, est);
        dticks = ticks_now() - t0;
        if (status != 0) break;
        ticks += dticks;
        if (dticks > max_ticks) max_ticks = dticks;
        ++steps;
        print_estimate('d');
        if (sh_read(in, row, sizeof row) != 0) break;
    }
    sh_close(in);
    sh_close(din);
    p = put_dec(p, "done_dt steps=", steps);
    p = put_dec(p, " status=", (unsigned long)(status < 0 ? 255 : status));
    p = put_dec(p, " ticks=", ticks);
    p = put_dec(p, " max_ticks=", max_ticks);
    p = put_dec(p, " stack=", stack_peak());
    *p++ = '\n';
    *p = '\0';
    sh_write0(line);
    return status;
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
            print_estimate('e');
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
    if (status == 0 && steps > 0) status = replay_dt();
    return status != 0 || steps == 0;
}
