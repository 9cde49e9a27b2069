"""A column mapping: a log's own column names onto the recording's (codegen.logs.recording)
``t, t_robot, q_<joint>, tau_<joint>, qd_<joint>, qdm_<joint>``.

Written as comma-separated rules ``SOURCE=TARGET`` and two options,

    position_*=q_*, effort_*=tau_*, velocity_*=qdm_*, time=t, t_unit=ms, joints=[shoulder,elbow]

or as a file (TOML or JSON) of the same: ``t_unit``, ``joints`` and a table ``columns`` of the
rules. A ``*`` in a rule stands for one non-empty part of a column's name (the log's name of a
joint), the same part in the target; a rule without one names one column. ``t_unit`` (s, ms, us
or µs, ns; default s) is the unit of the time columns; a mapped log's time counts from its first
row, exactly (from the digits written, however large the stamps). ``joints`` renames the log's
joints (the ``*`` parts of its q columns, in file order): a list, in that order, or a table
``{log name = joint}``. Columns that no rule maps are not read (text columns, a frame id).
"""
from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

GROUPS = ("q", "tau", "qd", "qdm")            # per-joint columns of a recording
TIMES = ("t", "t_robot")                      # its time columns
UNITS = {"s": 0, "ms": 3, "us": 6, "µs": 6, "ns": 9}   # t_unit -> the power of ten of a second
OPTIONS = ("t_unit", "joints")
FILE_SUFFIXES = (".toml", ".json")


class MappingError(ValueError):
    """A mapping that cannot be read or applied (the message names the rule or the column)."""


@dataclass(frozen=True)
class ColumnMap:
    """Rules from a log's columns to a recording's (module docstring).

    Attributes
    ----------
    rules : dict
        SOURCE -> TARGET (``*`` patterns or names), in the order given.
    t_unit : str or None
        One of UNITS: the time columns' unit; None: not stated (seconds).
    joints : list, dict or None
        The log's joints renamed: by position (list) or by name (dict); None keeps them.
    """

    rules: dict = field(default_factory=dict)
    t_unit: str | None = None
    joints: list | dict | None = None

    def __post_init__(self):
        if self.t_unit is not None and self.t_unit not in UNITS:
            raise MappingError(f"t_unit: expected one of {', '.join(UNITS)}, got {self.t_unit!r}")
        for source, target in self.rules.items():
            _check_rule(source, target)
        targets = list(self.rules.values())
        twice = sorted({t for t in targets if targets.count(t) > 1})
        if twice:
            raise MappingError(f"columns: {twice[0]!r} is the target of two rules "
                               f"({', '.join(s for s, t in self.rules.items() if t == twice[0])})")
        if self.joints is not None and not isinstance(self.joints, (list, dict)):
            raise MappingError(f"joints: expected a list of names or a table of log name = joint, "
                               f"got {self.joints!r}")

    @property
    def scale(self):
        """10^k: a time column's value / scale is in seconds."""
        return 10 ** UNITS[self.t_unit or "s"]

    def updated(self, other):
        """This mapping with ``other``'s rules over its own (a rule of ``other`` with the same
        source or target replaces this one's) and ``other``'s t_unit and joints where it states
        them (a bag's default mapping under the user's)."""
        if other is None:
            return self
        rules = {s: t for s, t in self.rules.items()
                 if s not in other.rules and t not in other.rules.values()}
        return ColumnMap({**rules, **other.rules}, other.t_unit or self.t_unit,
                         other.joints if other.joints is not None else self.joints)

    def text(self):
        """The mapping as one line of rules (what a message quotes)."""
        parts = [f"{s}={t}" for s, t in self.rules.items()] + [f"t_unit={self.t_unit}"] * bool(self.t_unit)
        if isinstance(self.joints, list):
            parts.append(f"joints=[{','.join(self.joints)}]")
        elif isinstance(self.joints, dict):
            parts.append("joints={" + ",".join(f"{k}:{v}" for k, v in self.joints.items()) + "}")
        return ",".join(parts)

    def resolve(self, header, where="log", optional=()):
        """{recording column: log column} of the log columns ``header`` (names), and the log's
        joints renamed. MappingError naming the log ``where`` and the rule that matches no column (but those of
        ``optional``), a column two rules take, or a ``joints`` list whose length is not the log's
        number of joints."""
        out, joint_of, used = {}, [], set()
        for source, target in self.rules.items():
            hits = [h for h in header if match(source, h) is not None]
            if not hits and source in optional:
                continue
            if not hits:
                raise MappingError(f"{where}: rule {source}={target} matches no column (its columns: "
                                   f"{some(header)})")
            for h in hits:
                if h in used:
                    raise MappingError(f"{where}: column {h!r} is taken by two rules")
                used.add(h)
                part = match(source, h)
                if "*" in target:
                    out[target.replace("*", part)] = h
                    if target.startswith("q_"):
                        joint_of.append(part)
                else:
                    out[target] = h
        return self._renamed(out, joint_of, where)

    def _renamed(self, out, joint_of, where):
        """``out`` with its joints renamed by ``joints`` (the log's q joints, in order, ``joint_of``)."""
        if self.joints is None:
            return out
        if isinstance(self.joints, list):
            if len(self.joints) != len(joint_of):
                raise MappingError(f"{where}: joints lists {len(self.joints)} names, the log has {len(joint_of)} "
                                   f"joints ({', '.join(joint_of) or 'no q column mapped'})")
            rename = dict(zip(joint_of, self.joints))
        else:
            rename = dict(self.joints)
            unknown = [k for k in rename if k not in joint_of]
            if unknown:
                raise MappingError(f"{where}: joints renames {', '.join(map(str, unknown))}, not a joint of the log "
                                   f"({', '.join(joint_of)})")
        renamed = {}
        for name, source in out.items():
            group, _, joint = name.partition("_")
            if group in GROUPS and joint in rename:
                name = f"{group}_{rename[joint]}"
            renamed[name] = source
        return renamed


def _check_rule(source, target):
    """MappingError unless ``target`` is a recording column (or pattern) and the ``*`` agree."""
    if not source or not target:
        raise MappingError(f"columns: expected SOURCE=TARGET, got {source!r}={target!r}")
    stars = (source.count("*"), target.count("*"))
    if stars not in ((0, 0), (1, 1)):
        raise MappingError(f"columns: rule {source}={target}: a '*' on both sides (one each) or on neither")
    group, _, joint = target.partition("_")
    ok = target in TIMES or (group in GROUPS and joint)
    if not ok or (target in TIMES and stars != (0, 0)):
        raise MappingError(f"columns: rule {source}={target}: the target must be t, t_robot or "
                           f"q_*, tau_*, qd_*, qdm_* (a joint's q_<joint>, ...)")


def match(pattern, name):
    """The part of ``name`` that the ``*`` of ``pattern`` stands for ('' for a plain name that is
    equal), or None when it does not match."""
    if "*" not in pattern:
        return "" if name == pattern else None
    head, _, tail = pattern.partition("*")
    if len(name) > len(head) + len(tail) and name.startswith(head) and name.endswith(tail):
        return name[len(head):len(name) - len(tail)]
    return None


def some(names, most=12):
    """The first ``most`` of ``names``, comma-separated, and how many there are (a message's list)."""
    names = list(names)
    return ", ".join(names[:most]) + (f", ... ({len(names)} in all)" if len(names) > most else "")


def _split(text):
    """``text`` split at the commas outside [] and {}."""
    parts, depth, cur = [], 0, ""
    for ch in text:
        depth += (ch in "[{") - (ch in "]}")
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    return [p.strip() for p in parts + [cur] if p.strip()]


def _joints_text(text):
    """``joints=`` of a rule line: [a,b,c] (a list) or {log:joint,...} (a table)."""
    inner = text.strip()
    if inner.startswith("[") and inner.endswith("]"):
        return [v.strip().strip("'\"") for v in inner[1:-1].split(",") if v.strip()]
    if inner.startswith("{") and inner.endswith("}"):
        pairs = [p.split(":", 1) for p in inner[1:-1].split(",") if p.strip()]
        if any(len(p) != 2 for p in pairs):
            raise MappingError(f"joints: expected {{log name:joint,...}}, got {text!r}")
        return {k.strip().strip("'\""): v.strip().strip("'\"") for k, v in pairs}
    raise MappingError(f"joints: expected [name,...] or {{log name:joint,...}}, got {text!r}")


def parse(text, base="."):
    """The ColumnMap of ``text``: a file (a name ending .toml or .json, relative to ``base``) or a
    line of rules (module docstring); None for None. MappingError naming what cannot be read."""
    if text is None or isinstance(text, ColumnMap):
        return text
    text = str(text).strip()
    if text.endswith(FILE_SUFFIXES):
        return read_file(Path(base) / Path(text).expanduser())
    rules, options = {}, {}
    for part in _split(text):
        source, eq, target = (s.strip() for s in part.partition("="))
        if not eq:
            raise MappingError(f"columns: expected SOURCE=TARGET (or t_unit=UNIT, joints=[...]), got {part!r}")
        if source in OPTIONS:
            options[source] = _joints_text(target) if source == "joints" else target
        elif source in rules:
            raise MappingError(f"columns: {source!r} is mapped twice")
        else:
            rules[source] = target
    return ColumnMap(rules, options.get("t_unit"), options.get("joints"))


def read_file(path):
    """The ColumnMap of the mapping file ``path`` (TOML or JSON: ``t_unit``, ``joints``, a table ``columns``)."""
    path = Path(path)
    if not path.is_file():
        raise MappingError(f"{path}: no such mapping file")
    try:
        data = json.loads(path.read_text()) if path.suffix == ".json" else tomllib.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as e:
        raise MappingError(f"{path}: not readable {path.suffix[1:].upper()}: {e}") from None
    unknown = [k for k in data if k not in ("columns", *OPTIONS)]
    if unknown or not isinstance(data.get("columns", {}), dict):
        raise MappingError(f"{path}: expected keys columns (a table of SOURCE = TARGET), t_unit, joints; "
                           f"got {', '.join(map(str, unknown or ['columns']))}")
    rules = {str(k): str(v) for k, v in data.get("columns", {}).items()}
    try:
        return ColumnMap(rules, data.get("t_unit"), data.get("joints"))
    except MappingError as e:
        raise MappingError(f"{path}: {e}") from None
