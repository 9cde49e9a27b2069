"""Serial-chain URDFs written from plain data, for the tests that need many small robots
(name collisions, bad inertial values, the property test over random URDFs)."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


@dataclass
class Link:
    """One link: name and <inertial> values as strings (written verbatim), None: no <inertial>."""
    name: str
    mass: str | None = "1.0"
    com: str = "0.1 0 0"
    inertia: dict = field(default_factory=lambda: {"ixx": "0.01", "ixy": "0", "ixz": "0",
                                                   "iyy": "0.01", "iyz": "0", "izz": "0.01"})


@dataclass
class Joint:
    """One joint moving ``child`` (a Link) relative to the previous link of the chain."""
    name: str
    type: str
    child: Link
    axis: str = "0 1 0"
    origin: str = "0.3 0 0"
    rpy: str = "0 0 0"


def chain_urdf(joints, base="base", robot="chain"):
    """The URDF text of base -joints[0]- joints[0].child -joints[1]- ... (a serial chain)."""
    root = ET.Element("robot", name=robot)
    ET.SubElement(root, "link", name=base)
    parent = base
    for j in joints:
        e = ET.SubElement(root, "joint", name=j.name, type=j.type)
        ET.SubElement(e, "parent", link=parent)
        ET.SubElement(e, "child", link=j.child.name)
        ET.SubElement(e, "origin", xyz=j.origin, rpy=j.rpy)
        if j.type != "fixed":
            ET.SubElement(e, "axis", xyz=j.axis)
        if j.type in ("revolute", "prismatic"):
            ET.SubElement(e, "limit", lower="-1", upper="1", effort="10", velocity="2")
        link = ET.SubElement(root, "link", name=j.child.name)
        if j.child.mass is not None:
            inertial = ET.SubElement(link, "inertial")
            ET.SubElement(inertial, "origin", xyz=j.child.com)
            ET.SubElement(inertial, "mass", value=j.child.mass)
            ET.SubElement(inertial, "inertia", **j.child.inertia)
        parent = j.child.name
    return ET.tostring(root, encoding="unicode")


def write_chain(path, joints, **kwargs):
    """Write ``chain_urdf(joints)`` to ``path`` (UTF-8) and return the path."""
    path.write_text('<?xml version="1.0" encoding="utf-8"?>\n' + chain_urdf(joints, **kwargs),
                    encoding="utf-8")
    return path


def revolute_chain(names, links=None, types=None):
    """Joints ``names`` (revolute unless ``types`` says otherwise) moving links ``links``
    (default l0, l1, ...), each with the default inertial."""
    links = links or [f"l{i}" for i in range(len(names))]
    types = types or ["revolute"] * len(names)
    return [Joint(n, t, Link(ln)) for n, ln, t in zip(names, links, types)]
