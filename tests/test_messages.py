"""Every bad argument gets an error naming it: one table, one row per case."""
import math

import numpy as np
import pytest

from codegen import compile_observer
from codegen.families import observers
from codegen.pipeline.emit import with_params
from codegen.core.target import Target
from conftest import ROOT
from models import load_robot
from models.robot import ModelError
from urdf_chain import Joint, Link, revolute_chain, write_chain

TWO_LINK = ROOT / "tests" / "data" / "two_link.urdf"
Z2 = [0.0, 0.0]


def _urdf_with(tmp_path, **joint2):
    """A two-joint chain whose second joint has the given attributes (axis, origin, rpy)."""
    joints = revolute_chain(["j1"]) + [Joint("j2", "revolute", Link("l1"), **joint2)]
    return write_chain(tmp_path / "bad.urdf", joints)


def _set(obj, attr, value):
    setattr(obj, attr, value)


# (case, call(obs, spec, tmp_path), exception, regex naming the argument)
CASES = [
    ("y a string", lambda o, s, t: o.step("ab", Z2), ValueError, r"^y: expected 2 real numbers, got str"),
    ("y complex", lambda o, s, t: o.step([1j, 0.0], Z2), ValueError, r"^y: .*complex"),
    ("y complex array", lambda o, s, t: o.step(np.array([1 + 1j, 0]), Z2), ValueError, r"^y: .*complex"),
    ("y a dict", lambda o, s, t: o.step({"a": 1}, Z2), ValueError, r"^y: expected 2 real numbers, got dict"),
    ("y 10**400", lambda o, s, t: o.step([10**400, 0], Z2), ValueError, r"^y: .*too large"),
    ("u a string", lambda o, s, t: o.step(Z2, "ab"), ValueError, r"^u: "),
    ("Y a string", lambda o, s, t: o.run("abc", [Z2]), ValueError, r"^Y: "),
    ("Y 10**400", lambda o, s, t: o.run([[10**400, 0]], [Z2]), ValueError, r"^Y: .*too large"),
    ("U complex", lambda o, s, t: o.run([Z2], [[1j, 0]]), ValueError, r"^U: .*complex"),
    ("y0 a dict", lambda o, s, t: o.reset({"a": 1}), ValueError, r"^y0: "),
    ("est0 a string", lambda o, s, t: o.reset(Z2, est0="x"), ValueError, r"^est0: "),
    ("p a string", lambda o, s, t: _set(o, "params", "x"), ValueError, r"^p: "),
    ("x 10**400", lambda o, s, t: _set(o, "state", [10**400, 0]), ValueError, r"^x: .*too large"),
    ("rhs x a string", lambda o, s, t: o.rhs("x", Z2, Z2), ValueError, r"^x: "),
    ("dt inf", lambda o, s, t: compile_observer(s, dt=math.inf), ValueError, r"^dt must be"),
    ("dt a string", lambda o, s, t: s.target(dt="a"), ValueError, r"^dt must be"),
    ("gain inf", lambda o, s, t: observers.build("reduced_order", s.robot, k0=math.inf),
     ValueError, r"^k0: .*finite"),
    ("gain 10**400", lambda o, s, t: observers.build("reduced_order", s.robot, k0=10**400),
     ValueError, r"^k0: .*too large"),
    ("gain complex", lambda o, s, t: observers.build("reduced_order", s.robot, k0=1j),
     ValueError, r"^k0: .*complex"),
    ("gain array with nan", lambda o, s, t: observers.build("reduced_order", s.robot, k0=[1.0, math.nan]),
     ValueError, r"^k0\[1\]: .*finite"),
    ("param a string", lambda o, s, t: with_params(s, {"k0": "abc"}), ValueError, r"^params\['k0'\]: "),
    ("param inf", lambda o, s, t: Target(robot={}, family="reduced_order", params={"k0": math.inf}),
     ValueError, r"^params"),
    ("default parameter inf", lambda o, s, t: type(s)(**{**s.__dict__, "p_default": [math.inf]}),
     ValueError, r"parameter 'k0'.*inf"),
    ("locked_joints a list", lambda o, s, t: load_robot(urdf=TWO_LINK, locked_joints=["j2"]),
     ValueError, r"^locked_joints: expected a dict"),
    ("locked at nan", lambda o, s, t: load_robot(urdf=TWO_LINK, locked_joints={"j2": math.nan}),
     ValueError, r"^locked_joints\['j2'\]: .*finite"),
    ("locked at a string", lambda o, s, t: load_robot(urdf=TWO_LINK, locked_joints={"j2": "abc"}),
     ValueError, r"^locked_joints\['j2'\]: "),
    ("snap_tol a string", lambda o, s, t: load_robot(urdf=TWO_LINK, snap_tol="abc"),
     ValueError, r"^snap_tol: "),
    ("URDF path too long", lambda o, s, t: load_robot(urdf=t / ("a" * 260 + ".urdf")),
     FileNotFoundError, r"^URDF file .*aaaa.*: File name too long"),
    ("URDF path a folder", lambda o, s, t: load_robot(urdf=t), FileNotFoundError, r"^URDF file not found"),
    ("joint axis nan", lambda o, s, t: load_robot(urdf=_urdf_with(t, axis="0 nan 1")),
     ModelError, r"joint 'j2': <axis> xyz '0 nan 1'"),
    ("joint origin junk", lambda o, s, t: load_robot(urdf=_urdf_with(t, origin="0.3 0 abc")),
     ModelError, r"joint 'j2': <origin> xyz '0.3 0 abc'"),
    ("joint rpy short", lambda o, s, t: load_robot(urdf=_urdf_with(t, rpy="0 0")),
     ModelError, r"joint 'j2': <origin> rpy '0 0'"),
]


@pytest.mark.parametrize("case, call, error, words", CASES, ids=[c[0] for c in CASES])
def test_message_names_the_argument(case, call, error, words, compiled, spec_of, tmp_path):
    obs, spec = compiled("seed000_2r"), spec_of("seed000_2r")
    obs.reset(Z2)
    with pytest.raises(error, match=words):
        call(obs, spec, tmp_path)
