"""Dynamic identification of a URDF robot from a log of q and tau, and the trajectory to log.

The model, per sample (n joints, one body per joint)::

    tau = Y(q, qd, qdd) pi + diag(qd) f_v + diag(tanh(qd / w)) f_c + f_o            (1)

``Y`` is pinocchio's joint torque regressor on the URDF's model with the locked joints removed,
``pi`` the 10 inertial parameters of each body (about the joint frame's origin), ``f_v, f_c, f_o``
viscous, Coulomb and constant friction, ``w`` the Coulomb smoothing width (rad/s).

One concern a module: ``parametrisation`` (pseudo-inertia, log-Cholesky, URDF <inertial>),
``regressor`` (the pinocchio arm, base parameters), ``fit`` (:func:`identify`), ``report`` (the
report dict and text), ``result`` (:class:`Identification`, its URDF and files), ``excitation``
(:func:`excitation`, :class:`Excitation`).
"""
from .excitation import Excitation, _Design, excitation
from .fit import (BAND_MARGIN, CHUNK, DEFAULT_PRIOR, DEFAULT_TEST_FRACTION,
                  DEFAULT_V_STICK, FIT_RATE, FTOL, MAX_NFEV, WIDE, WIDTHS, IdentificationError,
                  identification_cutoff, identify, lowpass)
from .parametrisation import (from_log_cholesky, inertial_to_urdf, log_cholesky, pseudo_inertia,
                              urdf_to_inertial)
from .regressor import DEFAULT_COULOMB_WIDTH, FRICTION, INERTIAL, STRUCTURAL_TOL, _Arm, base_parameters
from .report import report_text
from .result import Identification

__all__ = ["BAND_MARGIN", "CHUNK", "DEFAULT_COULOMB_WIDTH", "DEFAULT_PRIOR",
           "DEFAULT_TEST_FRACTION", "DEFAULT_V_STICK", "FIT_RATE", "FRICTION", "FTOL", "INERTIAL",
           "MAX_NFEV", "STRUCTURAL_TOL", "WIDE", "WIDTHS", "Excitation", "Identification",
           "IdentificationError", "base_parameters", "excitation", "from_log_cholesky",
           "identification_cutoff", "identify", "inertial_to_urdf", "log_cholesky", "lowpass",
           "pseudo_inertia", "report_text", "urdf_to_inertial", "_Arm", "_Design"]
