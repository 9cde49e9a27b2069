"""Any URDF turned into a :class:`UrdfRobot` with our own CasADi SX spatial algorithms.

The URDF is parsed by pinocchio (the ``pin`` wheel, which has no ``pinocchio.casadi``); we
check it (naming the joint or link at fault), snap its round-off and read the numeric data
of the resulting ``pin.Model`` (joint placements, inertias, joint axes, parents, gravity,
damping, armature) into a constant :class:`~models.tree.SpatialTree`. The recursive
algorithms of rigid-body dynamics run on that tree, one per file as in pinocchio:

    models/rnea.py        rnea(q, v, a)   inverse dynamics with gravity  (Featherstone Table 5.1)
    models/crba.py        crba(q)         joint-space inertia M(q)       (Featherstone Table 6.2)
    models/aba.py         aba(q, v, tau)  forward dynamics               (Featherstone Table 7.1)
    models/kinematics.py  com_positions(q)
    gravity(q) = rnea(q, 0, 0),  nle(q, v) = rnea(q, v, 0)

on the spatial algebra of ``models/spatial.py`` (conventions there) and the folding scalars
of ``models/algebra.py``; ``models/tree.py`` builds the tree in canonical (joint axis = z)
body frames.

pinocchio's ``model.armature`` is honoured as pinocchio does (added to diag M, to the
RNEA torque and to the ABA pivot D). Friction is not part of these algorithms: the URDF's
``<dynamics damping friction>`` (pinocchio's ``model.damping``, ``model.friction``) are the
viscous and Coulomb coefficients of tau_f(v) = viscous v + coulomb tanh(v / w) + offset
(models/robot.py), the offsets and w come from a side file (``load_urdf``), and
``forward_dynamics`` applies it as aba(q, v, tau - tau_f(v)).

Size of the generated ABA (``UrdfRobot.fd``): ur5 ~1.0k SX instructions, panda (7 DoF)
~1.8k; after ``gcc -O3`` about 0.2 us and 0.34 us per call on the development VM, where
pinocchio's C++ ``aba`` took about 1.9 us and 2.6 us.
"""
from __future__ import annotations

import hashlib
import importlib.metadata
import json
import math
import pathlib
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from functools import cached_property

import casadi as ca
import numpy as np
import pinocchio as pin

from models.aba import aba
from models.algebra import add, dot, split, sub
from models.crba import crba
from models.kinematics import com_positions
from models.rnea import rnea
from models.robot import ModelError, RobotModel
from models.tree import SpatialTree, joint_kind, link_names, snap, snapped_model, tree_from_pin

# snap, SpatialTree and the algorithms are re-exported: they were importable from here
__all__ = ["UrdfRobot", "load_urdf", "read_friction_file", "friction_file_path", "FRICTION_FORMAT",
           "example_robot_data_dir", "snap", "SpatialTree",
           "rnea", "crba", "aba", "com_positions"]

_URDF_SUPPORTED = {"revolute", "continuous", "prismatic", "fixed"}
_URDF_KNOWN = _URDF_SUPPORTED | {"floating", "planar"}
_HUGE_LIMIT = 1e4   # a limit beyond this (or non-finite) counts as "no range given"
_HUGE_EFFORT = 1e9  # an effort limit (N m, N) beyond this (or 0, or non-finite) counts as none declared


# =============================================================================================
# locating data
# =============================================================================================
def example_robot_data_dir() -> pathlib.Path:
    """The ``robots`` folder of the installed example-robot-data package.

    Found from the installed distribution's file list (cmeel layout
    ``cmeel.prefix/share/example-robot-data/robots``); no network, no hard-coded path.
    """
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        raise ModelError("the example-robot-data package is not installed "
                         "(pip install example-robot-data)") from None
    path = pathlib.Path(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))
    if not path.is_dir():
        for f in dist.files or ():
            parts = pathlib.PurePosixPath(str(f)).parts
            if "example-robot-data" in parts and "robots" in parts:
                k = parts.index("robots")
                path = pathlib.Path(dist.locate_file(pathlib.PurePosixPath(*parts[:k + 1])))
                break
    if not path.is_dir():
        raise ModelError(f"example-robot-data is installed but its robots folder was not found "
                         f"(looked at {path})")
    return path.resolve()


# =============================================================================================
# checks
# =============================================================================================
def _check_urdf_xml(path, locked):
    """Reject joint types and mimic joints we do not support, and numbers the URDF parser
    would misread, naming the joint or link; returns the XML root."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise ModelError(f"{path}: not a valid URDF (XML error: {e})") from None
    if root.tag != "robot":
        raise ModelError(f"{path}: not a URDF (root element <{root.tag}>, expected <robot>)")
    for kind in ("link", "joint"):
        seen = set()
        for e in root.findall(kind):
            if e.get("name") in seen or e.get("name") is None:
                raise ModelError(f"{path}: {kind} {e.get('name')!r} is defined twice or has no name "
                                 f"(URDF {kind} names are unique)")
            seen.add(e.get("name"))
    for j in root.iter("joint"):
        name, jtype = j.get("name"), j.get("type")
        if jtype is None:                      # <joint> inside <transmission> etc.
            continue
        if jtype not in _URDF_KNOWN:
            raise ModelError(f"{path}: joint {name!r} has unknown type {jtype!r} "
                             f"(URDF types: {', '.join(sorted(_URDF_KNOWN))})")
        if jtype not in _URDF_SUPPORTED:
            raise ModelError(f"{path}: joint {name!r} has unsupported type {jtype!r} "
                             f"(supported: revolute, continuous, prismatic, fixed)")
        if j.find("mimic") is not None and name not in locked:
            raise ModelError(f"{path}: joint {name!r} is a mimic joint, which is not supported "
                             f"(lock it with locked_joints={{{name!r}: value}})")
        for tag, attrs in _JOINT_NUMBERS.items():
            for attr, count in attrs:
                e = j.find(tag)
                if e is not None and e.get(attr) is not None:
                    values = _number(e.get(attr), count, f"{path}: joint {name!r}: <{tag}> {attr}")
                    if tag == "dynamics" and values[0] < 0.0:
                        raise ModelError(f"{path}: joint {name!r}: <dynamics> {attr} {e.get(attr)!r} "
                                         f"is negative (friction dissipates: expected >= 0)")
    _check_inertials(root, path)
    return root


# numbers urdfdom reads from a joint: <tag> -> (attribute, how many numbers)
_JOINT_NUMBERS = {"origin": (("xyz", 3), ("rpy", 3)), "axis": (("xyz", 3),),
                  "limit": (("lower", 1), ("upper", 1), ("effort", 1), ("velocity", 1)),
                  "dynamics": (("damping", 1), ("friction", 1))}
# urdfdom reads a number with a C++ stream: decimal, leading blanks only; no inf, nan or 1_5
_DECIMAL = re.compile(r"[ \t]*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def _number(text, count, what):
    """``count`` finite numbers (space separated) of a URDF attribute as urdfdom reads them,
    or ModelError "<what> '<text>' is not ...". (Python's float would take 1_5, inf, nan.)"""
    parts = [p for p in text.split(" ") if p] if count > 1 else [text]
    values = [float(p) for p in parts if _DECIMAL.fullmatch(p)]
    if len(parts) != count or len(values) != count or not all(map(math.isfinite, values)):
        raise ModelError(f"{what} {text!r} is not {'a' if count == 1 else count} finite decimal "
                         f"number{'s' if count > 1 else ''} (the URDF parser would drop or refuse it)")
    return values


def _check_inertials(root, path):
    """Every <inertial> as urdfdom reads it: a link whose <inertial> it cannot parse is kept
    WITHOUT mass (a silently wrong robot), so each value is checked here, naming the link."""
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        owner = f"{path}: link {link.get('name')!r}: <inertial>"
        origin = inertial.find("origin")
        for attr in ("xyz", "rpy"):
            if origin is not None and origin.get(attr) is not None:
                _number(origin.get(attr), 3, f"{owner} origin {attr}")
        mass, inertia = inertial.find("mass"), inertial.find("inertia")
        if mass is None or mass.get("value") is None:
            raise ModelError(f"{owner} mass missing")
        m, = _number(mass.get("value"), 1, f"{owner} mass")
        if m < 0.0:
            raise ModelError(f"{path}: link {link.get('name')!r} has negative mass {m}")
        for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
            if inertia is None or inertia.get(key) is None:
                raise ModelError(f"{owner} inertia {key} missing")
            _number(inertia.get(key), 1, f"{owner} inertia {key}")


def _check_total_mass(root, model, path):
    """The masses of the URDF's <inertial> elements add up to the parsed model's: the second
    line of defence should the parser read a value otherwise than ``_check_inertials``."""
    def mass(e):
        try:
            return float(e.get("value"))
        except (TypeError, ValueError):
            return math.nan
    xml = sum(mass(e) for e in root.findall("link/inertial/mass"))
    parsed = sum(model.inertias[i].mass for i in range(model.njoints))
    if not math.isclose(xml, parsed, rel_tol=1e-9, abs_tol=1e-12):
        raise ModelError(f"{path}: the <inertial> masses total {xml} kg, the parsed model {parsed} kg: "
                         f"the URDF parser dropped or misread an <inertial> (see its messages)")


def _check_bodies(model, model_raw=None):
    """Every body moved by a joint: mass > 0 and inertia about its CoM positive definite.

    ``model_raw`` (the unsnapped model) only adds a hint to the message when snapping is
    what made an inertia singular."""
    links = link_names(model)
    for i in range(1, model.njoints):
        Y = model.inertias[i]
        link, joint = links.get(i, model.names[i]), model.names[i]
        if not (Y.mass > 0.0) or not math.isfinite(Y.mass):
            raise ModelError(f"link {link!r} (moved by joint {joint!r}) has mass {Y.mass!r}; "
                             f"every body moved by a joint needs a positive mass")
        Ic = np.asarray(Y.inertia)
        if not np.isfinite(Ic).all():
            raise ModelError(f"link {link!r} (moved by joint {joint!r}) has a non-finite inertia")
        lam = np.linalg.eigvalsh(0.5 * (Ic + Ic.T))
        if lam[0] <= 0.0:
            note = ""
            raw = np.asarray((model_raw or model).inertias[i].inertia)
            if model_raw is not None and np.linalg.eigvalsh(0.5 * (raw + raw.T))[0] > 0.0:
                note = " after snapping entries below snap_tol to zero (use a smaller snap_tol)"
            raise ModelError(
                f"link {link!r} (moved by joint {joint!r}) has a rotational inertia about its "
                f"centre of mass that is not positive definite{note} "
                f"(eigenvalues {np.array2string(lam, precision=4)})")


# =============================================================================================
# the robot
# =============================================================================================
class UrdfRobot(RobotModel):
    """A rigid robot from a pinocchio model, with our own SX recursive algorithms.

    Parameters
    ----------
    model : pin.Model
        The (possibly reduced) model as pinocchio parsed it (kept as ``pin_model_raw``).
    name : str
    source : dict, optional
        JSON-able recipe to rebuild the robot without our symbolic code (``load_urdf`` sets
        ``{"kind": "urdf", "path", "sha256", "locked_joints", "snap_tol"}``).
    snap_tol : float
        Round-off snapping of placements, inertias and axes (see :func:`snap`); the snapped
        copy is ``pin_model``, and it is the model the algorithms use.
    """

    def __init__(self, model, name, source=None, snap_tol=1e-9):
        self.name = str(name)
        self.pin_model_raw = model
        if model.njoints <= 1:
            raise ModelError(f"robot {self.name!r} has no moving joint")
        for i in range(1, model.njoints):
            joint_kind(model, i)                       # unsupported joint types first
        _check_bodies(model)
        self.pin_model = snapped_model(model, snap_tol)
        _check_bodies(self.pin_model, model)
        self.tree = tree_from_pin(self.pin_model)
        pm = self.pin_model
        self.n = self.tree.n
        self.dim = 3
        self.joint_names = [b.joint for b in self.tree.bodies]
        self.link_names = [b.link for b in self.tree.bodies]
        self._periodic = np.array([b.kind == "R" for b in self.tree.bodies])   # revolute/continuous
        self.masses = np.array([b.mass for b in self.tree.bodies])
        self.F = np.diag(np.array(pm.damping, dtype=float))
        self._set_friction(coulomb=np.array(pm.friction, dtype=float))
        self.v_limit = np.array(pm.velocityLimit, dtype=float)
        self._idx_q = [pm.joints[i].idx_q for i in range(1, pm.njoints)]
        lo, up = np.empty(self.n), np.empty(self.n)
        limited = np.zeros(self.n, dtype=bool)
        for k, b in enumerate(self.tree.bodies):
            lo[k], up[k] = -math.pi, math.pi
            if b.continuous:
                continue
            l_, u_ = float(pm.lowerPositionLimit[self._idx_q[k]]), float(
                pm.upperPositionLimit[self._idx_q[k]])
            if l_ > u_:
                raise ModelError(f"joint {b.joint!r}: lower limit {l_} > upper limit {u_}")
            if (math.isfinite(l_) and math.isfinite(u_) and max(abs(l_), abs(u_)) <= _HUGE_LIMIT
                    and l_ < u_):
                lo[k], up[k], limited[k] = l_, u_, True
        self.q_lower, self.q_upper = lo, up
        self._position_limited = limited
        effort = np.array([float(pm.effortLimit[pm.joints[i].idx_v]) for i in range(1, pm.njoints)])
        self._effort_limit = np.where(np.isfinite(effort) & (effort > 0) & (effort <= _HUGE_EFFORT), effort, np.inf)
        self.snap_tol = float(snap_tol)
        self.source = source if source is not None else {
            "kind": "pin_model", "name": self.name, "snap_tol": self.snap_tol}
        self.check_mass_matrix()

    # ------------------------------------------------------------ symbolic algorithms
    def _sx_or_call(self, fun_name, builder, *args):
        if all(isinstance(x, ca.SX) or x is None for x in args):
            return builder(self.tree, *args)
        return getattr(self, fun_name)(*args)

    @cached_property
    def _rnea_fun(self):
        q, v = self._sym()
        a = ca.SX.sym("a", self.n)
        return ca.Function("rnea", [q, v, a], [rnea(self.tree, q, v, a)])

    @cached_property
    def _aba_fun(self):
        q, v = self._sym()
        tau = ca.SX.sym("tau", self.n)
        return ca.Function("aba", [q, v, tau], [aba(self.tree, q, v, tau)])

    def rnea(self, q, v, a):
        """tau = M(q) a + C(q, v) v + g(q)  (RNEA, Featherstone Table 5.1)."""
        return self._sx_or_call("_rnea_fun", rnea, q, v, a)

    def crba(self, q):
        """M(q)  (CRBA, Featherstone Table 6.2)."""
        return self._sx_or_call("M", crba, q)

    def aba(self, q, v, tau):
        """qdd = M^{-1}(tau - C v - g)  (ABA, Featherstone Table 7.1) at q, v, tau ((n, 1) each)."""
        return self._sx_or_call("_aba_fun", aba, q, v, tau)

    def mass_matrix(self, q):
        """M(q) by :meth:`crba`; ``q`` is an (n, 1) SX (or numeric, evaluated through ``M``)."""
        return self.crba(q)

    def gravity(self, q):
        """g(q) = rnea(q, 0, 0)."""
        if isinstance(q, ca.SX):
            return rnea(self.tree, q, None, None)
        return self.g(q)

    def nle(self, q, v):
        """C(q, v) v + g(q) = rnea(q, v, 0)."""
        if isinstance(q, ca.SX) and isinstance(v, ca.SX):
            return rnea(self.tree, q, v, None)
        return self._rnea_fun(q, v, ca.DM.zeros(self.n))

    def forward_dynamics(self, q, v, tau):
        """qdd = aba(q, v, tau - tau_f(v)), tau_f(v) = F v + coulomb tanh(v / w) + offset (the
        friction, models/robot.py), at (n, 1) SX ``q``, ``v``, ``tau`` (numeric: through ``fd``)."""
        if not all(isinstance(x, ca.SX) for x in (q, v, tau)):
            return self.fd(q, v, tau)
        F = np.asarray(self.F, dtype=float)
        vs = split(v, self.n, "v")
        ts = split(tau, self.n, "tau")
        t = [sub(ts[i], add(dot(tuple(float(x) for x in F[i]), vs), self._nonviscous(i, vs[i])))
             for i in range(self.n)]
        return aba(self.tree, q, vs, t)

    def com_positions(self, q):
        """World CoM position of the body moved by each joint, stacked (3n, 1) (m), at joint
        position ``q`` ((n, 1) SX, or numeric: evaluated through ``com``)."""
        if isinstance(q, ca.SX):
            return com_positions(self.tree, q)
        return self.com(q)

    # ------------------------------------------------------------ numeric helpers
    def pin_configuration(self, q):
        """Our angle coordinates -> pinocchio's q (cos, sin for continuous joints)."""
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape != (self.n,):
            raise ValueError(f"q: expected {self.n} entries, got {q.size}")
        out = np.zeros(self.pin_model.nq)
        for k, b in enumerate(self.tree.bodies):
            j = self._idx_q[k]
            if b.continuous:
                out[j], out[j + 1] = math.cos(q[k]), math.sin(q[k])
            else:
                out[j] = q[k]
        return out


# =============================================================================================
# loader
# =============================================================================================
def load_urdf(path, locked_joints=None, name=None, snap_tol=1e-9, friction_file="auto"):
    """Build a :class:`UrdfRobot` from a URDF file, with its joint friction.

    Friction, tau_f(v) = viscous v + coulomb tanh(v / w) + offset per joint (models/robot.py):
    viscous and coulomb are the URDF's ``<dynamics damping="..." friction="..."/>`` (as pinocchio
    reads them: ``model.damping``, ``model.friction``; 0 when absent). The offsets and w have no
    URDF tag: they come from a side file ``<stem>.friction.json`` beside the URDF (e.g.
    ``arm_identified.urdf`` -> ``arm_identified.friction.json``), read when present::

        {"format": "observer-codegen friction 1",
         "coulomb_width": 0.05,                        (rad/s, > 0; default DEFAULT_COULOMB_WIDTH)
         "offset": {"<joint>": 0.12, ...}}             (N m per joint name; others 0)

    Every key is optional; another key, another format, a joint that is not a moving joint of
    the URDF, or a value that is not a finite number is refused (ModelError naming the file).
    An offset on a locked joint is ignored (the lock holds the joint against any torque).

    Parameters
    ----------
    path : str or path-like
        The URDF; relative paths resolve against the current directory.
    locked_joints : dict, optional
        Joint name -> value (rad or m); these joints are removed with
        ``pin.buildReducedModel`` at that value (the rest of the neutral configuration).
    name : str, optional
        Robot name; the file stem by default.
    snap_tol : float
        Placement, inertia and axis entries within ``snap_tol`` of 0 or +-1 are snapped.
    friction_file : "auto", str, path-like or None
        The friction side file: "auto" reads ``<stem>.friction.json`` beside the URDF when it
        exists, a path reads that file (which must exist), None reads none.

    Raises
    ------
    FileNotFoundError
        The file (or a given friction file) does not exist.
    ModelError
        Unsupported joint (floating, planar, unknown type, mimic, ...), a body without
        positive mass or positive-definite inertia, an unknown locked joint, M(q) singular,
        negative damping or friction, or a friction side file we cannot use.
    """
    try:
        path = pathlib.Path(path).expanduser().resolve()
        found = path.is_file()
    except (OSError, ValueError) as e:                 # a name too long, a NUL byte
        raise FileNotFoundError(f"URDF file {str(path)!r} cannot be opened: "
                                f"{getattr(e, 'strerror', None) or e}") from None
    if not found:
        raise FileNotFoundError(f"URDF file not found: {path}")
    locked = _locked_values(locked_joints)
    side = _friction_file_path(path, friction_file)
    snap_tol = _finite("snap_tol", snap_tol, "a non-negative number")
    if snap_tol < 0.0:
        raise ValueError(f"snap_tol: expected a non-negative number, got {snap_tol!r}")
    data = path.read_bytes()
    root = _check_urdf_xml(path, locked)
    try:
        model = pin.buildModelFromUrdf(str(path))
    except Exception as e:  # pinocchio raises ValueError/RuntimeError on bad files
        raise ModelError(f"{path}: pinocchio could not parse the URDF: {e}") from None
    _check_total_mass(root, model, path)
    moving = list(model.names)[1:]
    if locked:
        ids = []
        q_ref = pin.neutral(model)
        for jn, val in locked.items():
            if not model.existJointName(jn):
                raise ModelError(f"{path}: locked joint {jn!r} is not a moving joint of the URDF "
                                 f"(joints: {', '.join(list(model.names)[1:])})")
            jid = model.getJointId(jn)
            jm = model.joints[jid]
            if jm.nq == 2 and jm.nv == 1:            # continuous: cos, sin
                q_ref[jm.idx_q], q_ref[jm.idx_q + 1] = math.cos(val), math.sin(val)
            elif jm.nq == 1:
                q_ref[jm.idx_q] = val
            else:
                raise ModelError(f"{path}: cannot lock joint {jn!r} of type {jm.shortname()}")
            ids.append(jid)
        model = _reduced(model, sorted(ids), q_ref)
    name = name if name is not None else path.stem
    source = {"kind": "urdf", "name": name, "path": str(path), "sha256": hashlib.sha256(data).hexdigest(),
              "locked_joints": locked, "snap_tol": snap_tol}
    robot = UrdfRobot(model, name=name, source=source, snap_tol=snap_tol)
    if side is not None:
        width, offsets = read_friction_file(side, moving)
        robot = robot.with_friction(offset=[offsets.get(j, 0.0) for j in robot.joint_names],
                                    width=width)
    return robot


FRICTION_FORMAT = "observer-codegen friction 1"
_FRICTION_KEYS = ("format", "coulomb_width", "offset")


def friction_file_path(urdf_path):
    """The friction side file of the URDF at ``urdf_path``: ``<stem>.friction.json`` in the same
    folder (a Path, whether or not it exists)."""
    urdf_path = pathlib.Path(urdf_path)
    return urdf_path.with_name(urdf_path.stem + ".friction.json")


def _friction_file_path(urdf_path, friction_file):
    """The side file to read for ``friction_file`` ("auto", a path or None), or None."""
    if friction_file is None:
        return None
    if isinstance(friction_file, str) and friction_file == "auto":
        side = friction_file_path(urdf_path)
        return side if side.is_file() else None
    try:
        side = pathlib.Path(friction_file).expanduser().resolve()
    except TypeError:
        raise ValueError(f"friction_file: expected 'auto', a path or None, got {friction_file!r}") from None
    if not side.is_file():
        raise FileNotFoundError(f"friction file not found: {side}")
    return side


def read_friction_file(path, joints):
    """The friction side file at ``path`` (format in :func:`load_urdf`): (coulomb_width or None,
    {joint: offset}).

    Parameters
    ----------
    path : str or path-like
        The JSON file.
    joints : list of str
        The moving joints of the URDF (before locking); an offset naming another joint is
        refused.

    Returns
    -------
    tuple
        (float or None, dict joint name -> float offset in N m).

    Raises
    ------
    ModelError
        Not JSON, not an object, another ``format``, an unknown key or joint, a value that is not
        a finite number, or a width that is not positive.
    """
    path = pathlib.Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ModelError(f"{path}: not a readable friction file (JSON: {e})") from None
    if not isinstance(data, dict):
        raise ModelError(f"{path}: a friction file is a JSON object with keys "
                         f"{', '.join(_FRICTION_KEYS)}, got {type(data).__name__}")
    unknown = [k for k in data if k not in _FRICTION_KEYS]
    if unknown:
        raise ModelError(f"{path}: unknown key {unknown[0]!r} (a friction file has "
                         f"{', '.join(_FRICTION_KEYS)})")
    if "format" in data and data["format"] != FRICTION_FORMAT:
        raise ModelError(f"{path}: format {data['format']!r} is not {FRICTION_FORMAT!r}")

    def number(value, what):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ModelError(f"{path}: {what} must be a finite number, got {value!r}")
        return float(value)

    width = None
    if "coulomb_width" in data:
        width = number(data["coulomb_width"], "coulomb_width")
        if width <= 0.0:
            raise ModelError(f"{path}: coulomb_width must be > 0 (rad/s), got {width!r}")
    offsets = data.get("offset", {})
    if not isinstance(offsets, dict):
        raise ModelError(f"{path}: offset must be an object joint name -> N m, got {offsets!r}")
    for joint in offsets:
        if joint not in joints:
            raise ModelError(f"{path}: offset names joint {joint!r}, which is not a moving joint of "
                             f"the URDF (joints: {', '.join(joints)})")
    return width, {j: number(v, f"offset[{j!r}]") for j, v in offsets.items()}


def _finite(name, value, expected):
    """float(value) if it is a finite real number, else ValueError naming ``name``."""
    try:
        v = float(value) if not isinstance(value, (bool, complex, str, bytes)) else None
    except (TypeError, ValueError, OverflowError):
        v = None
    if v is None or not math.isfinite(v):
        raise ValueError(f"{name}: expected {expected}, got {value!r}")
    return v


def _locked_values(locked_joints):
    """locked_joints as {joint name: finite value}, or ValueError naming the entry."""
    if locked_joints is None:
        return {}
    if not isinstance(locked_joints, Mapping):
        raise ValueError(f"locked_joints: expected a dict joint name -> value (rad or m), "
                         f"got {type(locked_joints).__name__} {locked_joints!r}")
    return {str(k): _finite(f"locked_joints[{str(k)!r}]", v, "a finite number (rad or m)")
            for k, v in locked_joints.items()}


def _reduced(model, ids, q_ref):
    """pin.buildReducedModel(model, ids, q_ref) by joint, whatever the frame names.

    pinocchio looks frames up by name while it reduces, and fails ("Several frames match the
    filter") when a link is named like a joint, as in arm descriptions (joint "gripper" moving
    link "gripper"); so the call sees every non-joint frame under a unique name, and the
    reduced model gets the original names back."""
    model = model.copy()
    original = {}
    for i in range(1, len(model.frames)):
        f = model.frames[i]
        if f.type != pin.FrameType.JOINT:
            original[f"{i}#{f.name}"] = f.name
            f.name = f"{i}#{f.name}"
            model.frames[i] = f
    reduced = pin.buildReducedModel(model, ids, q_ref)
    for i in range(len(reduced.frames)):
        f = reduced.frames[i]
        if f.name in original:
            f.name = original[f.name]
            reduced.frames[i] = f
    return reduced
