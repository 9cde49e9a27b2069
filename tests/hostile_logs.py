"""Hostile logs for the reliability tests (issue 42): each function writes one case into a folder
(``tmp_path``) and returns its path. The base is a clean log of seed000_2r (a closed form: no
declared limits) on a 1 ms clock: the built-in demo motion, its model's torques, positions on a
1e-6 rad encoder (numpy only; no log of a real arm is copied).
"""
import numpy as np

from codegen.core.columns import read_columns, write_columns
from codegen.verify.trajectory import demo_trajectory
from models import load_robot

ROBOT = "seed000_2r"


def clean(folder, T=6.0, name="clean.csv", robot=ROBOT, seed=2):
    """T s of ``robot``'s demo motion at 1 kHz: t, q_<joint> (1e-6 rad steps), tau_<joint>."""
    r = load_robot(robot)
    t, Q, _, TAU = demo_trajectory(r, T=T, dt=1e-3, seed=seed)
    cols = {"t": t, **{f"q_{j}": np.round(Q[:, i] / 1e-6) * 1e-6 for i, j in enumerate(r.joint_names)},
            **{f"tau_{j}": TAU[:, i] for i, j in enumerate(r.joint_names)}}
    return write_columns(folder / name, cols)


def _edit(folder, name, change, T=6.0):
    header, data = read_columns(clean(folder, T=T, name=f".{name}.base.csv"))
    change(header, data)
    return write_columns(folder / name, {h: data[:, i] for i, h in enumerate(header)})


def too_short(folder):
    """0.2 s: shorter than kalman_model's scoring start (twice its t_switch of 0.3 s)."""
    return clean(folder, T=0.2, name="short.csv")


def wild_sample(folder, row=4, column="q_q1", value=1e200):
    """One sample ``value`` at data row ``row`` (file row row + 2) of ``column``."""
    return _edit(folder, "wild.csv", lambda h, d: d.__setitem__((row, h.index(column)), value))


def torque_scaled(folder, factor=3.0):
    """Every torque x ``factor`` (a wrong unit or gear ratio): the model-based designs then fail
    (ii_speed's run stops) or sit at the velocity bound (reduced_order_nonlinear)."""
    def change(h, d):
        for i, name in enumerate(h):
            if name.startswith("tau_"):
                d[:, i] *= factor
    return _edit(folder, "torque_x3.csv", change)


def nul_padded(folder, pad=200_000):
    """The first half of a clean log, then ``pad`` NUL bytes (a logger killed with its file
    preallocated): one field longer than the csv module's 128 KiB limit."""
    data = clean(folder, name=".nul.base.csv").read_bytes()
    path = folder / "nul.csv"
    path.write_bytes(data[:len(data) // 2].rsplit(b"\n", 1)[0] + b"\n" + b"\0" * pad)
    return path


def targets_file(folder, log, family="reduced_order", robot=ROBOT):
    """A targets file of one target tuned on ``log`` (``tune = "..."``)."""
    path = folder / "targets.toml"
    path.write_text(f'[[target]]\nrobot = "{robot}"\nfamily = "{family}"\ntune = "{log}"\n')
    return path
