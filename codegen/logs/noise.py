"""What a log's sensors and motion are, measured from the log: the positions' resolution and noise,
the motion's spectrum, and (with a model) the torque's residual.

Measured on the log's sample clock (codegen.logs.clock), per joint:

* **resolution** D: the lattice the positions sit on (every value q0 + k D to 1 % of D: an
  encoder's count, or the decimals the logger wrote), 0 when none (a simulation's doubles);
* **noise** sigma: the RMS of the leave-one-out residual of q against the cubic through its
  neighbours (codegen.logs.clock), sigma^2 = mean(r^2 / (1 + h)) with h the cubic's own
  variance factor at the row, over the rows whose neighbourhood moves (a joint at rest on one
  count says nothing of its noise); the white part beyond the lattice's D^2 / 12 is
  ``white`` = sqrt(max(sigma^2 - D^2 / 12, 0));
* **the motion's band** f_c (Hz): the highest frequency at which q's power spectral density
  (Welch, on the uniform grid of the clock) is ten times the noise floor 2 sigma^2 h (one-sided,
  h the sample time): above it the log holds noise, below it motion. The densities of the
  constant-acceleration and constant-jerk models whose Kalman filters have their bandwidth
  there, with the measurement noise sigma^2 h: white jerk q_3 = sigma^2 h w^6, white snap
  q_4 = sigma^2 h w^8, w = 2 pi f_c (rad^2/s^5, rad^2/s^7);
* **torque** (with a robot model): the measured torque against the model's inverse dynamics
  M(q) qdd + C(q, qd) qd + g(q) + tau_f(qd) at the zero-phase derivatives of q (cut off at twice the
  motion's band), both through the same low-pass: its mean (an offset) and RMS (the model's
  error in the band), and the torque's white noise, about a local cubic as the positions';
  ``torque_uncertainty`` = sqrt(model RMS^2 + white^2) per joint, what a design that takes the
  model's torque error (kalman_model) needs.

``measure(t, q, tau, robot)`` returns a ``Noise``; ``Noise.design_inputs()`` gives the keyword
arguments of ``observers.build`` that describe this sensor (no default encoder where the data
say otherwise).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import clock as _clock

FLOOR_RATIO = 10.0           # the motion's band ends where q's spectrum falls to this x the noise floor
LATTICE_TOL = 0.01           # values within this fraction of D of the lattice sit on it


@dataclass
class Noise:
    """Measured sensor noise and motion of a log (module docstring); arrays (n,) per joint.

    Attributes
    ----------
    joint_names : list of str
    dt : float
        The sample time of the clock (s).
    resolution, sigma, white : arrays (rad)
    band : array
        f_c (Hz).
    jerk_density, snap_density : arrays
        q_3 (rad^2/s^5), q_4 (rad^2/s^7).
    torque_offset, torque_model_rms, torque_white, torque_uncertainty : arrays or None
        N m; None without a robot model.
    """

    joint_names: list
    dt: float
    resolution: np.ndarray
    sigma: np.ndarray
    white: np.ndarray
    band: np.ndarray
    jerk_density: np.ndarray
    snap_density: np.ndarray
    torque_offset: np.ndarray | None = None
    torque_model_rms: np.ndarray | None = None
    torque_white: np.ndarray | None = None
    torque_uncertainty: np.ndarray | None = None
    spectrum: tuple | None = None           # (f, S) of q, for the tuning's window (not printed)

    @property
    def quantization(self):
        """The coarsest joint's lattice step D (rad), 0 when no joint sits on one."""
        return float(np.max(self.resolution)) if len(self.resolution) else 0.0

    @property
    def noise(self):
        """The noisiest joint's white noise std (rad)."""
        return float(np.max(self.white)) if len(self.white) else 0.0

    def design_inputs(self, torque=True):
        """``observers.build`` keywords for this sensor: quantization (the lattice step), noise
        (the white std) and, when measured and ``torque``, torque_uncertainty (N m per joint)."""
        out = {"quantization": self.quantization, "noise": self.noise}
        if torque and self.torque_uncertainty is not None:
            out["torque_uncertainty"] = [float(v) for v in self.torque_uncertainty]
        return out

    def lines(self):
        """The lines `describe`, `compare` and `design` print."""
        f = lambda a, s=1.0: ", ".join(f"{s * v:.3g}" for v in a)  # noqa: E731
        res = ("none (full precision)" if not np.any(self.resolution > 0) else f(self.resolution) + " rad")
        out = [f"position resolution per joint: {res}",
               f"position noise per joint (RMS, rad): {f(self.sigma)} (white beyond the resolution: {f(self.white)})",
               f"motion band per joint (Hz; q above 10x the noise floor): {f(self.band)}; white-jerk density "
               f"{f(self.jerk_density)} rad^2/s^5"]
        if self.torque_uncertainty is not None:
            out.append(f"torque vs the model (N m): offset {f(self.torque_offset)}; RMS in the band "
                       f"{f(self.torque_model_rms)}; white noise {f(self.torque_white)}; torque uncertainty "
                       f"{f(self.torque_uncertainty)}")
        return out

    def to_dict(self):
        """JSON-ready dict (lists per joint)."""
        out = {"joint_names": list(self.joint_names), "dt": self.dt}
        for k in ("resolution", "sigma", "white", "band", "jerk_density", "snap_density", "torque_offset",
                  "torque_model_rms", "torque_white", "torque_uncertainty"):
            v = getattr(self, k)
            out[k] = None if v is None else [float(x) for x in v]
        return out


def lattice(q):
    """The step D of the lattice q0 + k D the values ``q`` (N,) sit on (to LATTICE_TOL D), 0.0
    when they sit on none. Candidates, coarsest first: the smallest gap g between distinct values
    over 1..12 (an encoder's count when the motion skips counts) and the powers of ten up to g (the
    decimals a logger wrote); the first that holds 99.9 % of the values is D."""
    q = np.asarray(q, dtype=float)
    v = np.unique(q)
    if len(v) < 3:
        return 0.0
    gaps = np.diff(v)
    g = float(np.min(gaps[gaps > 0]))
    scale = max(float(np.max(np.abs(v))), g)
    floor = 64 * np.finfo(float).eps * scale
    if not g > floor:
        return 0.0
    tens = [10.0 ** e for e in range(int(np.floor(np.log10(g) + 1e-6)), int(np.floor(np.log10(floor))), -1)]
    for D in sorted({*(g / k for k in range(1, 13)), *tens}, reverse=True):
        if D <= floor:
            break
        r = (q - v[0]) / D
        if np.mean(np.abs(r - np.rint(r)) <= LATTICE_TOL) >= 0.999:
            return float(D)
    return 0.0


def position_noise(t, q):
    """sigma (n,) (rad): RMS leave-one-out residual of q (N, n) at times ``t`` (N,), corrected by
    the cubic's variance factor, over the rows whose neighbourhood moves (module docstring)."""
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    span = 4 * _clock._WINDOW * float(np.median(np.diff(t)))
    model = _clock._loo_cubic(t, q, span=span)
    r = q - _clock._predict(model, t[:, None])[:, 0, :]
    # h: the prediction's variance factor e0' (V'V)^-1 e0 at u = 0 (the fit's centre)
    tau, scale, coef, ok = model
    idx = np.arange(len(t))[:, None] + np.concatenate([np.arange(-_clock._WINDOW, 0),
                                                       np.arange(1, _clock._WINDOW + 1)])[None, :]
    inside = (idx >= 0) & (idx < len(t))
    idx = np.clip(idx, 0, len(t) - 1)
    u = (t[idx] - t[:, None]) / scale
    inside &= np.abs(t[idx] - t[:, None]) <= span
    V = np.stack([np.ones_like(u), u, u * u, u * u * u], axis=2) * inside[:, :, None]
    A = np.einsum("mki,mkj->mij", V, V) + 1e-12 * np.eye(4)
    A[~ok] = np.eye(4)
    h = np.linalg.inv(A)[:, 0, 0]
    out = np.zeros(q.shape[1])
    for j in range(q.shape[1]):
        window = q[idx, j]
        moving = ok & (np.ptp(np.where(inside, window, window[:, :1]), axis=1) > 0)
        if not moving.any():
            continue
        z2 = r[moving, j] ** 2 / (1 + h[moving])
        z2 = np.sort(z2)[: max(1, int(np.ceil(0.999 * len(z2))))]      # the rarest 0.1 % left out
        out[j] = float(np.sqrt(np.mean(z2)))
    return out


def uniform_grid(t, q):
    """(h, Q): q (N, n) at times ``t`` linearly interpolated onto the uniform grid of the median
    step h (s) over the log."""
    h = float(np.median(np.diff(t)))
    grid = t[0] + h * np.arange(int(np.floor((t[-1] - t[0]) / h + 1e-9)) + 1)
    return h, np.column_stack([np.interp(grid, t, q[:, j]) for j in range(q.shape[1])])


def psd(t, q, smooth=8):
    """(f (F,), S (F, n)): the one-sided power spectral density of q (N, n) on the uniform grid of
    the clock ``t`` (rad^2/Hz), estimated pre-whitened: the periodogram of the second difference
    of q through one Blackman-Harris window over the whole log (side lobes -92 dB, a main lobe
    of +-4 bins: the finest resolution a short log allows), averaged over ``smooth`` neighbouring
    bins, divided by the difference's gain |2 sin(pi f h)|^4 (a manipulator's motion falls by
    40-80 dB per decade: a window's leakage from the low frequencies would otherwise hide the noise
    floor by decades)."""
    from scipy.signal import periodogram
    h, Q = uniform_grid(t, q)
    D = np.diff(Q, 2, axis=0)
    f, S2 = periodogram(D, fs=1.0 / h, window="blackmanharris", axis=0)
    if smooth > 1 and len(f) > 2 * smooth:
        k = np.ones(smooth) / smooth
        S2 = np.apply_along_axis(lambda c: np.convolve(c, k, mode="same"), 0, S2)
    gain = (2 * np.sin(np.pi * f * h)) ** 4
    S = np.zeros_like(S2)
    S[1:] = S2[1:] / gain[1:, None]
    return f, S


def motion_band(t, q, sigma, spectrum=None):
    """f_c (n,) Hz: the highest frequency at which q's one-sided PSD (``psd``) is FLOOR_RATIO x
    the white floor 2 sigma^2 h of each joint (module docstring); ``t`` (N,) s and ``q`` (N, n) the
    log, ``sigma`` (n,) rad its noise, ``spectrum`` its ``psd`` when already computed."""
    f, P = psd(t, q) if spectrum is None else spectrum
    h = float(np.median(np.diff(t)))
    out = np.empty(P.shape[1])
    for j in range(P.shape[1]):
        floor = 2 * max(sigma[j], 1e-300) ** 2 * h
        above = np.flatnonzero(P[1:, j] >= FLOOR_RATIO * floor) + 1
        out[j] = f[above[-1]] if len(above) else f[1]
    return out


def reference_cutoff(noise, order=4, derivative=1):
    """(n,) Hz: the cut-off of the zero-phase ``derivative``-th derivative of q (1: the velocity
    reference; 2: the acceleration identification regresses on) through codegen.logs.smoothing's
    Butterworth low-pass of ``order`` forward and backward, H(f) = 1 / (1 + (f / fc)^(2 order)),
    that minimises its predicted mean-square error per joint on the log's spectrum: the motion it
    loses, int |1 - H|^2 (2 pi f)^(2 k) S_m df, plus the noise it passes,
    int H^2 (2 pi f)^(2 k) 2 sigma^2 h df (k = ``derivative``; S_m the motion's PSD,
    ``motion_psd``: q's less the white floor, within the band), over a log-spaced grid of cut-offs."""
    f, S = motion_psd(noise, noise.spectrum)
    floor = 2 * noise.sigma ** 2 * noise.dt
    w2 = (2 * np.pi * f) ** (2 * derivative)
    nyq = 0.5 / noise.dt
    grid = np.exp(np.linspace(np.log(max(f[1], 1e-3)), np.log(0.45 * nyq), 200))
    H = 1.0 / (1.0 + (f[None, :] / grid[:, None]) ** (2 * order))            # (cut-offs, F)
    out = np.empty(S.shape[1])
    for j in range(S.shape[1]):
        cost = np.trapezoid((1 - H) ** 2 * (w2 * S[:, j]) + H ** 2 * w2 * floor[j], f, axis=1)
        out[j] = grid[int(np.argmin(cost))]
    return out


def motion_psd(noise, spectrum):
    """The motion's part of q's PSD ``spectrum`` = (f, S): S less the white floor 2 sigma^2 h,
    zero beyond each joint's band f_c (``Noise`` ``noise``)."""
    f, S = spectrum
    floor = 2 * noise.sigma ** 2 * noise.dt
    M = np.where(f[:, None] <= noise.band[None, :], np.maximum(S - floor[None, :], 0.0), 0.0)
    return f, M


def measure(t, q, tau=None, robot=None):
    """The Noise of a log on its sample clock (module docstring).

    Parameters
    ----------
    t : (N,) array
        Sample times (s), increasing: the clock's (``Clock.t``).
    q : (N, n) array
        Positions (rad or m) of those rows.
    tau : (N, n) array, optional
        Measured torques (N m); with ``robot``, the torque's residual is measured.
    robot : models.RobotModel, optional

    Returns
    -------
    Noise
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    q = q[:, None] if q.ndim == 1 else q
    n = q.shape[1]
    h = float(np.median(np.diff(t)))
    resolution = np.array([lattice(q[:, j]) for j in range(n)])
    sigma = np.maximum(position_noise(t, q), resolution / np.sqrt(12.0))
    white = np.sqrt(np.maximum(sigma ** 2 - resolution ** 2 / 12.0, 0.0))
    white = np.where(white > 1e-3 * np.maximum(resolution, 1e-300), white, 0.0)
    spectrum = psd(t, q)
    band = motion_band(t, q, sigma, spectrum)
    w = 2 * np.pi * band
    r = sigma ** 2 * h
    names = list(getattr(robot, "joint_names", [f"q{j}" for j in range(n)]))
    out = Noise(names, h, resolution, sigma, white, band, r * w ** 6, r * w ** 8)
    out.spectrum = spectrum
    if tau is not None and robot is not None:
        _torque(out, t, q, np.asarray(tau, dtype=float), robot)
    return out


def _torque(out, t, q, tau, robot):
    """Fill ``out``'s torque fields: the measured torque against the model (module docstring)."""
    from ..verify.trajectory import inverse_dynamics_function
    from .smoothing import derivatives
    nyq = 0.5 / out.dt
    cut = float(min(2 * np.max(out.band), 0.45 * nyq / np.sqrt(2)))     # all of the motion: g(q), C(q, v) v are not linear
    d = derivatives(t, q, cut)
    lp = derivatives(t, tau, cut).q
    f = inverse_dynamics_function(robot).map(len(t))
    model = np.asarray(f(d.q.T, d.qd.T, d.qdd.T)).T
    v = d.valid if np.count_nonzero(d.valid) >= 0.1 * len(t) else np.ones(len(t), bool)   # a short log: its edges too
    res = (lp - model)[v]
    out.torque_offset = res.mean(axis=0)
    out.torque_model_rms = np.sqrt(np.mean((res - out.torque_offset) ** 2, axis=0))
    out.torque_white = position_noise(t, tau)       # the same estimator: white noise about a local cubic
    out.torque_uncertainty = np.sqrt(out.torque_model_rms ** 2 + out.torque_white ** 2)
