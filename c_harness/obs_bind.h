/*
 * obs_bind.h - bind the harness programs to one generated target at compile time.
 *
 * Compile with
 *   -DOBS=<prefix> -DOBS_UPPER=<PREFIX> -DOBS_HEADER='"<prefix>.h"' -I <target dir>
 * and the names below expand to that target's API:
 *   OBS_FN(step)  -> <prefix>_step        OBS_SIZE(NX) -> <PREFIX>_NX
 *   OBS_STATE     -> <prefix>_state       OBS_NAME     -> "<prefix>"
 *   OBS_REAL      -> <prefix>_real (the target's real type: double or float)
 */
#ifndef OBS_BIND_H
#define OBS_BIND_H

#if !defined(OBS) || !defined(OBS_UPPER) || !defined(OBS_HEADER)
#error "define OBS=<prefix>, OBS_UPPER=<PREFIX> and OBS_HEADER='\"<prefix>.h\"'"
#endif

#define OBS_CAT_(a, b) a##b
#define OBS_CAT(a, b) OBS_CAT_(a, b)
#define OBS_STR_(a) #a
#define OBS_STR(a) OBS_STR_(a)

#include OBS_HEADER

#define OBS_FN(name) OBS_CAT(OBS, OBS_CAT(_, name))
#define OBS_SIZE(name) OBS_CAT(OBS_UPPER, OBS_CAT(_, name))
#define OBS_STATE OBS_CAT(OBS, _state)
#define OBS_REAL OBS_CAT(OBS, _real)
#define OBS_NAME OBS_STR(OBS)

#define OBS_NX OBS_SIZE(NX)
#define OBS_NY OBS_SIZE(NY)
#define OBS_NU OBS_SIZE(NU)
#define OBS_NP OBS_SIZE(NP)
#define OBS_NEST OBS_SIZE(NEST)
#define OBS_DT OBS_SIZE(DT)

/* Array length that stays legal C when a size is 0 (e.g. a target without input). */
#define OBS_LEN(n) ((n) > 0 ? (n) : 1)

/* Name of a status code returned by the target's functions. */
static const char *obs_status_name(int status)
{
    if (status == OBS_SIZE(OK)) return "OK";
    if (status == OBS_SIZE(ERR_BAD_ARG)) return "ERR_BAD_ARG (bad argument)";
    if (status == OBS_SIZE(ERR_NONFINITE_INPUT)) return "ERR_NONFINITE_INPUT (NaN or Inf in y or u)";
    if (status == OBS_SIZE(ERR_NONFINITE_RESULT)) return "ERR_NONFINITE_RESULT (NaN or Inf in the result)";
    if (status == OBS_SIZE(ERR_KERNEL)) return "ERR_KERNEL (a generated kernel failed)";
    if (status == OBS_SIZE(ERR_OUT_OF_RANGE)) return "ERR_OUT_OF_RANGE (y or u outside the declared ranges)";
    if (status == OBS_SIZE(SKIPPED)) return "SKIPPED (skip mode: predicted through a rejected sample)";
    return "unknown status";
}

#endif /* OBS_BIND_H */
