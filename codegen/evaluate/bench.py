"""Every benchmark: `python -m codegen bench` and `make bench` (timings and ratios; tests never
assert a speed).

    observer_rhs     ns per observer RHS and step of the default targets (C timing program)
                     against pinocchio's native ``aba``, as ratios; the default discretisation's
                     step against the plain RK4 zero-order-hold step of the same target
    seed000_loop     wall time of the Example-1a closed loop, observers as C and as the reference
    seed003_ii_ur5   the I&I speed observer on ur5 (seed003) and the AOV one (seed003_aov):
                     generation, C size, compile (kernel file at -O2, one job; gate 1 MB, 30 s
                     CPU), ns per RHS and step vs the reference
    seed004_cg       Ciccarella-Germani O1 on elastic robots: generation, C size, compile (also
                     the kernel file at -O2, one job), cross-check,
                     ns per RHS vs the reference, gates
    sweep_ur5        the 500-cell ur5 sweep in-process, on 1 and on 2 Dask workers: cells/s, ratio
    generate         `make generate` from scratch (empty build cache, new process): wall time
                     and each target's stage times, against the 60 s budget
    friction         the step with and without friction in the model (instructions, ns)
    native           the default targets portable (the default) and with -march=native (--native)
    scaling          generic serial chains n = 2, 6, 12, 24, 50: design, emit, compile, C size,
                     instructions and ns per step, ns per RHS, pinocchio's aba (a markdown table)

The observer-RHS table adds instructions per step (valgrind's callgrind, when valgrind is
installed: a figure the machine's load does not change).

``main`` prints the table and the scenario rows and writes them as JSON
({"observer_rhs": [...], "scenarios": {"seed000": ..., "seed003": ..., "seed004": [...]}}).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..pipeline.compile import compile_library, work_dir
from ..core.target import Discretization, Target

BENCH_GATES_NS = {"seed004_3r": 5000.0, "ur5": 50000.0}   # CG O1 rhs, ns per call


def _emit(spec, disc, check=True):
    """Emit ``spec`` under ``disc`` into build/bench (``check``: the discrete stability check of
    emit): (target folder, bytes of its C)."""
    from ..pipeline.emit import emit
    target = emit(spec.target(disc), work_dir() / "bench", spec=spec, check=check)
    return target, int(sum(p.stat().st_size for p in Path(target).glob("*.c")))


def compile_kernels(target, opt="-O2"):
    """Seconds (wall, CPU) of ``cc <opt> -c`` on the target's CasADi kernel file alone: one job,
    the flags of ``build`` otherwise. CPU seconds are the figure on a shared machine.

    Parameters
    ----------
    target : path of generated/<prefix>/
    opt : optimisation flag (last, so it wins)

    Returns
    -------
    (float, float)
    """
    import resource
    import tempfile

    from ..pipeline.compile import c_flags, compiler, run_tool
    kernels = next(Path(target).glob("*_kernels.c"))
    with tempfile.TemporaryDirectory() as tmp:
        cpu0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
        run_tool([compiler().path, *c_flags(extra=["-fPIC", opt]), "-c", kernels,
                  "-o", Path(tmp) / "kernels.o"], f"compiling {kernels.name}")
        wall, cpu1 = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime)
    return round(wall, 2), round(cpu, 2)


def _time_rhs(fn, args, repeat=20):
    """Median ns per call of fn(*args) over ``repeat`` calls (warm-up excluded)."""
    fn(*args)
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn(*args)
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts) * 1e9)


# ---------------------------------------------------------------------------- observer RHS vs pin
def observer_rhs(robots=("ur5", "panda"), native=False):
    """Default reduced-order targets timed by the C program (``c_programs.time_target``) against
    pinocchio's ``aba`` (``c_programs.time_pin``): the default discretisation (expmid1, first-order
    hold, dt = 1e-3) and, in the same run, the plain RK4 zero-order-hold step it replaced.

    Parameters
    ----------
    robots : sequence of catalog names with a URDF source
    native : bool, add -march=native

    Returns
    -------
    list of dict
        robot, ns_rhs, ns_step (default), ns_rk4_zoh_step, ns_pin_aba and the ratios RHS/aba,
        step/aba and step/(RK4 zoh step); instructions_step, instructions_rhs and
        instructions_pin_aba, the default step's, the RHS's and pinocchio aba's instructions per
        call (callgrind; None without valgrind) and the ratios to aba's.
    """
    from models import load_robot

    from ..verify import c_programs
    from ..pipeline.targets_file import default_spec
    rows = []
    for name in robots:
        src, spec = load_robot(name).source, default_spec(name)
        ns = {}
        for key, disc in (("default", Discretization(dt=1e-3)),
                          ("rk4_zoh", Discretization(dt=1e-3, method="rk4", substeps=1, hold="zoh"))):
            target, _ = _emit(spec, disc)
            compile_library(target, native=native)
            ns[key] = c_programs.time_target(target)
        pin = c_programs.time_pin(src["path"], list(src.get("locked_joints", {})))
        ours = ns["default"]
        default = _emit(spec, Discretization(dt=1e-3))[0]     # the folder the rk4_zoh emit reused
        instructions = _instructions_per_step(default, load_robot(name), 1e-3)
        per_call = c_programs.instructions_per_call(default) or {}
        pin_instructions = c_programs.pin_aba_instructions(src["path"], list(src.get("locked_joints", {})))
        rows.append({"robot": name, "ns_rhs": ours["ns_per_rhs"], "ns_step": ours["ns_per_step"],
                     "ns_rk4_zoh_step": ns["rk4_zoh"]["ns_per_step"], "ns_pin_aba": pin["ns_aba"],
                     "ratio_rhs_over_aba": ours["ns_per_rhs"] / pin["ns_aba"],
                     "ratio_step_over_aba": ours["ns_per_step"] / pin["ns_aba"],
                     "ratio_step_over_rk4_zoh": ours["ns_per_step"] / ns["rk4_zoh"]["ns_per_step"],
                     "instructions_step": instructions, "instructions_rhs": per_call.get("rhs"),
                     "instructions_pin_aba": pin_instructions,
                     "ratio_instructions_step_over_aba": instructions and pin_instructions
                     and instructions / pin_instructions,
                     "ratio_instructions_rhs_over_aba": per_call.get("rhs") and pin_instructions
                     and per_call["rhs"] / pin_instructions})
    return rows


# ---------------------------------------------------------------------------- scenarios
def seed000_loop(T=20.0):
    """Wall time of Example 1a's loop (plant at 1e-4 s + reduced-order + Nicosia–Tomei at 1 kHz,
    noisy sensor, compiled law (18)) over T seconds, observers as C and as the numpy reference.
    Setup (design, generation, compilation; cached after the first call) is timed separately."""
    from ..families.observers import build as build_observer
    from .sim.engine import simulate
    from .scenarios import seed000 as S
    from .sim.sensors import Sensor
    out = {"T_s": T, "samples": int(round(T / S.DT)) + 1}
    for key, ref in (("c", False), ("reference", True)):
        t0 = time.perf_counter()
        specs = [build_observer(f, S.robot(), eta=S.ETA, v_max=S.VMAX, design=S.PAPER) for f in ("reduced_order", "nicosia_tomei")]
        obs = {sp.family: S.observer(sp, ref) for sp in specs}
        pl, law = S.plant(), S.open_loop_law(1)
        t1 = time.perf_counter()
        simulate(pl, S.Q0, S.QD0, T, S.DT, law, obs, sensor=Sensor(**S.NOISE_1A, seed=1))
        t2 = time.perf_counter()
        out[f"{key}_setup_s"], out[f"{key}_run_s"] = round(t1 - t0, 3), round(t2 - t1, 3)
    return out


def seed003_ii_ur5(family="ii_speed", robot="ur5", N=8, native=False, wrap="auto", opt="-O2"):
    """ur5 I&I RHS in C vs the numpy/pin reference (``family``: "ii_speed" or "ii_aov"): generation,
    emit and compile times, C size, the kernel file's compile time alone (``compile_kernels``:
    ``opt``, one job) and ns per RHS and per step, at the default discretisation. Gate:
    <= 1 MB of C and <= 30 s CPU at -O2. ``wrap``: the interval reduction of the quadrature
    (ii_speed.build; "auto": ur5's revolute joints).

    Emitted without the discrete stability check (emit(check=False)): at dt = 1e-3 both observers
    are stiff on ur5 (the check finds spectral radius ~5 for I&I speed, ~1.6e3 for AOV at its
    working points) and emit would refuse them; the C's size and speed do not depend on it.
    ns per RHS and per step (``estimate``: the step's stages without advancing) through ctypes at
    a plausible state (~1 us of call overhead); the C timing program drives this observer out of
    range (timing errors). Sizes: the columns first inlined at every node made ii_speed 7.0 MB of
    C, ~170 s CPU at -O2; AOV at the default discretisation was 1.9 MB, ~26 s before it shared
    one column routine, a cheaper Cholesky velocity and the RHS between the step's stages.

    ``robot``: catalog name; ``N``: Gauss-Legendre nodes [S003 (12)]; ``native``: -march=native.
    Returns a dict of the figures and gates."""
    import timeit

    from models import load_robot

    from ..families.observers import build as build_observer
    from ..reference import reference_observer
    from ..pipeline.load import load
    rb = load_robot(robot)
    t0 = time.perf_counter()
    spec = build_observer(family, rb, N=N, wrap=wrap)
    t_gen = time.perf_counter() - t0
    t0 = time.perf_counter()
    disc = Discretization(dt=1e-3)
    target, c_bytes = _emit(spec, disc, check=False)
    t_emit = time.perf_counter() - t0
    cc_wall, cc_cpu = compile_kernels(target, opt)
    t0 = time.perf_counter()
    lib = compile_library(target, native=native, extra_flags=[opt])
    t_cc = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    y = rb.sample_configurations(1, 1)[0]
    r = spec.p_default[spec.p_names.index("r0")]
    x = np.concatenate([rng.normal(size=rb.n), y + 0.1, rng.normal(size=rb.n), [r]])
    u = np.zeros(rb.n)
    ref, reps = reference_observer(spec, disc), 20
    try:
        t_ref = min(timeit.repeat(lambda: ref.rhs(x, y, u), number=reps, repeat=3)) / reps
    except NotImplementedError:      # the AOV reference needs closed-form M, C (not ur5's URDF)
        t_ref = None
    obs = load(target, lib)
    ns_rhs = _time_rhs(obs.rhs, (x, y, u), repeat=2000)
    obs.state = x
    ns_step = _time_rhs(obs.estimate, (y, u), repeat=500)
    return {"observer": family, "robot": robot, "N": N, "wrap": list(spec.options.periodic),
            "opt": opt, "rhs_instructions": int(spec.rhs.n_instructions()),
            "generate_s": round(t_gen, 2), "emit_s": round(t_emit, 2), "compile_s": round(t_cc, 2),
            "c_bytes": c_bytes, "kernels_compile_wall_s": cc_wall, "kernels_compile_cpu_s": cc_cpu,
            "gate_1MB_30s": c_bytes <= 1e6 and cc_cpu <= 30.0,
            "ns_per_rhs_ctypes": ns_rhs, "ns_per_step_ctypes": ns_step,
            "ns_per_rhs_reference": t_ref and t_ref * 1e9, "speedup": t_ref and t_ref * 1e9 / ns_rhs,
            "gate_1ms": ns_rhs <= 1e6}


def seed003_ii_aov_ur5(**kwargs):
    """``seed003_ii_ur5`` for the AOV observer (``kwargs`` as there)."""
    return seed003_ii_ur5("ii_aov", **kwargs)


def seed004_cg(robots=("seed004_3r", "ur5"), method="rk4", dt=1e-4, checks=5):
    """CG O1 on elastic robots: spec and C generation time, C size, compile time, a cross-check
    of the C rhs against the reference (exact hyper-duals for DH robots; for URDF robots
    pinocchio's first-order ABA derivatives with central differences for the y4 rows of Q),
    ns per C rhs call from the C timing program (``c_programs.time_target``: medians of blocks,
    no Python in the loop), and ns per rhs of the reference path (numpy/pinocchio). Gates:
    BENCH_GATES_NS, and the kernel file compiled by gcc -O2 -c in <= 30 s CPU
    (``compile_kernels``). With RK4 the step calls the RHS routine (discretize.INLINE_LIMIT);
    inlining its four stages, as before, made elastic ur5 1.0 MB of C, ~31 s CPU at -O2 for the
    kernel file and a step ~4 times slower. Returns a list of dicts (one per robot).

    ``robots``: elastic catalog names; ``method``, ``dt`` (s): the discretisation; ``checks``:
    random states of the cross-check."""
    import tempfile

    from models.catalog import load_elastic

    from ..verify.c_programs import time_target
    from ..families.observers import ciccarella_germani
    from ..reference import reference_observer
    from ..pipeline.load import load
    rows = []
    for name in robots:
        robot = load_elastic(name)
        t0 = time.perf_counter()
        # The gains are runtime parameters (the C is the same for any eigenvalues). The timing
        # program drives the step with synthetic sinusoids (~250 rad/s at dt = 1e-4) that make
        # the default high-gain observer overflow in its warm-up, so the defaults here are slow.
        spec = ciccarella_germani.build(robot, "O1", eigenvalues=np.linspace(-1.0, -2.0, robot.nx))
        t_spec = time.perf_counter() - t0
        # the timing program steps at the fixed dt: the declared range of the elapsed time is
        # [dt/4, dt]. The default [dt/4, 2 dt] is refused on elastic ur5 (spectral radius 1.005
        # at 2 dt, the flow's 1.004: RK4 on its joints' elastic modes; stable up to 1.08 dt)
        disc = Discretization(dt=dt, method=method, hold="zoh", dt_max=dt)
        target, c_bytes = _emit(spec, disc)
        t_gen = time.perf_counter() - t0
        with tempfile.TemporaryDirectory() as tmp:   # a fresh cache: the real compile time
            t1 = time.perf_counter()
            compile_library(target, cache=tmp)
            t_cc = time.perf_counter() - t1
        cc_wall, cc_cpu = compile_kernels(target, "-O2")
        obs = load(target, compile_library(target))
        ref = reference_observer(spec, disc)
        rng = np.random.default_rng(0)
        worst = 0.0
        X = robot.sample_states(checks, seed=1)
        for x in X:
            y, u = x[:robot.n] + 0.01 * rng.normal(size=robot.n), 10 * rng.normal(size=robot.n)
            want = ref.rhs(x, y, u)
            worst = max(worst, float(np.linalg.norm(obs.rhs(x, y, u) - want) / np.linalg.norm(want)))
        t2 = time.perf_counter()
        timing = time_target(target, blocks=21, block_ms=10.0)
        t_time = time.perf_counter() - t2
        args = (X[0], X[0][:robot.n] + 0.01, np.ones(robot.n))
        gate = BENCH_GATES_NS.get(name)
        ns = float(timing["ns_per_rhs"])
        rows.append({"robot": robot.name, "observer": "ciccarella_germani O1", "nx": robot.nx,
                     "instructions_rhs": spec.rhs.n_instructions(),
                     "spec_s": round(t_spec, 3), "generate_s": round(t_gen, 3), "c_bytes": c_bytes,
                     "compile_s": round(t_cc, 2), "kernels_compile_O2_wall_s": cc_wall,
                     "kernels_compile_O2_cpu_s": cc_cpu, "gate_compile_30s": cc_cpu <= 30.0,
                     "timing_program_s": round(t_time, 2),
                     "rhs_rel_err_vs_reference": worst,
                     "reference_exact": bool(getattr(ref.robot, "exact", True)),
                     "ns_rhs_c": ns, "ns_step_c": float(timing["ns_per_step"]),
                     "ns_rhs_c_ctypes": _time_rhs(obs.rhs, args, repeat=2000),
                     "ns_rhs_reference": _time_rhs(ref.rhs, args, repeat=20),
                     "gate_ns_rhs": gate, "gate_ok": None if gate is None else ns <= gate})
    return rows


def generate_from_scratch(targets=None, jobs=None, budget_s=60.0):
    """Wall time of `python -m codegen generate -c targets.toml` in a new process with an empty
    build folder (so an empty compile cache), as on a fresh clone after the venv.

    Parameters
    ----------
    targets : path, optional
        The targets file (default ./targets.toml: `make bench` runs in the checkout).
    jobs : int, optional
        Parallel processes (default: generate's, one per core).
    budget_s : float
        The budget the issue sets (s).

    Returns
    -------
    dict
        wall_s, budget_s, within_budget, cpus, and "targets": the line generate printed per target
        (its stage times).
    """
    import os
    import subprocess
    import sys
    import tempfile

    targets = Path(targets or "targets.toml").resolve()
    root = Path(__file__).resolve().parents[3]          # the folder holding the codegen package
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, CODEGEN_BUILD=str(Path(tmp) / "build"), CODEGEN_CACHE="",
                   PYTHONPATH=os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")])))
        cmd = [sys.executable, "-m", "codegen", "generate", "-c", str(targets), "--out", str(Path(tmp) / "generated")]
        cmd += ["-j", str(jobs)] if jobs else []
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"generate failed (exit {proc.returncode}):\n{proc.stderr.strip()[-2000:]}")
    lines = [ln for ln in proc.stdout.splitlines() if " design " in ln]
    return {"wall_s": round(wall, 1), "budget_s": budget_s, "within_budget": wall <= budget_s,
            "cpus": os.cpu_count(), "jobs": jobs or "default", "targets": lines}



def sweep_ur5(path=None, modes=(0, 1, 2)):
    """The example sweep (``sweeps/ur5_quantisation.toml``: reduced-order on MuJoCo's ur5, 500
    cells) computed in-process (0), on a LocalCluster of 1 and of 2 workers: cells/s of each
    (cluster start and worker imports excluded, true runs included), cells per CPU-second of the
    cell computations (what a mode costs per cell, whatever else the machine runs), their ratio
    (the cores the mode had: on a shared machine the 2 workers may get no more than 1), the
    2-vs-1-worker ratio (target >= 1.7) and whether every mode gave identical rows.
    ``path``: the sweep file (default the example); ``modes``: worker counts (0: in-process)."""
    import tempfile

    from . import sweep
    path = Path(path or "sweeps/ur5_quantisation.toml")      # `make bench` runs in the checkout
    row, frames = {"sweep": path.name}, []
    with tempfile.TemporaryDirectory() as tmp:
        for w in modes:
            res = sweep.run(path, workers=w, out=Path(tmp) / f"w{w}", progress=False)
            row["cells"] = res.cells
            frame = res.frame()
            mode = f"{w}w" if w else "in_process"
            row[f"cells_per_s_{mode}"] = res.computed / res.seconds
            row[f"cells_per_cpu_s_{mode}"] = len(frame) / frame["cpu_s"].sum()
            row[f"cores_used_{mode}"] = row[f"cells_per_s_{mode}"] / row[f"cells_per_cpu_s_{mode}"]
            frames.append(frame.drop(columns=["worker", "cpu_s"]))
    if {1, 2} <= set(modes):
        row["ratio_2w_over_1w"] = row["cells_per_s_2w"] / row["cells_per_s_1w"]
    row["identical"] = all(f.equals(frames[0]) for f in frames)
    return row


def _instructions_per_step(target, robot, dt, steps=(200, 1200), native=False):
    """Instructions per ``<prefix>_step`` of ``target`` (a velocity observer of ``robot`` at
    sample time ``dt``): valgrind's callgrind on run_csv over ``steps`` samples of the demo
    trajectory, counting inside the step only (--toggle-collect), the difference of the totals
    over the difference of the counts (the first sample's start-up cancels); None without
    valgrind, or (``native``: the harness compiled with -march=native) when valgrind cannot
    emulate the native build's instructions."""
    import re
    import shutil
    import signal
    import subprocess
    import tempfile
    import warnings

    from ..verify.c_programs import compile_harness, write_csv
    from ..verify.trajectory import demo_trajectory
    if shutil.which("valgrind") is None:
        return None
    exe = compile_harness(target, native=native)["run_csv"]
    totals = []
    with tempfile.TemporaryDirectory() as tmp:
        for N in steps:
            t, Q, _, TAU = demo_trajectory(robot, T=(N - 1) * dt, dt=dt)
            write_csv(Path(tmp) / "in.csv", t, Q, TAU)
            out = Path(tmp) / "cg.out"
            proc = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                                   f"--toggle-collect={Path(target).name}_step", str(exe),
                                   str(Path(tmp) / "in.csv"), str(Path(tmp) / "est.csv")],
                                  capture_output=True)
            if native and proc.returncode == -signal.SIGILL:
                # -march=native emitted an instruction this valgrind cannot emulate (AVX-512 on
                # valgrind < 3.22): no count, the row keeps its ns
                warnings.warn("valgrind cannot run the -march=native build (SIGILL): no instruction "
                              "count", RuntimeWarning)
                return None
            proc.check_returncode()
            totals.append(int(re.search(r"^summary:\s+(\d+)", out.read_text(), re.M).group(1)))
    return (totals[1] - totals[0]) / (steps[1] - steps[0])


def friction_step(robot="ur5", families=("reduced_order", "kalman_model")):
    """The step's cost with friction in the model against the same observer without: ``robot``
    as shipped (no friction) and with viscous, Coulomb and offset on every joint (values of the
    real ur5's identification), each ``family`` at its defaults (quantisation 1e-4; kalman_model
    with a torque uncertainty, so the model is used). Instructions per step (valgrind) and
    ns per step (time_step, fastest of its blocks' medians) with their ratios.

    Parameters
    ----------
    robot : str
        A catalog robot.
    families : sequence of str
        Observer families compared.

    Returns
    -------
    list of dict
        Per family: instructions and ns per step without and with friction, their ratios.
    """
    from models import load_robot

    from ..families import observers
    from ..verify.c_programs import time_target
    plain = load_robot(robot)
    n = plain.n
    rough = plain.with_friction(viscous=np.linspace(1.8, 0.3, n), coulomb=np.linspace(3.0, 0.5, n),
                                offset=np.full(n, -0.2))
    rows = []
    for family in families:
        opts = {"quantization": 1e-4}
        if family == "kalman_model":
            opts["torque_uncertainty"] = [0.3] * n
        row = {"family": family, "robot": robot}
        for label, r in (("plain", plain), ("friction", rough)):
            spec = observers.build(family, r, **opts)
            target, _ = _emit(spec, Discretization(dt=1e-3, substeps="auto"))
            row[f"instructions_{label}"] = _instructions_per_step(target, r, 1e-3)
            row[f"ns_{label}"] = time_target(target)["ns_per_step"]
        if row["instructions_plain"]:
            row["ratio_instructions"] = row["instructions_friction"] / row["instructions_plain"]
        row["ratio_ns"] = row["ns_friction"] / row["ns_plain"]
        rows.append(row)
    return rows


def kalman_model_step(robot="ur5", cortex_m=True, targets=None, design=None):
    """The observer a real arm's user runs, ``kalman_model`` with the model, as the targets file
    has it for ``robot`` (ur5: the torque uncertainty of the real ur5's identification), at the
    default discretisation: its design from an empty design cache (wall and CPU s, in this
    process: the imports are not in it), instructions per step (callgrind, ``_instructions_per_step``)
    and pinocchio's ``aba`` in the same run and their ratio (the issue's target: <= 1.0), ns per
    step and per ``aba`` (one run's clock), and, with the ARM toolchain (``cortex_m=True``), the
    float build's instructions per step on the Cortex-M4F (QEMU, 300 steps) and the share of a
    1 kHz period they take at 168 MHz and one instruction a cycle.

    Parameters
    ----------
    robot : str
        A catalog robot with a kalman_model entry in the targets file.
    cortex_m : bool
        Also the Cortex-M4F float row (skipped, None, when the toolchain is missing).
    targets : path, optional
        The targets file (default ./targets.toml).
    design : dict, optional
        The build's keyword arguments in place of the targets file's entry (a robot without one).

    Returns
    -------
    dict
    """
    import os
    import resource
    import tempfile
    from dataclasses import replace

    from models import load_robot

    from ..pipeline.targets_file import build_spec, load_targets
    from ..verify import c_programs, cortex_m as arm
    if design is None:
        target = next(t for t, _ in load_targets(Path(targets or "targets.toml"))
                      if t.family == "kalman_model" and t.robot.get("name") == robot)
        target = replace(target, discretization=Discretization(dt=1e-3))
    else:
        target = Target(robot=load_robot(robot).source, family="kalman_model", build=design,
                        discretization=Discretization(dt=1e-3))
    with tempfile.TemporaryDirectory() as tmp:
        old = os.environ.get("CODEGEN_CACHE")
        os.environ["CODEGEN_CACHE"] = str(Path(tmp) / "cache")
        try:
            cpu0, t0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
            spec = build_spec(target)
            wall, cpu1 = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_SELF)
        finally:
            if old is None:
                os.environ.pop("CODEGEN_CACHE")
            else:
                os.environ["CODEGEN_CACHE"] = old
    folder, c_bytes = _emit(spec, target.discretization)
    compile_library(folder)
    rb, src = load_robot(robot), load_robot(robot).source
    locked = list(src.get("locked_joints", {}))
    step = _instructions_per_step(folder, rb, 1e-3)
    timing = c_programs.time_target(folder)
    if "path" in src:
        aba = c_programs.pin_aba_instructions(src["path"], locked)
        pin = c_programs.time_pin(src["path"], locked)["ns_aba"]
    else:       # a closed-form robot (no URDF): no pinocchio
        aba = pin = None
    row = {"robot": robot, "family": "kalman_model", "variant": spec.variant,
           "design_wall_s": round(wall, 2),
           "design_cpu_s": round(cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime, 2),
           "c_bytes": c_bytes, "instructions_step": step, "instructions_pin_aba": aba,
           "ratio_instructions_step_over_aba": step and aba and step / aba,
           "ns_step": timing["ns_per_step"], "ns_pin_aba": pin,
           "ratio_ns_step_over_aba": pin and timing["ns_per_step"] / pin,
           "m4f_instructions_step": None, "m4f_share_of_1ms_at_168MHz": None}
    if cortex_m and not arm.missing_packages():
        with tempfile.TemporaryDirectory() as tmp:
            recs = dict(arm.verify_target(spec, target, tmp))
        m4f = next(rec for prefix, rec in recs.items() if prefix.endswith("_float"))
        row["m4f_instructions_step"] = m4f["instructions_per_step"]
        row["m4f_share_of_1ms_at_168MHz"] = m4f["instructions_per_step"] / 168e3
    return row


def generic_chain_urdf(n, seed=0):
    """The URDF text of a generic serial chain of ``n`` revolute joints: axes, placements and
    inertials drawn with ``seed`` (no axis aligned, so no term folds away: the cost of a chain,
    not of a catalog arm's round numbers). Ranges +-2 rad, 2 rad/s, unit-ish masses."""
    import xml.etree.ElementTree as ET

    def txt(x):
        return " ".join(repr(float(e)) for e in x)
    rng = np.random.default_rng(seed)
    root = ET.Element("robot", name=f"chain{n}")
    ET.SubElement(root, "link", name="base")
    parent = "base"
    for i in range(n):
        joint = ET.SubElement(root, "joint", name=f"j{i}", type="revolute")
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=f"l{i}")
        ET.SubElement(joint, "origin", xyz=txt(rng.uniform(-0.2, 0.2, 3)), rpy=txt(rng.uniform(-np.pi, np.pi, 3)))
        axis = rng.normal(size=3)
        ET.SubElement(joint, "axis", xyz=txt(axis / np.linalg.norm(axis)))
        # effort 100 N m: the declared torque range (10 x) holds the demo trajectory's torques
        # (409 N m at n = 50; 10 N m refused chain24's at 189 N m with ERR_OUT_OF_RANGE)
        ET.SubElement(joint, "limit", lower="-2", upper="2", effort="100", velocity="2")
        inertial = ET.SubElement(ET.SubElement(root, "link", name=f"l{i}"), "inertial")
        ET.SubElement(inertial, "origin", xyz=txt(rng.uniform(-0.1, 0.1, 3)))
        ET.SubElement(inertial, "mass", value=repr(float(rng.uniform(0.5, 2.0))))
        m = rng.uniform(0.01, 0.05, 3)
        ET.SubElement(inertial, "inertia", ixx=repr(float(m[0])), ixy="0", ixz="0", iyy=repr(float(m[1])),
                      iyz="0", izz=repr(float(m[2])))
        parent = f"l{i}"
    return ET.tostring(root, encoding="unicode")


def scaling(ns=(2, 6, 12, 24, 50), seed=0):
    """Generic serial chains (``generic_chain_urdf``) of ``ns`` joints, the default reduced-order
    observer: CPU seconds of the design's sups over configurations (``reduced_order_gain``, (12))
    and of the whole design (``observers.build`` with an empty design cache, the noise-aware gain
    and the stability check included), of emit and of the compile (fresh compile cache, the compiler's
    CPU), bytes of C, instructions per step (callgrind, ``_instructions_per_step``; None without
    valgrind), instructions per RHS and step/RHS in instructions (``instructions_per_call``), ns per
    step and per RHS (timing program) and pinocchio's native ``aba`` (ns, and instructions per call by
    callgrind).

    Parameters
    ----------
    ns : sequence of int
        Numbers of joints of the chains.
    seed : int
        Seeds the chains' drawn geometry and inertials.

    Returns
    -------
    list of dict, one per n."""
    import os
    import resource
    import tempfile

    from models.urdf import load_urdf

    from ..families import observers
    from ..pipeline.compile import CompileError
    from ..verify import c_programs
    rows = []
    for n in ns:
        with tempfile.TemporaryDirectory() as tmp:
            urdf = Path(tmp) / f"chain{n}.urdf"
            urdf.write_text(generic_chain_urdf(n, seed))
            robot = load_urdf(urdf)
            old = os.environ.get("CODEGEN_CACHE")
            os.environ["CODEGEN_CACHE"] = str(Path(tmp) / "cache")      # the design from scratch
            try:
                from ..families.design.reduced_order import reduced_order_gain
                t0 = time.process_time()
                reduced_order_gain(robot)                 # the sups over configurations, (12)
                t_sups = time.process_time() - t0
                spec = observers.build("reduced_order", robot)
                t_design = time.process_time() - t0
            finally:
                if old is None:
                    os.environ.pop("CODEGEN_CACHE")
                else:
                    os.environ["CODEGEN_CACHE"] = old
            t0 = time.process_time()
            target, c_bytes = _emit(spec, Discretization(dt=1e-3))
            t_emit = time.process_time() - t0
            cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            compile_library(target, cache=Path(tmp) / "cc")
            cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            timing = c_programs.time_target(target, blocks=21, block_ms=10.0)
            try:
                pin_ns = c_programs.time_pin(str(urdf), blocks=21, block_ms=10.0)["ns_aba"]
                pin_instructions = c_programs.pin_aba_instructions(str(urdf))
            except CompileError:          # no Eigen headers: `make bench` installs them (.[bench])
                pin_ns = pin_instructions = None
            step_instructions = _instructions_per_step(target, robot, 1e-3)
            per_call = c_programs.instructions_per_call(target) or {}
            rows.append({"n": n, "sups_s": round(t_sups, 2), "design_s": round(t_design, 2), "emit_s": round(t_emit, 2),
                         "compile_s": round(cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime, 2),
                         "c_bytes": c_bytes, "step_instructions": step_instructions,
                         "pin_aba_instructions": pin_instructions, "rhs_instructions": per_call.get("rhs"),
                         "step_over_rhs_instructions": per_call.get("rhs") and per_call["step"] / per_call["rhs"],
                         "step_over_aba_instructions": step_instructions and pin_instructions
                         and step_instructions / pin_instructions,
                         "ns_step": timing["ns_per_step"], "ns_rhs": timing["ns_per_rhs"],
                         "ns_pin_aba": pin_ns, "step_over_rhs": timing["ns_per_step"] / timing["ns_per_rhs"],
                         "step_over_aba": pin_ns and timing["ns_per_step"] / pin_ns})
    return rows


def scaling_markdown(rows):
    """The ``scaling`` rows as a markdown table (the README's bench section)."""
    out = ["| n | sups s | design s | emit s | compile s | C kB | step instr | RHS instr | pin aba instr "
           "| step/RHS (instr) | step/aba (instr) | step ns | RHS ns | pin aba ns | step/RHS (ns) | step/aba (ns) |",
           "|---" * 16 + "|"]
    for r in rows:
        def fmt(x, f):
            return "-" if x is None else format(x, f)
        out.append(f"| {r['n']} | {r['sups_s']:.2f} | {r['design_s']:.2f} | {r['emit_s']:.2f} | {r['compile_s']:.1f} | "
                   f"{r['c_bytes'] / 1e3:.0f} | {fmt(r['step_instructions'], ',.0f')} | "
                   f"{fmt(r.get('rhs_instructions'), ',.0f')} | {fmt(r.get('pin_aba_instructions'), ',.0f')} | "
                   f"{fmt(r.get('step_over_rhs_instructions'), '.2f')} | "
                   f"{fmt(r.get('step_over_aba_instructions'), '.2f')} | {r['ns_step']:.0f} | "
                   f"{r['ns_rhs']:.0f} | {fmt(r['ns_pin_aba'], '.0f')} | {r['step_over_rhs']:.2f} | "
                   f"{fmt(r['step_over_aba'], '.2f')} |")
    return "\n".join(out)


def native_isa(robots=("ur5", "panda")):
    """The default target of each robot compiled portable (the default) and with -march=native
    (``--native``): instructions per step (callgrind, None without valgrind; with wider vectors
    native runs fewer) and ns per step and per RHS of each, and the speed-up native / portable
    (ns: on a shared machine, a single run's ratio moves by 2x; the instruction counts do not).

    Parameters
    ----------
    robots : sequence of str
        Catalog robots, each with its default target (``default_spec``).

    Returns
    -------
    list of dict, one per robot."""
    from models import load_robot

    from ..verify import c_programs
    from ..pipeline.targets_file import default_spec
    rows = []
    for name in robots:
        target, _ = _emit(default_spec(name), Discretization(dt=1e-3))
        row = {"robot": name}
        for label, native in (("portable", False), ("native", True)):
            t = c_programs.time_target(target, native=native)
            row[f"ns_step_{label}"], row[f"ns_rhs_{label}"] = t["ns_per_step"], t["ns_per_rhs"]
        for label, native in (("portable", False), ("native", True)):
            row[f"instructions_{label}"] = _instructions_per_step(target, load_robot(name), 1e-3, native=native)
        row["speedup_step"] = row["ns_step_portable"] / row["ns_step_native"]
        row["speedup_rhs"] = row["ns_rhs_portable"] / row["ns_rhs_native"]
        rows.append(row)
    return rows


SCENARIOS = {"kalman_model": kalman_model_step,
             "seed000": seed000_loop, "seed003": seed003_ii_ur5, "seed003_aov": seed003_ii_aov_ur5,
             "seed004": seed004_cg, "sweep_ur5": sweep_ur5, "friction": friction_step, "native": native_isa, "scaling": scaling}


# ---------------------------------------------------------------------------- report
def smoke_scenarios():
    """The cheap rows every path of the bench goes through (``bench --smoke``, CI's `make
    test-long`, about a minute): kalman_model's step on seed000_2r with the model (no Cortex-M, no
    pinocchio: a closed-form robot),
    and Ciccarella-Germani O1 on elastic ur5, the row the stability check once refused."""
    from functools import partial
    return {"kalman_model": partial(kalman_model_step, "seed000_2r", cortex_m=False,
                                    design={"torque_uncertainty": [0.5, 0.2]}),
            "seed004": partial(seed004_cg, robots=("ur5",), checks=2)}


def main(robots=("ur5", "panda"), native=False, json_path=None, scenarios=True, generate=True,
         smoke=False):
    """Print the observer-RHS table, (``scenarios``) every scenario bench and (``generate``) the
    time of `make generate` from scratch; with ``json_path`` also write the figures there.
    ``robots``: catalog names of the table; ``native``: compile with -march=native; ``smoke``:
    the table on ur5 and the scenarios of ``smoke_scenarios`` only, nothing generated.
    Returns 0 (the CLI's exit status)."""
    if smoke:
        robots, generate = ("ur5",), False
    rows = observer_rhs(robots, native)
    print(f"{'robot':8s} {'RHS ns':>9s} {'step ns':>9s} {'rk4/zoh ns':>11s} {'pin aba ns':>11s} {'RHS/aba':>8s} "
          f"{'step/aba':>9s} {'step/rk4zoh':>12s} {'step instr':>11s} {'RHS instr':>10s} {'aba instr':>10s} "
          f"{'step/aba':>9s} {'RHS/aba':>8s}"
          "   (step: the default, expmid1 with first-order hold)")
    for r in rows:
        print(f"{r['robot']:8s} {r['ns_rhs']:9.1f} {r['ns_step']:9.1f} {r['ns_rk4_zoh_step']:11.1f} "
              f"{r['ns_pin_aba']:11.1f} {r['ratio_rhs_over_aba']:8.3f} {r['ratio_step_over_aba']:9.3f} "
              f"{r['ratio_step_over_rk4_zoh']:12.3f} {r['instructions_step'] or 0:11,.0f} "
              f"{r['instructions_rhs'] or 0:10,.0f} {r['instructions_pin_aba'] or 0:10,.0f} "
              f"{r['ratio_instructions_step_over_aba'] or 0:9.3f} {r['ratio_instructions_rhs_over_aba'] or 0:8.3f}")
    print("(the last four columns: instructions per call, valgrind; the others: ns, this run's clock)")
    extra = {}
    benches = dict((smoke_scenarios() if smoke else SCENARIOS) if scenarios else {},
                   **({"generate": generate_from_scratch} if generate else {}))
    for name, fn in benches.items():
        print(f"\n{name}:", flush=True)
        extra[name] = fn()
        for row in (extra[name] if isinstance(extra[name], list) else [extra[name]]):
            print("  " + "  ".join(f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}"
                                   for k, v in row.items() if not isinstance(v, list)))
            for k, v in ((k, v) for k, v in row.items() if isinstance(v, list)):
                print("\n".join(f"    {k}: {item}" for item in v))
        if name == "scaling":
            print("\n" + scaling_markdown(extra[name]))
    if json_path:
        Path(json_path).write_text(json.dumps({"observer_rhs": rows, "scenarios": extra}, indent=2,
                                              default=float))
    return 0
