"""Figures of the scenarios (matplotlib, Agg backend: files only, no display).

One function per kind of figure, shared by the seeds; each takes arrays and a path, writes one
PNG and returns the path:

    per_joint            truth and estimates, one axes per joint     [S000 Figs. 2, 3; S003 Figs. 2, 3]
    error_norms          ||e(t)|| of several runs on a log axis      [S000, S003, S004 error plots]
    panels               traces on stacked (or gridded) axes          [S002 Figs. 1-4, S003 Figs. 4, 5]
    positions_and_bound  positions, speed norms and the bound r vbar [S000 Figs. 4, 6]
    tracking             tracking errors and torques                  [S000 Example 3]
    elastic_errors       link/motor position/velocity errors, 2 x 2   [S004 Figs. 3, 4, 8-17]
    joint_trajectory     q_d and its derivatives 1..3, 2 x 2          [S004 Figs. 2, 7]
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass
from itertools import cycle
from pathlib import Path

import numpy as np

STYLES = ["--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1))]
LINES = ["-", *STYLES]
MUTED = {"color": "0.72", "lw": 0.6, "ls": "-"}     # the curves a figure keeps but does not highlight
_caption = None                                    # the source every figure cites (``citing``)


def legend(ax, **kw):
    """The legend of the axes ``ax`` beside it, right of the plot (never over the data); ``kw``
    go to ``Axes.legend``."""
    return ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False, **kw)


@contextlib.contextmanager
def citing(text):
    """While inside, every figure written carries ``text`` (the paper and experiment it
    reproduces, e.g. a scenario's line of `simulate list`) at its bottom left."""
    global _caption
    outer, _caption = _caption, text
    try:
        yield
    finally:
        _caption = outer


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if _caption:
        fig.text(0.005, 0.003, _caption, fontsize=7, color="0.35", ha="left", va="bottom")
    fig.tight_layout(rect=(0, 0.03 if _caption else 0, 1, 1))
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    return path


@dataclass
class Panel:
    """One axes of :func:`panels`.

    Parameters
    ----------
    curves : dict
        label -> samples (1-D, no longer than the x axis; a shorter one is drawn from the start).
    ylabel, title : str
    log : {"", "y", "xy"}
        Logarithmic axes.
    hlines : sequence of float
        Horizontal reference lines (dotted gray).
    legend : bool
        Show the curves' labels (beside the axes).
    muted : dict
        label -> samples drawn thin and gray under the curves (one legend entry, "others: ...").
    """

    curves: dict
    ylabel: str = ""
    title: str = ""
    log: str = ""
    hlines: tuple = ()
    legend: bool = True
    muted: dict = None


def panels(path, x, rows, title="", cols=1, cell=(8.0, 2.6), xlabel="t [s]"):
    """Panels on a grid of ``cols`` columns sharing the x axis; line styles cycle within a panel.

    Parameters
    ----------
    path : path of the PNG
    x : (N,) array, the common x axis (time in s unless ``xlabel`` says otherwise)
    rows : list of Panel
    title : figure title ("" for none);  cols : number of columns of the grid
    cell : (width, height) of one panel in inches;  xlabel : label of the bottom x axes
    """
    plt = _plt()
    nrows = -(-len(rows) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(cell[0] * cols, cell[1] * nrows), squeeze=False,
                             sharex=True)
    for ax, p in zip(axes.flat, rows):
        for i, y in enumerate((p.muted or {}).values()):
            ax.plot(x[:len(y)], y, **MUTED, label=_others(p.muted) if i == 0 else None)
        for (label, y), ls in zip(p.curves.items(), cycle(LINES)):
            ax.plot(x[:len(y)], y, linestyle=ls, lw=1.0, label=label)
        if "y" in p.log:
            ax.set_yscale("log")
        if "x" in p.log:
            ax.set_xscale("log")
        for level in p.hlines:
            ax.axhline(level, color="gray", lw=0.7, ls=":")
        ax.set_ylabel(p.ylabel)
        ax.set_title(p.title, fontsize=9)
        ax.grid(alpha=0.3, which="both")
        if p.legend:
            legend(ax)
    for ax in axes.flat[len(rows):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel(xlabel)
    if title:
        fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def _others(names, width=30):
    """The muted curves' one legend entry, "others: a, b, ...", wrapped at ``width`` characters
    (on one line, six of compare's names made the legend wider than the figure)."""
    import textwrap
    return textwrap.fill(f"others: {', '.join(names)}", width, break_long_words=False)


def per_joint(path, t, truth, estimates, ylabel="qd{} [rad/s]", truth_label="true", title="", zoom=None):
    """Per joint i: the true signal (solid) and each estimate (dashed, dash-dotted, ...).

    Parameters
    ----------
    path : path of the PNG;  title : figure title
    t : (N,) s;  truth : (N, n);  estimates : dict label -> (N, >= n) (first n columns drawn)
    ylabel : axis label per joint, ``{}`` replaced by the joint number (1-based)
    truth_label : legend label of the true signal
    zoom : (t0, t1) in s, optional
        Adds the same curves over [t0, t1] in an inset box of each axes [S000 Fig. 7].
    """
    plt = _plt()
    n = truth.shape[1]
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.6 * n), sharex=True, squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        boxes = [ax]
        if zoom is not None:
            box = ax.inset_axes([0.55, 0.5, 0.42, 0.45])
            sel = (t >= zoom[0]) & (t <= zoom[1])
            box.set_xlim(*zoom)
            ax.indicate_inset_zoom(box, edgecolor="gray")
            box.tick_params(labelsize=7)
            box.grid(alpha=0.3)
            boxes.append((box, sel))
        for target in boxes:
            a, sel = (target, slice(None)) if target is ax else target
            a.plot(t[sel], truth[sel, i], "k-", lw=1.4, label=truth_label)
            for (name, E), ls in zip(estimates.items(), STYLES):
                a.plot(t[sel], E[sel, i], linestyle=ls, lw=1.1, label=name)
        ax.set_ylabel(ylabel.format(i + 1))
        ax.grid(alpha=0.3)
    legend(axes[0, 0])
    axes[0, 0].set_title(title)
    axes[-1, 0].set_xlabel("t [s]")
    return _save(fig, path)


def error_norms(path, t, errors, levels=(1e-2, 1e-3), ylabel="||qd - qd_hat|| [rad/s]", title="", muted=None):
    """||e(t)|| (row norms, floored at 1e-12) of each error on a log axis, with reference levels.

    Parameters
    ----------
    path : path of the PNG;  t : (N,) s
    errors : dict label -> (N_i, m) errors, or (N_i,) norms; N_i <= N (a run that stopped early
        is drawn as far as it went)
    levels : horizontal lines (e.g. the settling levels)
    ylabel, title : axis label and figure title
    muted : dict, optional
        label -> errors drawn thin and gray under the others (kept, not highlighted)
    """
    def norm(e):
        return np.maximum(np.linalg.norm(np.reshape(e, (len(e), -1)), axis=1), 1e-12)
    return panels(path, t, [Panel({k: norm(e) for k, e in errors.items()}, ylabel=ylabel, log="y",
                                  hlines=levels, muted={k: norm(e) for k, e in (muted or {}).items()})],
                  title=title, cell=(8, 3.4))


def tracking(path, t, e, tau, title=""):
    """Tracking errors q_d - q (top) and joint torques (bottom) of a closed-loop run, to the PNG
    ``path``: ``t`` (N,) s, ``e`` (N, n) rad, ``tau`` (N, n) N m, figure ``title``."""
    n = e.shape[1]
    return panels(path, t, [Panel({f"e{i + 1}": e[:, i] for i in range(n)}, ylabel="q_d - q [rad]"),
                            Panel({f"tau{i + 1}": tau[:, i] for i in range(n)}, ylabel="tau [N m]")],
                  title=title)


def positions_and_bound(path, t, q, qd, est, r, vbar, q_ref=None, title=""):
    """Top: joint positions (and references). Bottom: ||qd||, ||qd_hat|| and the bound r vbar
    [S000 Figs. 4, 6].

    Parameters
    ----------
    path : path of the PNG;  title : figure title
    t : (N,) s;  q, qd : (N, n) true positions (rad) and velocities (rad/s)
    est : (N, n) velocity estimate, rad/s
    r : (N,) logic state of the hybrid observer;  vbar : speed step of the bound, rad/s
    q_ref : (N, n) reference positions (rad), drawn dotted if given
    """
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5.6), sharex=True)
    for i in range(q.shape[1]):
        a1.plot(t, q[:, i], lw=1.2, label=f"q{i + 1}")
        if q_ref is not None:
            a1.plot(t, q_ref[:, i], ":", color=a1.lines[-1].get_color(), lw=1.0, label=f"q{i + 1},d (target)")
    a1.set_ylabel("q [rad]")
    a1.grid(alpha=0.3)
    legend(a1)
    a1.set_title(title)
    a2.plot(t, np.linalg.norm(qd, axis=1), "k-", lw=1.3, label="||qd||")
    a2.plot(t, np.linalg.norm(est, axis=1), "--", lw=1.1, label="||qd_hat||")
    a2.step(t, r * vbar, where="post", lw=1.1, label="bound r vbar")
    a2.set_ylabel("speed [rad/s]")
    a2.set_xlabel("t [s]")
    a2.grid(alpha=0.3)
    legend(a2)
    return _save(fig, path)


ELASTIC_QUANTITIES = (("Link", "position", "rad", 0), ("Motor", "position", "rad", 2),
                      ("Link", "velocity", "rad/s", 1), ("Motor", "velocity", "rad/s", 3))


def elastic_errors(path, t, E, title=""):
    """Estimation errors x - xhat of an elastic robot, one curve per joint, on a 2 x 2 grid:
    link positions, motor positions (top), link velocities, motor velocities (bottom)
    [S004 Figs. 3, 4, 8-17].

    Parameters
    ----------
    path : path of the PNG;  title : figure title
    t : (N,) s
    E : (N, 4n) errors in the state order [q1; q1'; q2; q2'] (rad, rad/s)
    """
    n = E.shape[1] // 4
    rows = [Panel({f"{who} {i + 1} {what} error": E[:, block * n + i] for i in range(n)},
                  ylabel=f"{who.lower()} {what} error [{unit}]")
            for who, what, unit, block in ELASTIC_QUANTITIES]
    return panels(path, t, rows, title=title, cols=2, cell=(5.2, 3.0))


def joint_trajectory(path, t, R, n, title=""):
    """Desired joint trajectory: position, acceleration (top), velocity, jerk (bottom), one
    curve per joint [S004 Figs. 2, 7].

    Parameters
    ----------
    path : path of the PNG;  title : figure title
    t : (N,) s
    R : (N, >= 4n) rows [q_d, its 1st, 2nd, 3rd derivative, ...] (rad, rad/s, rad/s^2, rad/s^3)
    n : int, number of joints
    """
    order = ((0, "position", "rad"), (2, "acceleration", "rad/s^2"), (1, "velocity", "rad/s"),
             (3, "jerk", "rad/s^3"))
    rows = [Panel({f"Link {i + 1} {what}": R[:, k * n + i] for i in range(n)}, ylabel=f"{what} [{unit}]")
            for k, what, unit in order]
    return panels(path, t, rows, title=title, cols=2, cell=(5.2, 3.0))
