"""The identified model (:class:`Identification`): its parameters, the URDF with the identified
<inertial>s and <dynamics>, the friction side file, and the files written for the commands."""
from __future__ import annotations

import copy
import io
import json
import os
import shutil
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .parametrisation import inertial_to_urdf
from .regressor import FRICTION
from .report import _jsonable, report_text, summary_text


class Identification:
    """The identified model of a robot and how well the log determines it.

    Attributes
    ----------
    x : (13 n,) array
        Parameters of (1): 10 per body (about the joint frame), then f_v, f_c, f_o.
    std : (13 n,) array
        Their standard deviation from data and prior (linearised weighted least squares).
    report : dict
        Everything of ``text`` as JSON-able data.
    text : str
        A readable report.
    """

    def __init__(self, arm, x, report):
        self.arm, self.x, self.report = arm, x, report
        self.std = np.array([p["std"] for p in report["parameters"]])

    @property
    def friction(self):
        """{"viscous", "coulomb", "offset"} -> (n,) array of the identified friction."""
        return dict(zip(FRICTION, (np.array(v) for v in self.arm.friction_value(self.x))))

    @property
    def text(self):
        """The readable report (:func:`report_text`)."""
        return report_text(self.report)

    @property
    def summary(self):
        """Its first screen (:func:`summary_text`): the residual and the friction per joint."""
        return summary_text(self.report)

    def urdf(self):
        """The original URDF text with each primary link's identified <inertial> (mass, origin
        xyz = centre of mass, inertia about it) and <dynamics damping=f_v friction=f_c> on each
        identified joint; locked joints and everything else as they were."""
        arm, n = self.arm, self.arm.n
        tree = copy.deepcopy(arm.tree)
        root = tree.getroot()
        links = {e.get("name"): e for e in root.findall("link")}
        joints = {e.get("name"): e for e in root.findall("joint")}
        fv, fc, _ = arm.friction_value(self.x)
        num = lambda v: repr(float(v))  # noqa: E731  (shortest round-trip decimal)
        for i in range(n):
            pi = self.x[10 * i:10 * i + 10] - arm.attached[10 * i:10 * i + 10]
            m, c, Ic = inertial_to_urdf(pi)
            link = links[arm.links[i]]
            old = link.find("inertial")
            pos = list(link).index(old) if old is not None else 0
            if old is not None:
                link.remove(old)
            e = ET.Element("inertial")
            e.text, e.tail = "\n      ", (old.tail if old is not None else "\n    ")
            ET.SubElement(e, "origin", xyz=" ".join(num(v) for v in c), rpy="0 0 0").tail = "\n      "
            ET.SubElement(e, "mass", value=num(m)).tail = "\n      "
            ET.SubElement(e, "inertia", ixx=num(Ic[0, 0]), ixy=num(Ic[0, 1]), ixz=num(Ic[0, 2]),
                          iyy=num(Ic[1, 1]), iyz=num(Ic[1, 2]), izz=num(Ic[2, 2])).tail = "\n    "
            link.insert(pos, e)
            j = joints[arm.joint_names[i]]
            dyn = j.find("dynamics")
            if dyn is None:
                last = list(j)[-1] if len(j) else None
                dyn = ET.SubElement(j, "dynamics")
                if last is not None:                       # indented like its siblings
                    dyn.tail, last.tail = last.tail, (last.tail or "") + "  "
            dyn.set("damping", num(fv[i]))
            dyn.set("friction", num(fc[i]))
        note = ET.Comment(f" <inertial> of {', '.join(arm.links)} and <dynamics> of {', '.join(arm.joint_names)} "
                          f"identified by observer-codegen (codegen.logs.identify); Coulomb width and "
                          f"offsets in {arm.name}_identified.friction.json ".replace("--", "- -"))
        note.tail = root.text
        root.insert(0, note)
        buf = io.BytesIO()
        ET.ElementTree(root).write(buf, encoding="utf-8", xml_declaration=True)
        return buf.getvalue().decode("utf-8") + "\n"

    def friction_file(self):
        """The side file of what URDF has no tag for (dict): ``{"format": "observer-codegen
        friction 1", "coulomb_width": w, "offset": {joint: f_o}}`` (models.urdf reads it beside
        the URDF)."""
        from models.urdf import FRICTION_FORMAT
        _, _, fo = self.arm.friction_value(self.x)
        return {"format": FRICTION_FORMAT, "coulomb_width": self.arm.width,
                "offset": {j: float(v) for j, v in zip(self.arm.joint_names, fo)}}

    def write(self, out):
        """Write ``out/<robot>_identified.urdf``, ``out/<robot>_identified.friction.json``,
        ``out/report.json`` and ``out/report.txt`` (staged in a temporary folder there; the URDF is
        checked first: pinocchio parses it back to the identified bodies, and it loads as every
        command loads a URDF).

        Parameters
        ----------
        out : path of the folder (created)

        Returns
        -------
        dict
            kind ("urdf", "friction", "report_json", "report_txt") -> Path.
        """
        arm = self.arm
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"urdf": out / f"{arm.name}_identified.urdf",
                 "friction": out / f"{arm.name}_identified.friction.json",
                 "report_json": out / "report.json", "report_txt": out / "report.txt"}
        report = dict(self.report, files={k: str(v) for k, v in paths.items()})
        texts = {"urdf": self.urdf(), "friction": json.dumps(self.friction_file(), indent=2) + "\n",
                 "report_json": json.dumps(_jsonable(report), indent=2) + "\n",
                 "report_txt": report_text(report)}
        stage = Path(tempfile.mkdtemp(prefix=".identify-", dir=out))
        tmp = {k: stage / p.name for k, p in paths.items()}
        try:
            for k, p in tmp.items():
                p.write_text(texts[k])
            self._check_urdf(tmp["urdf"])
            self._check_loads(tmp["urdf"])
            for k, p in tmp.items():
                os.replace(p, paths[k])
        finally:
            shutil.rmtree(stage, ignore_errors=True)
        self.report = report
        return paths

    def _check_loads(self, path):
        """The written URDF (with its side file beside it) loads as every command loads a URDF
        (``models.load_robot(urdf=..., locked_joints=...)``, default snapping), to the identified
        masses and friction."""
        from models import load_robot
        arm = self.arm
        try:
            robot = load_robot(urdf=path, locked_joints=arm.locked or None)
        except Exception as e:
            raise RuntimeError(f"{path}: the identified URDF does not load: {e}") from e
        fv, fc, fo = arm.friction_value(self.x)
        masses = [float(v) for v in robot.masses]
        want = [float(self.x[10 * i]) for i in range(arm.n)]
        if not (np.allclose(masses, want, rtol=1e-6) and np.allclose(robot.viscous, fv)
                and np.allclose(robot.coulomb, fc) and np.allclose(robot.offset, fo)
                and robot.coulomb_width == arm.width):
            raise RuntimeError(f"{path}: the identified URDF loads to other masses or friction than identified")

    def _check_urdf(self, path):
        """The written URDF, reduced like the robot, gives the identified bodies and friction."""
        from codegen.reference.robots.urdf import UrdfRobot
        arm = self.arm
        model = UrdfRobot(path, None, arm.locked, arm.snap_tol).model
        pi = np.concatenate([model.inertias[i].toDynamicParameters() for i in range(1, arm.n + 1)])
        # the robot's model snapped URDF round-off (|x| < snap_tol -> 0) in the other links' values
        err = np.abs(pi - self.x[:10 * arm.n]) / (1e-9 * arm.scale[:10 * arm.n] + 10 * arm.snap_tol)
        fv, fc, _ = arm.friction_value(self.x)
        if err.max() > 1 or not (np.allclose(model.damping, fv) and np.allclose(model.friction, fc)):
            raise RuntimeError(f"{path}: the written URDF does not reproduce the identified model "
                               f"(largest parameter error {err.max():.3g} x its tolerance)")
