"""The sweep file: what to run, and the cells it expands into (each with a stable id).

    name = "ur5-quantisation"
    robot = "ur5"                  # catalog name or .urdf path
    plant = "mujoco"               # "mujoco" (MuJoCo's simulation) or "model" (our model, exact)
    T = 2.0                        # run length (s); t_ss (default T/2) and level as in compare
    observers = ["reduced_order"]  # compare's syntax: "family[:name=value...]"
    baselines = ["butterworth"]    # tuned over their grid in every cell, as compare does
    batch = 16                     # cells per Dask task
    samples = 1                    # draws of the random axes per grid point
    seed = 0                       # seed of those draws
    designed = true                # false: no gain design (every gain from the axes or the item)
    retries = 3                    # Dask retries of a failed task
    [map]                          # optional: x, y, metric, method of map.png and best.txt

    [axes]                         # a list (grid), a number, {lin|log = [a, b, n]} (grid),
    k0 = {log = [5, 500, 12]}      # or {uniform|loguniform = [a, b]} (random)
    noise = [0, 1e-5, 1e-4]

Axes: ``noise``, ``quantization`` (rad), ``mismatch`` (plant masses and inertias x (1 + m)),
``seed`` (trajectory and noise), ``est0`` (initial estimate = true qd(0) + est0 on every
joint, rad/s; without this axis the estimate starts at 0 as in compare), ``dt`` (s), and any
runtime parameter of an observer (``k0``, ``kd``, ...): a gain axis. A cell is one method at one
point of the axes that concern it (a baseline has no gain and no est0); its id hashes the
method, the setting and those values.
"""
from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomllib

PLANTS = ("model", "mujoco")
PLANT_AXES = ("mismatch", "seed", "dt")          # a true run per point of these
SENSOR_AXES = ("noise", "quantization")
AXES = SENSOR_AXES + PLANT_AXES + ("est0",)
DEFAULTS = {"noise": 0.0, "quantization": 0.0, "mismatch": 0.0, "seed": 0, "dt": 1e-3, "est0": None}
KEYS = {"name", "robot", "plant", "T", "t_ss", "level", "observers", "baselines", "batch",
        "samples", "seed", "retries", "axes", "map", "designed"}
GRIDS = {"lin": np.linspace, "log": np.geomspace}
RANDOM = {"uniform": lambda rng, a, b: rng.uniform(a, b),
          "loguniform": lambda rng, a, b: float(np.exp(rng.uniform(np.log(a), np.log(b))))}


def digest(value, n=16):
    """Short sha256 of a JSON-able ``value`` (sorted keys): the ids of cells, batches, runs;
    the first ``n`` hex digits."""
    return hashlib.sha256(json.dumps(value, sort_keys=True, default=float).encode()).hexdigest()[:n]


@dataclass
class Sweep:
    """A parsed sweep file (see the module docstring); ``source`` is its text (TOML) or JSON."""

    robot: str
    plant: str = "model"
    T: float = 2.0
    t_ss: float | None = None
    level: float = 1e-2
    observers: list = field(default_factory=lambda: ["reduced_order"])
    baselines: list = field(default_factory=list)
    axes: dict = field(default_factory=dict)      # name -> list of values (grid) or (kind, a, b)
    batch: int = 16
    samples: int = 1
    seed: int = 0
    retries: int = 3
    designed: bool = True
    map: dict = field(default_factory=dict)
    name: str = "sweep"
    source: str = ""

    @property
    def steady(self):
        """Start of the steady-state window (s)."""
        return float(self.T / 2 if self.t_ss is None else self.t_ss)

    def setting(self):
        """What every cell shares (part of each cell id)."""
        return {"robot": self.robot, "plant": self.plant, "T": self.T, "t_ss": self.steady,
                "level": self.level}

    def points(self):
        """Every point of the axes: the grid product times ``samples`` draws of the random
        axes (seeded by ``seed``), as dicts axis -> value (all AXES present, defaults filled)."""
        grid = {k: v for k, v in self.axes.items() if isinstance(v, list)}
        rand = {k: v for k, v in sorted(self.axes.items()) if not isinstance(v, list)}
        rng = np.random.default_rng(self.seed)
        draws = [{k: RANDOM[kind](rng, a, b) for k, (kind, a, b) in rand.items()}
                 for _ in range(self.samples if rand else 1)]
        names = list(grid)
        for combo in itertools.product(*(grid[k] for k in names)):
            for d in draws:
                yield {**DEFAULTS, **dict(zip(names, combo)), **d}


def _number(where, v):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise ValueError(f"{where}: expected a finite number, got {v!r}")
    return v


def _axis(name, v):
    """An axis value of the file -> list of values (grid) or (kind, a, b) (random)."""
    where = f"axes.{name}"
    if isinstance(v, list):
        if not v:
            raise ValueError(f"{where}: empty list")
        return [_number(where, x) for x in v]
    if isinstance(v, dict):
        if len(v) != 1 or next(iter(v)) not in (*GRIDS, *RANDOM):
            raise ValueError(f"{where}: expected one of {{lin|log = [a, b, n]}} or "
                             f"{{uniform|loguniform = [a, b]}}, got {v!r}")
        (kind, args), = v.items()
        if kind in GRIDS:
            if len(args) != 3 or isinstance(args[2], bool) or not isinstance(args[2], int) or args[2] < 1:
                raise ValueError(f"{where}: {kind} takes [first, last, count], got {args!r}")
            a, b = (_number(where, x) for x in args[:2])
            if kind == "log" and not (a > 0 and b > 0):
                raise ValueError(f"{where}: log grid needs positive ends, got {args!r}")
            return [float(x) for x in GRIDS[kind](a, b, args[2])]
        if len(args) != 2:
            raise ValueError(f"{where}: {kind} takes [low, high], got {args!r}")
        a, b = (float(_number(where, x)) for x in args)
        if not a < b or (kind == "loguniform" and a <= 0):
            raise ValueError(f"{where}: {kind} needs low < high{' and low > 0' if kind == 'loguniform' else ''}, "
                             f"got {args!r}")
        return (kind, a, b)
    return [_number(where, v)]


def load(source):
    """A Sweep from ``source``: a TOML path, TOML text (a str with a newline) or a dict (the
    keys of the module docstring); ValueError naming the key otherwise."""
    if isinstance(source, dict):
        d, text = dict(source), json.dumps(source, sort_keys=True, indent=1, default=float)
    else:
        text = source if isinstance(source, str) and "\n" in source else None
        if text is None:
            path = Path(source)
            if not path.is_file():
                raise ValueError(f"sweep: no such file {path}")
            text = path.read_text()
        try:
            d = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise ValueError(f"sweep: not valid TOML: {e}") from None
    unknown = set(d) - KEYS
    if unknown:
        raise ValueError(f"sweep: unknown keys {sorted(unknown)}; known: {sorted(KEYS)}")
    if "robot" not in d:
        raise ValueError("sweep: robot is required (a catalog name or a .urdf path)")
    if d.get("plant", "model") not in PLANTS:
        raise ValueError(f"plant must be one of {PLANTS}, got {d.get('plant')!r}")
    axes = {k: _axis(k, v) for k, v in dict(d.pop("axes", {})).items()}
    for k in ("seed",):
        if k in axes and (not isinstance(axes[k], list) or any(int(x) != x for x in axes[k])):
            raise ValueError(f"axes.{k}: expected whole numbers, got {axes[k]!r}")
    for k in ("observers", "baselines"):
        if k in d and (not isinstance(d[k], list) or not all(isinstance(x, str) for x in d[k])):
            raise ValueError(f"{k}: expected a list of strings, got {d[k]!r}")
    s = Sweep(**d, axes=axes, source=text)
    if not s.observers and not s.baselines:
        raise ValueError("observers, baselines: the sweep names no method")
    for k in ("T", "level"):
        if not (isinstance(getattr(s, k), (int, float)) and getattr(s, k) > 0):
            raise ValueError(f"{k} must be a positive number, got {getattr(s, k)!r}")
    for k in ("batch", "samples"):
        v = getattr(s, k)
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ValueError(f"{k} must be a positive integer, got {v!r}")
    if isinstance(s.retries, bool) or not isinstance(s.retries, int) or s.retries < 0:
        raise ValueError(f"retries must be a whole number >= 0, got {s.retries!r}")
    if not isinstance(s.designed, bool):
        raise ValueError(f"designed must be true or false, got {s.designed!r}")
    if not 0 <= s.steady < s.T:
        raise ValueError(f"t_ss must be in [0, T), got {s.t_ss!r} (T = {s.T})")
    for k, v in axes.items():          # one type per axis: the cell ids do not see 0 vs 0.0
        if isinstance(v, list):
            axes[k] = [int(x) for x in v] if k == "seed" else [float(x) for x in v]
    if not isinstance(s.map, dict) or set(s.map) - {"x", "y", "metric", "method"}:
        raise ValueError(f"map: expected a table with x, y, metric, method, got {s.map!r}")
    for k in ("noise", "quantization", "dt"):
        for v in (axes.get(k) if isinstance(axes.get(k), list) else ()):
            if v < 0 or (k == "dt" and v == 0):
                raise ValueError(f"axes.{k}: values must be {'positive' if k == 'dt' else '>= 0'}, got {v!r}")
    return s


@dataclass
class Method:
    """One observer (compiled once per dt in the client) or baseline of the sweep."""

    item: str                 # as written in the file
    kind: str                 # "observer" or "baseline"
    family: str
    given: dict               # build arguments given in the item (observers)
    p_names: tuple = ()       # runtime parameters (observers)


def cells(sweep, methods, designed):
    """The cells of the sweep, in a fixed order.

    Parameters
    ----------
    sweep : Sweep
    methods : list of Method
    designed : callable
        (method, point) -> {parameter: value}: the runtime parameters an observer runs with
        where no gain axis sets them (given, else designed for the point's sensor and mismatch).

    Returns
    -------
    list of dict
        cell (id), method, kind, family, the AXES values (None where an axis does not concern
        the method), p (runtime parameters of an observer, {} for a baseline).
    """
    from .. import baselines
    gains = [k for k in sweep.axes if k not in AXES]
    for k in gains:
        if not any(k in m.p_names for m in methods):
            raise ValueError(f"axes.{k}: neither a sweep axis ({', '.join(AXES)}) nor a runtime "
                             f"parameter of an observer ({', '.join(sorted({p for m in methods for p in m.p_names})) or 'none'})")
    out, seen = [], set()
    for m in methods:
        for pt in sweep.points():
            c = {"method": m.item, "kind": m.kind, "family": m.family, **pt}
            if m.kind == "observer":
                p = dict(designed(m, pt))
                p.update({k: float(pt[k]) for k in gains if k in m.p_names})
                c["p"] = p
            else:
                c["est0"] = None
                c["p"] = {}
                c["grid"] = list(baselines.GRIDS.get(m.family, []))
            key = {**sweep.setting(), **{k: c[k] for k in ("method", "p", *AXES)}, "grid": c.pop("grid", None)}
            c["cell"] = digest(key)
            if c["cell"] not in seen:              # a baseline is one cell over every gain value
                seen.add(c["cell"])
                out.append(c)
    return out


def plant_key(cell):
    """The true run a cell needs: (mismatch, seed, dt)."""
    return tuple(cell[k] for k in PLANT_AXES)


def batches(cells_, size):
    """Cells grouped by true run (and sensor setting within it), in chunks of ``size``.

    Parameters
    ----------
    cells_ : list of dict
        Cells of ``cells`` (any subset, e.g. those not on disk).
    size : int
        Cells per batch (the sweep's ``batch``).

    Returns
    -------
    list of (tuple, list of dict)
        (plant key (mismatch, seed, dt), cells) per batch, grouped by plant key."""
    groups = {}
    for c in sorted(cells_, key=lambda c: (plant_key(c), c["noise"], c["quantization"], c["cell"])):
        groups.setdefault(plant_key(c), []).append(c)
    return [(k, g[i:i + size]) for k, g in groups.items() for i in range(0, len(g), size)]
