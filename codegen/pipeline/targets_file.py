"""Targets in the user's words: a targets file (TOML), the CLI's options, or Python (docs/architecture.md §3).

One ``[[target]]`` table per generated observer; the CLI's options are the same keys::

    [[target]]
    robot = "ur5"                  # a catalog name (python -m codegen list), or
    # urdf = "arm.urdf"            #   a URDF file (relative to this file), with
    # lock = { finger = 0.0 }      #   joints held at a value (rad or m)
    # elastic = true               # elastic joints on it: motor inertias J (kg m^2) and stiffness
    # J = 0.5                      #   K (N m/rad), scalars or one per joint (catalog defaults
    # K = 2e4                      #   for seed004_2r, seed004_3r, ur5)
    family = "ciccarella_germani"  # an observer family or control law
    variant = "O2"                 # of families that have variants (default: the family's)
    design = { eigenvalues = [] }  # keyword arguments of the family's build: design inputs, gains
    params = { rcond_min = 1e-9 }  # runtime parameters overriding the designed defaults
    # sources = { k0 = "tuned on the log log.csv" }   # where a params, design or dt value came from
                                   #   (the folder's design report and header state it; default: given by the user)
    dt = 1e-3                      # discretisation: dt (s), method, hold, substeps (a number, or
    substeps = "auto"              #   "auto", the default: the fewest that are stable), and the
    # dt_min = 2.5e-4              #   range of the elapsed time between samples (default [dt/4,
    # dt_max = 2e-3                #   2 dt]): checked stable; a longer one is split into sub-intervals
    precision = "double"           # real type of the C
    name = "arm_cg_o2"             # symbol prefix and folder (default <robot>_<family>[_<variant>])
    out = "generated"              # parent folder, relative to this file (default ./generated)
    # tune = "log.csv"             # a log of the robot (relative to this file): the sensor measured
                                   #   on it and the gains tuned on it without truth (the command
                                   #   line does it when it builds the target: `design LOG.csv`);
                                   #   a CSV of other column names or a ROS bag: tune_columns (a
                                   #   mapping, codegen.logs.mapping) and tune_topic (a bag's topic)

Catalog robots are recorded as ``{"kind": "catalog", "name": ...}`` (resolved by
``models.from_source``), so a targets file and the Target in a metadata JSON name no
installation path. Every mistake is a ``TargetError`` naming the file, the target and the valid
choices, found before any (slow) gain design.
"""
from __future__ import annotations

import importlib
import inspect
import tomllib
from pathlib import Path

from ..core.target import AUTO, Discretization, Target

KEYS = ("robot", "urdf", "lock", "elastic", "J", "K", "family", "variant", "design", "params", "sources",
        "dt", "dt_min", "dt_max", "method", "hold", "substeps", "precision", "name", "out", "tune",
        "tune_columns", "tune_topic")
DISCRETIZATION_KEYS = ("dt", "dt_min", "dt_max", "method", "hold", "substeps")
# the TOML type of each key checked here (elastic, lock, design, params, J, K and substeps are
# checked where they are read); a value of another type is refused, never converted
STRING_KEYS = ("robot", "urdf", "family", "variant", "method", "hold", "precision", "name", "out", "tune",
               "tune_columns", "tune_topic")
NUMBER_KEYS = ("dt", "dt_min", "dt_max")
DEFAULT_OUT = "generated"
DEFAULT_FAMILY = "reduced_order"


class TargetError(ValueError):
    """A target the user described wrongly; the message is one line naming what and where."""


def _fail(where, message):
    raise TargetError(f"{where}: {message}" if where else message)


# ------------------------------------------------------------------------------------ families
def families():
    """All family names: observers, then control laws."""
    from ..families import controllers, observers
    return list(observers.FAMILIES) + list(controllers.FAMILIES)


def _builder(family):
    """(build function, variants, needs an elastic robot) of ``family``."""
    from ..families import controllers, observers
    if family in observers.FAMILIES:
        module = importlib.import_module(f"{observers.__name__}.{family}")
        return module.build, tuple(getattr(module, "VARIANTS", ())), getattr(module, "ROBOT", "") == "elastic"
    return controllers._laws()[family], (), family in controllers.ELASTIC


def family_info(family, where=""):
    """(variants, default variant or None, design input names or None for any, needs elastic).

    Raises TargetError naming the known families when ``family`` is not one; ``where`` prefixes
    the message (which target of a file)."""
    if family not in families():
        _fail(where, f"unknown family {family!r}; families: {', '.join(families())}")
    build, variants, elastic = _builder(family)
    sig = inspect.signature(build).parameters
    default = sig["variant"].default if variants and "variant" in sig else None
    keyword = any(p.kind is p.VAR_KEYWORD for p in sig.values())
    names = None if keyword else [k for k in list(sig)[1:] if k != "variant"]
    if names is not None and family in observers_families():
        names.append("limits")          # every observer's: its inputs' declared ranges (codegen.core.limits)
    return variants, default, names, elastic


def observers_families():
    """The observer families (``codegen.families.observers.FAMILIES``)."""
    from ..families import observers
    return observers.FAMILIES


# ------------------------------------------------------------------------------------ robots
def robot_source(robot=None, *, urdf=None, lock=None, elastic=False, J=None, K=None, base=".", where=""):
    """The plain-data robot source of a target (``Target.robot``) from the user's words.

    Parameters
    ----------
    robot : str, optional
        Catalog name (``models.names()``).
    urdf : path, optional
        URDF file (relative to ``base``); exactly one of ``robot`` and ``urdf``.
    lock : dict, optional
        URDF joint name -> value (rad or m) held fixed.
    elastic : bool
        Elastic joints on the rigid robot, with motor inertias ``J`` (kg m^2) and stiffness
        ``K`` (N m/rad): scalars or one per joint; catalog defaults (models.catalog.ELASTIC).
    base : path
        Folder relative URDF paths are resolved against (a targets file's folder).
    where : str
        Prefix of error messages (file and target).

    Returns
    -------
    dict
        ``{"kind": "catalog", "name"}``, ``{"kind": "urdf", "name", "path", "locked_joints"}`` or
        ``{"kind": "elastic", "name", "rigid": <one of those>, "J", "K"}``.
    """
    from models import names
    from models.catalog import ELASTIC
    if (robot is None) == (urdf is None):
        _fail(where, "give a robot: a catalog name or a URDF file (urdf), not "
              + ("both" if robot is not None else "neither") + f"; catalog: {', '.join(names())}")
    if robot is not None:
        if robot not in names():
            hint = "; a URDF file goes with --urdf PATH (urdf = \"...\" in a targets file)" \
                if str(robot).endswith(".urdf") else ""
            _fail(where, f"unknown robot {robot!r}; catalog: {', '.join(names())}{hint}")
        if lock:
            _fail(where, f"lock applies to a URDF robot (urdf), not to catalog robot {robot!r}")
        source = {"kind": "catalog", "name": robot}
    else:
        path = (Path(base) / Path(urdf).expanduser()).resolve()
        if not path.is_file():
            _fail(where, f"URDF file not found: {path}")
        source = {"kind": "urdf", "name": path.stem, "path": str(path),
                  "locked_joints": {str(k): _number(v, f"lock {k}", where) for k, v in (lock or {}).items()}}
    if not elastic:
        if J is not None or K is not None:
            _fail(where, "J and K describe an elastic robot: add elastic (--elastic)")
        return source
    J0, K0 = ELASTIC.get(source["name"], (None, None)) if source["kind"] == "catalog" else (None, None)
    J, K = (J if J is not None else J0), (K if K is not None else K0)
    if J is None or K is None:
        _fail(where, f"elastic {source['name']}: give J and K (catalog defaults for: {', '.join(ELASTIC)})")
    return {"kind": "elastic", "name": f"{source['name']}_elastic", "rigid": source,
            "J": _numbers(J, "J", where), "K": _numbers(K, "K", where)}


def _number(value, what, where):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        _fail(where, f"{what} must be a number, got {value!r}")
    return float(value)


def _numbers(value, what, where):
    """A positive number or a list of them (one per joint)."""
    values = value if isinstance(value, (list, tuple)) else [value]
    out = [_number(v, what, where) for v in values]
    if not out or min(out) <= 0:
        _fail(where, f"{what} must be positive (a number or one per joint), got {value!r}")
    return out if isinstance(value, (list, tuple)) else out[0]


# ------------------------------------------------------------------------------------ targets
def make_target(entry, base=".", where="", tuner=None):
    """A checked Target and its output folder from one target's keys (``KEYS``).

    Parameters
    ----------
    entry : dict
        A ``[[target]]`` table of a targets file, or the CLI's options in the same keys.
    base : path
        Folder of the targets file: relative ``urdf``, ``out`` and ``tune`` resolve against it.
    where : str
        Prefix of error messages (file and target).
    tuner : callable, optional
        (Target, log path) -> Target with the build arguments and parameters tuned on the log
        (the command line's: codegen.evaluate.compare.design_on_log); a ``tune`` key without
        one is refused.

    Returns
    -------
    (Target, Path)
        The target (variant defaulted to the family's, so the name says it) and the parent
        folder of its generated folder (``out``, default ``./generated``).
    """
    if not isinstance(entry, dict):
        _fail(where, f"a target must be a table of key = value ([[target]]), got {entry!r} ({_toml_type(entry)})")
    unknown = sorted(set(entry) - set(KEYS))
    if unknown:
        _fail(where, f"unknown key{'s' * (len(unknown) > 1)} {', '.join(unknown)}; valid keys: {', '.join(KEYS)}")
    _check_types(entry, where)
    family = entry.get("family", DEFAULT_FAMILY)
    variants, default_variant, design_names, needs_elastic = family_info(family, where)
    variant = entry.get("variant", default_variant)
    if variant is not None and variant not in variants:
        _fail(where, f"{family} has no variant {variant!r}; "
              + (f"variants: {', '.join(variants)}" if variants else "it has no variants"))
    source = robot_source(entry.get("robot"), urdf=entry.get("urdf"), lock=_table(entry, "lock", where),
                          elastic=_flag(entry.get("elastic", False), where), J=entry.get("J"),
                          K=entry.get("K"), base=base, where=where)
    if needs_elastic != (source["kind"] == "elastic"):
        _fail(where, f"{family} needs {'an elastic' if needs_elastic else 'a rigid'} robot, "
              f"{source['name']} is {'elastic' if source['kind'] == 'elastic' else 'rigid'}"
              + (" (add elastic: --elastic, with J and K)" if needs_elastic else " (drop elastic)"))
    design = _table(entry, "design", where)
    bad = sorted(set(design) - set(design_names)) if design_names is not None else []
    if bad:
        _fail(where, f"unknown design input{'s' * (len(bad) > 1)} {', '.join(bad)} of {family}; "
              f"valid: {', '.join(design_names) or '(none)'}")
    params, sources = _table(entry, "params", where), _table(entry, "sources", where)
    stray = sorted(set(sources) - set(params) - set(design) - set(DISCRETIZATION_KEYS))
    if stray:
        _fail(where, f"sources: {', '.join(stray)} {'is' if len(stray) == 1 else 'are'} neither a parameter, a "
              f"design input nor {', '.join(DISCRETIZATION_KEYS)} of this target (sources say where a value of "
              "params, design or the discretisation came from)")
    try:
        # unstated substeps: the fewest stable ones (resolved when the target is made)
        disc = Discretization(**{"substeps": AUTO, **{k: entry[k] for k in DISCRETIZATION_KEYS if k in entry}})
        target = Target(robot=source, family=family, variant=variant, build=design,
                        params=params, discretization=disc, sources=sources,
                        precision=entry.get("precision", "double"), name=entry.get("name"))
    except (TypeError, ValueError) as e:
        _fail(where, str(e))
    out = Path(base) / entry["out"] if "out" in entry else Path(DEFAULT_OUT)
    lone = [k for k in ("tune_columns", "tune_topic") if k in entry and "tune" not in entry]
    if lone:
        _fail(where, f"{lone[0]}: belongs with tune = \"LOG\" (the log it reads)")
    if "tune" in entry:
        log = (Path(base) / Path(entry["tune"]).expanduser()).resolve()
        if not log.exists():
            _fail(where, f"tune: log not found: {log}")
        if tuner is None:
            _fail(where, "tune: a log's gains are tuned by the command line (python -m codegen build/generate "
                  "-c FILE), or in Python by codegen.evaluate.compare.design_on_log")
        try:
            columns = entry.get("tune_columns")
            if columns is not None and columns.endswith((".toml", ".json")):
                columns = str((Path(base) / Path(columns).expanduser()).resolve())   # relative to this file
            extra = {k: v for k, v in (("columns", columns), ("topic", entry.get("tune_topic"))) if v is not None}
            target = tuner(target, log, **extra)
        except (TypeError, ValueError) as e:
            _fail(where, f"tune {log.name}: {e}")
    return target, out.resolve()


def _toml_type(value):
    """The TOML name of ``value``'s type, for messages."""
    for kind, name in ((bool, "a boolean"), (int, "an integer"), (float, "a float"), (str, "a string"),
                       (list, "an array"), (dict, "a table")):
        if isinstance(value, kind):
            return name
    return type(value).__name__


def _check_types(entry, where):
    """TargetError naming the key, the type it takes and the one given, for a string or number
    key (``STRING_KEYS``, ``NUMBER_KEYS``) of ``entry`` holding another type."""
    for key in STRING_KEYS:
        if key in entry and not isinstance(entry[key], str):
            _fail(where, f"{key} must be a string, got {entry[key]!r} ({_toml_type(entry[key])})")
    for key in NUMBER_KEYS:
        value = entry.get(key, 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            _fail(where, f"{key} must be a number of seconds, got {value!r} ({_toml_type(value)})"
                  + ("; write it without quotes" if isinstance(value, str) else ""))


def _table(entry, key, where):
    value = entry.get(key, {})
    if not isinstance(value, dict):                   # design = [] is not an empty table
        _fail(where, f"{key} must be a table of name = value, got {value!r}")
    return dict(value)


def _flag(value, where):
    if not isinstance(value, bool):
        _fail(where, f"elastic must be true or false, got {value!r}")
    return value


def load_targets(path, tuner=None):
    """The targets of a TOML targets file (module docstring), checked.

    Parameters
    ----------
    path : path
        The file; relative ``urdf``, ``out`` and ``tune`` inside resolve against its folder.
    tuner : callable, optional
        Resolves a ``tune`` key (``make_target``).

    Returns
    -------
    list of (Target, Path)
        Each target and the parent folder of its generated folder. Raises TargetError naming
        the file and the target (its index and robot) on any mistake.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        _fail("", f"targets file not found: {path}")
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        _fail(str(path), f"not valid TOML: {e}")
    unknown = sorted(set(data) - {"target"})
    if unknown:
        _fail(str(path), f"unknown table {', '.join(unknown)}; a targets file holds [[target]] tables")
    entries = data.get("target", [])
    if not isinstance(entries, list) or not entries:
        _fail(str(path), "no [[target]] tables")
    out = []
    for i, entry in enumerate(entries, 1):
        where = f"{path}, target {i}"
        if isinstance(entry, dict):                 # (make_target refuses anything else)
            label = entry.get("robot") or Path(str(entry.get("urdf", "?"))).name
            where += f" ({label} {entry.get('family', DEFAULT_FAMILY)})"
        out.append(make_target(entry, base=path.parent, where=where, tuner=tuner))
    check_unique(out)
    return out


def check_unique(targets):
    """TargetError if two of the (Target, out folder) pairs ``targets`` would write the same folder."""
    seen = {}
    for i, (target, out) in enumerate(targets, 1):
        folder = out / target.prefix
        if folder in seen:
            _fail("", f"targets {seen[folder]} and {i} both write {folder}; give one a name")
        seen[folder] = i


# ------------------------------------------------------------------------------------ specs
def default_spec(robot_name, family=DEFAULT_FAMILY):
    """The spec of ``family`` with its default design on catalog robot ``robot_name``."""
    from models import load_robot

    from ..families import observers
    return observers.build(family, load_robot(robot_name))


def build_spec(target):
    """The ObserverSpec a Target describes: its robot rebuilt from the source, then the family's
    ``build`` with the target's variant and build arguments (observers, then control laws).

    Parameters
    ----------
    target : codegen.core.target.Target

    Returns
    -------
    codegen.core.spec.ObserverSpec
    """
    from models import from_source

    from ..families import controllers, observers
    kwargs = dict(target.build, **({"variant": target.variant} if target.variant else {}))
    robot = from_source(target.robot)
    if target.family in observers.FAMILIES:
        return observers.build(target.family, robot, **kwargs)
    return controllers.build(target.family, robot, **kwargs)
