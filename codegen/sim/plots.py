"""Figures of the scenarios (matplotlib, Agg backend: files only, no display).

Each helper takes arrays and a path, writes one PNG and returns the path.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

STYLES = ["--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1))]


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    return path


def velocities(path, t, qd, estimates, title=""):
    """Per joint: true velocity (solid) and each estimate (dashed, dash-dotted, ...) [Figs. 2, 3, 5, 7]."""
    plt = _plt()
    n = qd.shape[1]
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.6 * n), sharex=True, squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        ax.plot(t, qd[:, i], "k-", lw=1.4, label="true")
        for (name, E), ls in zip(estimates.items(), STYLES):
            ax.plot(t, E[:, i], linestyle=ls, lw=1.1, label=name)
        ax.set_ylabel(f"qd{i + 1} [rad/s]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[0, 0].set_title(title)
    axes[-1, 0].set_xlabel("t [s]")
    return _save(fig, path)


def error_norms(path, t, errors, levels=(1e-2, 1e-3), title=""):
    """||qd - qd_hat|| on a log scale for each observer, with the settling levels."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 3.4))
    for (name, e), ls in zip(errors.items(), ["-", "--", "-.", ":"] * 3):
        ax.semilogy(t, np.maximum(np.linalg.norm(e, axis=1), 1e-12), linestyle=ls, lw=1.0, label=name)
    for lv in levels:
        ax.axhline(lv, color="gray", lw=0.7, ls=":")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("||qd - qd_hat|| [rad/s]")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize=8)
    return _save(fig, path)


def positions_and_bound(path, t, q, qd, est, r, vbar, q_ref=None, title=""):
    """Top: joint positions (and references). Bottom: ||qd||, ||qd_hat||, bound r vbar,
    and r on a second axis [Figs. 4, 6]."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5.6), sharex=True)
    for i in range(q.shape[1]):
        a1.plot(t, q[:, i], lw=1.2, label=f"q{i + 1}")
        if q_ref is not None:
            a1.plot(t, q_ref[:, i], "k:", lw=1.0, label=f"q{i + 1},d" if i == 0 else None)
    a1.set_ylabel("q [rad]")
    a1.grid(alpha=0.3)
    a1.legend(loc="best", fontsize=8)
    a1.set_title(title)
    a2.plot(t, np.linalg.norm(qd, axis=1), "k-", lw=1.3, label="||qd||")
    a2.plot(t, np.linalg.norm(est, axis=1), "--", lw=1.1, label="||qd_hat||")
    a2.step(t, r * vbar, where="post", lw=1.1, label="bound r vbar")
    a2.set_ylabel("[rad/s]")
    a2.set_xlabel("t [s]")
    a2.grid(alpha=0.3)
    a2.legend(loc="best", fontsize=8)
    return _save(fig, path)


def tracking(path, t, e, tau, title=""):
    """Tracking errors q_d - q (top) and joint torques (bottom) of a closed-loop run."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5.2), sharex=True)
    for i in range(e.shape[1]):
        a1.plot(t, e[:, i], lw=1.1, label=f"e{i + 1}")
        a2.plot(t, tau[:, i], lw=1.0, label=f"tau{i + 1}")
    a1.set_ylabel("q_d - q [rad]")
    a2.set_ylabel("tau [N m]")
    a2.set_xlabel("t [s]")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend(loc="best", fontsize=8)
    a1.set_title(title)
    return _save(fig, path)


def joint_zoom(path, t, truth, estimates, window, title=""):
    """One joint's true velocity (solid) and each estimate over the time window (t0, t1)."""
    plt = _plt()
    m = (t >= window[0]) & (t <= window[1])
    fig, ax = plt.subplots(figsize=(8, 3.4))
    ax.plot(t[m], truth[m], "k-", lw=1.6, label="true")
    for (name, e), ls in zip(estimates.items(), ["--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1))] * 3):
        ax.plot(t[m], e[m], linestyle=ls, lw=1.1, label=name)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("qd [rad/s]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return _save(fig, path)
