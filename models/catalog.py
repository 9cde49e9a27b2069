"""Robot names -> models.

| name             | what                                                        |
|------------------|-------------------------------------------------------------|
| seed000_2r       | planar 2R of seed 000 (Table I)                             |
| seed002_2r       | planar 2R of seed 002 (§V)                                  |
| seed003_2r_abs   | 2-link arm of seed 003, absolute angles (Table II)          |
| ur5              | Universal Robots UR5, example-robot-data URDF (6 DoF)       |
| panda            | Franka Panda, fingers locked at 0 (7 DoF), example-robot-data |
"""
from __future__ import annotations

from . import closed_form

_URDFS = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", {}),
    "panda": ("panda_description/urdf/panda.urdf",
              {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
}
_CLOSED = {
    "seed000_2r": closed_form.seed000_2r,
    "seed002_2r": closed_form.seed002_2r,
    "seed003_2r_abs": closed_form.seed003_2r_abs,
}
_cache = {}


def names():
    """All catalog names."""
    return list(_CLOSED) + list(_URDFS)


def load_robot(name=None, *, urdf=None, locked_joints=None, **kwargs):
    """A RobotModel by catalog name, or from a URDF file.

    >>> load_robot("ur5")
    >>> load_robot(urdf="path.urdf", locked_joints={"panda_finger_joint1": 0.0})
    """
    if (name is None) == (urdf is None):
        raise ValueError("load_robot: give exactly one of a catalog name or urdf=path")
    if urdf is not None:
        from .urdf import load_urdf
        return load_urdf(urdf, locked_joints=locked_joints, **kwargs)
    key = (name, tuple(sorted(kwargs.items())))
    if key not in _cache:
        if name in _CLOSED:
            _cache[key] = _CLOSED[name](**kwargs)
        elif name in _URDFS:
            from .urdf import example_robot_data_dir, load_urdf
            rel, locked = _URDFS[name]
            _cache[key] = load_urdf(example_robot_data_dir() / rel, locked_joints=locked,
                                    name=name, **kwargs)
        else:
            raise KeyError(f"unknown robot {name!r}; catalog: {', '.join(names())}")
    return _cache[key]
