"""Step Function -> generated/<target>/ : CasADi kernels, C wrapper, header, build files, metadata.

Bytes only: nothing here knows any particular observer. The C wrapper, header, Makefile and
CMakeLists.txt are the template files of ``codegen/pipeline/templates/`` (package data) with their
``{{name}}`` placeholders filled from the metadata (``template_values``); CasADi writes the kernels.
The folder is written to a temporary sibling and swapped into place in one step
(``codegen.core.atomic``), so a failure never leaves half a target and a concurrent reader never
finds it absent; the process's working directory is never changed. Same inputs give
byte-identical files.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import shutil
import tempfile
from importlib import resources
from pathlib import Path

import casadi as ca
import numpy as np

from ..core.atomic import replace_dir
from ..core.version import __version__
from ..discrete.discretize import discretize, estimate
from ..core.spec import ObserverSpec, real_number
from ..discrete.stability import require_stable
from ..core.target import AUTO, REAL_TYPES, SPLIT_MAX, STAMP_ULPS, sanitize

HOLD_TEXT = {
    "zoh": "zero-order hold: y and u are held over [t_k, t_k+1];\n * step() returns the estimate at t_k, then advances the state to t_k+1.",
    "foh": "first-order hold: step() first brings the state from t_k-1 to t_k with y\n"
           " * linear between the last and this sample and the last input held, then returns the estimate at t_k.",
}

HYBRID_TEXT = " Hybrid: the jump map is applied at each sample before the estimate."
SPLIT_TEXT = ("\n * The model (M, C, g, F) is evaluated once per sub-step, at the configuration y of\n"
              " * the sub-step's midpoint; the gain terms see y linear in time.")

TEMPLATES = {"observer.h.in": "{prefix}.h", "observer.c.in": "{prefix}.c", "Makefile.in": "Makefile",
             "CMakeLists.txt.in": "CMakeLists.txt"}   # template -> file of the target folder

DT_TEXT = {
    "foh": ("First-order hold: dt is the time since the last sample.",
            "dt the time since the last sample",
            ("the interval before sample k,\n   t_k - t_k-1; for k = 0 since t_last, the stamp of "
             "the state's last sample (right after init nothing\n   is integrated before it; a "
             "state stepped since init by step() or step_dt() only has none: ERR_BAD_ARG).")),
    "zoh": ("Zero-order hold: dt is the time to the next sample (the step advances over it).",
            "dt the time to the next sample (the zero-order hold advances over it)",
            ("the interval after sample k,\n   t_k+1 - t_k; after the last sample DT (the next "
             "stamp is not known yet).")),
}

STATUS = {"OK": 0, "ERR_BAD_ARG": 1, "ERR_NONFINITE_INPUT": 2, "ERR_NONFINITE_RESULT": 3,
          "ERR_KERNEL": 4}


def _num(x, precision="double"):
    """A C literal of ``precision`` that round-trips exactly: the shortest repr of the double,
    or of the nearest float with an ``f`` suffix (so no double constant enters float code)."""
    x = float(x)
    single = precision == "float"
    if not math.isfinite(x) or (single and abs(x) > float(np.finfo(np.float32).max)):
        raise ValueError(f"non-finite default value {x!r} in {precision} precision")
    s = str(np.float32(x)) if single else repr(x)
    s = s if ("e" in s or "." in s) else s + ".0"
    return s + "f" if single else s


def _bind_real(code, prefix, precision):
    """Make CasADi's kernel file (or header) take its real type from ``<prefix>.h`` (one real type,
    set in one place); in single precision also the float math functions (``sin(`` -> ``sinf(``)
    and float constants (``2.*x`` -> ``2.f*x``): no double promotion anywhere."""
    block = f"#ifndef casadi_real\n#define casadi_real {REAL_TYPES[precision]}\n#endif\n"
    if block not in code:
        raise RuntimeError(f"CasADi {ca.__version__}: no casadi_real definition block in the kernels")
    code = code.replace(block, f'#include "{prefix}.h"\n#undef casadi_real\n'
                               f"#define casadi_real {prefix}_real  /* the target's real type ({prefix}.h) */\n")
    if precision == "float":
        code = _MATH_CALL.sub(r"\1f(", _FLOATING_LITERAL.sub(_float_literal, code))
    return code


def _float_literal(match):
    """A double constant as a float one; a constant float cannot hold (a guard such as 1e-300,
    a bound such as 1e300) becomes the nearest float of the same role: FLT_MIN or FLT_MAX."""
    text, x = match.group(1), float(match.group(1))
    with np.errstate(over="ignore"):
        f = np.float32(x)
    if x != 0 and f == 0:
        return str(np.finfo(np.float32).tiny) + "f"
    if not np.isfinite(f):
        return str(np.finfo(np.float32).max) + "f"
    return text + "f"


# a C floating constant without suffix (1., .5, 2.5e-03, 1e3), not part of a name or a version
_FLOATING_LITERAL = re.compile(r"(?<![\w.])((?:\d+\.\d*|\.\d+)(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+)(?![\w.])")
# the C99 <math.h> functions with a float variant (name + "f"); a call of one (not casadi_sin()
MATH_FUNCTIONS = (r"a?(?:sin|cos|tan)h?|atan2|exp2?|expm1|log(?:10|1p|2|b)?|cbrt|fabs|hypot|pow|sqrt"
                  r"|erfc?|[lt]gamma|ceil|floor|nearbyint|rint|round|trunc|fmod|remainder|copysign|fdim"
                  r"|fmax|fmin|fma")
_MATH_CALL = re.compile(rf"(?<![\w.])({MATH_FUNCTIONS})\(")


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


def metadata(spec, target, kernels, stability=None):
    """The target's metadata JSON (dict): what was built (the Target, the spec's declared data),
    what the C holds (sizes, slot names, defaults, kernels, status codes, fingerprints) and the
    discrete stability check of the default parameters (codegen.discrete.stability)."""
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
        "discretization": {**d.to_dict(), "hybrid": spec.jump is not None, "dt_min": d.dt_range[0],
                           "dt_max": d.dt_range[1], "split_max": SPLIT_MAX,
                           "stamp_tol": STAMP_ULPS * float(np.finfo(np.float32 if target.precision == "float"
                                                                    else np.float64).eps)},
        "rate_states": list(spec.rate_states),
        "rhs_split": spec.rhs_split is not None,
        "rhs_model": spec.model_size,
        "gains": {g: list(slots) for g, slots in spec.gains.items()},
        "stability": stability,
        "kernels": kernels,
        "status": STATUS,
        "precision": target.precision,
        "generator": {"codegen": __version__, "casadi": ca.__version__},
        "design": spec.design,
    }


def emit(target, out_dir, spec=None, force=True, check=True):
    """Write the C of a target into ``out_dir/<prefix>/`` (folders 0755, files 0644).

    Parameters
    ----------
    target : codegen.core.target.Target or codegen.core.spec.ObserverSpec
        What to build and how (a spec stands for ``spec.target()``: default discretisation).
    out_dir : str or Path
        Parent folder; the target's folder is written to a temporary sibling and renamed.
    spec : ObserverSpec, optional
        The spec the target describes, when already built (otherwise built from the target).
    force : bool
        Replace a folder generated from another target; False: raise FolderTaken instead
        (before building anything).
    check : bool
        Refuse discretely unstable default parameters (codegen.discrete.stability.require_stable);
        False skips the check and records it as not checked (benchmarks of the C alone).

    Returns
    -------
    Path
        The target's folder.
    """
    if isinstance(target, ObserverSpec):
        target, spec = target.target(), target
    if not force:
        check_folder(Path(out_dir) / target.prefix, target)
    if spec is None:
        from .targets_file import build_spec
        spec = build_spec(target)
    if target.params:
        spec = with_params(spec, target.params)
    target = resolve_substeps(target, spec)        # substeps "auto": the fewest stable ones
    stability = (require_stable(spec, target.discretization).as_dict() if check  # before writing
                 else {"checked": False, "gains": {}, "reason": "emit(check=False)"})
    prefix = target.prefix
    fns = {"step": discretize(spec, target.discretization, target.inline),
           "estimate": estimate(spec, target.discretization, target.inline), "rhs": spec.rhs,
           "init": spec.init, "retune": retune_function(spec)}
    kernels = {}
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{prefix}.", dir=out_dir))
    try:
        cg = ca.CodeGenerator(f"{prefix}_kernels.c", {"with_header": True, "casadi_int": "int",
                                                      "casadi_real": REAL_TYPES[target.precision],
                                                      "verbose": False})
        # a step that calls the spec's functions (MX, discretize.INLINE_LIMIT) shares their
        # bodies with the rhs and init kernels, which then call them rather than copy them
        calls = not fns["step"].is_a("SXFunction")
        for key, f in fns.items():
            ins = f.mx_in() if calls or f.is_a("MXFunction") else f.sx_in()
            named = ca.Function(f"{prefix}_k_{key}", ins, f.call(ins))
            cg.add(named)
            kernels[key] = {"name": named.name(), "n_instructions": int(named.n_instructions()),
                            "sz_arg": int(named.sz_arg()), "sz_res": int(named.sz_res()),
                            "sz_iw": int(named.sz_iw()), "sz_w": int(named.sz_w())}
        cg.generate(str(tmp) + os.sep)       # a directory prefix: no chdir (thread-safe)
        for kfile in (tmp / f"{prefix}_kernels.c", tmp / f"{prefix}_kernels.h"):
            code = _bind_real(kfile.read_text(), prefix, target.precision)
            kfile.write_text(_void_unused(code) if kfile.suffix == ".c" else code)
        meta = metadata(spec, target, kernels, stability)
        values = template_values(meta)
        for template, name in TEMPLATES.items():
            (tmp / name.format(prefix=prefix)).write_text(render(template, values))
        (tmp / f"{prefix}.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
        for f in tmp.iterdir():
            f.chmod(0o644)
        tmp.chmod(0o755)                     # mkdtemp makes 0700
        final = out_dir / prefix
        old = replace_dir(tmp, final)    # one step: the folder is never absent nor mixed
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return final
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def resolve_substeps(target, spec):
    """``target`` with substeps "auto" replaced by the fewest stable ones for ``spec`` (its
    parameters applied) (codegen.discrete.stability.auto_substeps: from 1 up, UnstableDiscretization
    naming the cause and the fix when none up to 64 is); any other target unchanged.

    Parameters
    ----------
    target : codegen.core.target.Target
    spec : codegen.core.spec.ObserverSpec
        The spec ``target`` describes, with the target's parameters applied.

    Returns
    -------
    codegen.core.target.Target
    """
    if target.discretization.substeps != AUTO:
        return target
    from ..discrete.stability import auto_substeps
    return dataclasses.replace(target, discretization=auto_substeps(spec, target.discretization))


class FolderTaken(ValueError):
    """The output folder holds something else than the target (emit(force=False) refuses)."""


def check_folder(folder, target):
    """Raise FolderTaken if ``folder`` exists and was not generated from ``target`` (compared
    with the Target recorded in its metadata JSON); nothing if it is absent or the same target."""
    folder = Path(folder)
    if not folder.exists():
        return
    try:
        recorded = json.loads((folder / f"{folder.name}.json").read_text())["target"]
    except (OSError, ValueError, KeyError, TypeError):
        raise FolderTaken(f"{folder} exists and is not a generated target; force (--force) replaces "
                          "it, a name (--name) writes elsewhere") from None
    mine = target.to_dict()
    diff = [f"{k}: {_short(recorded.get(k))} -> {_short(mine[k])}" for k in mine if recorded.get(k) != mine[k]]
    if diff:
        raise FolderTaken(f"{folder} holds another target ({'; '.join(diff)}); force (--force) "
                          "replaces it, a name (--name) writes elsewhere")


def _short(value, width=60):
    text = json.dumps(value, sort_keys=True)
    return text if len(text) <= width else text[:width - 3] + "..."


def retune_function(spec):
    """``spec.retune``, or the identity (x, y, p_old, p_new) -> x when the estimate does not
    depend on the parameters through the state."""
    if spec.retune is not None:
        return spec.retune
    x, y = ca.SX.sym("x", spec.nx), ca.SX.sym("y", spec.ny)
    p_old, p_new = ca.SX.sym("p_old", spec.np), ca.SX.sym("p_new", spec.np)
    return ca.Function("retune", [x, y, p_old, p_new], [x])


def with_params(spec, params):
    """A copy of ``spec`` whose default parameters are overridden by ``params`` (name -> value)."""
    unknown = set(params) - set(spec.p_names)
    if unknown:
        raise ValueError(f"params: unknown parameter(s) {sorted(unknown)} of {spec.family}; "
                         f"known: {spec.p_names}")
    p = spec.p_default.copy()
    for k, v in params.items():
        p[spec.p_names.index(k)] = real_number(f"params[{k!r}]", v)
    return dataclasses.replace(spec, p_default=p)


# --------------------------------------------------------------------------- templates
_PLACEHOLDER = re.compile(r"\{\{(\w+)\}\}")


def render(template, values):
    """The text of ``codegen/pipeline/templates/<template>`` with each ``{{name}}`` replaced by ``values[name]``.

    Parameters
    ----------
    template : str
        File name in ``codegen/pipeline/templates/`` (e.g. "observer.h.in").
    values : dict
        Placeholder name -> value (written with ``str``); see ``template_values``.

    Returns
    -------
    str
    """
    text = (resources.files(__package__) / "templates" / template).read_text()
    missing = sorted(set(_PLACEHOLDER.findall(text)) - set(values))
    if missing:
        raise ValueError(f"values: no value for placeholder(s) {missing} of template {template}")
    return _PLACEHOLDER.sub(lambda m: str(values[m.group(1)]), text)


def template_values(meta):
    """The placeholders of the templates, from the metadata ``meta`` alone (dict name -> value); the blocks
    repeated per slot (slot macros, status codes) are made here, the templates only substitute."""
    prefix, s, d, k = meta["prefix"], meta["sizes"], meta["discretization"], meta["kernels"]
    P, precision = prefix.upper(), meta.get("precision", "double")
    status = "\n".join(f"  {P}_{name} = {code}," for name, code in meta["status"].items())
    return {
        "prefix": prefix, "PREFIX": P, "family": _comment(meta["family"]),
        "robot": _comment(sanitize(meta["robot"]["name"])),
        "codegen_version": meta["generator"]["codegen"], "casadi_version": meta["generator"]["casadi"],
        "real": REAL_TYPES[precision], "precision": precision,
        "method": d["method"], "dt": _num(d["dt"], precision), "dt_text": _num(d["dt"]),
        "dt_min": _num(d["dt_min"], precision), "dt_max": _num(d["dt_max"], precision),
        "split_max": d["split_max"], "stamp_tol": _num(d["stamp_tol"], precision), "stamp_ulps": STAMP_ULPS,
        **dict(zip(("dt_text_hold", "dt_arg_text", "run_t_text"), DT_TEXT[d["hold"]])),
        "substeps": d["substeps"],
        "hold_text": HOLD_TEXT[d["hold"]] + (SPLIT_TEXT if d["hold"] == "foh" and meta.get("rhs_split")
                                             else ""),
        "hold_foh": int(d["hold"] == "foh"),
        "hybrid_text": HYBRID_TEXT if d["hybrid"] else "",
        **{n: s[n] for n in ("nx", "ny", "nu", "np", "nest")},
        **{f"{v}_len": max(1, s["n" + v]) for v in ("x", "y", "u", "p", "est")},  # C: no empty arrays
        **{key: max(v[key] for v in k.values()) for key in ("sz_arg", "sz_res")},
        **{key: max(1, max(v[key] for v in k.values())) for key in ("sz_iw", "sz_w")},
        "slot_macros": "\n".join(_slot_macros(P, meta["names"])), "status_enum": status,
        "stability_macros": "\n".join(_stability_macros(P, meta["stability"])),
        "p_default": ", ".join(_num(v, precision) for v in meta["p_default"]) or "0",
    }


def _stability_macros(P, report):
    """``#define <P>_<GAIN>_MAX_STABLE <value>`` per declared gain, and the spectral radius
    (nothing for a spec the check does not cover: a plant)."""
    if not report.get("checked", True):
        return [f"/* not checked: {report.get('reason', 'no measurement (a plant, not an observer)')} */"]
    out = [f"#define {P}_SPECTRAL_RADIUS {_num(report['spectral_radius'])}  "
           "/* of the linearised step at the default parameters */"]
    for g, v in report["gains"].items():
        if v["max_stable"] is None:
            continue
        note = "" if v["limit_found"] else "  /* no instability found up to this value */"
        out.append(f"#define {P}_{sanitize(g).upper()}_MAX_STABLE {_num(v['max_stable'])}{note}")
    return out


def _slot_macros(P, names):
    """``#define <P>_<KIND>_<NAME> <index>`` per slot of x, y, u, p, est.

    Names equal after sanitising (k_m and k_M; x and x.) get the slot index as a suffix,
    repeated until the macro is new (x_2, x, x. -> X_2, X, X_2_2): each macro is defined once."""
    out, used = [], set()
    for kind, slots in names.items():
        for i, nm in enumerate(slots):
            macro = f"{P}_{kind.upper()}_{sanitize(nm).upper()}"
            while macro in used:
                macro = f"{macro}_{i}"
            used.add(macro)
            out.append(f"#define {macro} {i}")
    return out
