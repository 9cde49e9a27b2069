"""A "real" arm: the URDF's MuJoCo plant (codegen.evaluate.sim.mujoco_plant) with what a real arm
adds and a model does not know, and the log a user of that arm would have.

Independent of our model code: MuJoCo, numpy and the URDF text only (no casadi, no models/); the
``robot`` arguments are read for their data (``source``, ``joint_names``, ``n``, ``q_lower``,
``q_upper``). Everything random is drawn from seeded streams (``numpy.random.default_rng([seed, stream,
crc32(robot name)])``), one stream per kind of draw, so changing one setting leaves the other
draws alone, and two robots drawn with the same seed differ.

The plant (``draw_perturbation``, ``RealPlant``), drawn once per robot:

* inertials: every moving URDF link with mass gets m' = m (1 + u), u ~ U(-s, s) (s = 0.2); its
  centre of mass c' = c + s |c| v, v ~ U(-1, 1)^3 (a shift of up to s |c| per axis, so a centre on
  the joint axis stays put); its rotational inertia about the centre of mass, I = V diag(lam) V^T
  (link frame), becomes V diag(lam (1 + w)) V^T, w ~ U(-s, s)^3, drawn again until the principal
  moments satisfy the triangle inequality lam'_a + lam'_b >= lam'_c (a physical body);
* payload: a sphere of mass m_p (1 kg) and radius 2 cm (I = 2/5 m_p r^2) fixed to the last link
  (the child link of the last joint, the flange side) at a seeded offset, U(-3, 3) cm per axis,
  from that link's frame; it becomes part of that body (MuJoCo's fusestatic, like a fixed link);
* joint friction on top of the URDF's own ``<dynamics damping friction>`` (which MuJoCo's URDF
  import maps to ``dof_damping`` and ``dof_frictionloss``): Coulomb friction (``frictionloss``,
  MuJoCo's dry-friction constraint, not a smooth function of the velocity) U(1, 3) N m on the big
  joints and U(0.3, 1) N m on the last ``wrist`` = 3 joints, viscous damping U(0.5, 2) and
  U(0.2, 0.5) N m s/rad. The friction constraint is made nearly hard (``dof_solref`` (0.002 s, 1),
  ``dof_solimp`` 0.9999): with MuJoCo's default soft constraint a joint held below its
  frictionloss creeps at ~0.1 rad/s, with these settings at ~1e-5 rad/s (below one encoder count
  per second);
* torque-sensor offset: b_j = +-0.2 N m, seeded sign per joint.

The run (``RealPlant.run``), drawn per run from ``seed``, on one of two clocks (``log_clock``):

* ``"jitter"`` (the default): the controller (computed torque with MuJoCo's ``mj_inverse`` on the
  true state, the robot's own controller: it knows the real plant, friction included) runs at
  jittered instants t_k+1 = t_k + h_k, h_k ~ U(0.7, 1.6) ms rounded to a 1 us clock; the plant
  integrates exactly over each interval (``MujocoPlant.advance``: RK4 steps of 1e-4 s, the last one
  shortened); the log's stamps are those instants (a sampler that really jitters), and the log
  misses 1 % of the rows (each row but the first and last dropped with probability 0.01, never two
  in a row; the control still happened);
* ``"receive"``: the controller runs on a fixed tick, s_k = k T_s (T_s = ``tick``, 1 ms), and the
  robot sends every tick's state to a non-realtime logger whose ``t`` is when it received the row.
  Row k of the log is written for tick k (one row per tick, N rows), with

      d_k = sigma_d X_k / std(X),  X_k ~ (1 - w) Gamma(2, 1) + w LogNormal(ln 7, 0.25),  w = 0.004

  (a delay >= 0: a gamma body and a rare log-normal tail, scaled so std(d) = sigma_d =
  ``delay_std``, 0.4 ms; the tail's median, 7 body units, is 1.9 ms at sigma_d = 0.4 ms, and the
  largest of 20 000 draws is ~4 ms; std(X)^2 = E X^2 - (E X)^2 with E X = 2 (1 - w) + w e^(mu + s^2/2),
  E X^2 = 6 (1 - w) + w e^(2 mu + 2 s^2)), and the stamp, in units of the resolution r
  (``stamp_resolution``, 0.1 ms),

      m_k = max(round((s_k + d_k) / r), m_k-1 + 1),   t_k = m_k r,

  so the stamps increase strictly in the order the logger writes them and a late row delays the
  ones after it (bunching: after a 4 ms delay the next rows are written 0.1 ms apart). With
  probability p (``repeat``, 0.05; never the first row) row k repeats the previous row's q and tau
  exactly (the logger wrote a row before the new state arrived; tick k's own state is lost: some
  ticks never appear in the log). Delays (stream ``delays``) and repeats (stream ``repeats``) are
  drawn independently; ``receive_rows`` draws them without a simulation.

The sensors, the same on both clocks:

* logged position: the encoder of ``counts_per_rev`` (2^16) counts per revolution, q_m = D round((q +
  sigma_q n) / D), D = 2 pi / counts_per_rev, with optional white noise sigma_q (``position_noise``,
  rad, default 0; stream ``position``), then optionally written to ``position_decimals`` decimals
  (a logger's format: a 2^20-count encoder logged to 1e-6 rad is ``counts_per_rev=2**20,
  position_decimals=6``);
* logged torque: tau_m = tau + sigma_j n_k + b_j, n_k ~ N(0, 1), sigma_j = 1 % of joint j's effort
  limit (the URDF's; a sensor's noise is a fraction of its full scale; ``torque_noise_of="rms"``:
  of the run's applied-torque RMS instead, also used when the URDF gives no effort;
  ``"absolute"``: ``torque_noise`` N m on every joint).

Outputs (``RealRun.write``): ``<name>.csv``, the log (t, q_<joint>, tau_<joint>: measured, the
clock's stamps, no qd, in the recording format of codegen.logs.recording), ``<name>_truth.csv``
(jitter: every controller instant: t, logged (1/0), true q_<joint>, qd_<joint> and applied
tau_<joint>; receive, or ``truth="rows"``: every log row: its stamp t, the true sample time
t_sample and integer tick of the state it carries (the controller instant's index on the jitter
clock), repeat (1/0), and that sample's true q, qd and applied tau), and ``RealPlant.truth()``: the
perturbation actually drawn and the sensors and clock, as JSON.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...core.columns import write_columns
from ...logs.recording import Recording
from .mujoco_plant import KD, KP, TIMESTEP, MujocoPlant, mujoco_urdf

FRICTION_SOLREF = (0.002, 1.0)                      # time constant (s), damping ratio
FRICTION_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)  # impedance d0, dwidth, width, midpoint, power
PAYLOAD_RADIUS = 0.02                                # m
STREAMS = {"inertial": 10, "payload": 11, "friction": 12, "offset": 13,
           "steps": 1, "drops": 2, "noise": 3, "delays": 4, "repeats": 5, "position": 6,
           "excitation": 20, "task": 21, "bursts": 22}
CLOCKS = ("jitter", "receive")
DELAY_TAIL = 0.004                                  # w: weight of the delays' log-normal tail
DELAY_SHAPE = 2.0                                   # shape of the gamma body (scale 1)
DELAY_TAIL_MU, DELAY_TAIL_S = float(np.log(7.0)), 0.25   # the tail's log-normal (body units)


def _rng(seed, stream, robot=""):
    seed = [int(s) for s in np.atleast_1d(seed)]
    return np.random.default_rng([*seed, STREAMS[stream], zlib.crc32(str(robot).encode())])


def _vec(text, default=(0.0, 0.0, 0.0)):
    return np.array([float(v) for v in text.split()]) if text else np.array(default, dtype=float)


def _rpy(rpy):
    """URDF rotation R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _fmt(a):
    return " ".join(repr(float(v)) for v in np.ravel(a))


def _check_range(name, r):
    lo, hi = (float(v) for v in r)
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo <= hi):
        raise ValueError(f"{name} must be a range (low, high) with 0 <= low <= high, got {r!r}")
    return lo, hi


# ------------------------------------------------------------------------------ URDF data
def urdf_joint_limits(path, joint_names):
    """The ``<limit>`` of each joint of a URDF: lower, upper, velocity and effort.

    Parameters
    ----------
    path : path-like
        URDF file.
    joint_names : list of str
        Joints, in the order wanted.

    Returns
    -------
    dict
        ``{"lower", "upper", "velocity", "effort"}``, each (n,), NaN where the URDF gives none
        (and lower/upper NaN for a continuous joint).
    """
    joints = {j.get("name"): j for j in ET.parse(Path(path)).getroot().iter("joint")
              if j.get("type") is not None}
    out = {k: np.full(len(joint_names), np.nan) for k in ("lower", "upper", "velocity", "effort")}
    for i, name in enumerate(joint_names):
        if name not in joints:
            raise ValueError(f"joint_names: {name!r} is not a joint of {path}")
        lim = joints[name].find("limit")
        continuous = joints[name].get("type") == "continuous"
        for k, column in out.items():
            if lim is not None and lim.get(k) is not None and not (continuous and k in ("lower", "upper")):
                column[i] = float(lim.get(k))
    return out


def _urdf_inertials(root):
    """name -> (mass, com (3,), inertia about the com (3, 3)) in the link frame, for each link
    with an ``<inertial>``."""
    out = {}
    for link in root.iter("link"):
        e = link.find("inertial")
        if e is None or e.find("mass") is None:
            continue
        o = e.find("origin")
        c = _vec(o.get("xyz") if o is not None else None)
        R = _rpy(_vec(o.get("rpy") if o is not None else None))
        a = e.find("inertia").attrib if e.find("inertia") is not None else {}
        xx, xy, xz, yy, yz, zz = (float(a.get(k, 0.0)) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
        I0 = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        out[link.get("name")] = (float(e.find("mass").get("value")), c, R @ I0 @ R.T)
    return out


def _moving_links(root, locked):
    """Links below at least one joint that moves (not fixed, not locked)."""
    children = {}
    for j in root.iter("joint"):
        if j.get("type") is None or j.find("parent") is None:
            continue
        moves = j.get("type") != "fixed" and j.get("name") not in locked
        children.setdefault(j.find("parent").get("link"), []).append((j.find("child").get("link"), moves))
    childset = {c for v in children.values() for c, _ in v}
    stack = [(link.get("name"), False) for link in root.iter("link") if link.get("name") not in childset]
    moving = set()
    while stack:
        name, below = stack.pop()
        if below:
            moving.add(name)
        stack.extend((c, below or m) for c, m in children.get(name, []))
    return moving


def _joint_child(root, joint):
    for j in root.iter("joint"):
        if j.get("name") == joint and j.find("child") is not None:
            return j.find("child").get("link")
    raise ValueError(f"joint {joint!r} has no child link")


# ------------------------------------------------------------------------------ the draw
@dataclass
class Perturbation:
    """What a real arm has and its URDF does not (module docstring), as drawn.

    Attributes
    ----------
    robot : str
        Robot name.
    joint_names : list of str
        Joint order of the per-joint arrays.
    links : dict
        Link name -> ``{"mass": [nominal, real], "com": [nominal (3,), real (3,)], "inertia":
        [nominal (3, 3), real (3, 3)]}``: the centre of mass and the inertia about it in the
        link frame (kg, m, kg m^2).
    payload : dict
        ``{"link", "mass", "position" (3,), "radius"}``: a sphere fixed to ``link``.
    coulomb, viscous : (n,) arrays
        Drawn friction, added to the URDF's own (N m, N m s/rad).
    torque_offset : (n,) array
        Offset of the logged torque (N m).
    settings : dict
        The seed and the ranges it was drawn with.
    """
    robot: str
    joint_names: list
    links: dict
    payload: dict
    coulomb: np.ndarray
    viscous: np.ndarray
    torque_offset: np.ndarray
    settings: dict = field(default_factory=dict)

    def to_dict(self):
        """The perturbation as JSON-ready lists and numbers (``from_dict`` reads it back)."""
        return {"robot": self.robot, "joint_names": list(self.joint_names), "settings": dict(self.settings),
                "links": {k: {f: [np.asarray(x).tolist() for x in v[f]] for f in ("mass", "com", "inertia")}
                          for k, v in self.links.items()},
                "payload": {k: (np.asarray(v).tolist() if k == "position" else v) for k, v in self.payload.items()},
                "coulomb": np.asarray(self.coulomb).tolist(), "viscous": np.asarray(self.viscous).tolist(),
                "torque_offset": np.asarray(self.torque_offset).tolist()}

    @classmethod
    def from_dict(cls, d):
        """The Perturbation of ``to_dict``'s output ``d`` (e.g. read from the JSON)."""
        links = {k: {"mass": [float(x) for x in v["mass"]],
                     "com": [np.asarray(x, dtype=float) for x in v["com"]],
                     "inertia": [np.asarray(x, dtype=float) for x in v["inertia"]]}
                 for k, v in d["links"].items()}
        payload = dict(d["payload"])
        payload["position"] = np.asarray(payload["position"], dtype=float)
        return cls(robot=d["robot"], joint_names=list(d["joint_names"]), links=links, payload=payload,
                   coulomb=np.asarray(d["coulomb"], dtype=float), viscous=np.asarray(d["viscous"], dtype=float),
                   torque_offset=np.asarray(d["torque_offset"], dtype=float), settings=dict(d.get("settings", {})))


def _principal(lam, w, rng, s, link):
    """Principal moments lam (1 + w), w drawn again until they form a physical body."""
    lam = np.maximum(lam, 0.0)
    if lam.max() > 0 and 2 * lam.max() > lam.sum() * (1 + 1e-9):
        raise ValueError(f"urdf: link {link!r} has an inertia that violates the triangle inequality "
                         f"(principal moments {lam})")
    for _ in range(1000):
        new = lam * (1 + w)
        if 2 * new.max() <= new.sum():
            return new
        w = rng.uniform(-s, s, 3)
    raise ValueError(f"urdf: no physical draw of link {link!r}'s principal moments {lam} within +-{s}")


def draw_perturbation(robot, seed=0, inertial=0.2, payload_mass=1.0, payload_offset=0.03,
                      payload_link=None, coulomb=((1.0, 3.0), (0.3, 1.0)),
                      viscous=((0.5, 2.0), (0.2, 0.5)), wrist=3, torque_offset=0.2):
    """Draw the perturbation of the module docstring for ``robot`` (seeded, reproducible).

    Parameters
    ----------
    robot : models.RobotModel
        A URDF robot (``robot.source["kind"] == "urdf"``); read for its URDF, locked joints and
        joint names only.
    seed : int
        Seed of every draw.
    inertial : float
        Relative spread s of masses, principal moments and centres of mass, in [0, 1).
    payload_mass : float
        Payload (kg), >= 0 (0: none).
    payload_offset : float
        Largest offset of the payload from the last link's frame, per axis (m), >= 0.
    payload_link : str, optional
        Link carrying the payload; default the child link of the last joint.
    coulomb, viscous : ((low, high), (low, high))
        Ranges of the drawn Coulomb (N m) and viscous (N m s/rad) friction: big joints, wrist.
    wrist : int
        Number of wrist joints (the last ones), 0 <= wrist <= n.
    torque_offset : float
        Magnitude of the logged torque's offset (N m), >= 0; its sign is drawn per joint.

    Returns
    -------
    Perturbation
    """
    src = getattr(robot, "source", {}) or {}
    if src.get("kind") != "urdf":
        raise ValueError(f"robot: the real plant needs a URDF robot, got source kind {src.get('kind')!r}")
    if not (np.isfinite(inertial) and 0 <= inertial < 1):
        raise ValueError(f"inertial must be a relative spread in [0, 1), got {inertial!r}")
    for name, v in (("payload_mass", payload_mass), ("payload_offset", payload_offset),
                    ("torque_offset", torque_offset)):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
    n, name = robot.n, getattr(robot, "name", "")
    if not (isinstance(wrist, (int, np.integer)) and 0 <= wrist <= n):
        raise ValueError(f"wrist must be an integer number of joints in [0, {n}], got {wrist!r}")
    cb, cw = (_check_range("coulomb", r) for r in coulomb)
    vb, vw = (_check_range("viscous", r) for r in viscous)
    root = ET.fromstring(mujoco_urdf(src["path"], src.get("locked_joints")))
    locked = set(src.get("locked_joints") or {})
    moving = _moving_links(root, locked)

    rng = _rng(seed, "inertial", name)
    links = {}
    for lname, (m, c, I) in _urdf_inertials(root).items():
        u, v, w = rng.uniform(-inertial, inertial), rng.uniform(-1, 1, 3), rng.uniform(-inertial, inertial, 3)
        if lname not in moving or m <= 0:
            continue                              # draws made anyway: the streams do not shift
        lam, V = np.linalg.eigh(I)
        lam2 = _principal(lam, w, rng, inertial, lname)
        links[lname] = {"mass": [m, m * (1 + u)], "com": [c, c + inertial * np.linalg.norm(c) * v],
                       "inertia": [I, V @ np.diag(lam2) @ V.T]}

    rng = _rng(seed, "payload", name)
    link = payload_link or _joint_child(root, robot.joint_names[-1])
    if link not in {e.get("name") for e in root.iter("link")}:
        raise ValueError(f"payload_link: {link!r} is not a link of {src['path']}")
    payload = {"link": link, "mass": float(payload_mass),
               "position": rng.uniform(-payload_offset, payload_offset, 3), "radius": PAYLOAD_RADIUS}

    rng = _rng(seed, "friction", name)
    big = np.arange(n) < n - wrist
    draw = lambda b, w: np.where(big, rng.uniform(*b, n), rng.uniform(*w, n))
    fc = draw(cb, cw)
    fv = draw(vb, vw)
    offset = torque_offset * _sign(_rng(seed, "offset", name), n)
    settings = {"seed": int(seed), "inertial": float(inertial), "payload_mass": float(payload_mass),
                "payload_offset": float(payload_offset), "coulomb": [list(cb), list(cw)],
                "viscous": [list(vb), list(vw)], "wrist": int(wrist), "torque_offset": float(torque_offset)}
    return Perturbation(robot=name, joint_names=list(robot.joint_names), links=links,
                        payload=payload, coulomb=fc, viscous=fv, torque_offset=offset, settings=settings)


def _sign(rng, n):
    """n signs +-1 drawn with equal probability from the generator ``rng``."""
    return np.where(rng.random(n) < 0.5, -1.0, 1.0)


def perturbed_urdf(path, perturbation, locked_joints=None):
    """The URDF text of ``mujoco_urdf(path, locked_joints)`` with the perturbation's real
    inertials (written in the link frame: origin xyz = com, rpy = 0) and its payload link.

    Parameters
    ----------
    path : path-like
        URDF file.
    perturbation : Perturbation
        What to apply (``links`` real values, ``payload``).
    locked_joints : dict, optional
        As in ``mujoco_urdf``.

    Returns
    -------
    str
    """
    root = ET.fromstring(mujoco_urdf(path, locked_joints))
    names = {link.get("name"): link for link in root.iter("link")}
    for name, v in perturbation.links.items():
        if name not in names:
            raise ValueError(f"perturbation: link {name!r} is not in {path}")
        link = names[name]
        for e in link.findall("inertial"):
            link.remove(e)
        _inertial(link, v["mass"][1], v["com"][1], v["inertia"][1])
    p = perturbation.payload
    if p["mass"] > 0:
        if p["link"] not in names:
            raise ValueError(f"perturbation: payload link {p['link']!r} is not in {path}")
        pname = "payload"
        while pname in names or any(j.get("name") == f"{pname}_joint" for j in root.iter("joint")):
            pname += "_"
        link = ET.Element("link", name=pname)
        _inertial(link, p["mass"], p["position"], 0.4 * p["mass"] * p["radius"] ** 2 * np.eye(3))
        joint = ET.Element("joint", name=f"{pname}_joint", type="fixed")
        ET.SubElement(joint, "parent", link=p["link"])
        ET.SubElement(joint, "child", link=pname)
        ET.SubElement(joint, "origin", xyz="0 0 0", rpy="0 0 0")
        mj_el = root.find("mujoco")
        idx = list(root).index(mj_el)
        root.insert(idx, joint)
        root.insert(idx, link)
    return ET.tostring(root, encoding="unicode")


def _inertial(link, mass, com, inertia):
    e = ET.SubElement(link, "inertial")
    ET.SubElement(e, "origin", xyz=_fmt(com), rpy="0 0 0")
    ET.SubElement(e, "mass", value=repr(float(mass)))
    I = np.asarray(inertia)
    ET.SubElement(e, "inertia", ixx=repr(float(I[0, 0])), ixy=repr(float(I[0, 1])), ixz=repr(float(I[0, 2])),
                  iyy=repr(float(I[1, 1])), iyz=repr(float(I[1, 2])), izz=repr(float(I[2, 2])))


def body_inertials(model, body):
    """The inertial of a MuJoCo body in its own frame.

    Parameters
    ----------
    model : mujoco.MjModel
    body : int
        Body id.

    Returns
    -------
    dict
        ``mass`` (kg), ``com`` (3,) (m), ``inertia`` (3, 3) about the centre of mass (kg m^2) and
        ``parameters``, the 10 standard parameters about the frame origin in pinocchio's order
        [m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz], I_O = I_c + m (|c|^2 E - c c^T).
    """
    import mujoco as mj
    R = np.zeros(9)
    mj.mju_quat2Mat(R, model.body_iquat[body])
    R = R.reshape(3, 3)
    m, c = float(model.body_mass[body]), model.body_ipos[body].copy()
    Ic = R @ np.diag(model.body_inertia[body]) @ R.T
    IO = Ic + m * (c @ c * np.eye(3) - np.outer(c, c))
    par = [m, *(m * c), IO[0, 0], IO[0, 1], IO[1, 1], IO[0, 2], IO[1, 2], IO[2, 2]]
    return {"mass": m, "com": c.tolist(), "inertia": Ic.tolist(), "parameters": [float(x) for x in par]}


# ------------------------------------------------------------------------------ the plant
class RealPlant(MujocoPlant):
    """The MuJoCo plant of ``robot``'s URDF with a ``Perturbation`` applied and the sensors of a
    real arm (module docstring).

    Parameters
    ----------
    robot : models.RobotModel
        A URDF robot; read for its URDF, locked joints, joint names and n.
    perturbation : Perturbation, optional
        Default ``draw_perturbation(robot, seed)``.
    seed : int
        Seed of the default perturbation.
    torque_noise : float
        Standard deviation of the logged torque's white noise, >= 0: relative (0.01) or, with
        ``torque_noise_of="absolute"``, in N m.
    torque_noise_of : {"effort", "rms", "absolute"}
        Relative to each joint's URDF effort limit, to the run's applied-torque RMS, or absolute.
    counts_per_rev : int
        Encoder resolution (counts per revolution), >= 1.
    step_range : (float, float)
        Controller step range of the jitter clock (s), 0 < low <= high.
    drop : float
        Probability that a row is missing from the log of the jitter clock, in [0, 0.5).
    clock : float
        Resolution of the controller's clock and of the jitter clock's stamps (s); 1 / clock must
        be an integer.
    timestep : float
        MuJoCo's RK4 step (s), the largest sub-step.
    log_clock : {"jitter", "receive"}
        The clock of the controller and the log (module docstring).
    tick : float
        The receive clock's controller period T_s (s), a whole number of ``clock`` units.
    delay_std : float
        sigma_d, the standard deviation of the receive delays (s), >= 0.
    stamp_resolution : float
        r, the resolution of the receive clock's stamps (s), a whole number of ``clock`` units.
    repeat : float
        p, the probability that a receive-clock row repeats the previous row's state, in [0, 0.5).
    position_noise : float
        sigma_q, white noise on the position before the encoder (rad), >= 0.
    position_decimals : int, optional
        The logged position rounded to this many decimals (rad); None: the encoder's value in full.
    """

    def __init__(self, robot, perturbation=None, seed=0, torque_noise=0.01, torque_noise_of="effort",
                 counts_per_rev=2 ** 16, step_range=(0.7e-3, 1.6e-3), drop=0.01, clock=1e-6,
                 timestep=TIMESTEP, log_clock="jitter", tick=1e-3, delay_std=0.4e-3, stamp_resolution=1e-4,
                 repeat=0.05, position_noise=0.0, position_decimals=None):
        src = getattr(robot, "source", {}) or {}
        if src.get("kind") != "urdf":
            raise ValueError(f"robot: the real plant needs a URDF robot, got source kind {src.get('kind')!r} "
                             f"for {getattr(robot, 'name', robot)!r}")
        p = draw_perturbation(robot, seed) if perturbation is None else perturbation
        if list(p.joint_names) != list(robot.joint_names):
            raise ValueError(f"perturbation: drawn for joints {p.joint_names}, the robot has {robot.joint_names}")
        if not (np.isfinite(torque_noise) and torque_noise >= 0):
            raise ValueError(f"torque_noise must be a finite number >= 0, got {torque_noise!r}")
        if torque_noise_of not in ("effort", "rms", "absolute"):
            raise ValueError(f"torque_noise_of must be 'effort', 'rms' or 'absolute', got {torque_noise_of!r}")
        if not (isinstance(counts_per_rev, (int, np.integer)) and counts_per_rev >= 1):
            raise ValueError(f"counts_per_rev must be an integer >= 1, got {counts_per_rev!r}")
        lo, hi = (float(v) for v in step_range)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi):
            raise ValueError(f"step_range must be (low, high) seconds with 0 < low <= high, got {step_range!r}")
        if not (np.isfinite(drop) and 0 <= drop < 0.5):
            raise ValueError(f"drop must be a probability in [0, 0.5), got {drop!r}")
        ticks = round(1.0 / clock) if np.isfinite(clock) and clock > 0 else 0
        if ticks < 1 or abs(ticks * clock - 1) > 1e-9 or clock > lo:
            raise ValueError(f"clock must be 1/N s (N an integer) and <= the shortest step, got {clock!r}")
        if log_clock not in CLOCKS:
            raise ValueError(f"log_clock must be one of {', '.join(CLOCKS)}, got {log_clock!r}")
        units = {}
        for name, v in (("tick", tick), ("stamp_resolution", stamp_resolution)):
            u = round(float(v) * ticks) if np.isfinite(v) and v > 0 else 0
            if u < 1 or abs(u - float(v) * ticks) > 1e-6:
                raise ValueError(f"{name} must be a positive whole number of clock units ({clock:g} s), got {v!r}")
            units[name] = u
        if units["stamp_resolution"] > units["tick"]:
            raise ValueError(f"stamp_resolution must be <= tick ({tick:g} s), got {stamp_resolution!r}")
        if not (np.isfinite(delay_std) and delay_std >= 0):
            raise ValueError(f"delay_std must be a finite number of seconds >= 0, got {delay_std!r}")
        if not (np.isfinite(repeat) and 0 <= repeat < 0.5):
            raise ValueError(f"repeat must be a probability in [0, 0.5), got {repeat!r}")
        if not (np.isfinite(position_noise) and position_noise >= 0):
            raise ValueError(f"position_noise must be a finite number of radians >= 0, got {position_noise!r}")
        if position_decimals is not None and not (isinstance(position_decimals, (int, np.integer))
                                                  and not isinstance(position_decimals, bool)
                                                  and 0 <= position_decimals <= 15):
            raise ValueError(f"position_decimals must be None or an integer in [0, 15], got {position_decimals!r}")
        text = perturbed_urdf(src["path"], p, src.get("locked_joints"))
        super().__init__(robot, timestep=timestep, urdf_text=text)
        mj, m = self._mj, self.model
        self.perturbation = p
        self.urdf_damping = m.dof_damping[self._vi].copy()          # MuJoCo's import of <dynamics>
        self.urdf_frictionloss = m.dof_frictionloss[self._vi].copy()
        m.dof_damping[self._vi] += p.viscous
        m.dof_frictionloss[self._vi] += p.coulomb
        m.dof_solref[self._vi] = FRICTION_SOLREF
        m.dof_solimp[self._vi] = FRICTION_SOLIMP
        mj.mj_setConst(m, self.data)
        self.limits = urdf_joint_limits(src["path"], robot.joint_names)
        self.torque_noise, self.torque_noise_of = float(torque_noise), torque_noise_of
        self.counts_per_rev, self.step_range, self.drop = int(counts_per_rev), (lo, hi), float(drop)
        self.clock, self._ticks = float(clock), int(ticks)
        self.log_clock, self.tick, self.delay_std = log_clock, float(tick), float(delay_std)
        self.stamp_resolution, self.repeat = float(stamp_resolution), float(repeat)
        self._tick_units, self._stamp_units = units["tick"], units["stamp_resolution"]
        self.position_noise = float(position_noise)
        self.position_decimals = None if position_decimals is None else int(position_decimals)

    @property
    def encoder_step(self):
        """Encoder quantum D = 2 pi / counts_per_rev (rad)."""
        return 2 * np.pi / self.counts_per_rev

    @property
    def damping(self):
        """Viscous friction of each joint, URDF's plus drawn (N m s/rad)."""
        return self.model.dof_damping[self._vi].copy()

    @property
    def frictionloss(self):
        """Coulomb friction of each joint, URDF's plus drawn (N m)."""
        return self.model.dof_frictionloss[self._vi].copy()

    def torque_noise_std(self, tau=None):
        """sigma_j of the logged torque's noise: ``torque_noise`` x effort limit (or x RMS of the
        applied torque ``tau`` (N, n) for ``torque_noise_of="rms"`` and where the URDF gives no
        effort; NaN there when ``tau`` is None); ``torque_noise`` N m on every joint for
        ``torque_noise_of="absolute"``."""
        if self.torque_noise_of == "absolute":
            return np.full(self.n, self.torque_noise)
        eff = self.limits["effort"]
        rms = (np.sqrt(np.mean(np.asarray(tau) ** 2, axis=0)) if tau is not None
               else np.full(self.n, np.nan))
        use_eff = (self.torque_noise_of == "effort") & np.isfinite(eff) & (eff > 0)
        return self.torque_noise * np.where(use_eff, eff, rms)

    def truth(self):
        """The perturbation actually in the plant, JSON-ready: the draw (``Perturbation.to_dict``),
        each joint's body inertial nominal (the URDF's, lumped as MuJoCo fuses fixed links) and
        real (``body_inertials``, payload included), the friction (URDF's, drawn, total) and the
        sensors and the clock (encoder step, position noise and decimals, torque noise and offset,
        ``clock_settings``)."""
        mj = self._mj
        src = self.robot.source
        nominal = mj.MjModel.from_xml_string(mujoco_urdf(src["path"], src.get("locked_joints")))
        m = self.model
        bodies = {}
        for j in self.robot.joint_names:
            b = m.jnt_bodyid[mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, j)]
            bn = nominal.jnt_bodyid[mj.mj_name2id(nominal, mj.mjtObj.mjOBJ_JOINT, j)]
            bodies[j] = {"body": mj.mj_id2name(m, mj.mjtObj.mjOBJ_BODY, b),
                         "nominal": body_inertials(nominal, bn), "real": body_inertials(m, b)}
        std = self.torque_noise_std()
        return {**self.perturbation.to_dict(), "bodies": bodies,
                "friction": {"urdf_damping": self.urdf_damping.tolist(),
                             "urdf_frictionloss": self.urdf_frictionloss.tolist(),
                             "damping": self.damping.tolist(), "frictionloss": self.frictionloss.tolist(),
                             "solref": list(FRICTION_SOLREF), "solimp": list(FRICTION_SOLIMP)},
                "sensors": {"encoder_counts_per_rev": self.counts_per_rev, "encoder_step": self.encoder_step,
                            "torque_noise": self.torque_noise, "torque_noise_of": self.torque_noise_of,
                            "torque_noise_std": [None if not np.isfinite(s) else float(s) for s in std],
                            "torque_offset": self.perturbation.torque_offset.tolist(),
                            "step_range": list(self.step_range), "drop": self.drop, "clock": self.clock,
                            "position_noise": self.position_noise, "position_decimals": self.position_decimals,
                            **self.clock_settings()},
                "effort": [None if not np.isfinite(e) else float(e) for e in self.limits["effort"]]}

    def clock_settings(self):
        """The clock of the log, JSON-ready: ``log_clock`` and, for the receive clock, its tick,
        delay std, stamp resolution and repeat probability (s, s, s, -)."""
        if self.log_clock == "jitter":
            return {"log_clock": "jitter"}
        return {"log_clock": "receive", "tick": self.tick, "delay_std": self.delay_std,
                "stamp_resolution": self.stamp_resolution, "repeat": self.repeat}

    def instants(self, T, seed=0):
        """Controller instants on [0, T]: on the jitter clock t_0 = 0, t_k+1 = t_k + h_k, h_k ~
        U(step_range) rounded to the clock (stream ``steps`` of ``seed``); on the receive clock
        the ticks s_k = k T_s, k = 0 .. floor(T / T_s) (``seed`` unused).

        Parameters
        ----------
        T : float
            Length (s), > step_range high.
        seed : int or tuple of int
            Seed of the run.

        Returns
        -------
        (N,) array
        """
        if self.log_clock == "receive":
            if not (np.isfinite(T) and T >= self.tick):
                raise ValueError(f"T must be a number of seconds >= the tick {self.tick:g}, got {T!r}")
            K = int(np.floor(T * self._ticks / self._tick_units + 1e-9))
            return np.arange(K + 1) * self._tick_units / self._ticks
        if not (np.isfinite(T) and T > self.step_range[1]):
            raise ValueError(f"T must be a number of seconds > {self.step_range[1]:g}, got {T!r}")
        rng = _rng(seed, "steps")
        h = np.rint(rng.uniform(*self.step_range, int(T / self.step_range[0]) + 2) * self._ticks)
        ticks = np.concatenate([[0], np.cumsum(h.astype(np.int64))])
        ticks = ticks[ticks <= round(T * self._ticks)]
        return ticks / self._ticks

    def dropped(self, N, seed=0):
        """Rows missing from the log: each row but the first and last with probability ``drop``
        (stream ``drops`` of ``seed``), a row right after a dropped one kept.

        Parameters
        ----------
        N : int
            Number of controller instants.
        seed : int or tuple of int
            Seed of the run.

        Returns
        -------
        (N,) bool array
        """
        mask = _rng(seed, "drops").random(N) < self.drop
        mask[0] = mask[-1] = False
        for k in np.flatnonzero(mask):
            if mask[k - 1]:
                mask[k] = False
        return mask

    def delays(self, N, seed=0):
        """N receive delays d_k = sigma_d X_k / std(X) >= 0 (s), X_k from the gamma/log-normal
        mixture of the module docstring (stream ``delays`` of ``seed``).

        Parameters
        ----------
        N : int
            Number of delays.
        seed : int or tuple of int
            Seed of the run.

        Returns
        -------
        (N,) array
        """
        rng = _rng(seed, "delays")
        body = rng.gamma(DELAY_SHAPE, 1.0, N)
        tail = rng.lognormal(DELAY_TAIL_MU, DELAY_TAIL_S, N)
        x = np.where(rng.random(N) < DELAY_TAIL, tail, body)
        w, k, mu, s2 = DELAY_TAIL, DELAY_SHAPE, DELAY_TAIL_MU, DELAY_TAIL_S ** 2
        mean = (1 - w) * k + w * np.exp(mu + s2 / 2)
        second = (1 - w) * (k + k * k) + w * np.exp(2 * mu + 2 * s2)
        return self.delay_std * x / np.sqrt(second - mean * mean)

    def receive_rows(self, N, seed=0):
        """The receive clock's log rows for N ticks (module docstring), without a simulation.

        Parameters
        ----------
        N : int
            Number of ticks, >= 1 (one row each).
        seed : int or tuple of int
            Seed of the run (streams ``delays`` and ``repeats``).

        Returns
        -------
        stamps : (N,) array
            t_k = m_k r (s), strictly increasing.
        source : (N,) int array
            The tick whose state row k carries (k, or the previous row's for a repeat).
        repeat : (N,) bool array
            Rows that repeat the previous row's state.
        """
        k = np.arange(N)
        a = (k * self._tick_units + self.delays(N, seed) * self._ticks) / self._stamp_units
        m = np.rint(a).astype(np.int64) - k                  # m_k = max(round(a_k), m_k-1 + 1)
        m = np.maximum.accumulate(m) + k
        stamps = m * self._stamp_units / self._ticks
        repeat = _rng(seed, "repeats").random(N) < self.repeat
        repeat[0] = False
        source = np.maximum.accumulate(np.where(repeat, 0, k))
        return stamps, source, repeat

    def measure_position(self, q, seed=0):
        """The logged position of the true q (N, n): D round((q + sigma_q n) / D), n ~ N(0, 1)
        (stream ``position`` of ``seed``; none when sigma_q = 0), then rounded to
        ``position_decimals`` decimals when set (rad)."""
        D = self.encoder_step
        if self.position_noise > 0:
            q = q + self.position_noise * _rng(seed, "position").standard_normal(np.shape(q))
        q_meas = D * np.round(q / D)
        return q_meas if self.position_decimals is None else np.round(q_meas, self.position_decimals)

    def run(self, reference, T, seed=0, kp=KP, kd=KD):
        """One run: the closed loop on the plant's clock, the log and the truth (module docstring).

        Parameters
        ----------
        reference : callable
            t -> (q_d, qd_d, qdd_d), each (n,); the plant starts on it.
        T : float
            Length (s).
        seed : int or tuple of int
            Seed of the instants (jitter), the dropped rows (jitter), the delays and repeated rows
            (receive) and the sensors' noise.
        kp, kd : float
            Computed-torque gains (1/s^2, 1/s).

        Returns
        -------
        RealRun
        """
        t = self.instants(T, seed)
        rec = self.track_at(reference, t, kp=kp, kd=kd)
        q_ref = np.array([reference(tk)[0] for tk in t])
        std = self.torque_noise_std(rec.tau)
        noise = _rng(seed, "noise").standard_normal(rec.tau.shape)
        if self.log_clock == "jitter":
            logged = ~self.dropped(len(t), seed)
            rows = dict(row_t=t[logged], row_source=np.flatnonzero(logged), row_repeat=np.zeros(logged.sum(), bool))
        else:
            stamps, source, repeat = self.receive_rows(len(t), seed)
            logged = np.zeros(len(t), bool)
            logged[source] = True
            rows = dict(row_t=stamps, row_source=source, row_repeat=repeat)
        return RealRun(joint_names=list(self.robot.joint_names), t=t, q=rec.q, qd=rec.qd, tau=rec.tau,
                       q_meas=self.measure_position(rec.q, seed),
                       tau_meas=rec.tau + std * noise + self.perturbation.torque_offset,
                       logged=logged, torque_noise_std=std,
                       torque_offset=self.perturbation.torque_offset.copy(), encoder_step=self.encoder_step,
                       tracking_error=np.max(np.abs(rec.q - q_ref), axis=0), effort=self.limits["effort"],
                       velocity_limit=self.limits["velocity"], step_range=self.step_range,
                       clock=self.clock_settings(), **rows)


@dataclass
class RealRun:
    """A run of the real plant: every controller instant's truth and what the log keeps.

    Attributes
    ----------
    joint_names : list of str
    t : (N,) array
        Controller instants (s).
    q, qd, tau : (N, n) arrays
        True position, true velocity, applied torque (held over [t_k, t_k+1]).
    q_meas, tau_meas : (N, n) arrays
        Encoder reading and torque-sensor reading.
    logged : (N,) bool array
        Instants whose state the log holds.
    torque_noise_std, torque_offset : (n,) arrays
        Stated sigma and offset of the torque sensor (N m).
    encoder_step : float
        Encoder quantum (rad).
    tracking_error : (n,) array
        max_k |q_k - q_d(t_k)| (rad).
    effort, velocity_limit : (n,) arrays
        The URDF's limits (NaN where absent).
    step_range : (float, float)
        The controller's step range (s).
    row_t : (R,) array
        The log's stamps (s), one per row.
    row_source : (R,) int array
        The instant whose state each row carries (an index into ``t``).
    row_repeat : (R,) bool array
        Rows that repeat the previous row's state.
    clock : dict
        ``RealPlant.clock_settings()``.
    """
    joint_names: list
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    q_meas: np.ndarray
    tau_meas: np.ndarray
    logged: np.ndarray
    torque_noise_std: np.ndarray
    torque_offset: np.ndarray
    encoder_step: float
    tracking_error: np.ndarray
    effort: np.ndarray
    velocity_limit: np.ndarray
    step_range: tuple
    row_t: np.ndarray = None
    row_source: np.ndarray = None
    row_repeat: np.ndarray = None
    clock: dict = field(default_factory=lambda: {"log_clock": "jitter"})

    def __post_init__(self):
        if self.row_t is None:                    # the jitter clock's rows: the logged instants
            self.row_source = np.flatnonzero(self.logged)
            self.row_t = self.t[self.row_source]
            self.row_repeat = np.zeros(len(self.row_source), bool)

    def log(self):
        """The user's log as a Recording (the clock's stamps, measured q and tau, no qd)."""
        k = self.row_source
        return Recording(t=self.row_t, q=self.q_meas[k], tau=self.tau_meas[k], qd=None,
                         joint_names=list(self.joint_names))

    def log_columns(self):
        """name -> column of the log: t, q_<joint>..., tau_<joint>... (one per log row)."""
        k = self.row_source
        cols = {"t": self.row_t}
        cols.update({f"q_{j}": self.q_meas[k, i] for i, j in enumerate(self.joint_names)})
        cols.update({f"tau_{j}": self.tau_meas[k, i] for i, j in enumerate(self.joint_names)})
        return cols

    def truth_columns(self):
        """name -> column of the truth: t, logged, q_<joint>, qd_<joint>, tau_<joint> (applied),
        every controller instant."""
        cols = {"t": self.t, "logged": self.logged.astype(float)}
        for g, a in (("q", self.q), ("qd", self.qd), ("tau", self.tau)):
            cols.update({f"{g}_{j}": a[:, i] for i, j in enumerate(self.joint_names)})
        return cols

    def row_truth_columns(self):
        """name -> column of the truth of each log row: t (its stamp), t_sample and tick (the
        true time and the index of the controller instant whose state it carries), repeat (1/0),
        and that instant's true q_<joint>, qd_<joint> and applied tau_<joint>."""
        k = self.row_source
        cols = {"t": self.row_t, "t_sample": self.t[k], "tick": k.astype(float),
                "repeat": self.row_repeat.astype(float)}
        for g, a in (("q", self.q), ("qd", self.qd), ("tau", self.tau)):
            cols.update({f"{g}_{j}": a[k, i] for i, j in enumerate(self.joint_names)})
        return cols

    def write(self, folder, name, truth=None):
        """Write ``<name>.csv`` (the log) and ``<name>_truth.csv`` into ``folder`` (created),
        atomically (codegen.core.columns.write_columns).

        Parameters
        ----------
        folder : path-like
        name : str
            File stem.
        truth : {"instants", "rows"}, optional
            The truth of every controller instant (``truth_columns``) or of every log row
            (``row_truth_columns``); default "instants" on the jitter clock, "rows" on the
            receive clock.

        Returns
        -------
        (pathlib.Path, pathlib.Path)
            The log and the truth.
        """
        truth = truth or ("instants" if self.clock["log_clock"] == "jitter" else "rows")
        if truth not in ("instants", "rows"):
            raise ValueError(f"truth must be 'instants' or 'rows', got {truth!r}")
        folder = Path(folder)
        cols = self.truth_columns() if truth == "instants" else self.row_truth_columns()
        return (write_columns(folder / f"{name}.csv", self.log_columns()),
                write_columns(folder / f"{name}_truth.csv", cols))

    def stats(self):
        """Summary of the run, JSON-ready: sample times (all instants and the log), dropped rows,
        the torque sensor's error (measured - applied over the logged rows: mean and std per
        joint, with the stated offset and sigma), the encoder step, tracking error, peak |qd|
        and |tau| against the URDF's limits; on the receive clock also the rows, repeats, lost
        ticks, and the delay of each stamp behind its row's tick, t_k - s_k (ms)."""
        steps = np.diff(self.t)
        log_steps = np.diff(self.row_t)
        lo, hi = self.step_range
        single = (log_steps >= lo - 1e-12) & (log_steps <= hi + 1e-12)
        err = (self.tau_meas - self.tau)[self.logged]
        ms = lambda a: {"min": float(a.min() * 1e3), "mean": float(a.mean() * 1e3),
                        "max": float(a.max() * 1e3), "std": float(a.std() * 1e3)}
        lst = lambda a: [None if not np.isfinite(x) else float(x) for x in a]
        out = {"T": float(self.t[-1]), "instants": len(self.t), "logged": int(self.logged.sum()),
               "dropped": int((~self.logged).sum()), "dropped_fraction": float((~self.logged).mean()),
               "step_ms": ms(steps), "log_step_ms": ms(log_steps),
               "log_steps_outside_range": int((~single).sum()),
               "torque_error_mean": lst(err.mean(axis=0)), "torque_offset": lst(self.torque_offset),
               "torque_error_std": lst(err.std(axis=0)), "torque_noise_std": lst(self.torque_noise_std),
               "encoder_step": float(self.encoder_step),
               "position_error_max": lst(np.abs(self.q_meas - self.q)[self.logged].max(axis=0)),
               "tracking_error_max": lst(self.tracking_error), "qd_max": lst(np.abs(self.qd).max(axis=0)), "velocity_limit": lst(self.velocity_limit),
               "tau_max": lst(np.abs(self.tau).max(axis=0)), "effort": lst(self.effort)}
        if self.clock["log_clock"] == "receive":
            delay = self.row_t - self.t[:len(self.row_t)]           # row k is written for tick k
            out.update({"rows": len(self.row_t), "repeats": int(self.row_repeat.sum()),
                        "repeat_fraction": float(self.row_repeat.mean()), "delay_ms": ms(delay),
                        "bunched_rows": int(np.sum(log_steps <= self.clock["stamp_resolution"] * (1 + 1e-9)))})
        return out


# ------------------------------------------------------------------------------ trajectories
def _urdf_velocity(robot):
    """Each joint's URDF velocity limit (rad/s); NaN where there is none."""
    src = getattr(robot, "source", {}) or {}
    return (urdf_joint_limits(src["path"], robot.joint_names)["velocity"] if src.get("kind") == "urdf"
            else np.full(robot.n, np.nan))


def _amplitude_and_speed(robot, fill, max_amplitude, speed):
    lo, hi = np.asarray(robot.q_lower, dtype=float), np.asarray(robot.q_upper, dtype=float)
    A = np.minimum(fill * (hi - lo), max_amplitude)
    v = _urdf_velocity(robot)
    vmax = np.where(np.isfinite(v) & (v > 0), speed * v, np.inf)
    return 0.5 * (lo + hi), A, vmax


def _peak(f, period, grid=2048):
    """max_t |f(t)| over one period (f vectorised): the largest of a grid, refined by a bounded
    scalar search around it."""
    from scipy.optimize import minimize_scalar
    tt = np.linspace(0, period, grid, endpoint=False)
    v = np.abs(f(tt))
    k = int(np.argmax(v))
    dt = period / grid
    res = minimize_scalar(lambda t: -abs(f(t)), bounds=(tt[k] - dt, tt[k] + dt), method="bounded",
                          options={"xatol": 1e-10 * period})
    return max(v[k], -res.fun)


def fourier_excitation(robot, harmonics=5, f0=0.1, fill=0.3, max_amplitude=1.0, speed=0.8, seed=0):
    """A multi-sine excitation, periodic with period 1 / f0 (10 s):

        q_d,i(t) = c_i + sum_{l=1}^{L} a_il sin(2 pi l f0 t + phi_il),

    c_i the middle of joint i's range, phi_il ~ U(0, 2 pi), a_il = k_i r_il with r_il ~
    U(0.2, 1) / l and k_i the largest scale with max_t |q_d,i - c_i| <= min(fill x range,
    max_amplitude) and max_t |qd_d,i| <= speed x the URDF's velocity limit (maxima over a grid of
    one period, refined by a scalar search). Seeded (stream ``excitation``).

    Parameters
    ----------
    robot : models.RobotModel
        Read for n, q_lower, q_upper, joint_names and its URDF's velocity limits.
    harmonics : int
        L, >= 1.
    f0 : float
        Base frequency (Hz), > 0.
    fill : float
        Largest excursion as a fraction of the joint range, in (0, 0.5].
    max_amplitude : float
        Largest excursion (rad), > 0.
    speed : float
        Fraction of the velocity limit, > 0.
    seed : int

    Returns
    -------
    callable
        t -> (q_d, qd_d, qdd_d).
    """
    if not (isinstance(harmonics, (int, np.integer)) and harmonics >= 1):
        raise ValueError(f"harmonics must be an integer >= 1, got {harmonics!r}")
    for name, v in (("f0", f0), ("max_amplitude", max_amplitude), ("speed", speed)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive number, got {v!r}")
    if not (np.isfinite(fill) and 0 < fill <= 0.5):
        raise ValueError(f"fill must be in (0, 0.5], got {fill!r}")
    c, A, vmax = _amplitude_and_speed(robot, fill, max_amplitude, speed)
    rng = _rng(seed, "excitation")
    ell = np.arange(1, harmonics + 1)
    w = 2 * np.pi * f0 * ell                                        # (L,)
    r = rng.uniform(0.2, 1.0, (robot.n, harmonics)) / ell
    phi = rng.uniform(0, 2 * np.pi, (robot.n, harmonics))
    s = np.array([_peak(lambda t, i=i: np.sin(np.multiply.outer(t, w) + phi[i]) @ r[i], 1 / f0)
                  for i in range(robot.n)])
    sd = np.array([_peak(lambda t, i=i: np.cos(np.multiply.outer(t, w) + phi[i]) @ (r[i] * w), 1 / f0)
                   for i in range(robot.n)])
    a = np.minimum(A / s, vmax / sd)[:, None] * r

    def reference(t):
        x = w * t + phi
        sn, cs = np.sin(x), np.cos(x)
        return c + (a * sn).sum(1), (a * w * cs).sum(1), -(a * w * w * sn).sum(1)
    return reference


def point_to_point(robot, moves=4, move=3.0, dwell=2.0, fill=0.3, max_amplitude=1.0, speed=0.8, seed=0):
    """A task: ``moves`` minimum-jerk moves between seeded via points, each followed by a rest,

        q_d(t) = w_j + (w_j+1 - w_j) s(tau / move),  s(x) = 10 x^3 - 15 x^4 + 6 x^5,

    tau the time into move j (then ``dwell`` s at w_j+1; after the last rest, at rest). w_0 is
    the middle of the ranges, w_j = w_0 + U(-1, 1) min(fill x range, max_amplitude), each step
    shortened so the peak speed 1.875 |w_j+1 - w_j| / move stays <= speed x the URDF's velocity
    limit. Length moves x (move + dwell) (20 s). Seeded (stream ``task``).

    Parameters
    ----------
    robot : models.RobotModel
        Read for n, q_lower, q_upper, joint_names and its URDF's velocity limits.
    moves : int
        Number of moves, >= 1.
    move, dwell : float
        Duration of a move (> 0) and of the rest after it (>= 0) (s).
    fill, max_amplitude, speed : float
        As in ``fourier_excitation``.
    seed : int

    Returns
    -------
    callable
        t -> (q_d, qd_d, qdd_d).
    """
    if not (isinstance(moves, (int, np.integer)) and moves >= 1):
        raise ValueError(f"moves must be an integer >= 1, got {moves!r}")
    if not (np.isfinite(move) and move > 0 and np.isfinite(dwell) and dwell >= 0):
        raise ValueError(f"move must be > 0 and dwell >= 0 seconds, got {move!r}, {dwell!r}")
    if not (np.isfinite(fill) and 0 < fill <= 0.5):
        raise ValueError(f"fill must be in (0, 0.5], got {fill!r}")
    c, A, vmax = _amplitude_and_speed(robot, fill, max_amplitude, speed)
    rng = _rng(seed, "task")
    W = [c]
    for _ in range(moves):
        target = c + rng.uniform(-1, 1, robot.n) * A
        step = np.clip(target - W[-1], -vmax * move / 1.875, vmax * move / 1.875)
        W.append(W[-1] + step)
    W = np.array(W)
    period = move + dwell

    def reference(t):
        j = min(int(t // period), moves)
        x = 1.0 if j == moves else min((t - j * period) / move, 1.0)
        j = min(j, moves - 1)
        d = W[j + 1] - W[j]
        s = x ** 3 * (10 - 15 * x + 6 * x * x)
        sd = 30 * x * x * (1 - x) ** 2 / move
        sdd = 60 * x * (1 - x) * (1 - 2 * x) / move ** 2
        return W[j] + d * s, d * sd, d * sdd
    return reference


def drifts_and_bursts(robot, T=20.0, bursts=None, burst_duration=(0.2, 0.5), burst_speed=(0.5, 0.7),
                      burst_acceleration=5.0, drift=0.25, drift_speed=0.1, drift_frequency=(0.02, 0.1), fill=0.3, max_amplitude=1.0,
                      seed=0):
    """A task of slow drifts with fast bursts: every joint drifts slowly, and a few times a few
    joints make a short, fast minimum-jerk move to a new level,

        q_d,i(t) = c_i + sum_{l=1}^{3} a_il (1 - cos(2 pi f_il t)) + b_i(t),

    c_i the middle of joint i's range, f_il ~ U(drift_frequency) (Hz), a_il = k_i r_il (+-1),
    r_il ~ U(0.5, 1), k_i the largest scale with 2 sum_l |a_il| <= drift x A_i and sum_l |a_il|
    2 pi f_il <= drift_speed x v_i (A_i = min(fill x range, max_amplitude), v_i the URDF's
    velocity limit, 1 rad/s where it gives none). b_i is piecewise constant but for ``bursts``
    moves: burst j starts at a seeded instant in its slot (the slots split [t_a, T - t_b], t_a =
    min(1, T / 10), t_b = min(0.5, T / 20), in ``bursts`` equal parts) and moves m_j ~ U{1, ..,
    ceil(n / 2)} seeded joints by

        b_i(t) = b_i,j + Delta_ij s((t - t_j) / D_j),   s(x) = 10 x^3 - 15 x^4 + 6 x^5,

    |Delta_ij| = u_ij v_i D_j / 1.875 (peak speed u_ij x v_i, u_ij ~ U(burst_speed)), its sign
    drawn among those that keep |b_i| <= (1 - drift) A_i (the step shortened to reach that bound
    when neither does). Its duration D_j ~ U(burst_duration) is lengthened (up to the slot) until
    the peak acceleration (10 / sqrt 3) |Delta_ij| / D_j^2 = 3.08 u_ij v_i / D_j is at most
    ``burst_acceleration`` x v_i for every joint it moves (u_ij lowered where the slot is too
    short): a real arm's joints have an acceleration, not only a speed, limit (ur5's shoulder at
    22 rad/s^2 with the 1 kg payload needed 159 N m of its 150). So |q_d - c| <= A, |qd_d| <=
    (drift_speed + burst_speed high) x v, and at t = 0 the task is at rest (qd_d = 0) at c.
    Seeded (stream ``bursts``).

    Parameters
    ----------
    robot : models.RobotModel
        Read for n, q_lower, q_upper, joint_names and its URDF's velocity limits.
    T : float
        Length (s), long enough for the bursts: each slot >= burst_duration high.
    bursts : int, optional
        Number of bursts, >= 0; default round(0.3 T) (6 in 20 s), fewer if they do not fit.
    burst_duration : (float, float)
        Range of a burst's duration (s), 0 < low <= high.
    burst_speed : (float, float)
        Range of a burst's peak speed, fractions of the velocity limit, 0 < low <= high.
    burst_acceleration : float
        Largest peak acceleration of a burst, a multiple of the velocity limit (1/s), > 0.
    drift : float
        The drifts' share of the excursion A, in (0, 1).
    drift_speed : float
        The drifts' largest speed, a fraction of the velocity limit, > 0, with drift_speed +
        burst_speed high <= 1.
    drift_frequency : (float, float)
        Range of the drifts' frequencies (Hz), 0 < low <= high.
    fill, max_amplitude : float
        As in ``fourier_excitation`` (A above).
    seed : int
        Seed of the drifts and bursts.

    Returns
    -------
    callable
        t -> (q_d, qd_d, qdd_d), the task.
    """
    if not (bursts is None or isinstance(bursts, (int, np.integer)) and bursts >= 0):
        raise ValueError(f"bursts must be an integer >= 0, got {bursts!r}")
    if not (np.isfinite(T) and T > 0):
        raise ValueError(f"T must be a positive number of seconds, got {T!r}")
    (d_lo, d_hi), (u_lo, u_hi), (f_lo, f_hi) = (
        _check_range(name, r) for name, r in (("burst_duration", burst_duration), ("burst_speed", burst_speed),
                                              ("drift_frequency", drift_frequency)))
    if not (d_lo > 0 and u_lo > 0 and f_lo > 0):
        raise ValueError(f"burst_duration, burst_speed and drift_frequency must be positive ranges, got "
                         f"{burst_duration!r}, {burst_speed!r}, {drift_frequency!r}")
    if not (np.isfinite(burst_acceleration) and burst_acceleration > 0):
        raise ValueError(f"burst_acceleration must be a positive number (1/s), got {burst_acceleration!r}")
    if not (np.isfinite(drift) and 0 < drift < 1):
        raise ValueError(f"drift must be in (0, 1), got {drift!r}")
    if not (np.isfinite(drift_speed) and drift_speed > 0 and drift_speed + u_hi <= 1):
        raise ValueError(f"drift_speed must be > 0 with drift_speed + burst_speed high <= 1, got "
                         f"{drift_speed!r} + {u_hi!r}")
    if not (np.isfinite(fill) and 0 < fill <= 0.5):
        raise ValueError(f"fill must be in (0, 0.5], got {fill!r}")
    if not (np.isfinite(max_amplitude) and max_amplitude > 0):
        raise ValueError(f"max_amplitude must be a positive number, got {max_amplitude!r}")
    t_a, t_b = min(1.0, T / 10), min(0.5, T / 20)
    if bursts is None:
        bursts = max(0, min(round(0.3 * T), int((T - t_a - t_b) // d_hi)))
    slot = (T - t_a - t_b) / max(bursts, 1)
    if bursts and slot < d_hi:
        raise ValueError(f"T: {T:g} s has no room for {bursts} bursts of up to {d_hi:g} s (slots of {slot:g} s)")
    n = robot.n
    lo, hi = np.asarray(robot.q_lower, dtype=float), np.asarray(robot.q_upper, dtype=float)
    v = _urdf_velocity(robot)
    c, A, v = 0.5 * (lo + hi), np.minimum(fill * (hi - lo), max_amplitude), np.where(np.isfinite(v) & (v > 0), v, 1.0)
    rng = _rng(seed, "bursts")
    w = 2 * np.pi * rng.uniform(f_lo, f_hi, (n, 3))
    a = rng.uniform(0.5, 1.0, (n, 3)) * _sign(rng, 3 * n).reshape(n, 3)
    k = np.minimum(drift * A / (2 * np.abs(a).sum(1)), drift_speed * v / (np.abs(a) * w).sum(1))
    a = k[:, None] * a
    B = (1 - drift) * A
    starts, durations, steps, levels = [], [], [], [np.zeros(n)]
    for j in range(bursts):
        D, place = rng.uniform(d_lo, d_hi), rng.random()
        joints = rng.permutation(n)[:rng.integers(1, (n + 1) // 2 + 1)]
        u, coin = rng.uniform(u_lo, u_hi, n), rng.random(n)
        peak = 10 / np.sqrt(3) / 1.875                   # peak acceleration / (u v / D) of s(x)
        D = min(max(D, peak * u[joints].max() / burst_acceleration), slot)
        u = np.minimum(u, burst_acceleration * D / peak)
        start = t_a + j * slot + place * (slot - D)
        b, step = levels[-1], np.zeros(n)
        for i in joints:
            size = u[i] * v[i] * D / 1.875
            fits = [sg for sg in (1.0, -1.0) if abs(b[i] + sg * size) <= B[i]]
            if fits:
                step[i] = (fits[0] if len(fits) == 1 or coin[i] < 0.5 else fits[1]) * size
            else:                                       # as far as the bound on the other side
                step[i] = -np.sign(b[i]) * B[i] - b[i]
        starts.append(start)
        durations.append(D)
        steps.append(step)
        levels.append(b + step)
    starts = np.array(starts)

    def reference(t):
        x = w * t
        q = c + (a * (1 - np.cos(x))).sum(1)
        qd = (a * w * np.sin(x)).sum(1)
        qdd = (a * w * w * np.cos(x)).sum(1)
        j = int(np.searchsorted(starts, t, side="right")) - 1
        if j < 0:
            return q, qd, qdd
        D, d = durations[j], steps[j]
        y = min((t - starts[j]) / D, 1.0)
        s = y ** 3 * (10 - 15 * y + 6 * y * y)
        sd = 30 * y * y * (1 - y) ** 2 / D
        sdd = 60 * y * (1 - y) * (1 - 2 * y) / D ** 2
        return q + levels[j] + d * s, qd + d * sd, qdd + d * sdd
    return reference
