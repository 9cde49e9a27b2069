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


# the cases that held before issue 42 (kept as tests): a reader's refusal naming the row and column
def _text_edit(folder, name, change):
    lines = clean(folder, T=0.5, name=f".{name}.base.csv").read_text().splitlines()
    change(lines)
    path = folder / name
    path.write_text("\n".join(lines) + "\n")
    return path


def nan_value(folder):
    """'nan' in q_q2 at file row 11."""
    return _text_edit(folder, "nan.csv", lambda ls: ls.__setitem__(10, ",".join(
        v if k != 2 else "nan" for k, v in enumerate(ls[10].split(",")))))


def not_a_number(folder):
    """'abc' in tau_q1 at file row 21."""
    return _text_edit(folder, "abc.csv", lambda ls: ls.__setitem__(20, ",".join(
        v if k != 3 else "abc" for k, v in enumerate(ls[20].split(",")))))


def ragged_row(folder):
    """File row 31 with one value missing."""
    return _text_edit(folder, "ragged.csv", lambda ls: ls.__setitem__(30, ls[30].rsplit(",", 1)[0]))


def time_goes_back(folder):
    """The stamp of file row 41 before row 40's."""
    def change(ls):
        a, b = ls[39].split(","), ls[40].split(",")
        b[0] = repr(float(a[0]) - 1e-3)
        ls[40] = ",".join(b)
    return _text_edit(folder, "back.csv", change)


def missing_column(folder):
    """No tau_q2 column."""
    header, data = read_columns(clean(folder, T=0.5, name=".missing.base.csv"))
    return write_columns(folder / "missing.csv", {h: data[:, i] for i, h in enumerate(header) if h != "tau_q2"})


def wild_torque(folder):
    """tau_q2 = 1e300 N m at file row 51 (beyond any drive)."""
    return _edit(folder, "wild_tau.csv", lambda h, d: d.__setitem__((49, h.index("tau_q2")), 1e300), T=0.5)


# (case, the words its refusal has); the clock names the row of a stamp going back by its 0-based
# sample (39 here, file row 41): only its words are checked (codegen/logs/clock.py, not ours)
HELD = [(nan_value, "NaN or Inf in column 'q_q2', row 11"),
        (not_a_number, "row 21, column 'tau_q1': 'abc' is not a number"),
        (ragged_row, "row 31 has 4 values, the header 5"),
        (time_goes_back, "time stamps go back at sample "),
        (missing_column, "missing columns tau_q2"),
        (wild_torque, "row 51, column 'tau_q2': 1e+300 outside")]
