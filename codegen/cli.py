"""`python -m codegen list | generate | build | check | simulate | compare | sweep | bench | sanitize | embedded`."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from .build import BuildError, build, repo_root
from .stability import UnstableDiscretization
from .target import METHODS
from .targets import DEFAULT_FAMILY, DEFAULT_ROBOTS, default_spec


def _progress(items, desc):
    """(iterable with a progress bar on stderr, print function that does not break the bar)."""
    try:
        from tqdm import tqdm
        return (tqdm(items, desc=desc, unit="target", file=sys.stderr, leave=False),
                lambda s: tqdm.write(s, file=sys.stdout))
    except ImportError:  # pragma: no cover
        return items, print


def cmd_list(args):
    from models import names

    from . import observers
    print("robots:   " + ", ".join(names()))
    print("families: " + ", ".join(observers.FAMILIES))
    print("default targets (make generate): " + ", ".join(f"{r}_{DEFAULT_FAMILY}" for r in DEFAULT_ROBOTS))
    return 0


def _discretization(args, spec=None):
    """The discretisation of the options; ``--substeps auto``: the fewest stable ones for spec."""
    from .target import discretization
    auto = args.substeps == "auto"
    disc = discretization(None, dt=args.dt, method=args.method, substeps=None if auto else args.substeps,
                          hold=args.hold)
    if auto and spec is not None:
        from .stability import auto_substeps
        disc = auto_substeps(spec, disc)
    return disc


def _substeps(text):
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a positive integer or 'auto', got {text!r}") from None


def _emit_and_build(robot_name, args):
    from .emit import emit
    spec = default_spec(robot_name, args.family)
    t0 = time.perf_counter()
    target = emit(spec.target(_discretization(args, spec)), args.out, spec=spec)
    t1 = time.perf_counter()
    lib = build(target, native=args.native)
    return spec, target, lib, t1 - t0, time.perf_counter() - t1


def cmd_generate(args):
    """Generate, compile, and run the C harness on the built-in trajectory per target."""
    from . import harness
    from .runtime import load
    from .trajectory import demo_trajectory

    rows = []
    items, say = _progress(args.robots, "generate")
    for name in items:
        spec, target, lib, t_gen, t_cc = _emit_and_build(name, args)
        t, Q, QD, TAU = demo_trajectory(spec.robot, T=args.T, dt=_discretization(args).dt)
        work = repo_root() / "build" / "demo"
        work.mkdir(parents=True, exist_ok=True)
        csv_in, csv_out = work / f"{target.name}_in.csv", work / f"{target.name}_out.csv"
        harness.write_csv(csv_in, t, Q, TAU)
        harness.run_csv(target, csv_in, csv_out)
        _, EST = harness.read_csv(csv_out)
        obs = load(target, lib)
        obs.reset(Q[0])
        same = np.array_equal(obs.run(Q, TAU), EST)
        err0, errT = (np.linalg.norm(EST[i] - QD[i]) for i in (0, -1))
        rows.append((target.name, spec.p_default[0], t_gen, t_cc, err0, errT, same))
        say(f"{target.name:30s} k0 = {spec.p_default[0]:7.4g}  gen {t_gen:4.1f}s  cc {t_cc:4.1f}s  "
              f"|qd - qd_hat|: t=0 {err0:.3g} -> t={t[-1]:g}s {errT:.2g}   C harness == ctypes: {same}")
    d = _discretization(args)
    print(f"{len(rows)} targets ({d.method}, dt = {d.dt:g} s, {d.hold} hold) in {Path(args.out).resolve()}")
    return 0 if all(r[-1] for r in rows) else 1


def cmd_build(args):
    for name in args.robots:
        spec, target, lib, t_gen, t_cc = _emit_and_build(name, args)
        print(f"{target.name}: {lib}  (generate {t_gen:.1f}s, compile {t_cc:.1f}s)")
    return 0


def cmd_check(args):
    worst = 0.0
    for name in args.robots:
        from .check import cross_check
        spec = default_spec(name, args.family)
        r = cross_check(spec, _discretization(args, spec), count=args.count)
        w = float(np.max([v for k, v in r.items() if k != "samples"]))
        worst = float(np.max([worst, w]))
        print(f"{name}_{args.family}: worst relative error {w:.2e}  "
              + "  ".join(f"{k} {v:.1e}" for k, v in r.items() if k != "samples"))
    ok = worst <= args.tol
    print(f"{'OK' if ok else 'FAIL'}: worst {worst:.2e} (tolerance {args.tol:g})")
    return 0 if ok else 1


def cmd_bench(args):
    from .bench import main
    return main(args.bench_robots, native=args.native, json_path=args.json, scenarios=not args.no_scenarios)


def cmd_embedded(args):
    """Every target in double on an emulated Cortex-M7 and in float on a Cortex-M4F: flash, static
    RAM, peak stack, instructions per step and the difference from the host build, recorded in
    each target's JSON and printed as a table."""
    from . import embedded
    missing = embedded.missing_packages()
    if missing:
        print(f"error: ARM toolchain missing; install it with: apt-get install {' '.join(missing)} "
              "(`make embedded` does)", file=sys.stderr)
        return 2
    print(f"{'target':34s} {'cpu':10s} {'flash KB':>8s} {'RAM B':>7s} {'stack B':>7s} {'insn/step':>9s} "
          f"{'max':>7s} {'vs host':>8s} {'identical':>9s} {'vs double':>9s}")
    rows = []
    items, say = _progress(args.robots, "embedded")
    for name in items:
        spec = default_spec(name, args.family)
        for prefix, rec in embedded.verify_target(spec, spec.target(_discretization(args)), args.out,
                                                  steps=args.steps):
            rows.append(rec)
            say(f"{prefix:34s} {rec['cpu']:10s} {rec['flash_bytes'] / 1024:8.1f} {rec['static_ram_bytes']:7d} "
                f"{rec['stack_peak_bytes']:7d} {rec['instructions_per_step']:9d} "
                f"{rec['instructions_per_step_max']:7d} {rec['rel_diff_host']:8.1e} "
                f"{'yes' if rec['bit_identical'] else 'no':>9s} {rec.get('rel_diff_double', 0):9.1e}  "
                f"{'ok' if rec['ok'] else 'FAIL'}")
    print(f"{len(rows)} runs of {args.steps} steps on QEMU (-icount shift=0); records in {Path(args.out).resolve()}"
          "/<target>/<target>.json under \"embedded\"")
    return 0 if rows and all(rec["ok"] for rec in rows) else 1


def cmd_simulate(args):
    from .sim import scenarios
    options = {k: getattr(args, k) for k in ("quantization", "noise", "mismatch", "T")
               if getattr(args, k) is not None}
    return scenarios.run(args.name, reference=args.reference, out=args.out, **options)


def _compare_source(args):
    """(Recording, robot, title) of ``compare``'s source: a mujoco-* scenario run with the
    sensor and mismatch options, or a recorded CSV of ``--robot``."""
    from .compare import robot_by_name
    from .recording import read_csv
    from .sim.scenarios import mujoco
    if args.source in mujoco.SCENARIOS:
        name = args.source.removeprefix("mujoco-")
        if args.robot not in (None, name):
            raise ValueError(f"robot: scenario {args.source} is {name}, got --robot {args.robot}")
        # a simulated sensor is what the options say: unstated means exact
        args.quantization, args.noise = args.quantization or 0.0, args.noise or 0.0
        rec = mujoco.recording(name, args.T or mujoco.T_DEFAULT, args.quantization, args.noise, args.mismatch)
        return rec, robot_by_name(name), mujoco.title(name, args.quantization, args.noise, args.mismatch)
    if not str(args.source).endswith(".csv"):
        raise ValueError(f"source: expected a scenario ({', '.join(mujoco.SCENARIOS)}) or a .csv file, "
                         f"got {args.source!r}")
    if args.robot is None:
        raise ValueError("robot: a CSV needs --robot (the robot it was recorded on)")
    robot = robot_by_name(args.robot)
    return read_csv(args.source, robot.joint_names), robot, f"{Path(args.source).name} ({robot.name})"


def cmd_compare(args):
    """Observers and tuned baselines on a scenario or a CSV: table, figures, JSON."""
    from .compare import compare, design_inputs
    from .recording import RecordingError
    try:
        rec, robot, title = _compare_source(args)
        families = [f for f in args.observers.split(",") if f]
        bl = [b for b in args.baselines.split(",") if b] if args.baselines else None
        cmp = compare(rec, robot, families=families, t_ss=args.t_ss, level=args.level,
                      design=design_inputs(args.quantization, args.noise, args.mismatch),
                      baseline_names=bl, reference=args.reference, title=title)
    except (RecordingError, ValueError, KeyError) as e:
        print(f"error: {e.args[0] if isinstance(e, KeyError) else e}", file=sys.stderr)
        return 2
    print(cmp.table())
    out = Path(args.out)
    paths = cmp.figures(out)
    (out / "compare.json").write_text(json.dumps({"title": title, "t_ss": cmp.t_ss, "level": cmp.level,
                                                  "rows": cmp.rows()}, indent=2, default=float) + "\n")
    print(f"figures and compare.json in {out.resolve()} ({', '.join(p.name for p in paths)})")
    return 0


def cmd_sweep(args):
    """A Monte-Carlo sweep on Dask (codegen.sweep): results, map and best-gain table in --out."""
    from . import sweep
    from .sweep import maps, plan
    try:
        spec = plan.load(args.file)
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
    from .check import sanitize
    return sanitize.run(args.runs, args.seconds)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m codegen", description=__doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    sub.add_parser("list", help="robots, observer families, default targets")

    def common(p, robots=True):
        if robots:
            p.add_argument("robots", nargs="*", default=DEFAULT_ROBOTS, help="catalog names")
        p.add_argument("--family", default=DEFAULT_FAMILY)
        p.add_argument("--dt", type=float, help="sample time in s (default: codegen.target.DEFAULT_DISCRETIZATION)")
        p.add_argument("--method", choices=list(METHODS),
                       help="integrator (default etdrk4: RK4 with the gain term integrated exactly)")
        p.add_argument("--substeps", type=_substeps,
                       help="integrator sub-steps per sample (default 1; 'auto': the fewest that are stable)")
        p.add_argument("--hold", choices=["zoh", "foh"],
                       help="measurement hold between samples (default foh; see codegen.discretize)")
        p.add_argument("--native", action="store_true", help="add -march=native")

    g = sub.add_parser("generate", help="emit + compile the default targets, run the C harness")
    common(g)
    g.add_argument("--out", default=str(repo_root() / "generated"))
    g.add_argument("--T", type=float, default=2.0, help="length of the built-in trajectory (s)")
    b = sub.add_parser("build", help="emit + compile")
    common(b)
    b.add_argument("--out", default=str(repo_root() / "generated"))
    c = sub.add_parser("check", help="cross-check the emitted C against the reference")
    common(c)
    c.add_argument("--count", type=int, default=1000)
    c.add_argument("--tol", type=float, default=1e-9)
    be = sub.add_parser("bench", help="ns per RHS / step (default discretisation) vs pinocchio native aba")
    be.add_argument("bench_robots", nargs="*", default=["ur5", "panda"])
    be.add_argument("--native", action="store_true")
    be.add_argument("--json", help="also write the figures to this file")
    be.add_argument("--no-scenarios", action="store_true", help="only the observer RHS table")
    e = sub.add_parser("embedded", help="run the targets on emulated Cortex-M4F (float) and M7 (double)")
    common(e)
    e.add_argument("--out", default=str(repo_root() / "generated"), help="parent folder of the targets")
    e.add_argument("--steps", type=int, default=300, help="samples of the run on each CPU (default 300)")
    s = sub.add_parser("simulate", help="run a scenario of the seed papers")
    s.add_argument("name")
    s.add_argument("--reference", action="store_true", help="run observers with the numpy reference")
    s.add_argument("--out", default=str(repo_root() / "build" / "sim"))
    s.add_argument("--quantization", type=float, help="encoder step (rad; mujoco-* scenarios)")
    s.add_argument("--noise", type=float, help="Gaussian noise std (rad; mujoco-* scenarios)")
    s.add_argument("--mismatch", type=float, help="plant masses and inertias x (1 + mismatch) (mujoco-*)")
    s.add_argument("--T", type=float, help="length (s; mujoco-* scenarios)")
    cp = sub.add_parser("compare", help="observers against tuned baselines on a scenario or a CSV")
    cp.add_argument("source", help="mujoco-ur5, mujoco-panda, or a CSV (t, q_<joint>, tau_<joint>[, qd_<joint>])")
    cp.add_argument("--robot", help="robot of a CSV: catalog name or a .urdf path")
    cp.add_argument("--observers", default="reduced_order,nicosia_tomei", help="comma-separated families")
    cp.add_argument("--baselines", help="comma-separated (default: all of codegen.baselines)")
    cp.add_argument("--quantization", type=float,
                    help="encoder step (rad); scenario: of its sensor (default 0); both this and --noise "
                         "unset on a CSV: the design assumes a 2^16 counts/rev encoder")
    cp.add_argument("--noise", type=float, help="Gaussian noise std (rad; scenario default 0)")
    cp.add_argument("--mismatch", type=float, default=0.0,
                    help="scenario: plant masses and inertias x (1 + mismatch); CSV: model uncertainty")
    cp.add_argument("--T", type=float, help="scenario length (s, default 20)")
    cp.add_argument("--t-ss", type=float, help="start of the steady-state window (s, default half the run)")
    cp.add_argument("--level", type=float, default=1e-2, help="convergence threshold (rad/s)")
    cp.add_argument("--reference", action="store_true", help="run observers with the numpy reference")
    cp.add_argument("--out", default=str(repo_root() / "build" / "compare"))
    sw = sub.add_parser("sweep", help="Monte-Carlo sweep of observers and baselines on Dask (resumable)")
    sw.add_argument("file", help="the sweep file (TOML; see codegen.sweep.plan)")
    where = sw.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="local cluster of N worker processes (default: one "
                       "per CPU; 0: in this process, no Dask)")
    where.add_argument("--scheduler", help="address of an existing Dask scheduler (tcp://host:8786)")
    sw.add_argument("--out", help="output folder (default build/sweeps/<name>)")
    sa = sub.add_parser("sanitize", help="C harness and sample targets under ASan/UBSan on edge-case "
                        "CSVs, and a libFuzzer campaign of their step")
    sa.add_argument("--runs", type=int, default=100000, help="libFuzzer runs per target")
    sa.add_argument("--seconds", type=int, default=60, help="at most this long fuzzing per target")
    args = ap.parse_args(argv)
    try:
        return {"list": cmd_list, "generate": cmd_generate, "build": cmd_build, "check": cmd_check,
                "bench": cmd_bench, "simulate": cmd_simulate, "compare": cmd_compare,
                "sweep": cmd_sweep, "sanitize": cmd_sanitize, "embedded": cmd_embedded}[args.cmd](args)
    except (BuildError, UnstableDiscretization) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
