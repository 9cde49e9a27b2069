/*
 * time_step - time one generated observer target: ns per <prefix>_step and per <prefix>_rhs.
 *
 * Usage: time_step [--blocks=N] [--block-ms=MS]        (defaults: 51 blocks of ~15 ms)
 *
 * Inputs are fixed and finite: a table of K samples of smooth periodic signals
 * y_i(k) = c_i + a_i sin(2 pi k / K + phi_i) (likewise u, c_i = 0), with amplitudes in
 * [0.25, 1] and phases drawn from a fixed-seed generator, inside the target's declared ranges
 * (the header's Y_LOWER, Y_UPPER, U_MAX): c_i the middle of a bounded range of y_i, a_i at
 * most 0.45 of its width (U_MAX for u), so no sample is refused with ERR_OUT_OF_RANGE.  The step loop cycles through the table;
 * every block starts from the same state (a copy taken after init and a warm-up run), so
 * all blocks do the same work.  The rhs loop evaluates the right-hand side at the state
 * reached after the warm-up, cycling through the same table of y, u.
 *
 * The number of calls per block is doubled until one block takes at least MS
 * milliseconds; after three warm-up blocks, `blocks` blocks are timed with
 * clock_gettime(CLOCK_MONOTONIC) and the median ns per call is reported.  The target is a
 * separate translation unit, so its calls cannot be optimised away; results are also
 * folded into a volatile sink.
 *
 * Prints one JSON line:
 *   {"target": "<prefix>", "ns_per_step": ..., "ns_per_rhs": ..., "blocks": ...,
 *    "calls_per_block": ..., "calls_per_block_rhs": ..., "nx": ..., "ny": ..., "nu": ...,
 *    "nest": ..., "dt": ..., "errors": ...}
 * where "errors" counts step calls that returned a non-zero status (the state is then
 * restored from the copy; a non-zero count means the timing is not representative).
 *
 * Build (see Makefile): cc -O3 -std=c99 -DOBS=<prefix> -DOBS_UPPER=<PREFIX>
 *   -DOBS_HEADER='"<prefix>.h"' -I <target dir> time_step.c <prefix>.c <prefix>_kernels.c -lm
 */
#define _POSIX_C_SOURCE 199309L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "obs_bind.h"

#define K_TABLE 256 /* samples in the input table (power of two) */

static OBS_REAL Y_tab[K_TABLE][OBS_LEN(OBS_NY)];
static OBS_REAL U_tab[K_TABLE][OBS_LEN(OBS_NU)];
static OBS_STATE state0;        /* state every step block starts from */
static OBS_STATE state;         /* working state */
static OBS_REAL x_rhs[OBS_LEN(OBS_NX)];
static long n_errors = 0;
static volatile double sink = 0.0;

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return 1e9 * (double)ts.tv_sec + (double)ts.tv_nsec;
}

/* Fixed-seed generator (xorshift64*), uniform in [0, 1). */
static unsigned long long rng_state = 0x9E3779B97F4A7C15ULL;
static double uniform01(void)
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return (double)((rng_state * 2685821657736338717ULL) >> 11) * (1.0 / 9007199254740992.0);
}

/* The declared ranges (-+REAL_MAX: unchecked; a header without CHECK_RANGES checks none);
   lower == NULL: u's, symmetric, |u| <= upper. */
#if OBS_SIZE(CHECK_RANGES)
static const OBS_REAL y_lower[OBS_LEN(OBS_NY)] = OBS_SIZE(Y_LOWER), y_upper[OBS_LEN(OBS_NY)] = OBS_SIZE(Y_UPPER);
static const OBS_REAL u_max[OBS_LEN(OBS_NU)] = OBS_SIZE(U_MAX);
#define Y_RANGE y_lower, y_upper
#define U_RANGE NULL, u_max
#else
#define Y_RANGE NULL, NULL
#define U_RANGE NULL, NULL
#endif

static void fill_table(OBS_REAL *tab, int width, int n, const OBS_REAL *lower, const OBS_REAL *upper)
{
    const double two_pi = 6.283185307179586;
    int i, k;
    for (i = 0; i < n; ++i) {
        double a = 0.25 + 0.75 * uniform01();
        double phi = two_pi * uniform01();
        double hi = upper ? (double)upper[i] : 1e300, lo = lower ? (double)lower[i] : -hi;
        double c = 0.5 * lo + 0.5 * hi; /* the halves: no overflow at -+REAL_MAX */
        if (a > 0.45 * (hi - lo)) a = 0.45 * (hi - lo);
        for (k = 0; k < K_TABLE; ++k) tab[k * width + i] = (OBS_REAL)(c + a * sin(two_pi * k / K_TABLE + phi));
    }
}

static void step_block(long n)
{
    OBS_REAL est[OBS_LEN(OBS_NEST)] = {0};
    double acc = 0.0;
    long i;
    for (i = 0; i < n; ++i) {
        int j = (int)(i & (K_TABLE - 1));
        int st = OBS_FN(step)(&state, Y_tab[j], U_tab[j], est);
        if (st != 0) {
            ++n_errors;
            state = state0;
        }
        acc += (double)est[0];
    }
    sink = sink + acc;
}

static void rhs_block(long n)
{
    OBS_REAL xdot[OBS_LEN(OBS_NX)];
    double acc = 0.0;
    long i;
    for (i = 0; i < n; ++i) {
        int j = (int)(i & (K_TABLE - 1));
        OBS_FN(rhs)(&state, x_rhs, Y_tab[j], U_tab[j], xdot);
        acc += (double)xdot[0];
    }
    sink = sink + acc;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median ns per call of block(n) over `blocks` blocks; *calls gets n. */
static double time_median(void (*block)(long), int reset_state, int blocks, double block_ms,
                          long *calls)
{
    const double target = block_ms * 1e6;
    double *per_call = (double *)malloc((size_t)blocks * sizeof(double));
    double med;
    long n = 1;
    int b;
    if (!per_call) {
        fprintf(stderr, "time_step: out of memory\n");
        exit(1);
    }
    if (reset_state) state = state0;
    block(100); /* first calls: lazy symbol binding, cold caches */
    for (;;) { /* calibrate */
        double t0, dt;
        if (reset_state) state = state0;
        t0 = now_ns();
        block(n);
        dt = now_ns() - t0;
        if (dt >= target || n > (1L << 40)) break;
        if (dt > 0.1 * target)
            n = (long)((double)n * target / dt) + 1;
        else
            n *= 2;
    }
    for (b = 0; b < 3; ++b) { /* warm-up */
        if (reset_state) state = state0;
        block(n);
    }
    for (b = 0; b < blocks; ++b) {
        double t0;
        if (reset_state) state = state0;
        t0 = now_ns();
        block(n);
        per_call[b] = (now_ns() - t0) / (double)n;
    }
    qsort(per_call, (size_t)blocks, sizeof(double), cmp_double);
    med = (blocks % 2) ? per_call[blocks / 2]
                       : 0.5 * (per_call[blocks / 2 - 1] + per_call[blocks / 2]);
    free(per_call);
    *calls = n;
    return med;
}

int main(int argc, char **argv)
{
    int blocks = 51, i, st;
    double block_ms = 15.0, ns_step, ns_rhs;
    long calls_step, calls_rhs, warm_errors;
    OBS_REAL est[OBS_LEN(OBS_NEST)];

    for (i = 1; i < argc; ++i) {
        if (strncmp(argv[i], "--blocks=", 9) == 0)
            blocks = atoi(argv[i] + 9);
        else if (strncmp(argv[i], "--block-ms=", 11) == 0)
            block_ms = atof(argv[i] + 11);
        else {
            fprintf(stderr, "usage: %s [--blocks=N] [--block-ms=MS]   (target '%s')\n", argv[0],
                    OBS_NAME);
            return 2;
        }
    }
    if (blocks < 1 || !(block_ms > 0.0)) {
        fprintf(stderr, "time_step: --blocks must be >= 1 and --block-ms > 0\n");
        return 2;
    }

    fill_table(&Y_tab[0][0], OBS_LEN(OBS_NY), OBS_NY, Y_RANGE);
    fill_table(&U_tab[0][0], OBS_LEN(OBS_NU), OBS_NU, U_RANGE);

    st = OBS_FN(init)(&state, NULL, Y_tab[0], NULL);
    if (st != 0) {
        fprintf(stderr, "time_step: %s_init returned %d: %s\n", OBS_NAME, st, obs_status_name(st));
        return 3;
    }
    /* warm-up run over the table, then keep that state as every block's start; an observer
       that the synthetic table drives out of range (non-finite result) restarts from init and
       the failure is counted in "errors" (the RHS timing does not depend on it) */
    state0 = state;
    for (i = 0; i < 4 * K_TABLE; ++i) {
        st = OBS_FN(step)(&state, Y_tab[i % K_TABLE], U_tab[i % K_TABLE], est);
        if (st != 0) {
            ++n_errors;
            state = state0;
        }
    }
    state0 = state;
    memcpy(x_rhs, state.x, sizeof state.x);
    {
        OBS_REAL xdot[OBS_LEN(OBS_NX)];
        st = OBS_FN(rhs)(&state, x_rhs, Y_tab[0], U_tab[0], xdot);
        if (st != 0) {
            fprintf(stderr, "time_step: %s_rhs returned %d: %s\n", OBS_NAME, st, obs_status_name(st));
            return 3;
        }
    }

    ns_step = time_median(step_block, 1, blocks, block_ms, &calls_step);
    warm_errors = n_errors;
    state = state0;
    ns_rhs = time_median(rhs_block, 0, blocks, block_ms, &calls_rhs);

    printf("{\"target\": \"%s\", \"ns_per_step\": %.6g, \"ns_per_rhs\": %.6g, \"blocks\": %d, "
           "\"calls_per_block\": %ld, \"calls_per_block_rhs\": %ld, \"nx\": %d, \"ny\": %d, "
           "\"nu\": %d, \"nest\": %d, \"dt\": %.17g, \"errors\": %ld}\n",
           OBS_NAME, ns_step, ns_rhs, blocks, calls_step, calls_rhs, (int)OBS_NX, (int)OBS_NY,
           (int)OBS_NU, (int)OBS_NEST, (double)OBS_DT, warm_errors);
    if (warm_errors > 0)
        fprintf(stderr, "time_step: warning: %ld step calls returned a non-zero status\n",
                warm_errors);
    return 0;
}
