"""Joint friction of the reference robots, written from its equation (numpy only):

    tau_f(v) = F v + coulomb tanh(v / w) + offset                (per joint)
    d tau_f / dv = F + diag(coulomb (1 - tanh(v / w)^2) / w)

F is the (n, n) viscous matrix of [S000 (1)], ``coulomb`` (n,) the Coulomb levels, w the width of
the smooth sign (rad/s) and ``offset`` (n,) a constant torque (N m). The values come from the
robot's description (closed-form and DH "F", the URDF's damping and friction through pinocchio)
and a source's optional ``"friction"`` entry ({"viscous", "coulomb", "offset": (n,) each,
"coulomb_width"}), which replaces them. The functions take floats and hyper-duals alike
(reference/hyperdual.py), so the exact derivatives of the DH robots carry the friction too.
"""
from __future__ import annotations

import math

import numpy as np

from .hyperdual import HyperDual, tanh

FRICTION_KEYS = ("viscous", "coulomb", "offset", "coulomb_width")


class Friction:
    """The friction of a reference robot (module docstring); a robot sets ``n`` and ``F``.

    Attributes
    ----------
    F : (n, n) array
        Viscous friction, N m s/rad.
    coulomb : (n,) array or None
        Coulomb levels, N m (None: none).
    offset : (n,) array or None
        Constant torques, N m (None: none).
    coulomb_width : float or None
        Width w of tanh(v / w), rad/s (needed when some Coulomb level is not zero).
    """

    coulomb = None
    offset = None
    coulomb_width = None

    def set_friction(self, entry):
        """Apply a source's ``"friction"`` entry (None: nothing).

        Parameters
        ----------
        entry : dict or None
            {"viscous": (n,) N m s/rad, "coulomb": (n,) N m, "offset": (n,) N m,
            "coulomb_width": rad/s}, each optional; a key given replaces the description's value.
        """
        if entry is not None:
            if not isinstance(entry, dict) or any(k not in FRICTION_KEYS for k in entry):
                raise ValueError(f"robot source: 'friction' must be a dict with keys among "
                                 f"{', '.join(FRICTION_KEYS)}, got {entry!r}")
            vec = {k: np.asarray(entry[k], dtype=float).reshape(self.n) for k in FRICTION_KEYS[:3]
                   if k in entry}
            if "viscous" in vec:
                self.F = np.diag(vec["viscous"])
            if "coulomb" in vec:
                self.coulomb = vec["coulomb"]
            if "offset" in vec:
                self.offset = vec["offset"]
            if "coulomb_width" in entry:
                self.coulomb_width = float(entry["coulomb_width"])
        if self.coulomb is not None and np.any(self.coulomb != 0.0):
            w = self.coulomb_width
            if w is None or not (math.isfinite(w) and w > 0.0):
                raise ValueError(f"robot {getattr(self, 'name', '?')!r}: Coulomb friction "
                                 f"{self.coulomb.tolist()} needs a positive 'coulomb_width' in the "
                                 f"source's 'friction' entry, got {w!r}")

    def _coulomb_on(self):
        return self.coulomb is not None and np.any(self.coulomb != 0.0)

    def friction_torque(self, v):
        """tau_f(v) = F v + coulomb tanh(v / w) + offset (n,), N m, at joint velocities ``v`` (n,),
        rad/s (floats or a hyper-dual)."""
        tau = self.F @ v
        if self._coulomb_on():
            tau = tau + self.coulomb * tanh(v * (1.0 / self.coulomb_width))
        if self.offset is not None and np.any(self.offset != 0.0):
            tau = tau + self.offset
        return tau

    def friction_jacobian(self, v):
        """d tau_f / dv = F + diag(coulomb (1 - tanh(v / w)^2) / w) (n, n), N m s/rad, at joint
        velocities ``v`` (n,), rad/s (floats)."""
        J = np.array(self.F, dtype=float)
        if self._coulomb_on():
            v = v.a if isinstance(v, HyperDual) else np.asarray(v, dtype=float)
            w = self.coulomb_width
            J = J + np.diag(self.coulomb * (1.0 - np.tanh(v / w) ** 2) / w)
        return J
