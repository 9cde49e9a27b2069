"""Step Function -> generated/<target>/ : CasADi kernels, C wrapper, header, build files, metadata.

Bytes room: nothing here knows any particular observer. The folder is written to a
temporary sibling and renamed into place, so a failure never leaves half a target.
Same inputs give byte-identical files.
"""
from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from . import __version__
from .discretize import discretize, estimate
from .spec import ObserverSpec
from .target import sanitize

HOLD_TEXT = {
    "zoh": "zero-order hold: y and u are held over [t_k, t_k+1];\n * step() returns the estimate at t_k, then advances the state to t_k+1.",
    "foh": "first-order hold: step() first brings the state from t_k-1 to t_k with y\n"
           " * linear between the last and this sample and the last input held, then returns the estimate at t_k.",
}

STATUS = {"OK": 0, "ERR_BAD_ARG": 1, "ERR_NONFINITE_INPUT": 2, "ERR_NONFINITE_RESULT": 3,
          "ERR_KERNEL": 4}


def _num(x):
    """A C double literal that round-trips exactly."""
    s = repr(float(x))
    if s in ("inf", "-inf", "nan"):
        raise ValueError(f"non-finite default value {s}")
    return s if ("e" in s or "." in s) else s + ".0"


def _void_unused(code):
    """CasADi's kernels leave parameters unused; cast them to void so that
    -Wall -Wextra -Werror -pedantic passes (portable, unlike a pragma)."""
    out = []
    for line in code.splitlines():
        out.append(line)
        m = re.match(r"^(?:static |CASADI_SYMBOL_EXPORT )?[\w\* ]+?\b\w+\((.+)\) \{$", line)
        if m and not line.startswith(("if", "for", "while", "switch")):
            names = [re.findall(r"\w+", a)[-1] for a in m.group(1).split(",") if a.strip() != "void"]
            if names:
                out.append("  " + " ".join(f"(void){n};" for n in names))
    return "\n".join(out) + "\n"


def _comment(text):
    return str(text).replace("*/", "* /").replace("\n", " ")


def metadata(spec, target, kernels):
    """The target's metadata JSON (dict): what was built (the Target, the spec's declared data)
    and what the C holds (sizes, slot names, defaults, kernels, status codes, fingerprints)."""
    d = target.discretization
    return {
        "prefix": target.prefix,
        "family": spec.family,
        "variant": spec.variant,
        "target": target.to_dict(),
        "robot": {"name": spec.robot.name, "n": spec.robot.n, "fingerprint": spec.robot.fingerprint,
                  "source": spec.robot_source},
        "sizes": {"nx": spec.nx, "ny": spec.ny, "nu": spec.nu, "np": spec.np, "nest": spec.nest},
        "names": {"x": spec.x_names, "y": spec.y_names, "u": spec.u_names, "p": spec.p_names,
                  "est": spec.est_names},
        "p_default": [float(v) for v in spec.p_default],
        "options": spec.options.to_dict(),
        "discretization": {**d.to_dict(), "hybrid": spec.jump is not None},
        "kernels": kernels,
        "status": STATUS,
        "generator": {"codegen": __version__, "casadi": ca.__version__},
        "design": spec.design,
    }


def emit(target, out_dir, spec=None):
    """Write the C of a target into ``out_dir/<prefix>/``.

    Parameters
    ----------
    target : codegen.target.Target or codegen.spec.ObserverSpec
        What to build and how (a spec stands for ``spec.target()``: default discretisation).
    out_dir : str or Path
        Parent folder; the target's folder is written to a temporary sibling and renamed.
    spec : ObserverSpec, optional
        The spec the target describes, when already built (otherwise built from the target).

    Returns
    -------
    Path
        The target's folder.
    """
    if isinstance(target, ObserverSpec):
        target, spec = target.target(), target
    if spec is None:
        from . import build_spec
        spec = build_spec(target)
    if target.params:
        spec = with_params(spec, target.params)
    prefix = target.prefix
    fns = {"step": discretize(spec, target.discretization, target.inline),
           "estimate": estimate(spec, target.discretization, target.inline), "rhs": spec.rhs,
           "init": spec.init}
    kernels = {}
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{prefix}.", dir=out_dir))
    try:
        cg = ca.CodeGenerator(f"{prefix}_kernels.c", {"with_header": True, "casadi_int": "int",
                                                      "casadi_real": "double", "verbose": False})
        for key, f in fns.items():
            ins = f.mx_in() if f.is_a("MXFunction") else f.sx_in()
            named = ca.Function(f"{prefix}_k_{key}", ins, f.call(ins))
            cg.add(named)
            kernels[key] = {"name": named.name(), "n_instructions": int(named.n_instructions()),
                            "sz_arg": int(named.sz_arg()), "sz_res": int(named.sz_res()),
                            "sz_iw": int(named.sz_iw()), "sz_w": int(named.sz_w())}
        cwd = os.getcwd()
        try:
            os.chdir(tmp)
            cg.generate()
        finally:
            os.chdir(cwd)
        kfile = tmp / f"{prefix}_kernels.c"
        kfile.write_text(_void_unused(kfile.read_text()))
        meta = metadata(spec, target, kernels)
        (tmp / f"{prefix}.h").write_text(_header(spec, prefix, meta))
        (tmp / f"{prefix}.c").write_text(_wrapper(spec, prefix, meta))
        (tmp / "Makefile").write_text(_makefile(prefix))
        (tmp / "CMakeLists.txt").write_text(_cmake(prefix))
        (tmp / f"{prefix}.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
        final = out_dir / prefix
        old = None
        if final.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{prefix}.old.", dir=out_dir))
            os.replace(final, old / prefix)
        os.replace(tmp, final)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return final
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def with_params(spec, params):
    """A copy of ``spec`` whose default parameters are overridden by ``params`` (name -> value)."""
    unknown = set(params) - set(spec.p_names)
    if unknown:
        raise ValueError(f"params: unknown parameter(s) {sorted(unknown)} of {spec.family}; "
                         f"known: {spec.p_names}")
    p = spec.p_default.copy()
    for k, v in params.items():
        p[spec.p_names.index(k)] = float(v)
    return dataclasses.replace(spec, p_default=p)


# --------------------------------------------------------------------------- C text
def _sizes(meta):
    k = meta["kernels"]
    return {"SZ_ARG": max(v["sz_arg"] for v in k.values()),
            "SZ_RES": max(v["sz_res"] for v in k.values()),
            "SZ_IW": max(1, max(v["sz_iw"] for v in k.values())),
            "SZ_W": max(1, max(v["sz_w"] for v in k.values()))}


def _header(spec, prefix, meta):
    P = prefix.upper()
    s, d = meta["sizes"], meta["discretization"]
    z = _sizes(meta)
    slot_macros, used = [], set()
    for kind, names in meta["names"].items():
        for i, nm in enumerate(names):
            macro = f"{P}_{kind.upper()}_{sanitize(nm).upper()}"
            if macro in used:  # names differing only in case or punctuation (k_m, k_M)
                macro = f"{macro}_{i}"
            used.add(macro)
            slot_macros.append(f"#define {macro} {i}")
    status = "\n".join(f"  {P}_{k} = {v}," for k, v in STATUS.items())
    return f"""/* {prefix}.h -- {_comment(spec.family)} observer for robot {_comment(sanitize(spec.robot.name))}.
 *
 * Generated by observer-codegen {__version__} (CasADi {ca.__version__}); do not edit.
 * Discretisation: {d['method']}, dt = {_num(d['dt'])} s, {d['substeps']} substep(s), {HOLD_TEXT[d['hold']]}
 * {' Hybrid: the jump map is applied at each sample before the estimate.' if d['hybrid'] else ''}
 *
 * C99, no heap, no mutable globals, reentrant: every buffer lives in {prefix}_state.
 * Usage:
 *   {prefix}_state s;
 *   {prefix}_init(&s, NULL, y0, NULL);          default parameters, zero initial estimate
 *   each sample: status = {prefix}_step(&s, y, u, est);
 * Every function returns a status ({P}_OK = 0); on error the state is left unchanged.
 */
#ifndef {P}_H
#define {P}_H

#ifdef __cplusplus
extern "C" {{
#endif

#define {P}_NX {s['nx']}     /* observer state size */
#define {P}_NY {s['ny']}     /* measurement size */
#define {P}_NU {s['nu']}     /* known input size */
#define {P}_NP {s['np']}     /* parameter size */
#define {P}_NEST {s['nest']}   /* estimate size */
#define {P}_DT {_num(d['dt'])}  /* step (s) */
#define {P}_HOLD_FOH {1 if d['hold'] == 'foh' else 0}  /* 1: y linear between samples (see above) */
#define {P}_SZ_W {z['SZ_W']}
#define {P}_SZ_IW {z['SZ_IW']}

/* Slot indices: state x, measurement y, input u, parameters p, estimate est. */
{chr(10).join(slot_macros)}

enum {{
{status}
}};

typedef struct {{
  double x[{max(1, s['nx'])}];       /* observer state */
  double p[{max(1, s['np'])}];       /* parameters (gains) */
  double x_next[{max(1, s['nx'])}];  /* scratch: candidate next state */
  double est[{max(1, s['nest'])}];     /* scratch: candidate estimate */
  double y_prev[{max(1, s['ny'])}];  /* last measurement (first-order hold) */
  double u_prev[{max(1, s['nu'])}];  /* last input (first-order hold) */
  int primed;              /* 0 until the first step after init */
  double w[{P}_SZ_W];       /* kernel work */
  int iw[{P}_SZ_IW];        /* kernel integer work */
}} {prefix}_state;

/* Designed default parameters into p[{P}_NP]. */
void {prefix}_default_params(double *p);
/* Initialise: parameters p (NULL: defaults), first measurement y0, initial estimate est0 (NULL: zeros). */
int {prefix}_init({prefix}_state *s, const double *p, const double *y0, const double *est0);
/* One sample: est[{P}_NEST] = estimate at this sample (see the discretisation above). */
int {prefix}_step({prefix}_state *s, const double *y, const double *u, double *est);
/* The estimate step() would return for (y, u), without advancing the state (closed loops:
   est first, then the control input, then step). */
int {prefix}_estimate(const {prefix}_state *s, const double *y, const double *u, double *est);
/* n samples, row-major Y (n x NY), U (n x NU), EST (n x NEST); *n_done = samples completed. */
int {prefix}_run({prefix}_state *s, long n, const double *Y, const double *U, double *EST, long *n_done);
/* Continuous-time right-hand side xdot = f(x, y, u, s->p) (uses s's work buffers only). */
int {prefix}_rhs({prefix}_state *s, const double *x, const double *y, const double *u, double *xdot);
/* Replace or read the parameters (set: checked finite). */
int {prefix}_set_params({prefix}_state *s, const double *p);
int {prefix}_get_params(const {prefix}_state *s, double *p);
/* Read or overwrite the observer state. */
int {prefix}_get_state(const {prefix}_state *s, double *x);
int {prefix}_set_state({prefix}_state *s, const double *x);
/* sizeof({prefix}_state), for callers that allocate it themselves (e.g. through an FFI). */
long {prefix}_state_size(void);

#ifdef __cplusplus
}} /* extern "C" */
#endif

#endif /* {P}_H */
"""


def _wrapper(spec, prefix, meta):
    P = prefix.upper()
    z = _sizes(meta)
    defaults = ", ".join(_num(v) for v in meta["p_default"]) or "0.0"
    return f"""/* {prefix}.c -- wrapper around the CasADi kernels of {prefix}_kernels.c. Generated; do not edit. */
#include <math.h>
#include <stddef.h>
#include "{prefix}.h"
#include "{prefix}_kernels.h"

static const double {prefix}_p_default[{max(1, meta['sizes']['np'])}] = {{{defaults}}};

static int {prefix}_finite(const double *v, int n) {{
  int i;
  for (i = 0; i < n; ++i) if (!isfinite(v[i])) return 0;
  return 1;
}}

static void {prefix}_copy(double *dst, const double *src, int n) {{
  int i;
  for (i = 0; i < n; ++i) dst[i] = src[i];
}}

void {prefix}_default_params(double *p) {{
  if (p) {prefix}_copy(p, {prefix}_p_default, {P}_NP);
}}

long {prefix}_state_size(void) {{ return (long)sizeof({prefix}_state); }}

int {prefix}_init({prefix}_state *s, const double *p, const double *y0, const double *est0) {{
  const double *arg[{z['SZ_ARG']}];
  double *res[{z['SZ_RES']}];
  double zeros[{max(1, meta['sizes']['nest'])}] = {{0.0}};
  if (!s || !y0) return {P}_ERR_BAD_ARG;
  if (!p) p = {prefix}_p_default;
  if (!est0) est0 = zeros;
  if (!{prefix}_finite(p, {P}_NP) || !{prefix}_finite(y0, {P}_NY) || !{prefix}_finite(est0, {P}_NEST))
    return {P}_ERR_NONFINITE_INPUT;
  arg[0] = y0; arg[1] = est0; arg[2] = p;
  res[0] = s->x_next;
  if ({prefix}_k_init(arg, res, s->iw, s->w, 0)) return {P}_ERR_KERNEL;
  if (!{prefix}_finite(s->x_next, {P}_NX)) return {P}_ERR_NONFINITE_RESULT;
  {prefix}_copy(s->p, p, {P}_NP);
  {prefix}_copy(s->x, s->x_next, {P}_NX);
  s->primed = 0;
  return {P}_OK;
}}

/* Check the arguments of step/estimate; fill the 7 kernel arguments (x, y_prev, y, u_prev, u, p, active). */
static int {prefix}_prepare(const {prefix}_state *s, const double *y, const double *u, const double *est,
                            double *active, const double **arg) {{
  if (!s || !y || !est || (!u && {P}_NU > 0)) return {P}_ERR_BAD_ARG;
  if (!{prefix}_finite(y, {P}_NY) || ({P}_NU > 0 && !{prefix}_finite(u, {P}_NU)))
    return {P}_ERR_NONFINITE_INPUT;
  *active = s->primed ? 1.0 : 0.0;
  arg[0] = s->x;
  arg[1] = s->primed ? s->y_prev : y;
  arg[2] = y;
  arg[3] = s->primed ? s->u_prev : u;
  arg[4] = u;
  arg[5] = s->p;
  arg[6] = active;
  return {P}_OK;
}}

int {prefix}_step({prefix}_state *s, const double *y, const double *u, double *est) {{
  const double *arg[{z['SZ_ARG']}];
  double *res[{z['SZ_RES']}];
  double active;
  int status = {prefix}_prepare(s, y, u, est, &active, arg);
  if (status != {P}_OK) return status;
  res[0] = s->x_next; res[1] = s->est;
  if ({prefix}_k_step(arg, res, s->iw, s->w, 0)) return {P}_ERR_KERNEL;
  if (!{prefix}_finite(s->x_next, {P}_NX) || !{prefix}_finite(s->est, {P}_NEST))
    return {P}_ERR_NONFINITE_RESULT;
  {prefix}_copy(s->x, s->x_next, {P}_NX);
  {prefix}_copy(s->y_prev, y, {P}_NY);
  if ({P}_NU > 0) {prefix}_copy(s->u_prev, u, {P}_NU);
  s->primed = 1;
  {prefix}_copy(est, s->est, {P}_NEST);
  return {P}_OK;
}}

int {prefix}_estimate(const {prefix}_state *s, const double *y, const double *u, double *est) {{
  const double *arg[{z['SZ_ARG']}];
  double *res[{z['SZ_RES']}];
  double w[{P}_SZ_W];
  int iw[{P}_SZ_IW];
  double active;
  int status = {prefix}_prepare(s, y, u, est, &active, arg);
  if (status != {P}_OK) return status;
  res[0] = est;
  if ({prefix}_k_estimate(arg, res, iw, w, 0)) return {P}_ERR_KERNEL;
  if (!{prefix}_finite(est, {P}_NEST)) return {P}_ERR_NONFINITE_RESULT;
  return {P}_OK;
}}

int {prefix}_run({prefix}_state *s, long n, const double *Y, const double *U, double *EST, long *n_done) {{
  long k;
  int status = {P}_OK;
  if (n_done) *n_done = 0;
  if (!s || n < 0 || (n > 0 && (!Y || !EST || (!U && {P}_NU > 0)))) return {P}_ERR_BAD_ARG;
  for (k = 0; k < n; ++k) {{
    status = {prefix}_step(s, Y + k * {P}_NY, {P}_NU > 0 ? U + k * {P}_NU : U, EST + k * {P}_NEST);
    if (status != {P}_OK) break;
    if (n_done) *n_done = k + 1;
  }}
  return status;
}}

int {prefix}_rhs({prefix}_state *s, const double *x, const double *y, const double *u, double *xdot) {{
  const double *arg[{z['SZ_ARG']}];
  double *res[{z['SZ_RES']}];
  if (!s || !x || !y || !xdot || (!u && {P}_NU > 0)) return {P}_ERR_BAD_ARG;
  arg[0] = x; arg[1] = y; arg[2] = u; arg[3] = s->p;
  res[0] = xdot;
  if ({prefix}_k_rhs(arg, res, s->iw, s->w, 0)) return {P}_ERR_KERNEL;
  return {P}_OK;
}}

int {prefix}_set_params({prefix}_state *s, const double *p) {{
  if (!s || !p) return {P}_ERR_BAD_ARG;
  if (!{prefix}_finite(p, {P}_NP)) return {P}_ERR_NONFINITE_INPUT;
  {prefix}_copy(s->p, p, {P}_NP);
  return {P}_OK;
}}

int {prefix}_get_params(const {prefix}_state *s, double *p) {{
  if (!s || !p) return {P}_ERR_BAD_ARG;
  {prefix}_copy(p, s->p, {P}_NP);
  return {P}_OK;
}}

int {prefix}_get_state(const {prefix}_state *s, double *x) {{
  if (!s || !x) return {P}_ERR_BAD_ARG;
  {prefix}_copy(x, s->x, {P}_NX);
  return {P}_OK;
}}

int {prefix}_set_state({prefix}_state *s, const double *x) {{
  if (!s || !x) return {P}_ERR_BAD_ARG;
  if (!{prefix}_finite(x, {P}_NX)) return {P}_ERR_NONFINITE_INPUT;
  {prefix}_copy(s->x, x, {P}_NX);
  return {P}_OK;
}}
"""


def _makefile(prefix):
    return f"""# Build lib{prefix}.a and lib{prefix}.so from the generated sources (no Python needed).
CC ?= cc
CFLAGS ?= -O3 -std=c99 -Wall -Wextra -pedantic
SRC = {prefix}.c {prefix}_kernels.c

all: lib{prefix}.a lib{prefix}.so

lib{prefix}.a: $(SRC:.c=.o)
\t$(AR) rcs $@ $^

lib{prefix}.so: $(SRC)
\t$(CC) $(CFLAGS) -fPIC -shared -o $@ $(SRC) -lm

%.o: %.c {prefix}.h {prefix}_kernels.h
\t$(CC) $(CFLAGS) -c -o $@ $<

clean:
\trm -f *.o lib{prefix}.a lib{prefix}.so

.PHONY: all clean
"""


def _cmake(prefix):
    return f"""cmake_minimum_required(VERSION 3.10)
project({prefix} C)
set(CMAKE_C_STANDARD 99)
set(CMAKE_C_STANDARD_REQUIRED ON)
add_library({prefix} {prefix}.c {prefix}_kernels.c)
target_include_directories({prefix} PUBLIC ${{CMAKE_CURRENT_SOURCE_DIR}})
find_library(M_LIB m)
if(M_LIB)
  target_link_libraries({prefix} PUBLIC ${{M_LIB}})
endif()
"""
