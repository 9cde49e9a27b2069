"""observer-codegen (python -m codegen): list | generate | build | check | simulate | compare |
sweep | bench | sanitize | cortex_m | excite | identify | describe | design | simulate-log.

`generate`, `build`, `check` and `embedded` take the same targets: catalog robots or a URDF with
options, a targets file (-c FILE), or ./targets.toml. A mistake prints one line (--debug: the
traceback).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tomllib
from dataclasses import replace
from pathlib import Path

from .core.atomic import OutputSet, WriteError, check_not_input, check_writable, write_text
from .pipeline.compile import ToolError, work_dir
from .pipeline.emit import FolderTaken
from .core.target import HOLDS, METHODS, PRECISIONS, check_substeps
from .pipeline.targets_file import DEFAULT_FAMILY, TargetError, check_unique, load_targets, make_target

TARGETS_FILE = "targets.toml"
# optional packages -> the extra of pyproject.toml that installs them (tests/test_cli.py checks)
EXTRAS = {"mujoco": "mujoco", "rosbags": "ros", "dask": "sweep", "distributed": "sweep", "pyarrow": "sweep", "pandas": "sweep"}
USER_ERRORS = (TargetError, FolderTaken, ToolError, WriteError, ValueError, KeyError, FileNotFoundError)


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors."""

    def error(self, message):
        """Exit with status 2 and the one-line ``message`` (argparse's hook)."""
        self.exit(2, f"{self.prog}: error: {message} (--help for usage)\n")


def _message(e):
    """The one line a user error prints: a KeyError's key text, an unstable discretisation's fix in
    command-line flags (--substeps, --dt, --lock), else the error's text."""
    if getattr(e, "cli_message", None):
        return e.cli_message
    return str(e.args[0]) if isinstance(e, KeyError) and e.args else str(e)


class MissingPackage(ImportError):
    """An optional package is not installed; the message names the extra that installs it."""


def _missing(module, what="this"):
    """The MissingPackage for the optional ``module`` (top-level name) that ``what`` needs."""
    extra = EXTRAS.get(module)
    how = f"pip install 'observer-codegen[{extra}]'" if extra else f"pip install {module}"
    return MissingPackage(f"{what} needs the optional package {module}: {how}")


def _require(module, what):
    """Raise MissingPackage (one line naming the extra) when the optional ``module`` is not
    installed; ``what`` needs it (for the message)."""
    import importlib.util
    if importlib.util.find_spec(module) is None:
        raise _missing(module, what)


# ------------------------------------------------------------------------------------ targets
def _pairs(items, option, convert):
    """{NAME: convert(VALUE)} from repeated NAME=VALUE options."""
    out = {}
    for item in items or ():
        name, eq, value = item.partition("=")
        if not eq or not name:
            raise TargetError(f"{option} expects NAME=VALUE, got {item!r}")
        out[name] = convert(value, f"{option} {name}")
    return out


def _number(text, what):
    try:
        return float(text)
    except ValueError:
        raise TargetError(f"{what}: expected a number, got {text!r}") from None


def _numbers(text, what):
    """A number, or comma-separated numbers (one per joint)."""
    if text is None:
        return None
    values = [_number(v, what) for v in text.split(",")]
    return values if len(values) > 1 else values[0]


def _substeps(text):
    """--substeps: a positive integer up to SUBSTEPS_MAX, or "auto" (argparse type)."""
    if text == "auto":
        return text
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f'expected a positive integer or "auto", got {text!r}')
    try:
        return check_substeps(value)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _value(text, what):
    """A TOML value (number, bool, list, "string"), else the text itself as a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _targets(args):
    """[(Target, out folder)] the command line names (module docstring)."""
    disc = {k: getattr(args, k) for k in ("dt", "dt_min", "dt_max", "method", "hold", "substeps", "precision")
            if getattr(args, k) is not None}
    options = {"family": args.family, "variant": args.variant, "name": args.name,
               "design": _pairs(args.design, "--design", _value), "params": _pairs(args.param, "--param", _number),
               "lock": _pairs(args.lock, "--lock", _number), "elastic": args.elastic or None,
               "J": _numbers(args.J, "--J"), "K": _numbers(args.K, "--K")}
    options["sources"] = _sources(args, options["params"], options["design"])
    options = {k: v for k, v in options.items() if v not in (None, {})}
    robots = [{"robot": r} for r in args.robots] + ([{"urdf": args.urdf}] if args.urdf else [])
    if robots and args.config:
        raise TargetError("give targets on the command line (robots, --urdf) or in a file (-c), not both")
    if robots:
        if args.name and len(robots) > 1:
            raise TargetError(f"--name names one target, got {len(robots)}")
        targets = [make_target({**entry, **options, **disc}) for entry in robots]
    else:
        if options:
            given = ", ".join("--tuned-on/--source" if k == "sources" else "--" + k for k in options)
            raise TargetError(f"{given}: describe a robot given on the command line; a targets file "
                              "(-c) holds its own")
        path = Path(args.config or TARGETS_FILE)
        if not args.config and not path.exists():
            raise TargetError(f"no targets: name a catalog robot (python -m codegen list), --urdf PATH "
                              f"or -c FILE (no {TARGETS_FILE} in {Path.cwd()})")
        targets = [(_override(t, disc), out) for t, out in load_targets(path, tuner=tune_target)]
    if args.out:
        targets = [(t, Path(args.out).resolve()) for t, _ in targets]
    check_unique(targets)
    return targets


def _sources(args, params, design):
    """Where the command line's values came from (``Target.sources``): with ``--tuned-on LOG``
    the --param values tuned on the log and the --design values measured on it, then each
    ``--source NAME=TEXT``."""
    out = {}
    if getattr(args, "tuned_on", None):
        log = Path(args.tuned_on).name
        out.update({k: f"measured on the log {log}" for k in design})
        out.update({k: f"tuned on the log {log}" for k in params})
    out.update(_pairs(getattr(args, "source", None), "--source", lambda v, what: v))
    return out


def design_failure(entry, family):
    """The one line refusing the design ``entry`` of ``family`` (codegen.evaluate.verdict), with
    its remedy as a flag, or ""."""
    from .evaluate.verdict import design_failure as failure
    found = failure(entry, family)
    if found is None:
        return ""
    why, remedy = found
    return why + (f"; {remedy[1]} (--design {remedy[0]}=...) or choose another family" if remedy else "")


def _check_out(path, option, inputs=()):
    """A file output ``path`` of ``option`` checked before the work: writable, not an input."""
    if path is not None:
        check_writable(path, f"or choose another {option}")
        check_not_input([path], inputs, f"choose another {option}")


def tune_target(target, log, columns=None, topic=None):
    """``target`` with its sensor measured on the recording ``log`` (its column mapping ``columns``,
    a bag's ``topic``) and its gains tuned on it without truth (a targets file's
    ``tune = "log.csv"``, with ``tune_columns`` and ``tune_topic``;
    codegen.evaluate.compare.design_on_log): the measured design inputs under the target's own
    ``build``, the tuned parameters under its own ``params`` (what the file states wins)."""
    from models import from_source

    from .evaluate.compare import design_on_log
    robot = from_source(target.robot)
    rec, clock = _read_log(log, robot.joint_names, robot=robot, columns=columns, topic=topic)
    entry, _, _ = design_on_log(rec, robot, target.family, design=dict(target.build), clock=clock)
    failed = design_failure(entry, target.family)
    if failed:
        raise ValueError(failed)
    tuned = entry.tuned.params if entry.tuned is not None else {}
    print(f"{target.prefix}: tuned on {Path(log).name}: "
          + (", ".join(f"{k} = {v:.4g}" for k, v in tuned.items()) or "its designed gains (no bandwidth)")
          + (f"; variant {entry.variant}" if entry.variant else ""), file=sys.stderr)
    build = {**(entry.build or {}), **target.build}
    sources = {**{k: f"measured on the log {Path(log).name}" for k in build if k not in target.build},
               **{k: f"tuned on the log {Path(log).name}" for k in tuned if k not in target.params},
               **target.sources}
    return replace(target, build=build, variant=entry.variant if "torque_uncertainty" in build else target.variant,
                   params={**tuned, **target.params}, sources=sources)


def _override(target, disc):
    """``target`` with the command line's discretisation and precision (a targets file's)."""
    over = {k: v for k, v in disc.items() if k != "precision"}
    return replace(target.with_discretization(None, **over), precision=disc.get("precision", target.precision))


def _jobs(args, stages, **options):
    from .jobs import Job
    return [Job(t, out, stages, force=args.force, native=args.native, options=options)
            for t, out in _targets(args)]


def _report(jobs, args, line):
    """Run ``jobs``; print ``line(job, row)`` per finished target, an error line per failure.
    Returns (rows, number of failures)."""
    from tqdm import tqdm

    from .jobs import run
    rows, failed = [], 0
    for job, row in run(jobs, processes=args.jobs, debug=args.debug):
        if isinstance(row, Exception):
            if not isinstance(row, USER_ERRORS):
                raise row
            failed += 1
            tqdm.write(f"error: {job.target.prefix}: {_message(row)}", file=sys.stderr)
        else:
            rows.append(row)
            tqdm.write(line(job, row), file=sys.stdout)
    return rows, failed


def _times(row, stages):
    return "  ".join(f"{s} {row[s + '_s']:.1f}s" for s in stages)


# ------------------------------------------------------------------------------------ commands
def cmd_list(args):
    """`list`: print the catalog robots, the families and the targets of ./targets.toml.
    ``args``: the parsed argparse namespace; returns the exit status."""
    from models import names
    from models.catalog import ELASTIC

    from .pipeline.targets_file import family_info, families
    print("robots:   " + ", ".join(names()) + f"  (elastic defaults J, K: {', '.join(ELASTIC)})")
    print("families:")
    for f in families():
        variants, default, design, elastic = family_info(f)
        print(f"  {f:22s} {'elastic' if elastic else 'rigid':7s} "
              + (f"variants {', '.join(variants)} (default {default})  " if variants else "")
              + f"design: {', '.join(design) if design is not None else '(any)'}")
    if Path(TARGETS_FILE).exists():
        print(f"targets of ./{TARGETS_FILE}: " + ", ".join(t.prefix for t, _ in load_targets(TARGETS_FILE)))
    return 0


def cmd_generate(args):
    """Design, emit, compile, run the C harness and ctypes on each target (`make generate`).
    ``args``: the parsed argparse namespace; returns the exit status."""
    from .jobs import GENERATE

    def line(job, row):
        err, of = row.get("error"), row.get("error_of")
        conv = f"  |{of} - {of}_hat| {err[0]:.3g} -> {err[1]:.2g} at t = {row['T']:g} s" if err else ""
        return (f"{row['prefix']:38s} {_times(row, GENERATE)}  C harness == ctypes: "
                f"{row['harness_equal']}{conv}")

    jobs = _jobs(args, GENERATE, T=args.T)
    rows, failed = _report(jobs, args, line)
    folders = sorted({str(j.out) for j in jobs})
    print(f"{len(rows)} of {len(jobs)} targets in {', '.join(folders)}")
    return 2 if failed else (0 if all(r["harness_equal"] for r in rows) else 1)


def cmd_build(args):
    """Design, emit and compile each target; print its library, the designed gains and why
    (``DesignReport.brief``). ``args``: the parsed argparse namespace; returns the exit status."""
    from .jobs import COMPILE

    def line(job, row):
        report = "".join(f"\n  {text}" for text in row["design"].brief(row["params"], row.get("stability")))
        report += _assumption(row["design"], job.target)
        return (f"{row['prefix']}: {row['lib']}  ({_times(row, COMPILE)}){report}\n"
                f"  the full design report: print(codegen.load(\"{row['folder']}\").design)")

    rows, failed = _report(_jobs(args, COMPILE), args, line)
    return 2 if failed else 0


def _assumption(design, target):
    """The line under a design whose predicted error assumes the model exact
    (``DesignReport.assumption``): what it assumes and the `compare` command that measures it on a
    log of the target's robot; "" otherwise."""
    import shlex
    a = design.assumption()
    if not a:
        return ""
    src = target.robot
    if src.get("kind") == "catalog":
        robot = ["--robot", str(src.get("name"))]
    elif src.get("kind") == "urdf":
        robot = ["--urdf", str(src.get("path"))] + [w for k, v in (src.get("locked_joints") or {}).items()
                                                    for w in ("--lock", f"{k}={v:g}")]
    else:
        robot = ["--robot", "ROBOT"]
    line = shlex.join(["python", "-m", "codegen", "compare", "LOG.csv", *robot, "--observers", target.family,
                       "--build", "DIR"])
    return f"\n  assumes: {a['text']}; measure it on a log of the robot: {line}"


def cmd_check(args):
    """Cross-check each target's C against the reference (worst relative errors).
    ``args``: the parsed argparse namespace; returns the exit status."""
    from .jobs import CHECK
    if args.out is None:
        args.out, args.force = str(work_dir() / "check"), True   # a scratch folder

    def line(job, row):
        r = {k: v for k, v in row["check"].items() if k != "samples"}
        return (f"{row['prefix']:38s} worst {max(r.values()):.2e}  "
                + "  ".join(f"{k} {v:.1e}" for k, v in r.items()))

    rows, failed = _report(_jobs(args, CHECK, count=args.count), args, line)
    worst = max([max(v for k, v in r["check"].items() if k != "samples") for r in rows], default=0.0)
    ok = not failed and worst <= args.tol
    print(f"{'OK' if ok else 'FAIL'}: worst {worst:.2e} over {len(rows)} targets (tolerance {args.tol:g})")
    return 2 if failed else (0 if ok else 1)


def cmd_bench(args):
    """`bench`: timings as ratios (codegen.evaluate.bench, `make bench`).
    ``args``: the parsed argparse namespace; returns the exit status."""
    from .evaluate.bench import main
    return main(args.bench_robots, native=args.native, json_path=args.json, scenarios=not args.no_scenarios,
                generate=not args.no_generate, smoke=args.smoke)


def _vs_newlib(rec):
    """The firmware against the host build with newlib's math: "identical", the relative
    difference, or "n/a" (newlib's libm not buildable here)."""
    if rec["bit_identical_newlib"] is None:
        return "n/a"
    return "identical" if rec["bit_identical_newlib"] else f"{rec['rel_diff_host_newlib']:.1e}"


def cmd_embedded(args):
    """Every target in double on an emulated Cortex-M7 and in float on a Cortex-M4F: flash, static
    RAM, peak stack, instructions per step (and per step_dt over jittered elapsed times, a few
    of them split) and the difference from the host build, recorded in each target's JSON and
    printed as a table.
    ``args``: the parsed argparse namespace; returns the exit status."""
    from .verify import cortex_m
    missing = cortex_m.missing_packages()
    if missing:
        print(f"error: ARM toolchain missing; install it with: apt-get install {' '.join(missing)} "
              "(`make embedded` does)", file=sys.stderr)
        return 2
    print(f"{'target':46s} {'cpu':10s} {'flash KB':>8s} {'RAM B':>7s} {'stack B':>7s} {'insn/step':>9s} "
          f"{'max':>7s} {'step_dt':>7s} {'max':>7s} {'vs glibc':>8s} {'vs newlib':>9s} {'vs double':>9s}")
    from tqdm import tqdm

    from .core.progress import bar as progress_bar
    from .pipeline.emit import with_params
    from .pipeline.stages import resolve_substeps
    from .pipeline.targets_file import build_spec
    rows, targets = [], _targets(args)
    for target, out in progress_bar(targets, desc="embedded", unit="target", file=sys.stderr, leave=False,
                                    disable=None):
        spec = with_params(build_spec(target), target.params)
        target = resolve_substeps(target, spec)
        for prefix, rec in cortex_m.verify_target(spec, target, out, steps=args.steps):
            rows.append(rec)
            tqdm.write(f"{prefix:46s} {rec['cpu']:10s} {rec['flash_bytes'] / 1024:8.1f} {rec['static_ram_bytes']:7d} "
                       f"{rec['stack_peak_bytes']:7d} {rec['instructions_per_step']:9d} "
                       f"{rec['instructions_per_step_max']:7d} {rec['instructions_per_step_dt']:7d} "
                       f"{rec['instructions_per_step_dt_max']:7d} {rec['rel_diff_host']:8.1e} "
                       f"{_vs_newlib(rec):>9s} {rec.get('rel_diff_double', 0):9.1e}  "
                       f"{'ok' if rec['ok'] else 'FAIL'}", file=sys.stdout)
    folders = ", ".join(sorted({str(out) for _, out in targets}))
    print(f"{len(rows)} runs of {args.steps} steps on QEMU (-icount shift=0); records in {folders}"
          "/<target>/<target>.json under \"embedded\"")
    unavailable = {rec["newlib_unavailable"] for rec in rows if "newlib_unavailable" in rec}
    if unavailable:
        print(f"vs newlib not checked: {'; '.join(sorted(unavailable))}")
    return 0 if rows and all(rec["ok"] for rec in rows) else 1


def cmd_simulate(args):
    """`simulate`: run a scenario of the seed papers (codegen.evaluate.scenarios).
    ``args``: the parsed argparse namespace; returns the exit status."""
    from .evaluate import scenarios
    if args.name.startswith("mujoco-") or args.name == "log-grid":
        _require("mujoco", f"scenario {args.name}")
    options = {k: getattr(args, k) for k in ("quantization", "noise", "mismatch", "T", "jobs")
               if getattr(args, k) is not None}
    return scenarios.run(args.name, reference=args.reference, out=args.out or work_dir() / "sim", **options)


def _is_log(source):
    """True for a recorded log: a .csv file or a ROS bag (codegen.logs.bag.is_bag)."""
    from .logs.bag import is_bag
    return source is not None and (str(source).endswith(".csv") or is_bag(source))


def _remedy(e):
    """The RecordingError ``e`` with its fix in command-line flags (--columns, --topic)."""
    if e.option == "columns":
        e.cli_message = (f"{e} (name the log's own columns: --columns 'position_*=q_*,effort_*=tau_*,time=t"
                         f"[,t_unit=ms][,joints=[a,b]]' or --columns mapping.toml)")
    elif e.option == "t_unit" and e.choices:
        e.cli_message = f"{e}: --columns t_unit={e.choices[0]} (with other rules, add t_unit={e.choices[0]} to them)"
    elif e.option == "topic":
        e.cli_message = f"{e}: --topic {e.choices[0] if e.choices else 'NAME'}"
    return e


def _read_log(path, joints, clock="auto", robot=None, columns=None, topic=None):
    """``codegen.logs.recording.read_log`` of a command: a bag needs the ``ros`` extra (one line
    naming it), a refusal names the flag that fixes it (``_remedy``)."""
    from .logs.bag import is_bag
    from .logs.recording import RecordingError, read_log
    if is_bag(path):
        _require("rosbags", f"reading the ROS bag {path}")
    try:
        return read_log(path, joints, clock, robot=robot, columns=columns, topic=topic)
    except RecordingError as e:
        raise _remedy(e) from None


def _read_args(args, path, joints, robot):
    """``_read_log`` with the command's --clock, --columns and --topic."""
    return _read_log(path, joints, args.clock, robot=robot, columns=args.columns, topic=args.topic)


def _compare_robot(args):
    """The robot of ``compare``: ``--robot NAME`` or ``--urdf PATH [--lock JOINT=VALUE ...]``, read
    as ``build`` reads them (``targets_file.robot_source``). ``--elastic`` is refused: compare
    builds an elastic robot for a CSV (its link q and motor torque; the MuJoCo plant is rigid)."""
    from models import from_source

    from .pipeline.targets_file import robot_source
    if args.robot is None and args.urdf is None:
        what = "a CSV needs" if args.source else "give a source (a CSV, mujoco-ur5, mujoco-panda) or"
        raise ValueError(f"robot: {what} --robot NAME or --urdf PATH (the robot it was recorded on)")
    elastic = bool(args.elastic or args.J or args.K)
    if elastic and not _is_log(args.source):
        raise ValueError("--elastic: the MuJoCo plant has rigid joints; compare an elastic robot on its log "
                         "(a CSV of link q_<joint> and motor tau_<joint>), or run seed 004's in `simulate "
                         "seed004-sim1`")
    return from_source(robot_source(args.robot, urdf=args.urdf, lock=_pairs(args.lock, "--lock", _number),
                                    elastic=elastic, J=_numbers(args.J, "--J"), K=_numbers(args.K, "--K")))


def _torque_uncertainty(text, robot):
    """``compare --torque-uncertainty``: None when not given; a path to `identify`'s report.json
    (its held-out residual after identification, N m per joint), else one number for every joint
    or one per joint, comma-separated (N m). ValueError naming the option otherwise."""
    if text is None:
        return None
    path = Path(text)
    if path.suffix == ".json" or path.is_file():
        try:
            after = json.loads(path.read_text())["residual_rms"]["after"]
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise ValueError(f"--torque-uncertainty {text}: not a readable identify report.json (its "
                             f"residual_rms.after per joint): {e}") from None
        missing = [j for j in robot.joint_names if j not in after]
        if missing:
            raise ValueError(f"--torque-uncertainty {text}: the report has no residual for "
                             f"{', '.join(missing)} (identified on another robot?)")
        values = [after[j] for j in robot.joint_names]
    else:
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            raise ValueError(f"--torque-uncertainty: expected N m (one number, or {robot.n} comma-separated) "
                             f"or identify's report.json, got {text!r}") from None
    from .families.design.kalman_model import check_torque_uncertainty
    try:
        return [float(v) for v in check_torque_uncertainty(values, robot.n)]
    except ValueError as e:
        raise ValueError(f"--torque-uncertainty {text}: {e}") from None


def _compare_source(args):
    """(Recording, robot, title, clock) of ``compare``'s source: a mujoco-* scenario run with the
    sensor and mismatch options, a MuJoCo run of the robot of ``--robot`` / ``--urdf`` (no
    source), or a recorded CSV of that robot read on its sample clock (``--clock``; the Clock, None
    for a simulation)."""
    from .evaluate.scenarios.mujoco import SCENARIOS
    if args.source is None:              # a MuJoCo plant from the robot's URDF
        from .evaluate.scenarios import mujoco
        robot = _compare_robot(args)
        _require("mujoco", f"a MuJoCo run of {robot.name}")
        args.quantization, args.noise = args.quantization or 0.0, args.noise or 0.0
        rec = mujoco.recording(robot, args.T or mujoco.T_DEFAULT, args.quantization, args.noise, args.mismatch)
        return rec, robot, mujoco.title(robot.name, args.quantization, args.noise, args.mismatch), None
    if args.source in SCENARIOS:
        from models import load_robot

        from .evaluate.scenarios import mujoco
        name = args.source.removeprefix("mujoco-")
        if args.robot not in (None, name) or args.urdf or args.lock:
            given = f"--robot {args.robot}" if args.robot not in (None, name) else "--urdf/--lock"
            raise ValueError(f"robot: scenario {args.source} is {name}, got {given}")
        _require("mujoco", f"scenario {args.source}")
        # a simulated sensor is what the options say: unstated means exact
        args.quantization, args.noise = args.quantization or 0.0, args.noise or 0.0
        rec = mujoco.recording(name, args.T or mujoco.T_DEFAULT, args.quantization, args.noise, args.mismatch)
        return rec, load_robot(name), mujoco.title(name, args.quantization, args.noise, args.mismatch), None
    if not _is_log(args.source):
        from models import names
        hint = (f"; a MuJoCo run of {args.source} is `compare --robot {args.source}`"
                if args.source in names() else "")
        raise ValueError(f"source: expected a scenario ({', '.join(SCENARIOS)}), a .csv file or a ROS bag, "
                         f"got {args.source!r}{hint}")
    robot = _compare_robot(args)
    rec, clock = _read_args(args, args.source, robot.joint_names, robot)
    return rec, robot, f"{Path(args.source).name} ({robot.name})", clock


def _rigid_check(families, robot, remedy="give --elastic (with --J, --K)"):
    """ValueError before any work when an elastic-joint family of ``families`` meets the rigid
    ``robot``: the ``remedy``, and the robots elastic by default."""
    from models.catalog import ELASTIC

    from .evaluate.compare import parse_observer
    from .pipeline.targets_file import family_info
    if hasattr(robot, "rigid"):
        return
    for f in families:
        family = parse_observer(f)[0]
        if family_info(family)[3]:
            raise ValueError(f"family {family}: needs an elastic robot (joint stiffness K, motor inertias J); "
                             f"{robot.name} is rigid: {remedy} (J, K by default on {', '.join(ELASTIC)})")


COMPARE_OUTPUTS = ("errors.png", "joint0.png", "estimates.csv", "compare.json")


def cmd_compare(args):
    """Observers and tuned baselines on a scenario or a CSV: a progress bar (stderr), the table
    (every parameter, the reference and its uncertainty, the verdict line), figures, JSON.
    ``args``: the parsed argparse namespace; returns the exit status."""
    from .evaluate.compare import DEFAULT_FAMILIES, compare, design_inputs
    from .evaluate.sim.blocks import stage_lines
    from .logs.recording import RecordingError
    stepping = {k: getattr(args, k) for k in ("method", "hold", "substeps") if getattr(args, k) is not None}
    if args.build and not _is_log(args.source):
        raise ValueError(f"--build {args.build}: builds the winner on a log (a CSV or a ROS bag), got "
                         f"{args.source or 'a MuJoCo run'}")
    if args.build:
        check_writable(Path(args.build), "or choose another --build", folder=True)
    outputs = OutputSet(args.out or work_dir() / "compare", COMPARE_OUTPUTS, ours=args.out is None,
                        inputs=[args.source, args.torque_uncertainty, args.urdf], elsewhere="or choose another --out")
    try:
        with stage_lines():              # a line per stage on stderr (the MuJoCo run), then a bar
            rec, robot, title, clock = _compare_source(args)
            families = [f for f in args.observers.split(",") if f] if args.observers else DEFAULT_FAMILIES
            _rigid_check(families, robot)
            bl = [b for b in args.baselines.split(",") if b] if args.baselines else None
            sensor = (None, None) if args.quantization is None and args.noise is None else (args.quantization,
                                                                                             args.noise)
            cmp = compare(rec, robot, families=families, t_ss=args.t_ss, level=args.level,
                          design=design_inputs(*sensor, args.mismatch,
                                               _torque_uncertainty(args.torque_uncertainty, robot)),
                          baseline_names=bl, reference=args.reference, title=title,
                          ref_cutoff=args.ref_cutoff, progress=True, stepping=stepping,
                          tune=args.tune, clock=clock)
    except (RecordingError, ValueError, KeyError) as e:
        print(f"error: {_message(e)}", file=sys.stderr)
        return 2
    print(cmp.table())
    ref = cmp.ref
    with outputs.writing() as tmp:       # the set moves into --out at once (codegen.core.atomic.OutputSet)
        paths = cmp.figures(tmp)
        paths.append(cmp.write_estimates(tmp / "estimates.csv", clock))
        (tmp / "compare.json").write_text(json.dumps(
            {"title": title, "t_ss": cmp.t_ss, "level": cmp.level, "recording": cmp.info.get("recording"),
             "clock": None if clock is None else clock.to_dict(), "noise": cmp.info.get("noise_data"),
             "tune": cmp.info.get("tune"), "validation": cmp.info.get("validation"),
             "reference": {"label": ref.label, "cutoff": ref.cutoff, "uncertainty": cmp.uncertainty},
             "verdict": cmp.verdict(), "ranking": cmp.ranking(), "rows": cmp.rows()}, indent=2,
            default=float) + "\n")
        paths.append(tmp / "compare.json")
    print(f"figures, estimates.csv and compare.json in {outputs.folder.resolve()} "
          f"({', '.join(p.name for p in paths)})")
    if args.build:
        _build_winner(args, cmp, robot, rec, stepping)
    return 0


def _build_winner(args, cmp, robot, rec, stepping):
    """`compare --build DIR`: the winner's C folder (codegen.evaluate.winner) made as `build` makes
    it, its library, gains and their sources printed."""
    from .evaluate.winner import winner_target
    from .pipeline.stages import make
    stated = {k: "given by the user" for k in ("quantization", "noise") if getattr(args, k) is not None}
    if args.torque_uncertainty is not None:
        stated["torque_uncertainty"] = f"given by the user ({args.torque_uncertainty})"
    stated["uncertainty"] = ("given by the user" if args.mismatch else
                             "the default: 0 (no relative model uncertainty stated)")
    target, e = winner_target(cmp, robot, rec.t, rec.dt, Path(args.source).name, stated=stated,
                              stepping=stepping)
    made = make(target, Path(args.build), force=True)
    meta = json.loads((made.folder / f"{made.target.prefix}.json").read_text())
    print(f"built the winner, {e.name} (the lowest truth-free error estimate of the observers that did not fail: "
          f"{e.metrics['validation_rms']:.3g} rad/s by forward validation): {made.folder}"
          + "".join(f"\n  {line}" for line in made.spec.design.brief(made.spec.params, meta.get("stability"))))


def cmd_sweep(args):
    """A Monte-Carlo sweep on Dask (codegen.evaluate.sweep): results, map and best-gain table in --out.
    ``args``: the parsed argparse namespace; returns the exit status."""
    from .evaluate import sweep
    from .evaluate.sweep import maps, plan
    try:
        spec = plan.load(args.file)
        # every optional package the sweep needs, named before any cell runs
        for module in ("pyarrow", "pandas", *(("dask", "distributed") if args.workers != 0 else ()),
                       *(("mujoco",) if spec.plant == "mujoco" else ())):
            _require(module, f"sweep {spec.name}")
        res = sweep.run(args.file, workers=args.workers, scheduler=args.scheduler, out=args.out)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"{res.cells} cells: {res.computed} computed in {res.seconds:.1f} s "
          f"({res.computed / max(res.seconds, 1e-9):.1f} cells/s), {res.skipped} already done, "
          f"{res.failed} failed; results in {res.out / 'results'}")
    for p in maps.write(res.out, spec):
        print(f"wrote {p}")
    return 0 if res.failed == 0 else 1


def cmd_sanitize(args):
    """`sanitize`: the C harness under ASan/UBSan and a libFuzzer campaign (codegen.verify.sanitize).
    ``args``: the parsed argparse namespace; returns the exit status."""
    from .verify import sanitize
    return sanitize.run(args.runs, args.seconds)


def _robot_of(args):
    """The robot of ``--robot NAME`` or ``--urdf PATH [--lock JOINT=VALUE ...]`` (as `build`)."""
    from models import from_source
    from .pipeline.targets_file import robot_source
    return from_source(robot_source(args.robot, urdf=args.urdf, lock=_pairs(args.lock, "--lock", _number)))


def cmd_excite(args):
    """`excite`: an excitation trajectory for `identify` (codegen.logs.identify.excitation),
    written as a CSV (t, q_, qd_, qdd_ per joint). ``args``: the parsed namespace; returns 0."""
    from .logs.identify import excitation
    robot = _robot_of(args)
    traj = excitation(robot, args.T, base_frequency=args.f0, harmonics=args.harmonics, seed=args.seed,
                      progress=True)
    path = traj.write_csv(args.out, dt=args.dt)
    q = traj.sample(args.dt)[1]
    print(f"{robot.name}: {traj.T:g} s, f0 = {traj.f0:g} Hz, {traj.a.shape[1]} harmonics, condition number "
          f"{traj.condition:.4g}; starts and ends at rest at q = [{', '.join(f'{v:.4g}' for v in q[0])}] "
          f"(move there first; check it for collisions)\nwrote {path}")
    import shlex
    src = _robot_words(args)
    print("play it on the robot, log t, q_<joint>, tau_<joint>, then: "
          + shlex.join(["python", "-m", "codegen", "identify", "LOG.csv", *src]))
    return 0


def _width(text):
    """--coulomb-width: "auto" or a positive number (rad/s)."""
    if text == "auto":
        return text
    try:
        w = float(text)
    except ValueError:
        w = float("nan")
    if not (math.isfinite(w) and w > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number (rad/s) or auto, got {text!r}")
    return w


def _robot_words(args):
    """The robot of ``args`` as command-line words: ``--urdf PATH [--lock J=V ...]`` or ``--robot NAME``."""
    if args.urdf:
        return ["--urdf", str(args.urdf), *[w for v in args.lock or () for w in ("--lock", v)]]
    return ["--robot", str(args.robot)]


def _identify_remedy(e, args):
    """The one line of an IdentificationError with its remedy (``e.remedy``) as flags: an
    excitation trajectory of the robot as the command line named it (``--urdf`` the user's file
    and its locks, or ``--robot`` a catalog name)."""
    ex = e.remedy.get("excite")
    if not ex:
        return str(e)
    import shlex
    src = _robot_words(args)
    line = shlex.join(["python", "-m", "codegen", "excite", *src, "--out", "traj.csv"])
    return str(e).replace("(excitation())", f"({line})")


def cmd_identify(args):
    """`identify`: the robot's inertial parameters and friction from a log of t, q_, tau_ per
    joint (codegen.logs.identify); writes the identified URDF, the friction side file and the
    report to --out. ``args``: the parsed namespace; returns 0."""
    from .logs.identify import IdentificationError, identify
    robot = _robot_of(args)
    names = (f"{robot.name}_identified.urdf", f"{robot.name}_identified.friction.json", "report.json", "report.txt")
    outputs = OutputSet(args.out or work_dir() / "identify", names, inputs=[args.log, args.urdf],   # before the work
                        elsewhere="or choose another --out", ours=args.out is None)
    rec, clock = _read_args(args, args.log, robot.joint_names, robot)
    print(clock.describe())
    try:
        ident = identify(rec, robot, cutoff=args.cutoff,
                         test_fraction=args.test_fraction, coulomb_width=args.coulomb_width,
                         v_stick=args.v_stick, progress=True)
    except IdentificationError as e:
        e.cli_message = _identify_remedy(e, args)
        raise
    paths = ident.write(outputs.folder)      # its own writer (each file through a temporary one)
    outputs.record()
    print(ident.summary, end="")
    print(f"the full report (links, base combinations, every parameter): {paths['report_txt']}")
    import shlex
    lock = [w for k, v in (robot.source.get("locked_joints") or {}).items() for w in ("--lock", f"{k}={v:g}")]
    print("\nthe observers with this model, on a log of the robot: " + shlex.join(
        ["python", "-m", "codegen", "compare", "LOG.csv", "--urdf", str(paths["urdf"]), *lock,
         "--torque-uncertainty", str(paths["report_json"])]))
    return 0


def _log_joints(args):
    """The joints of the log of ``args`` (its q_<joint> columns after --columns; a bag's), in file order."""
    from .logs.bag import is_bag
    from .logs.recording import RecordingError, log_joints
    if is_bag(args.log):
        _require("rosbags", f"reading the ROS bag {args.log}")
    try:
        return log_joints(args.log, args.columns, args.topic)
    except RecordingError as e:
        raise _remedy(e) from None


def cmd_describe(args):
    """`describe`: what a log is, measured from it: its clock (codegen.logs.clock), its position
    resolution and noise, its motion's band and, with a robot, the torque against the model
    (codegen.logs.noise). ``args``: the parsed namespace; returns 0."""
    from .logs import noise as noise_of
    robot = _robot_of(args) if (args.robot or args.urdf) else None
    _check_out(args.json, "--json", inputs=[args.log])
    joints = list(robot.joint_names) if robot is not None else _log_joints(args)
    rec, clock = _read_args(args, args.log, joints, robot)
    nz = noise_of.measure(rec.t, rec.q, rec.tau if robot is not None else None, robot)
    print(clock.describe())
    print(f"recording: {rec.describe()}")
    print(f"joints: {', '.join(joints)}")
    for line in nz.lines():
        print(line)
    print("zero-phase reference cut-off per joint (Hz): "
          + ", ".join(f"{c:.3g}" for c in noise_of.reference_cutoff(nz)))
    if args.json:
        write_text(args.json, json.dumps({"clock": clock.to_dict(), "recording": rec.describe(),
                                          "noise": nz.to_dict()}, indent=2) + "\n", "or choose another --json")
        print(f"wrote {args.json}")
    return 0


def cmd_design(args):
    """`design LOG.csv --robot R --family F`: the family designed for the log's measured sensor and
    its gains tuned on the log without truth (codegen.evaluate.compare.design_on_log); prints the
    measured quantities, the tuned gains, the criterion and the lines that build the observer with
    them. ``args``: the parsed namespace; returns 0."""
    from .core.progress import bar as progress_bar
    from .evaluate.compare import design_inputs, design_on_log
    from .evaluate.sim.blocks import stage_lines
    robot = _robot_of(args)
    _rigid_check([args.family], robot, remedy="`design` has no elastic robot; run it on the log with `compare "
                 f"LOG.csv --robot R --elastic --observers {args.family}`")
    _check_out(args.json, "--json", inputs=[args.log])
    rec, clock = _read_args(args, args.log, robot.joint_names, robot)
    print(clock.describe())
    print(f"recording: {rec.describe()}")
    sensor = (None, None) if args.quantization is None and args.noise is None else (args.quantization, args.noise)
    design = design_inputs(*sensor, 0.0, _torque_uncertainty(args.torque_uncertainty, robot))
    with stage_lines(), progress_bar(desc=f"design {args.family}", unit="run", file=sys.stderr, leave=False) as bar:
        def step(text):
            bar.set_postfix_str(text)
            bar.update()
        entry, nz, val = design_on_log(rec, robot, args.family, design=design, clock=clock, progress=step)
    for line in nz.lines():
        print(line)
    tuned = entry.tuned
    print(f"forward validation: each estimate against the velocity the next {val.window} samples imply")
    failed = design_failure(entry, args.family)
    if failed:
        print(f"error: {failed}", file=sys.stderr)
        return 2
    if tuned is None:
        print(f"{args.family}: declares no bandwidth to tune; its designed gains")
    else:
        print(tuned.line())
    if entry.variant:
        print(f"variant: {entry.variant}")
    print("parameters: " + ", ".join(f"{k}={v:.6g}" for k, v in entry.params.items() if not k.startswith(("pole_", "cq", "ca"))))
    if entry.note:
        print(f"note: {entry.note}")
    print("build it: " + _build_line(args, entry, tuned, rec.dt))
    print(f'or in a targets file: tune = "{args.log}"' + "".join(f', {k} = {json.dumps(v)}' for k, v in (
        ("tune_columns", args.columns), ("tune_topic", args.topic)) if v) + " (this design, redone when the target is built)")
    if args.json:
        write_text(args.json, json.dumps({
            "clock": clock.to_dict(), "noise": nz.to_dict(), "family": args.family, "variant": entry.variant,
            "build": entry.build, "params": entry.params,
            "tuned": None if tuned is None else {"params": tuned.params, "scale": tuned.scale,
                                                 "criterion": tuned.score, "rms_estimate": tuned.rms,
                                                 "tried": tuned.tried},
            "validation": {"window": val.window, "constant": val.constant}}, indent=2, default=float) + "\n",
                   "or choose another --json")
        print(f"wrote {args.json}")
    return 0


def _build_line(args, entry, tuned, dt):
    """The `build` command (one line that pastes into a POSIX shell: every value shell-quoted, lists
    without spaces) of the design ``entry`` of `design` ``args``: the robot, the family, the log's
    dt, the build inputs (``--design``, measured on the log unless the user stated them:
    ``--source NAME=TEXT``), the tuned gains (``--param``) and ``--tuned-on LOG``."""
    import shlex
    words = ["python", "-m", "codegen", "build", *([args.robot] if args.robot else ["--urdf", args.urdf])]
    words += [w for v in args.lock or () for w in ("--lock", v)]
    given = {"quantization": args.quantization, "noise": args.noise, "torque_uncertainty": args.torque_uncertainty}
    build = {k: v for k, v in (entry.build or {}).items() if not (k == "uncertainty" and v == 0.0)}
    words += ["--family", args.family.split(":")[0], "--dt", f"{dt:.6g}"]
    words += [w for k, v in build.items() for w in ("--design", f"{k}={json.dumps(v, separators=(',', ':'))}")]
    words += [w for k, v in (tuned.params if tuned else {}).items() for w in ("--param", f"{k}={v:.6g}")]
    words += ["--tuned-on", str(args.log)]
    words += [w for k in build if given.get(k) is not None
              for w in ("--source", f"{k}=given by the user ({given[k]})")]
    return shlex.join(words)


def cmd_simulate_log(args):
    """`simulate-log`: a realistic synthetic log of one's own URDF and its truth
    (codegen.evaluate.scenarios.log_grid.synthetic_log). ``args``: the parsed namespace; returns 0."""
    from .evaluate.scenarios.log_grid import synthetic_log
    robot = _robot_of(args)
    _require("mujoco", "simulate-log")
    log, truth, stats = synthetic_log(robot, args.out, T=args.seconds, task=args.task, clock=args.clock,
                                      torque=args.torque, seed=args.seed)
    rows = stats.get("rows", stats["logged"])
    what = (f"{rows} rows stamped when a logger received them (1 ms ticks, {stats['repeats']} repeated rows)"
            if args.clock == "receive" else f"{rows} rows at jittered instants ({stats['dropped']} dropped)")
    print(f"wrote {log}: {robot.name}, {stats['T']:g} s of {args.task}, {what}; t, q_<joint>, tau_<joint>")
    print(f"its truth: {truth} (per row: the true sample time, q, qd and applied tau)")
    print(f"the plant: the URDF perturbed (masses and inertias, a payload, friction, torque offsets; seed "
          f"{args.seed}), a 2^20 counts/rev encoder logged to 1e-6 rad, torque noise ({args.torque})")
    return 0


def cmd_detect(args):
    """`detect`: the momentum observer's external torque, alarms and collided link over a log
    (codegen.evaluate.detect), thresholds set on a collision-free log (--calibrate) for
    --false-alarms per hour; writes external_torque.csv, events.csv, detect.json and a figure to
    --out. ``args``: the parsed namespace; returns 0."""
    from .evaluate.detect import detect, write_detection
    robot = _robot_of(args)
    rec, clock = _read_args(args, args.log, robot.joint_names, robot)
    clean = None
    if args.calibrate:
        clean, _ = _read_args(args, args.calibrate, robot.joint_names, robot)
    build = {} if args.torque_noise is None else {"torque_noise": args.torque_noise}
    det = detect(robot, rec, clean=clean, false_alarms=args.false_alarms, **build)
    paths = write_detection(det, Path(args.out or work_dir() / "detect"))
    how = (f"set on {args.calibrate} for {args.false_alarms:g} false alarm(s) per hour" if clean is not None
           else "the design's defaults (no collision-free log given)")
    print(f"thresholds ({how}): " + ", ".join(f"{j} {a:.3g} + {b:.3g}|qd|" for j, a, b in
                                            zip(robot.joint_names, det.th0, det.th1)))
    print(f"{len(det.events)} event(s) in {det.t[-1] - det.t[0]:.1f} s" + "".join(
        f"\n  {e['start']:.3f}-{e['end']:.3f} s  link {e['link']}" for e in det.events[:20]))
    print(f"files in {paths['json'].parent.resolve()} ({', '.join(p.name for p in paths.values())})")
    return 0


COMMANDS = {"list": cmd_list, "generate": cmd_generate, "build": cmd_build, "check": cmd_check,
            "bench": cmd_bench, "simulate": cmd_simulate, "compare": cmd_compare, "sweep": cmd_sweep,
            "sanitize": cmd_sanitize, "embedded": cmd_embedded, "excite": cmd_excite, "identify": cmd_identify,
            "describe": cmd_describe, "design": cmd_design, "detect": cmd_detect}
COMMANDS["simulate-log"] = cmd_simulate_log


# ------------------------------------------------------------------------------------ parser
def _robot_options(p):
    """The robot options of `build` (and of `compare`): --urdf, --lock, --elastic, --J, --K."""
    a = p.add_argument
    a("--urdf", metavar="PATH", help="a robot from a URDF file (revolute, continuous, prismatic joints)")
    a("--lock", action="append", metavar="JOINT=VALUE", help="hold a URDF joint at VALUE (rad or m); repeatable")
    a("--elastic", action="store_true", help="elastic joints on the robot (tomei, ciccarella_germani, spong_*)")
    a("--J", metavar="J", help="motor inertias (kg m^2): one number or one per joint, comma-separated "
      "(default: the catalog's for seed004_2r, seed004_3r, ur5)")
    a("--K", metavar="K", help="joint stiffness (N m/rad): one number or one per joint, comma-separated")


def _log_command(sub, name, debug, text, robot_help="catalog robot",
                 urdf_help="a robot from a URDF file (e.g. identify's)"):
    """The subcommand ``name`` (help ``text``) of a command that reads a log: the log, the robot
    (``robot_help``, ``urdf_help``), --lock and the clock and column options."""
    p = sub.add_parser(name, parents=[debug], help=text)
    p.add_argument("log", help="a CSV (t, q_<joint>, tau_<joint>; other names: --columns) or a ROS bag "
                               "(.bag file, ROS 2 bag folder)")
    p.add_argument("--robot", help=robot_help)
    p.add_argument("--urdf", metavar="PATH", help=urdf_help)
    p.add_argument("--lock", action="append", metavar="JOINT=VALUE", help="hold a URDF joint; repeatable")
    _clock_option(p)
    return p


def _clock_option(p):
    """--clock of every command that reads a log (and its --columns and --topic)."""
    p.add_argument("--clock", default="auto", metavar="auto|stamps|ticks[=PERIOD]",
                   help="what the log's time column is: auto (default: found from the data: a logger's "
                        "receive times are rebuilt on the robot's fixed tick, repeated rows dropped; a robot-"
                        "time column t_robot is used), stamps (as written), ticks[=PERIOD s] (rebuilt on a tick)")
    _input_options(p)


def _input_options(p):
    """--columns and --topic of every command that reads a log (codegen.logs.mapping, .bag)."""
    p.add_argument("--columns", metavar="MAP|FILE",
                   help="the log's own column names mapped onto t, q_<joint>, tau_<joint>, qd_<joint>, qdm_<joint>: "
                        "rules SOURCE=TARGET, * for the joint (e.g. 'position_*=q_*,effort_*=tau_*,time=t'), "
                        "t_unit=s|ms|us|ns (the time column's unit; a mapped log's time counts from its first row), "
                        "joints=[a,b,...] (the log's joints renamed, in file order); or a .toml/.json file of the "
                        "same (t_unit, joints, a [columns] table). On a ROS bag, over its default "
                        "(header.stamp=t, position_*=q_*, velocity_*=qdm_*, effort_*=tau_*)")
    p.add_argument("--topic", metavar="NAME", help="a ROS bag's sensor_msgs/JointState topic (default: its only one)")


def _stepping_options(p):
    """How the observers step, as `build` takes it (and `compare`): --method, --hold, --substeps."""
    a = p.add_argument
    a("--method", choices=METHODS, help="integrator (default expmid1: the model once per sub-step, at its midpoint "
                                        "configuration, the gain term integrated exactly; expmid: the model twice; "
                                        "etdrk4, rk4, euler)")
    a("--hold", choices=HOLDS, help="measurement hold between samples (default foh; see codegen.discrete.discretize)")
    a("--substeps", type=_substeps, help='integrator sub-steps per sample, or "auto" (the default): the '
      "fewest that make the discrete observer stable")


def _target_options(p, out_help):
    a = p.add_argument
    a("robots", nargs="*", metavar="ROBOT", help="catalog robot names (see `list`); none: the targets "
      f"of -c FILE or ./{TARGETS_FILE}")
    a("-c", "--config", metavar="FILE", help="a targets file (TOML, [[target]] tables; see codegen/pipeline/targets_file.py)")
    _robot_options(p)
    a("--family", help=f"observer family or control law (see `list`; default {DEFAULT_FAMILY})")
    a("--variant", help="family variant, e.g. O2 of ciccarella_germani (default: the family's)")
    a("--design", action="append", metavar="NAME=VALUE", help="design input or gain passed to the family's "
      "build (e.g. noise=1e-4, eta=1, eigenvalues=[-300,-400]); repeatable")
    a("--param", action="append", metavar="NAME=VALUE", help="runtime parameter overriding the designed "
      "default (e.g. k0=50); repeatable")
    a("--tuned-on", metavar="LOG", help="the --param values were tuned on this log and the --design values "
      "measured on it (the line `design` prints): the folder's design report and header say so")
    a("--source", action="append", metavar="NAME=TEXT", help="where a --param or --design value came from "
      "(the folder's design report and header say it; default: given by the user); repeatable")
    a("--dt", type=float, help="sample time in s (default 1e-3)")
    a("--dt-min", type=float, help="shortest elapsed time between samples the step is checked for, s "
      "(default dt/4)")
    a("--dt-max", type=float, help="longest elapsed time one step integrates, s (default 2 dt); a longer "
      "one is split into sub-intervals of at most this")
    _stepping_options(p)
    a("--precision", choices=PRECISIONS, help="real type of the C (default double)")
    a("--name", help="symbol prefix and folder name (default <robot>_<family>[_<variant>])")
    a("--out", metavar="DIR", help=out_help)
    a("--force", action="store_true", help="replace a folder generated from another target")
    a("--native", action="store_true", help="compile with -march=native")
    a("-j", "--jobs", type=int, help="targets built in parallel processes (default: one per core)")


def parser():
    """The argparse parser of all commands (a :class:`Parser`)."""
    ap = Parser(prog="observer-codegen", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--debug", action="store_true", help="show the traceback of an error")
    debug = Parser(add_help=False)     # also after the command; SUPPRESS keeps a --debug given before it
    debug.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                       help="show the traceback of an error")
    sub = ap.add_subparsers(dest="cmd", required=True, parser_class=Parser, metavar="COMMAND")
    sub.add_parser("list", parents=[debug], help="robots, families (variants, design inputs), targets.toml")
    g = sub.add_parser("generate", parents=[debug], help="design, emit, compile and run each target")
    _target_options(g, "parent folder of the generated folders (default ./generated, or the file's out)")
    g.add_argument("--T", type=float, default=2.0, help="length of the run (s, default 2)")
    b = sub.add_parser("build", parents=[debug], help="design, emit and compile each target")
    _target_options(b, "parent folder of the generated folders (default ./generated, or the file's out)")
    c = sub.add_parser("check", parents=[debug], help="cross-check each target's C against the reference")
    _target_options(c, "parent folder of the checked folders (default build/check, replaced freely)")
    c.add_argument("--count", type=int, default=1000, help="random inputs per check (default 1000)")
    c.add_argument("--tol", type=float, default=1e-9, help="largest relative error accepted (default 1e-9)")
    be = sub.add_parser("bench", parents=[debug], help="timings as ratios (make bench)")
    be.add_argument("bench_robots", nargs="*", default=["ur5", "panda"], metavar="ROBOT",
                    help="robots of the observer-RHS table (default ur5 panda)")
    be.add_argument("--native", action="store_true", help="compile with -march=native")
    be.add_argument("--json", metavar="FILE", help="also write the figures to this file")
    be.add_argument("--no-scenarios", action="store_true", help="skip the scenario benchmarks")
    be.add_argument("--no-generate", action="store_true", help="skip timing `make generate` from scratch")
    be.add_argument("--smoke", action="store_true", help="the cheap rows only (about a minute; CI's "
                    "`make test-long`): the table on ur5, kalman_model's step on seed000_2r, elastic ur5's CG")
    e = sub.add_parser("embedded", parents=[debug], help="run the targets on emulated Cortex-M4F (float) "
                       "and M7 (double)")
    _target_options(e, "parent folder of the targets (default ./generated, or the file's out)")
    e.add_argument("--steps", type=int, default=300, help="samples of the run on each CPU (default 300)")
    s = sub.add_parser("simulate", parents=[debug], help="run a scenario of the seed papers")
    s.add_argument("name", help="scenario name, or `list`")
    s.add_argument("--reference", action="store_true", help="run observers with the numpy reference")
    s.add_argument("--out", metavar="DIR", help="parent folder of the results (default build/sim)")
    s.add_argument("--quantization", type=float, help="encoder step (rad; mujoco-* scenarios)")
    s.add_argument("--noise", type=float, help="Gaussian noise std (rad; mujoco-* scenarios)")
    s.add_argument("--mismatch", type=float, help="plant masses and inertias x (1 + mismatch) (mujoco-*)")
    s.add_argument("--T", type=float, help="length (s; mujoco-* scenarios, log-grid's task runs)")
    s.add_argument("--jobs", type=int, help="cells simulated in parallel processes (log-grid; default 1)")
    cp = sub.add_parser("compare", parents=[debug], help="observers against tuned baselines on a MuJoCo "
                        "run of any URDF robot, a scenario or a CSV")
    cp.add_argument("source", nargs="?", help="a CSV (t, q_<joint>, tau_<joint>[, qd_<joint>][, qdm_<joint>]; "
                    "other names: --columns; jittered stamps and gaps allowed), a ROS bag, mujoco-ur5 or mujoco-panda; none: a MuJoCo run of "
                    "the robot of --robot or --urdf (computed-torque tracking of sinusoids, --T s)")
    cp.add_argument("--robot", help="the robot: a catalog name (see `list`)")
    _robot_options(cp)
    _stepping_options(cp)
    cp.add_argument("--ref-cutoff", type=float, metavar="HZ",
                    help="CSV without qd_<joint>: cut-off of the zero-phase reference velocity the methods "
                         "are measured against (Hz; default each joint's motion band measured on the log)")
    _clock_option(cp)
    cp.add_argument("--tune", choices=("log", "none", "reference"), default="log",
                    help="log (default): every family's bandwidth and every baseline's parameter chosen on the "
                         "log without truth (forward validation), kalman_model's variant too; none: the "
                         "designed gains (baselines tuned against the reference); reference: the baselines only")
    from .evaluate.compare import DEFAULT_FAMILIES
    cp.add_argument("--observers", help="comma-separated families, each optionally with gains "
                    f"(family:name=value:...); default {','.join(DEFAULT_FAMILIES)}")
    cp.add_argument("--baselines", help="comma-separated (default: all of codegen.evaluate.baselines)")
    cp.add_argument("--quantization", type=float,
                    help="encoder step (rad); scenario: of its sensor (default 0); a log: default its "
                         "resolution and noise measured on it (this and --noise state them instead)")
    cp.add_argument("--noise", type=float, help="Gaussian noise std (rad; scenario default 0)")
    cp.add_argument("--mismatch", type=float, default=0.0,
                    help="scenario: plant masses and inertias x (1 + mismatch); CSV: model uncertainty")
    cp.add_argument("--torque-uncertainty", metavar="NM|FILE",
                    help="the model's torque error the designs take (N m: one number or one per joint, "
                         "comma-separated; or identify's report.json: its held-out residual); kalman_model "
                         "then uses the model, not only the motion (default: not stated)")
    cp.add_argument("--T", type=float, help="length of a MuJoCo run (s, default 20)")
    cp.add_argument("--t-ss", type=float, help="start of the steady-state window (s, on the log's clock; "
                    "default the middle of the run)")
    cp.add_argument("--level", type=float, default=1e-2, help="convergence threshold (rad/s)")
    cp.add_argument("--reference", action="store_true", help="run observers with the numpy reference")
    cp.add_argument("--out", metavar="DIR", help="folder of the figures and compare.json (default build/compare)")
    cp.add_argument("--build", metavar="DIR", help="a log: also write the winner's C folder into DIR (the observer "
                    "with the lowest truth-free error estimate, as `build` writes it: the gains tuned on the log, "
                    "its dt range, each value's source in the header)")
    sw = sub.add_parser("sweep", parents=[debug], help="Monte-Carlo sweep of observers and baselines on Dask (resumable)")
    sw.add_argument("file", help="the sweep file (TOML; see codegen.evaluate.sweep.plan)")
    where = sw.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="local cluster of N worker processes (default: one "
                       "per CPU; 0: in this process, no Dask)")
    where.add_argument("--scheduler", help="address of an existing Dask scheduler (tcp://host:8786)")
    sw.add_argument("--out", metavar="DIR", help="output folder (default build/sweeps/<name>)")
    sa = sub.add_parser("sanitize", parents=[debug], help="C harness and sample targets under ASan/UBSan on "
                        "edge-case CSVs, and a libFuzzer campaign of their step")
    sa.add_argument("--runs", type=int, default=100000, help="libFuzzer runs per target")
    sa.add_argument("--seconds", type=int, default=60, help="at most this long fuzzing per target")
    d = _log_command(sub, "describe", debug, "what a log is: its clock, resolution, noise, motion band and "
                     "(with a robot) torque residual, measured from it",
                     "catalog robot (the torque against its model is measured too)", "a robot from a URDF file")
    d.add_argument("--json", metavar="FILE", help="also write the figures to this file")
    de = _log_command(sub, "design", debug, "a family's gains tuned on a log without truth")
    de.add_argument("--family", required=True, help="observer family (see `list`)")
    de.add_argument("--quantization", type=float, help="encoder step (rad; default: measured on the log)")
    de.add_argument("--noise", type=float, help="position noise std (rad; default: measured on the log)")
    de.add_argument("--torque-uncertainty", metavar="NM|FILE",
                    help="the model's torque error (N m, or identify's report.json; default: measured on the log)")
    de.add_argument("--json", metavar="FILE", help="also write the design to this file")
    dt_ = _log_command(sub, "detect", debug, "external torque, collisions and the collided link over a log "
                       "(the momentum observer)")
    dt_.add_argument("--calibrate", metavar="CLEAN.csv", help="a collision-free log of the arm: the thresholds "
                     "are set on it (default: the design's, from the torque noise)")
    dt_.add_argument("--false-alarms", type=float, default=1.0, metavar="PER_HOUR",
                     help="false alarms per hour the calibrated thresholds allow (default 1)")
    dt_.add_argument("--torque-noise", type=float, metavar="NM", help="torque sensor noise std (N m) for the "
                     "default thresholds")
    dt_.add_argument("--out", metavar="DIR", help="folder of the outputs (default build/detect)")
    from models.catalog import urdf_names

    from .logs import identify as idf
    for name, text in (("excite", "an excitation trajectory (CSV) to log for `identify`"),
                       ("identify", "inertial parameters and friction from a log of q and tau")):
        x = sub.add_parser(name, parents=[debug], help=text)
        if name == "identify":
            x.add_argument("log", help="a CSV (t, q_<joint>, tau_<joint>; other names: --columns) or a ROS bag (.bag file, ROS 2 bag folder); jittered stamps allowed")
            _clock_option(x)
        x.add_argument("--robot", help=f"catalog robot with a URDF ({', '.join(urdf_names())})")
        x.add_argument("--urdf", metavar="PATH", help="a robot from a URDF file")
        x.add_argument("--lock", action="append", metavar="JOINT=VALUE", help="hold a URDF joint; repeatable")
        if name == "excite":
            x.add_argument("--T", type=float, default=10.0, help="duration (s, default 10), whole periods")
            x.add_argument("--f0", type=float, help="base frequency (Hz; default the smallest >= 0.1 with T f0 whole)")
            x.add_argument("--harmonics", type=int, default=5, help="harmonics per joint (default 5)")
            x.add_argument("--dt", type=float, default=1e-3, help="sample step of the CSV (s, default 1e-3)")
            x.add_argument("--seed", type=int, default=0, help="seed of the optimiser's starts")
            x.add_argument("--out", metavar="CSV", default="traj.csv", help="the trajectory (default traj.csv)")
        else:
            x.add_argument("--cutoff", type=float,
                           help="zero-phase low-pass (Hz; default selected with the Coulomb width: the one whose "
                                "fit predicts the held-out tail best)")
            x.add_argument("--test-fraction", type=float, default=idf.DEFAULT_TEST_FRACTION,
                           help=f"held-out tail of the log (default {idf.DEFAULT_TEST_FRACTION:g})")
            x.add_argument("--coulomb-width", type=_width, default="auto",
                           help="w of tanh(qd/w) (rad/s), or auto (default): the width of "
                                f"{', '.join(f'{w:g}' for w in idf.WIDTHS)} and the model's own that "
                                "predicts the held-out tail best")
            x.add_argument("--v-stick", type=float, default=idf.DEFAULT_V_STICK,
                           help="rad/s: a joint's samples slower than this are left out of the fit (it may "
                                f"stick under dry friction; default {idf.DEFAULT_V_STICK:g}, 0 keeps every one)")
            x.add_argument("--out", metavar="DIR", help="folder of the identified URDF and report (default build/identify)")
    _simulate_log_parser(sub, debug)
    return ap


def _simulate_log_parser(sub, debug):
    """The parser of `simulate-log`."""
    from .evaluate.scenarios.log_grid import CLOCKS, TASKS, TORQUE_SENSORS
    sl = sub.add_parser("simulate-log", parents=[debug], help="a realistic synthetic log of your URDF (and its "
                        "truth): a perturbed MuJoCo plant, an encoder, torque noise, a logger's clock")
    sl.add_argument("--urdf", metavar="PATH", help="the robot's URDF")
    sl.add_argument("--robot", help="or a catalog robot")
    sl.add_argument("--lock", action="append", metavar="JOINT=VALUE", help="hold a URDF joint; repeatable")
    sl.add_argument("--out", metavar="CSV", default="log.csv", help="the log (default log.csv; its truth "
                    "beside it, <stem>_truth.csv)")
    sl.add_argument("--seconds", type=float, default=20.0, help="length (s, default 20)")
    sl.add_argument("--task", choices=TASKS, default="multisine", help="the motion: multisine (default), p2p "
                    "(minimum-jerk moves with rests), bursts (slow drifts, short fast moves)")
    sl.add_argument("--clock", choices=tuple(CLOCKS), default="receive", help="receive (default: 1 ms ticks "
                    "stamped when a logger received them, repeated rows) or jitter (jittered instants, dropped rows)")
    sl.add_argument("--torque", choices=tuple(TORQUE_SENSORS), default="rms", help="torque noise: rms (default: "
                    "1 %% of each joint's RMS torque) or abs (0.05 N m); both with offsets")
    sl.add_argument("--seed", type=int, default=0, help="seed of the plant, the motion and the sensors")


def main(argv=None):
    """Run the command of ``argv`` (None: sys.argv[1:]); returns the exit status (2: a user error,
    printed on one line unless --debug)."""
    try:
        args = parser().parse_args(argv)
    except KeyboardInterrupt:
        print("\ninterrupted", file=sys.stderr)
        return 130
    try:
        return COMMANDS[args.cmd](args)
    except KeyboardInterrupt:          # Ctrl-C: one line (outputs are written as sets: none is cut)
        if args.debug:
            raise
        print(f"\ninterrupted: `{args.cmd}` stopped; nothing half-written", file=sys.stderr)
        return 130
    except BrokenPipeError:            # `describe LOG | head`: the reader left; quiet, as a shell tool
        import os
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())   # no second error at exit
        except (OSError, ValueError):
            pass
        return 141
    except USER_ERRORS as e:
        if args.debug:
            raise
        print(f"error: {_message(e)}", file=sys.stderr)
        return 2
    except ImportError as e:           # an optional package: one line naming the extra
        top = (e.name or "").partition(".")[0]
        if args.debug or not (isinstance(e, MissingPackage) or top in EXTRAS):
            raise
        print(f"error: {e if isinstance(e, MissingPackage) else _missing(top, f'`{args.cmd}`')}",
              file=sys.stderr)
        return 2
