"""Robot names -> models.

| name             | what                                                        |
|------------------|-------------------------------------------------------------|
| seed000_2r       | planar 2R of seed 000 (Table I)                             |
| seed002_2r       | planar 2R of seed 002 (§V)                                  |
| seed003_2r_abs   | 2-link arm of seed 003, absolute angles (Table II)          |
| ur5              | Universal Robots UR5, example-robot-data URDF (6 DoF)       |
| panda            | Franka Panda, fingers locked at 0 (7 DoF), example-robot-data |
| ur3, ur10        | Universal Robots UR3 and UR10 (6 DoF), example-robot-data   |
| kinova           | Kinova JACO2 j2s6s200 (6 DoF; its two fingers and tips are  |
|                  | fixed joints in the URDF: nothing to lock)                  |
| xarm7            | UFACTORY xArm7 (7 DoF; the URDF has no gripper; friction    |
|                  | viscous 2..10 N m s/rad, Coulomb 1 N m, light wrist links)  |
| z1               | Unitree Z1 (6 DoF), gripper joint jointGripper locked at 0  |
| so100, so101     | SO-ARM100 / SO-101 (5 DoF), jaw joint gripper locked at 0   |
| seed004_2r       | planar 2R of seed 004 from its DH table (rigid part)        |
| seed004_3r       | spatial 3R elbow of seed 004 from its DH table (rigid part) |

The URDF arms are the ones example-robot-data ships (``models.urdf.example_robot_data_dir()``);
a gripper joint is locked (the observers estimate the arm, and a gripper's tiny inertia makes the
model stiff: codegen.discrete.stability names it when it does).

Elastic-joint robots (docs/papers/seed004.md §6): ``load_elastic(name)`` wraps a catalog robot with the motor
inertias J and stiffness K of ``ELASTIC`` (or given ones); e.g. ``load_elastic("seed004_2r")``.
"""
from __future__ import annotations

from models import closed_form, dh

_URDFS = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", {}),
    "panda": ("panda_description/urdf/panda.urdf",
              {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "ur3": ("ur_description/urdf/ur3_robot.urdf", {}),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", {}),
    "kinova": ("kinova_description/robots/kinova.urdf", {}),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", {}),
    "z1": ("z1_description/urdf/z1.urdf", {"jointGripper": 0.0}),
    "so100": ("so_arm_description/urdf/so100.urdf", {"gripper": 0.0}),
    "so101": ("so_arm_description/urdf/so101.urdf", {"gripper": 0.0}),
}
ARMS = ("ur3", "ur10", "kinova", "xarm7", "z1", "so100", "so101")   # the arms added with ur5 and panda
_CLOSED = {
    "seed000_2r": closed_form.seed000_2r,
    "seed002_2r": closed_form.seed002_2r,
    "seed003_2r_abs": closed_form.seed003_2r_abs,
    "seed004_2r": dh.seed004_2r,
    "seed004_3r": dh.seed004_3r,
}
# elastic-joint defaults (J, K): [S004 (2.3), Tables 1-2] A4-1, A4-2; ur5 values are an
# [ASSUMPTION] for the scale test (reflected motor inertia 1 kg m^2, K as in seed 004)
ELASTIC = {
    "seed004_2r": (37.5, 20000.0),
    "seed004_3r": (87.5, 20000.0),
    "ur5": (1.0, 20000.0),
}
_cache = {}


def names():
    """All catalog names."""
    return list(_CLOSED) + list(_URDFS)


def urdf_names():
    """The catalog names of robots read from a URDF (identification and excitation need one)."""
    return list(_URDFS)


def load_robot(name=None, *, urdf=None, locked_joints=None, **kwargs):
    """A RobotModel by catalog ``name``, or from the ``urdf`` file with ``locked_joints`` (joint
    name -> fixed value, rad or m); ``kwargs`` go to the catalog entry's constructor or ``load_urdf``.

    >>> load_robot("ur5")
    >>> load_robot(urdf="path.urdf", locked_joints={"panda_finger_joint1": 0.0})
    """
    if (name is None) == (urdf is None):
        raise ValueError("load_robot: give exactly one of a catalog name or urdf=path")
    if urdf is not None:
        from models.urdf import load_urdf
        return load_urdf(urdf, locked_joints=locked_joints, **kwargs)
    key = (name, tuple(sorted(kwargs.items())))
    if key not in _cache:
        if name in _CLOSED:
            _cache[key] = _CLOSED[name](**kwargs)
        elif name in _URDFS:
            from models.urdf import example_robot_data_dir, load_urdf
            rel, locked = _URDFS[name]
            _cache[key] = load_urdf(example_robot_data_dir() / rel, locked_joints=locked,
                                    name=name, **kwargs)
        else:
            raise KeyError(f"unknown robot {name!r}; catalog: {', '.join(names())}")
    return _cache[key]


def from_source(source):
    """The robot a ``RobotModel.source`` dict describes (the inverse of ``robot.source``).

    Parameters
    ----------
    source : dict
        ``{"kind": "catalog", "name": <catalog name>, "params": {...}}`` (portable: what a
        targets file records), or ``{"kind": "closed_form" | "urdf" | "dh" | "elastic", ...}``
        as recorded in a target's metadata. A catalog robot's own source gives the (cached)
        catalog robot. A "friction" entry (``RobotModel.source``) sets the friction; a URDF
        source with a "sha256" (recorded) does not read the friction side file again, one
        without (a targets file's) reads it as ``load_urdf`` does.

    Returns
    -------
    RobotModel or ElasticRobot
    """
    if not isinstance(source, dict) or "kind" not in source:
        raise ValueError(f"robot source must be a dict with a 'kind', got {source!r}")
    kind, name = source["kind"], source.get("name")
    if kind == "catalog":
        return load_robot(name, **source.get("params", {}))
    if name in names() and load_robot(name).source == source:
        return load_robot(name)
    if kind == "elastic":
        from models.elastic import ElasticRobot
        rigid = from_source(source["rigid"])
        if name == f"{rigid.name}_elastic" and rigid.name in ELASTIC:
            cached = load_elastic(rigid.name, J=source["J"], K=source["K"])
            if cached.source == dict(source, rigid=rigid.source):
                return cached
        return ElasticRobot(rigid, source["J"], source["K"], name=name)
    if kind == "urdf":
        # a recorded source (robot.source: it pins the URDF by its sha256) holds the friction
        # side file's values in its "friction" entry; a portable one (a targets file's: no sha256)
        # reads the side file as load_urdf does
        from models.urdf import load_urdf
        robot = load_urdf(source["path"], locked_joints=source.get("locked_joints") or None,
                          name=name, snap_tol=source.get("snap_tol", 1e-9),
                          friction_file=None if "sha256" in source else "auto")
    elif kind == "dh":
        robot = dh.DHRobot(name, source["dh"], source["masses"], source["coms"], source["inertias"],
                           source["gravity"], F=source.get("F"))
    elif kind == "closed_form":
        cls = {"planar_2r": closed_form.Planar2R, "absolute_2r": closed_form.Absolute2R}[source["model"]]
        robot = cls(name, **source["params"])
    else:
        raise ValueError(f"unknown robot source kind {kind!r} (catalog, closed_form, urdf, dh, elastic)")
    return _with_source_friction(robot, source.get("friction"))


_FRICTION_ENTRY = ("viscous", "coulomb", "offset", "coulomb_width")


def _with_source_friction(robot, entry):
    """``robot`` with the friction of a source's "friction" entry (RobotModel.source) applied
    (the URDF side file is not read again: the entry holds its values)."""
    if entry is None:
        return robot
    if not isinstance(entry, dict) or any(k not in _FRICTION_ENTRY for k in entry):
        raise ValueError(f"robot source: 'friction' must be a dict with keys among "
                         f"{', '.join(_FRICTION_ENTRY)}, got {entry!r}")
    return robot.with_friction(viscous=entry.get("viscous"), coulomb=entry.get("coulomb"),
                               offset=entry.get("offset"), width=entry.get("coulomb_width"))


def load_elastic(name, J=None, K=None):
    """ElasticRobot (docs/papers/seed004.md §6) on catalog robot ``name``; J, K default to ``ELASTIC[name]``."""
    from models.elastic import ElasticRobot
    if (J is None or K is None) and name not in ELASTIC:
        raise KeyError(f"no default J, K for {name!r}; give J= and K= (defaults for: {', '.join(ELASTIC)})")
    J0, K0 = ELASTIC.get(name, (None, None))
    key = ("elastic", name, repr(J if J is not None else J0), repr(K if K is not None else K0))
    if key not in _cache:
        _cache[key] = ElasticRobot(load_robot(name), J if J is not None else J0, K if K is not None else K0)
    return _cache[key]
