"""Closed-loop simulation at a fixed sample rate.

At each sample k (t = k dt):
  1. y_k = sensor(q(t_k))                     measurement (noise, quantisation, hold)
  2. est_k^i = observer_i.estimate(y_k, u_{k-1})   (our observers' outputs do not depend on u);
     only for the observers the controller reads (``controller.feedback``, default all)
  3. u_k = controller(t_k, y_k, est_k, x_k)   any callable; compiled laws wrap a block
  4. observer_i.step(y_k, u_k); plant advances over [t_k, t_k+1] with u_k held.
Observers are any objects with reset/estimate/step/state (CompiledObserver or the
numpy ReferenceObserver), so the same scenario runs on the C or on the reference.

Speed: blocks are called through :class:`Port`, which shares preallocated y/u buffers
between blocks and calls the C entry points without per-step allocation or argument checks
(the C still checks finiteness and returns a status, which is checked); see sim/blocks.py.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from ...core.columns import write_columns
from .blocks import bind, stage, staged


@dataclass
class Result:
    """The record of one :func:`simulate` run, one row per sample k (t_k = k dt).

    Attributes
    ----------
    t : (N,) sample times, s
    x : (N, 2n) true state [q, qd] at t_k (rad, rad/s); ``q``, ``qd`` and ``n`` view it
    y : (N, ny) measurements;  u : (N, nu) inputs held over [t_k, t_k+1] (N m)
    est, states : dict name -> (N, nest) estimates / (N, nx) observer states before the step
    extra : dict, anything a scenario or controller logs (e.g. ``<name>_state_final``)
    """

    t: np.ndarray                     # (N,)
    x: np.ndarray                     # (N, 2n) true [q, qd]
    y: np.ndarray                     # (N, ny) measurements
    u: np.ndarray                     # (N, nu) inputs applied over [t_k, t_k+1]
    est: dict = field(default_factory=dict)     # name -> (N, nest)
    states: dict = field(default_factory=dict)  # name -> (N, nx) observer states (before the step)
    extra: dict = field(default_factory=dict)   # anything a controller logs

    @property
    def n(self):
        return self.x.shape[1] // 2

    @property
    def q(self):
        return self.x[:, : self.n]

    @property
    def qd(self):
        return self.x[:, self.n:]

    def write_csv(self, path):
        """Write the run to the CSV file ``path`` (``codegen.core.columns.write_columns``), one row per sample:
        t, q, qd, y, u, then each observer's estimate and each logged state; returns the path."""
        cols = {"t": self.t, "q": self.q, "qd": self.qd, "y": self.y, "u": self.u}
        cols.update({f"{name}_est": E for name, E in self.est.items()})
        cols.update({f"{name}_x": S for name, S in self.states.items()})
        return write_columns(path, cols)


class Port:
    """A block (observer, law or plant) wired to shared buffers ``y`` and ``u``.

    ``estimate()`` and ``step()`` write the block's output into ``self.est`` (reused, not
    copied); ``state()`` returns the block state. The calls are ``blocks.bind``'s: the C entry
    points of a CompiledObserver directly, the Python methods of the numpy reference."""

    def __init__(self, block, y, u):
        self.block, self.y, self.u = block, y, u
        self.nest, self.nx = block.nest, block.nx
        self._est = np.zeros(max(1, self.nest))   # C may touch one slot even when nest = 0
        self.est = self._est[: self.nest]
        self._step, self._estimate = bind(block, y, u, self._est)

    def step(self):
        """Advance the block one sample from the shared ``y``, ``u``; returns its output ``est``."""
        self._step()
        return self.est

    def estimate(self):
        """The block's output for the current state and shared ``y`` (no step), in ``est``."""
        self._estimate()
        return self.est

    def state(self):
        """The block's current state vector (nx,)."""
        return self.block.state


class Law:
    """A compiled control law (a stateless block, see codegen.families.controllers) as a controller.

    ``assemble(t, y, est, x, out)`` writes the law's measurement vector into ``out``;
    ``feedback`` names the observers whose estimate the law reads."""

    def __init__(self, block, assemble, feedback=()):
        self.block, self.assemble, self.feedback = block, assemble, tuple(feedback)
        self.y = np.zeros(block.ny)
        block.reset(self.y)
        self.port = Port(block, self.y, np.zeros(max(1, block.nu)))

    def __call__(self, t, y, est, x):
        self.assemble(t, y, est, x, self.y)
        return self.port.step()


def simulate(plant, q0, qd0, T, dt, controller, observers=None, sensor=None, est0=None,
             log_states=(), progress=False):
    """Run the loop of the module docstring for T seconds; returns a Result.

    plant       sim.plant.Plant (its dt must equal dt)
    q0, qd0     (n,) initial joint positions (rad) and velocities (rad/s) of the plant
    T, dt       horizon and sample period, s (N = round(T / dt) + 1 samples)
    controller  callable(t, y, est: dict, x_true) -> u; an optional attribute ``feedback``
                (names of the observers it reads) spares the other observers' estimate call
    observers   dict name -> observer; each is reset with y_0 and est0.get(name) (zeros)
    sensor      sim.sensors.Sensor (default: exact, every sample)
    est0        dict name -> initial estimate of that observer (default: zeros)
    log_states  names of observers whose state is recorded each sample (before its step);
                the state after the last step is in ``extra[name + "_state_final"]``
    progress    show a progress bar on stderr (codegen.core.progress: lines off a terminal); also inside
                blocks.stage_lines (`simulate`)

    ``est`` passed to the controller holds buffers that are overwritten at the next sample.
    """
    from .sensors import Sensor

    if abs(plant.dt - dt) > 1e-15:
        raise ValueError(f"plant dt {plant.dt} differs from the simulation dt {dt}")
    observers = observers or {}
    est0 = est0 or {}
    sensor = sensor or Sensor()
    sensor.reset()
    N = int(round(T / dt)) + 1
    n = plant.n
    plant.reset(np.asarray(q0, float), np.asarray(qd0, float))
    ybuf, ubuf, empty = np.zeros(n), np.zeros(n), np.zeros(1)
    sensor.measure(0, plant.state[:n], ybuf)
    for name, obs in observers.items():
        obs.reset(ybuf.copy(), est0=est0.get(name))
    ports = {name: Port(obs, ybuf, ubuf) for name, obs in observers.items()}
    fb = getattr(controller, "feedback", None)
    fb_ports = [ports[name] for name in (ports if fb is None else fb)]
    est = {name: port.est for name, port in ports.items()}
    plant_port = Port(plant.block, empty, ubuf)
    x = plant_port.state()
    X, Yl, U = np.empty((N, 2 * n)), np.empty((N, n)), np.empty((N, n))
    E = {name: np.empty((N, obs.nest)) for name, obs in observers.items()}
    S = {name: np.empty((N, observers[name].nx)) for name in log_states}
    logged = [(S[name], ports[name]) for name in log_states]
    stepped = [(E[name], port) for name, port in ports.items()]
    steps = range(N)
    stage(f"simulating {T:g} s at dt {dt:g} s ({N} samples, {len(observers)} observers)")
    if progress or staged():
        try:
            from ...core.progress import bar
            steps = bar(steps, desc="simulate", unit="step", file=sys.stderr, leave=False,
                        miniters=max(1, N // 100), disable=None if not progress else False)
        except ImportError:  # pragma: no cover
            pass
    measure = sensor.measure
    for k in steps:
        measure(k, x[:n], ybuf)
        for port in fb_ports:
            port.estimate()                       # u_{k-1} still in ubuf
        ubuf[:] = controller(k * dt, ybuf, est, x)
        for Sk, port in logged:
            Sk[k] = port.state()
        for Ek, port in stepped:
            Ek[k] = port.step()
        X[k], Yl[k], U[k] = x, ybuf, ubuf
        if k < N - 1:
            plant_port.step()
            x = plant_port.state()
    extra = {f"{name}_state_final": port.state().copy() for name, port in ports.items()
             if name in S}
    return Result(t=np.arange(N) * dt, x=X, y=Yl, u=U, est=E, states=S, extra=extra)


def settling_time(t, err, level):
    """First time in ``t`` (N,) s after which ||err|| stays below ``level`` (inf if never).

    ``err`` is (N, m) (row norms) or (N,) (absolute values); t[0] if it is below from the start."""
    norm = np.linalg.norm(np.atleast_2d(err.T).T, axis=1) if err.ndim > 1 else np.abs(err)
    above = np.nonzero(norm >= level)[0]
    if len(above) == 0:
        return float(t[0])
    return float(t[above[-1] + 1]) if above[-1] + 1 < len(t) else float("inf")


def rms(err):
    """Root mean square of the norm of each row of ``err`` (N, m), or of its entries if (N,)."""
    return float(np.sqrt(np.mean(np.sum(np.atleast_2d(err.T).T ** 2, axis=-1))))
