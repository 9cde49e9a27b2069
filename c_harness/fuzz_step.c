/*
 * fuzz_step - libFuzzer harness: a generated target's step (and step_dt, run, run_t, estimate,
 * estimate_dt, rhs, set_state, set_params) on hostile numbers, asserting the contract its
 * header documents.
 *
 * Build (codegen/verify/sanitize.py does this; clang with libFuzzer, e.g. Debian's clang and
 * libclang-rt-14-dev):
 *   clang -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all \
 *     -DOBS=<prefix> -DOBS_UPPER=<PREFIX> -DOBS_HEADER='"<prefix>.h"' -I <target dir> -I . \
 *     fuzz_step.c <target dir>/<prefix>.c <target dir>/<prefix>_kernels.c -lm -o fuzz_step
 *   ./fuzz_step -runs=100000 -seed=1
 *
 * An input is a small program over one state: init from the first numbers, then up to 64
 * operations, each one byte and the numbers it takes. A number is one selector byte: a
 * special value (0, -0, +-1, +-1e300, +-DBL_MAX, NaN, +-Inf, denormals, 1e-300, 0.5; for a float
 * target the float ones: +-1e30, +-FLT_MAX, float denormals, 1e-30), a small value in [-8, 7],
 * or the next sizeof(<prefix>_real) bytes as a raw number of the target's real type. An elapsed
 * time (step_dt, estimate_dt) is SPLIT_MAX * DT_MAX (the longest allowed), the next real above
 * it, or DT times a number (0, -0, NaN, +-Inf, huge, denormal, ...); a run_t's stamps start at a
 * number and go on by DT times a number (repeated, decreasing, NaN stamps). The skip mode is
 * turned on and off by an operation. Checked on every call (a violation prints what and aborts;
 * libFuzzer keeps the input):
 *   - the status is one the header documents;
 *   - a dt outside (0, SPLIT_MAX * DT_MAX] (NaN, Inf, <= 0, huge; first-order hold: with the time
 *     skipped since the last accepted sample) gives ERR_BAD_ARG; otherwise
 *     a non-finite argument gives ERR_NONFINITE_INPUT, a finite one outside the declared ranges
 *     (the header's Y_LOWER, Y_UPPER, U_MAX) ERR_OUT_OF_RANGE, one inside neither; in the skip
 *     mode after the first sample both are SKIPPED instead;
 *   - a status other than OK and SKIPPED leaves the state (x, p, y_prev, u_prev, m_prev, primed,
 *     t_last, stamped, the skip mode and the counters) byte-identical; run() and run_t() failing
 *     at sample k set *n_done = k and roll the state back to its entry;
 *   - OK: outputs and the new state are finite; run() equals as many step() calls, run_t()
 *     as many step_dt() calls over the intervals its header documents, step() is step_dt(DT),
 *     and estimate() (estimate_dt()) equals the estimate step() (step_dt()) returns, bit for bit;
 *   - SKIPPED: first-order hold, the estimate is estimate_dt()'s on the last accepted y and u
 *     (y_prev, u_prev) and the state is kept but for the time skipped (t_skip), the stamp and the
 *     counters; zero-order hold, the estimate and the state are the step's on y_prev, u_prev; bit
 *     for bit, and the skip counter is one more;
 *   - a wild sample in a long run (once per input: a fresh state in the skip mode, 200 samples of
 *     a sine per measurement about the middle of its range, one of them, after the first half,
 *     replaced by a fuzzed value outside the ranges or not finite): every status OK but that
 *     sample's SKIPPED, and one sample later each velocity estimate is within the error of the
 *     run without the wild sample (its largest error over the second half against the sine's
 *     derivative) of that run's estimate.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obs_bind.h"

#define ST(name) OBS_SIZE(name)
#define MAX_RUN 4
#define MAX_OPS 64

typedef struct {
    const uint8_t *d;
    size_t n;
} source;

static int next_byte(source *in)
{
    if (in->n == 0) return -1;
    --in->n;
    return *in->d++;
}

/* The target's real type (double, or float for a single-precision target). */
typedef OBS_REAL real;

static real number(source *in)
{
    static const double special_d[16] = {0.0, -0.0, 1.0, -1.0, 1e300, -1e300, DBL_MAX, -DBL_MAX,
                                         NAN, INFINITY, -INFINITY, 4.9e-324, -4.9e-324,
                                         2.2250738585072014e-308, 1e-300, 0.5};
    static const float special_f[16] = {0.0f, -0.0f, 1.0f, -1.0f, 1e30f, -1e30f, FLT_MAX, -FLT_MAX,
                                        NAN, INFINITY, -INFINITY, 1.4e-45f, -1.4e-45f,
                                        1.17549435e-38f, 1e-30f, 0.5f};
    int b = next_byte(in), i;
    uint8_t raw[sizeof(real)] = {0};
    real v;
    if (b < 0) return 0;
    if (b < 16) return sizeof(real) == sizeof(float) ? (real)special_f[b] : (real)special_d[b];
    if (b < 240) return (real)(b - 128) / 16;
    for (i = 0; i < (int)sizeof(real); ++i) {
        int c = next_byte(in);
        raw[i] = (uint8_t)(c < 0 ? 0 : c);
    }
    memcpy(&v, raw, sizeof v);
    return v;
}

static void numbers(source *in, real *v, int n)
{
    int i;
    for (i = 0; i < n; ++i) v[i] = number(in);
}

static int finite(const real *v, int n)
{
    int i;
    for (i = 0; i < n; ++i)
        if (!isfinite(v[i])) return 0;
    return 1;
}

static void fail(const char *what, int status)
{
    fprintf(stderr, "fuzz_step(%s): %s (status %d: %s)\n", OBS_NAME, what, status,
            obs_status_name(status));
    abort();
}

/* The persistent part of the state (what "left unchanged" means). */
static int same_state(const OBS_STATE *a, const OBS_STATE *b)
{
    return memcmp(a->x, b->x, sizeof a->x) == 0 && memcmp(a->p, b->p, sizeof a->p) == 0
        && memcmp(a->y_prev, b->y_prev, sizeof a->y_prev) == 0
        && memcmp(a->u_prev, b->u_prev, sizeof a->u_prev) == 0
        && memcmp(a->m_prev, b->m_prev, sizeof a->m_prev) == 0 && a->primed == b->primed
        && memcmp(&a->t_last, &b->t_last, sizeof a->t_last) == 0 && a->stamped == b->stamped
        && a->skip == b->skip && a->clipped == b->clipped && a->skipped == b->skipped
        && memcmp(&a->t_skip, &b->t_skip, sizeof a->t_skip) == 0;
}

/* The declared ranges, from the header's macros (the contract, not the C's own check). */
static const real y_lower[OBS_LEN(OBS_NY)] = ST(Y_LOWER), y_upper[OBS_LEN(OBS_NY)] = ST(Y_UPPER);
static const real u_max[OBS_LEN(OBS_NU)] = ST(U_MAX);

static int in_range(const real *y, const real *u)
{
    int i;
    for (i = 0; i < OBS_NY; ++i)
        if (!(y[i] >= y_lower[i] && y[i] <= y_upper[i])) return 0;
    for (i = 0; u && i < OBS_NU; ++i)
        if (!(u[i] >= -u_max[i] && u[i] <= u_max[i])) return 0;
    return 1;
}

/* What a sample of a state s should return, dt aside: OK, ERR_NONFINITE_INPUT, ERR_OUT_OF_RANGE,
   or SKIPPED (the skip mode after the first sample). */
static int expected(const OBS_STATE *s, const real *y, const real *u)
{
    int st = !(finite(y, OBS_NY) && finite(u, OBS_NU)) ? ST(ERR_NONFINITE_INPUT)
             : !in_range(y, u) ? ST(ERR_OUT_OF_RANGE) : ST(OK);
    return st != ST(OK) && s->skip && s->primed ? ST(SKIPPED) : st;
}

/* The longest elapsed time one step_dt takes. */
static real dt_limit(void)
{
    return (real)ST(SPLIT_MAX) * ST(DT_MAX);
}

/* dt is a valid elapsed time for state s (first-order hold: with the time skipped since its last
   accepted sample). */
static int dt_ok(const OBS_STATE *s, real dt)
{
    return dt > 0 && dt <= dt_limit() && (!ST(HOLD_FOH) || dt + s->t_skip <= dt_limit());
}

/* An elapsed time: the limit, just above it, or DT times a number. */
static real elapsed(source *in)
{
    int b = next_byte(in);
    real top = dt_limit();
    if (b == 0) return top;
    if (b == 1) return top + top * (sizeof(real) == sizeof(float) ? (real)FLT_EPSILON : (real)DBL_EPSILON);
    return ST(DT) * number(in);
}

/* run_t()'s documented interval: b - a, or DT when within STAMP_TOL max(|a|, |b|) of it. */
static real stamp_interval(real a, real b)
{
    real h = b - a, d = h > ST(DT) ? h - ST(DT) : ST(DT) - h, m = a < 0 ? -a : a, mb = b < 0 ? -b : b;
    if (mb > m) m = mb;
    return isfinite(h) && d <= ST(STAMP_TOL) * m ? ST(DT) : h;
}

/* A call given inputs that are all finite (or not): the documented statuses. */
static void check_status(int status, int inputs_finite, int may_fail_result, const char *call)
{
    if (!inputs_finite && status != ST(ERR_NONFINITE_INPUT)) fail(call, status);
    if (inputs_finite && status != ST(OK) && !(may_fail_result && status == ST(ERR_NONFINITE_RESULT)))
        fail(call, status);
}

/* A sample's status against what() expects of it (a non-finite result allowed for a finite one). */
static void check_sample(int status, int want, const char *call)
{
    if (status != want && !(want != ST(ERR_NONFINITE_INPUT) && want != ST(ERR_OUT_OF_RANGE)
                            && status == ST(ERR_NONFINITE_RESULT)))
        fail(call, status);
}

static int changed(int status)
{
    return status == ST(OK) || status == ST(SKIPPED);
}

/* 1 when a velocity estimate of est lies beyond the header's V_BOUND. */
static int at_bound(const real *est)
{
    static const int slot[OBS_LEN(ST(NV))] = ST(V_SLOTS);
    static const real bound[OBS_LEN(ST(NV))] = ST(V_BOUND);
    int i;
    for (i = 0; i < ST(NV); ++i)
        if (est[slot[i]] < -bound[i] || est[slot[i]] > bound[i]) return 1;
    return 0;
}

/* A SKIPPED step_dt(dt) of `before` (estimate est, state after), bit for bit: first-order hold,
   the estimate estimate_dt(dt) gives on the last accepted sample, the state kept but for the time
   skipped, the stamp and the counters; zero-order hold, the step_dt(dt) of the last accepted
   sample, one more skip. */
static void check_skipped(const OBS_STATE *before, const OBS_STATE *after, real dt, const real *est, const char *call)
{
    OBS_STATE t = *before;
    real e[OBS_LEN(OBS_NEST)], y[OBS_LEN(OBS_NY)], u[OBS_LEN(OBS_NU)];
    int st;
    memcpy(y, before->y_prev, sizeof y);
    memcpy(u, before->u_prev, sizeof u);
    if (ST(HOLD_FOH)) {
        st = OBS_FN(estimate_dt)(&t, dt, y, u, e);
        t.t_skip += dt;
        t.t_last += dt;
        t.clipped += (unsigned long)at_bound(e);
    } else {
        st = OBS_FN(step_dt)(&t, dt, y, u, e);
    }
    t.skipped += 1;
    if (st != ST(OK) || memcmp(e, est, sizeof e) != 0 || !same_state(&t, after))
        fail(call, st);
}

static void step_op(OBS_STATE *s, source *in)
{
    real y[OBS_LEN(OBS_NY)], u[OBS_LEN(OBS_NU)], est[OBS_LEN(OBS_NEST)];
    OBS_STATE before = *s;
    int st;
    numbers(in, y, OBS_NY);
    numbers(in, u, OBS_NU);
    st = OBS_FN(step)(s, y, u, est);
    check_sample(st, dt_ok(&before, ST(DT)) ? expected(&before, y, u) : ST(ERR_BAD_ARG), "step: status");
    if (!changed(st) && !same_state(s, &before)) fail("step: state changed on error", st);
    if (changed(st) && !(finite(est, OBS_NEST) && finite(s->x, OBS_NX)))
        fail("step: OK with a non-finite estimate or state", st);
    if (st == ST(SKIPPED)) check_skipped(&before, s, ST(DT), est, "step: SKIPPED is not the held sample's step");
}

static void step_dt_op(OBS_STATE *s, source *in)
{
    real y[OBS_LEN(OBS_NY)], u[OBS_LEN(OBS_NU)], est[OBS_LEN(OBS_NEST)], est2[OBS_LEN(OBS_NEST)];
    OBS_STATE before = *s, t = *s;
    int st, st2;
    real dt = elapsed(in);
    numbers(in, y, OBS_NY);
    numbers(in, u, OBS_NU);
    st = OBS_FN(step_dt)(s, dt, y, u, est);
    if (!dt_ok(&before, dt)) {
        if (st != ST(ERR_BAD_ARG)) fail("step_dt: a dt outside (0, SPLIT_MAX * DT_MAX] is not ERR_BAD_ARG", st);
    } else {
        check_sample(st, expected(&before, y, u), "step_dt: status");
    }
    if (!changed(st) && !same_state(s, &before)) fail("step_dt: state changed on error", st);
    if (changed(st) && !(finite(est, OBS_NEST) && finite(s->x, OBS_NX)))
        fail("step_dt: OK with a non-finite estimate or state", st);
    if (st == ST(SKIPPED)) check_skipped(&before, s, dt, est, "step_dt: SKIPPED is not the held sample's step");
    if (dt == ST(DT)) {                     /* step() is step_dt(DT) */
        st2 = OBS_FN(step)(&t, y, u, est2);
        if (st2 != st || (changed(st) && (memcmp(est, est2, sizeof est) != 0 || !same_state(s, &t))))
            fail("step_dt(DT) differs from step()", st2);
    }
}

static void estimate_dt_op(OBS_STATE *s, source *in)
{
    real y[OBS_LEN(OBS_NY)], u[OBS_LEN(OBS_NU)], est[OBS_LEN(OBS_NEST)], est2[OBS_LEN(OBS_NEST)];
    OBS_STATE before = *s, t;
    int st, st2;
    real dt = elapsed(in);
    numbers(in, y, OBS_NY);
    numbers(in, u, OBS_NU);
    st = OBS_FN(estimate_dt)(s, dt, y, u, est);
    if (!dt_ok(&before, dt)) {
        if (st != ST(ERR_BAD_ARG)) fail("estimate_dt: a bad dt is not ERR_BAD_ARG", st);
    } else {
        check_sample(st, expected(&before, y, u), "estimate_dt: status");
    }
    if (!same_state(s, &before)) fail("estimate_dt: state changed", st);
    if (!changed(st)) return;
    if (!finite(est, OBS_NEST)) fail("estimate_dt: OK with a non-finite estimate", st);
    t = *s;
    st2 = OBS_FN(step_dt)(&t, dt, y, u, est2);
    if (st2 == st && memcmp(est, est2, sizeof est) != 0)
        fail("estimate_dt: differs from the estimate step_dt() returns", st2);
}

/* run_t over stamps t[0] = a number, t[k] = t[k-1] + DT * a number: equals step_dt() one by one
   over the intervals the header documents. */
static void run_t_op(OBS_STATE *s, source *in)
{
    real Y[MAX_RUN * OBS_LEN(OBS_NY)], U[MAX_RUN * OBS_LEN(OBS_NU)], T[MAX_RUN];
    real EST[MAX_RUN * OBS_LEN(OBS_NEST)], est[OBS_LEN(OBS_NEST)], h;
    OBS_STATE before = *s, t = *s;
    long n = 1 + (long)(next_byte(in) & 3), done = -1, k;
    int st, st_k = ST(OK), skipped = 0;
    T[0] = number(in);
    for (k = 1; k < n; ++k) T[k] = T[k - 1] + ST(DT) * number(in);
    numbers(in, Y, (int)(n * OBS_NY));
    numbers(in, U, (int)(n * OBS_NU));
    st = OBS_FN(run_t)(s, n, T, Y, U, EST, &done);
    for (k = 0; k < n; ++k) {
        if (!isfinite(T[k]) || (!ST(HOLD_FOH) && k + 1 < n && !isfinite(T[k + 1]))) {
            st_k = ST(ERR_BAD_ARG);
            break;
        }
        if (ST(HOLD_FOH)) {
            if (k > 0) h = stamp_interval(T[k - 1], T[k]);
            else if (!t.primed) h = ST(DT);
            else if (t.stamped) h = stamp_interval(t.t_last, T[0]);
            else {
                st_k = ST(ERR_BAD_ARG);
                break;
            }
        } else {
            h = k + 1 < n ? stamp_interval(T[k], T[k + 1]) : ST(DT);
        }
        st_k = OBS_FN(step_dt)(&t, h, Y + k * OBS_NY, U + k * OBS_NU, est);
        if (st_k == ST(SKIPPED)) {
            skipped = 1;
            st_k = ST(OK);
        }
        if (st_k != ST(OK)) break;
        t.t_last = T[k];
        t.stamped = 1;
        if (memcmp(est, EST + k * OBS_NEST, sizeof(real) * OBS_NEST) != 0)
            fail("run_t: estimate differs from step_dt()'s", st);
    }
    if (st_k == ST(OK) && skipped) st_k = ST(SKIPPED);
    if (st != st_k || done != k) fail("run_t: status or n_done differs from step_dt() one by one", st);
    if (!changed(st) && !same_state(s, &before)) fail("run_t: state not rolled back on error", st);
    if (changed(st) && !same_state(s, &t)) fail("run_t: state differs from step_dt() one by one", st);
}

static void estimate_op(OBS_STATE *s, source *in)
{
    real y[OBS_LEN(OBS_NY)], u[OBS_LEN(OBS_NU)], est[OBS_LEN(OBS_NEST)], est2[OBS_LEN(OBS_NEST)];
    OBS_STATE before = *s, t;
    int st, st2;
    numbers(in, y, OBS_NY);
    numbers(in, u, OBS_NU);
    st = OBS_FN(estimate)(s, y, u, est);
    check_sample(st, dt_ok(&before, ST(DT)) ? expected(&before, y, u) : ST(ERR_BAD_ARG), "estimate: status");
    if (!same_state(s, &before)) fail("estimate: state changed", st);
    if (!changed(st)) return;
    if (!finite(est, OBS_NEST)) fail("estimate: OK with a non-finite estimate", st);
    t = *s;
    st2 = OBS_FN(step)(&t, y, u, est2);
    if (st2 == st && memcmp(est, est2, sizeof est) != 0)
        fail("estimate: differs from the estimate step() returns", st2);
}

static void run_op(OBS_STATE *s, source *in)
{
    real Y[MAX_RUN * OBS_LEN(OBS_NY)], U[MAX_RUN * OBS_LEN(OBS_NU)];
    real EST[MAX_RUN * OBS_LEN(OBS_NEST)], est[OBS_LEN(OBS_NEST)];
    OBS_STATE before = *s, t = *s;
    long n = 1 + (long)(next_byte(in) & 3), done = -1, k;
    int st, st_k = ST(OK), skipped = 0;
    numbers(in, Y, (int)(n * OBS_NY));
    numbers(in, U, (int)(n * OBS_NU));
    st = OBS_FN(run)(s, n, Y, U, EST, &done);
    /* the same samples one step() at a time, from a copy of the state */
    for (k = 0; k < n; ++k) {
        st_k = OBS_FN(step)(&t, Y + k * OBS_NY, U + k * OBS_NU, est);
        if (st_k == ST(SKIPPED)) {
            skipped = 1;
            st_k = ST(OK);
        }
        if (st_k != ST(OK)) break;
        if (memcmp(est, EST + k * OBS_NEST, sizeof(real) * OBS_NEST) != 0)
            fail("run: estimate differs from step()'s", st);
    }
    if (st_k == ST(OK) && skipped) st_k = ST(SKIPPED);
    if (st != st_k || done != k) fail("run: status or n_done differs from step() one by one", st);
    if (!changed(st) && !same_state(s, &before)) fail("run: state not rolled back on error", st);
    if (changed(st) && !same_state(s, &t)) fail("run: state differs from step() one by one", st);
}

static void rhs_op(OBS_STATE *s, source *in)
{
    real x[OBS_LEN(OBS_NX)], y[OBS_LEN(OBS_NY)], u[OBS_LEN(OBS_NU)], xdot[OBS_LEN(OBS_NX)];
    OBS_STATE before = *s;
    int st;
    numbers(in, x, OBS_NX);
    numbers(in, y, OBS_NY);
    numbers(in, u, OBS_NU);
    st = OBS_FN(rhs)(s, x, y, u, xdot);
    check_status(st, finite(x, OBS_NX) && finite(y, OBS_NY) && finite(u, OBS_NU), 1, "rhs: status");
    if (!same_state(s, &before)) fail("rhs: state changed", st);
    if (st == ST(OK) && !finite(xdot, OBS_NX)) fail("rhs: OK with a non-finite xdot", st);
}

static void set_op(OBS_STATE *s, source *in, int params)
{
    real v[OBS_LEN(OBS_NX) + OBS_LEN(OBS_NP)];
    int n = params ? OBS_NP : OBS_NX, st;
    OBS_STATE before = *s;
    numbers(in, v, n);
    st = params ? OBS_FN(set_params)(s, v) : OBS_FN(set_state)(s, v);
    /* set_params retunes the state (bumpless): finite but huge values may overflow it */
    check_status(st, finite(v, n), params, params ? "set_params: status" : "set_state: status");
    if (st != ST(OK) && !same_state(s, &before)) fail("set: state changed on error", st);
    if (st == ST(OK) && memcmp(params ? s->p : s->x, v, sizeof(real) * (size_t)n) != 0)
        fail("set: value not stored", st);
    if (st == ST(OK) && params && !finite(s->x, OBS_NX)) fail("set_params: OK with a non-finite state", st);
}

static void skip_op(OBS_STATE *s, source *in)
{
    OBS_STATE before = *s;
    unsigned long c[2];
    int on = next_byte(in) & 1;
    if (OBS_FN(set_skip)(s, on) != ST(OK) || s->skip != on) fail("set_skip: not set", -1);
    before.skip = on;
    if (!same_state(s, &before)) fail("set_skip: changed more than the mode", -1);
    if (OBS_FN(counters)(s, c) != ST(OK) || c[0] != s->clipped || c[1] != s->skipped)
        fail("counters: not the state's", -1);
}

#define LONG_RUN 200

/* The wild sample in a long run (file comment): one sample of a sine run replaced. Velocity slot
   i of the estimate (V_SLOTS) is taken as the derivative of measurement i. */
static void wild_op(source *in)
{
    OBS_STATE clean, wild;
    static const int v_slot[OBS_LEN(ST(NV))] = ST(V_SLOTS);
    real y[OBS_LEN(OBS_NY)], u[OBS_LEN(OBS_NU)], yw[OBS_LEN(OBS_NY)], uw[OBS_LEN(OBS_NU)];
    real mid[OBS_LEN(OBS_NY)], amp[OBS_LEN(OBS_NY)], ec[OBS_LEN(OBS_NEST)], ew[OBS_LEN(OBS_NEST)];
    real after_c[OBS_LEN(OBS_NEST)], after_w[OBS_LEN(OBS_NEST)], err = 0;
    real w = (real)6.283185307179586 * (real)(1 + (next_byte(in) & 3));
    long k, at = LONG_RUN / 2 + (long)(next_byte(in) & 63);
    int i, slot = next_byte(in), st;
    real value = number(in);
    memset(u, 0, sizeof u);
    for (i = 0; i < OBS_NY; ++i) {          /* about the middle of the range (0 unchecked), a small sine */
        real lo = y_lower[i] > -1 ? y_lower[i] : -1, hi = y_upper[i] < 1 ? y_upper[i] : 1;
        mid[i] = (lo + hi) / 2;
        amp[i] = (hi - lo) / 8;
    }
    slot = slot < 0 ? 0 : slot % (OBS_NY + OBS_NU);
    for (i = 0; i < OBS_NY; ++i) y[i] = mid[i];
    if (OBS_FN(init)(&clean, NULL, y, NULL) != ST(OK)) fail("wild run: init in the range refused", -1);
    OBS_FN(set_skip)(&clean, 1);
    wild = clean;
    for (k = 1; k < LONG_RUN; ++k) {
        for (i = 0; i < OBS_NY; ++i) y[i] = mid[i] + amp[i] * (real)sin((double)(w * ST(DT) * (real)k));
        memcpy(yw, y, sizeof y);
        memcpy(uw, u, sizeof u);
        if (k == at) {
            if (slot < OBS_NY) yw[slot] = value;
            else uw[slot - OBS_NY] = value;
            if (in_range(yw, uw) && finite(yw, OBS_NY) && finite(uw, OBS_NU)) return;    /* not wild */
        }
        st = OBS_FN(step)(&clean, y, u, ec);
        if (st == ST(ERR_NONFINITE_RESULT)) return;           /* this observer cannot take the sine */
        if (st != ST(OK)) fail("wild run: the clean run's step", st);
        st = OBS_FN(step)(&wild, yw, uw, ew);
        if (st != (k == at ? ST(SKIPPED) : ST(OK))) fail("wild run: not SKIPPED at the wild sample alone", st);
        if (!finite(ew, OBS_NEST)) fail("wild run: a non-finite estimate", st);
        for (i = 0; i < ST(NV) && k >= LONG_RUN / 2; ++i) {   /* the clean run's error, 2nd half */
            real e = ec[v_slot[i]] - amp[i] * w * (real)cos((double)(w * ST(DT) * (real)k));
            if (e < 0) e = -e;
            if (e > err) err = e;
        }
        if (k == at + 1) {
            memcpy(after_c, ec, sizeof ec);
            memcpy(after_w, ew, sizeof ew);
        }
    }
    for (i = 0; i < ST(NV); ++i) {
        real d = after_w[v_slot[i]] - after_c[v_slot[i]];
        if (d < 0) d = -d;
        if (!(d <= err)) fail("wild run: one sample after the wild one, farther from the clean run than its error", -1);
    }
}

static void null_op(OBS_STATE *s)
{
    real y[OBS_LEN(OBS_NY)] = {0}, u[OBS_LEN(OBS_NU)] = {0}, est[OBS_LEN(OBS_NEST)];
    long done;
    OBS_STATE before = *s;
    real t0 = 0;
    if (OBS_FN(step)(NULL, y, u, est) != ST(ERR_BAD_ARG) || OBS_FN(step)(s, NULL, u, est) != ST(ERR_BAD_ARG)
        || OBS_FN(step)(s, y, u, NULL) != ST(ERR_BAD_ARG) || OBS_FN(run)(s, -1, y, u, est, &done) != ST(ERR_BAD_ARG)
        || OBS_FN(run)(s, 1, NULL, u, est, &done) != ST(ERR_BAD_ARG) || OBS_FN(set_state)(s, NULL) != ST(ERR_BAD_ARG)
        || OBS_FN(step_dt)(NULL, ST(DT), y, u, est) != ST(ERR_BAD_ARG)
        || OBS_FN(step_dt)(s, 0, y, u, est) != ST(ERR_BAD_ARG)
        || OBS_FN(estimate_dt)(s, -ST(DT), y, u, est) != ST(ERR_BAD_ARG)
        || OBS_FN(run_t)(s, 1, NULL, y, u, est, &done) != ST(ERR_BAD_ARG)
        || OBS_FN(run_t)(s, -1, &t0, y, u, est, &done) != ST(ERR_BAD_ARG))
        fail("a NULL or negative argument is not ERR_BAD_ARG", -1);
    if (!same_state(s, &before)) fail("state changed by a bad argument", ST(ERR_BAD_ARG));
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    source in = {data, size};
    real y0[OBS_LEN(OBS_NY)], est0[OBS_LEN(OBS_NEST)];
    OBS_STATE s;
    int st, ops, wild_done = 0;
    memset(&s, 0, sizeof s);
    numbers(&in, y0, OBS_NY);
    numbers(&in, est0, OBS_NEST);
    st = OBS_FN(init)(&s, NULL, y0, est0);
    if (!(finite(y0, OBS_NY) && finite(est0, OBS_NEST)) ? st != ST(ERR_NONFINITE_INPUT)
        : !in_range(y0, NULL) ? st != ST(ERR_OUT_OF_RANGE) : !(st == ST(OK) || st == ST(ERR_NONFINITE_RESULT)))
        fail("init: status", st);
    if (st != ST(OK)) return 0;
    for (ops = 0; ops < MAX_OPS && in.n > 0; ++ops) {
        switch (next_byte(&in) % 12) {
        case 0: step_op(&s, &in); break;
        case 1: run_op(&s, &in); break;
        case 2: estimate_op(&s, &in); break;
        case 3: rhs_op(&s, &in); break;
        case 4: set_op(&s, &in, 0); break;
        case 5: set_op(&s, &in, 1); break;
        case 6: step_dt_op(&s, &in); break;
        case 7: estimate_dt_op(&s, &in); break;
        case 8: run_t_op(&s, &in); break;
        case 10: skip_op(&s, &in); break;
        case 11:
            if (!wild_done) wild_op(&in);
            wild_done = 1;
            break;
        default: null_op(&s); break;
        }
    }
    return 0;
}
