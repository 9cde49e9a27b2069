"""Robustness maps of a finished sweep: a metric over two axes, the best gain per noise level.

    frame = Store(out).read();  designed = Store(out).get("designed.json")
    heatmap(frame, "k0", "noise", path, designed=designed)    # median over the other axes
    best_gain(frame, "k0", "noise", designed=designed)        # a DataFrame, one row per level

Diverged cells count as +inf. The designed gain (``designed.json``, written by ``run``) is
drawn over the map, one marker per level of the y axis, beside the swept optimum.
"""
from __future__ import annotations

import numpy as np


def _observer(frame, method):
    obs = frame[frame["kind"] == "observer"]
    method = method or (obs["method"].iloc[0] if len(obs) else None)
    sub = frame[frame["method"] == method].copy()
    if sub.empty:
        raise ValueError(f"method: no rows of {method!r}; have {sorted(frame['method'].unique())}")
    return method, sub


def table(frame, x, y, metric="rms", method=None):
    """(method, pivot): the median of ``metric`` per (y, x) over every other axis (diverged
    cells as +inf), rows y, columns x, both sorted.

    Parameters
    ----------
    frame : pandas.DataFrame
        Rows of a sweep (``Store.read``).
    x, y : str
        Columns of the axes (a gain or AXES name).
    metric : str
        Metric column (rms, max, t_conv, ...).
    method : str, optional
        Observer item of the sweep (default: the first observer in ``frame``).

    Returns
    -------
    (str, pandas.DataFrame)"""
    method, sub = _observer(frame, method)
    for a in (x, y, metric):
        if a not in sub.columns:
            raise ValueError(f"{a!r} is not a column of the results; have {', '.join(sub.columns)}")
    sub[metric] = np.where(sub["diverged"].astype(bool), np.inf, sub[metric].astype(float))
    return method, sub.groupby([y, x])[metric].median().unstack(x).sort_index().sort_index(axis=1)


def _designed(designed, method, y, gain):
    """{y value: [designed gain values]} of ``method`` from designed.json rows."""
    out = {}
    for r in designed or ():
        if r.get("method") == method and gain in r and y in r:
            out.setdefault(r[y], set()).add(float(r[gain]))
    return {k: sorted(v) for k, v in out.items()}


def best_gain(frame, gain, by="noise", metric="rms", method=None, designed=None):
    """Per level of ``by``: the swept gain with the lowest median ``metric``, that metric, the
    designed gain and the metric of the swept gain nearest to it (in log), and their ratio.

    Parameters
    ----------
    frame : pandas.DataFrame
        Rows of a sweep (``Store.read``).
    gain : str
        The gain axis (a runtime parameter, e.g. "k0").
    by : str
        The axis whose levels make the rows (noise, quantization, ...).
    metric : str
        Metric column minimised (median over the other axes; diverged cells +inf).
    method : str, optional
        Observer item (default: the first observer in ``frame``).
    designed : list of dict, optional
        Rows of designed.json (NaN designed gain without them).

    Returns
    -------
    pandas.DataFrame
        One row per level of ``by``.
    """
    import pandas as pd
    method, piv = table(frame, gain, by, metric, method)
    des = _designed(designed, method, by, gain)
    xs = np.asarray(piv.columns, dtype=float)
    rows = []
    for level, row in piv.iterrows():
        vals = row.to_numpy(dtype=float)
        i = int(np.nanargmin(np.where(np.isnan(vals), np.inf, vals)))
        d = des.get(level, [np.nan])[0]
        j = int(np.argmin(np.abs(np.log(xs) - np.log(d)))) if np.isfinite(d) and d > 0 and np.all(xs > 0) else None
        rows.append({by: level, f"best {gain}": xs[i], f"{metric} at best": vals[i], f"designed {gain}": d,
                     f"{metric} near designed": vals[j] if j is not None else np.nan,
                     "near designed / best": vals[j] / vals[i] if j is not None else np.nan})
    return pd.DataFrame(rows)


# units of the swept axes and the metrics (a gain not listed is labelled by its name alone)
UNITS = {"noise": "rad", "quantization": "rad", "mismatch": "relative", "dt": "s", "k0": "1/s",
         "k0_final": "1/s", "kd": "1/s", "kp": "1/s^2", "omega": "rad/s", "omega0": "rad/s",
         "rms": "rad/s", "max": "rad/s", "t_conv": "s", "lag": "s", "gain": "1"}


def label(name):
    """An axis label with its unit, ``"k0 [1/s]"``; a name without a known unit as it is."""
    return f"{name} [{UNITS[name]}]" if name in UNITS else name


def cites(family):
    """Where ``family``'s equations are: the first ``docs/papers/<page>.md §n`` its module's
    docstring names, else "beyond the papers" (a family of our own, its docstring says which)."""
    import importlib
    import re
    try:
        doc = importlib.import_module(f"codegen.families.observers.{family}").__doc__ or ""
    except ImportError:
        return f"{family}: a baseline of codegen/evaluate/baselines.py"
    found = re.search(r"docs/papers/\w+\.md §[\d.]+", " ".join(doc.split()))
    return f"{family}: {found.group(0)}" if found else f"{family}: beyond the papers (its module docstring)"


def heatmap(frame, x, y, path, metric="rms", method=None, designed=None, title=None, note=None):
    """A map of log10(median ``metric``) over the swept values of x (columns) and y (rows),
    each cell a grid point (equal spacing, ticks the values), the best x per row marked (x)
    and the designed value of x per row (o, placed between the swept values in log).

    Parameters
    ----------
    frame : pandas.DataFrame
        Rows of a sweep (``Store.read``).
    x, y : str
        Axes of the columns and rows (as ``table``).
    path : path
        The PNG written (parents created).
    metric : str
        Metric column.
    method : str, optional
        Observer item (default: the first observer in ``frame``).
    designed : list of dict, optional
        Rows of designed.json (no designed markers without them).
    title : str, optional
        Figure title (default: method, metric and axes).
    note : str, optional
        A second title line (the run, the window of the metric, the paper of the observer).

    Returns
    -------
    Path
        ``path``."""
    import matplotlib
    matplotlib.use("Agg")
    from pathlib import Path

    import matplotlib.pyplot as plt
    method, piv = table(frame, x, y, metric, method)
    Z = np.log10(piv.to_numpy(dtype=float))
    xs, ys = np.asarray(piv.columns, dtype=float), np.asarray(piv.index, dtype=float)
    fig, ax = plt.subplots(figsize=(1.2 + 0.55 * len(xs), 1.4 + 0.4 * len(ys)))
    im = ax.imshow(np.where(np.isfinite(Z), Z, np.nan), origin="lower", aspect="auto", cmap="viridis")
    fig.colorbar(im, ax=ax, label=f"log10 median {label(metric)}")
    ax.set_xticks(range(len(xs)), [f"{v:.3g}" for v in xs], rotation=60)
    ax.set_yticks(range(len(ys)), [f"{v:.3g}" for v in ys])
    ax.set_xlabel(label(x))
    ax.set_ylabel(label(y))
    for r, row in enumerate(piv.to_numpy(dtype=float)):
        if np.any(np.isfinite(row)):
            ax.plot(int(np.nanargmin(np.where(np.isnan(row), np.inf, row))), r, "rx", ms=9, mew=2,
                    label="swept best" if r == 0 else None)
    des = _designed(designed, method, y, x)
    if des and np.all(xs > 0):
        pos = [(np.interp(np.log(v), np.log(xs), np.arange(len(xs))), r)
               for r, level in enumerate(ys) for v in des.get(level, []) if v > 0]
        if pos:
            ax.plot(*zip(*pos), "o", color="darkorange", mfc="none", ms=10, mew=2.5, label=f"designed {x}")
    ax.legend(loc="upper left", bbox_to_anchor=(0, -0.25), ncol=2, fontsize=8, frameon=False)
    ax.set_title((title or f"{method}: {metric} over {x} x {y}") + (f"\n{note}" if note else ""), fontsize=9)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def default_axes(sweep):
    """(x, y) of the default map: the first gain axis over noise (else quantisation), or None
    when the sweep has no such pair; the sweep's [map] table (x, y) wins."""
    from .plan import AXES
    gains = [k for k in sweep.axes if k not in AXES]
    x = sweep.map.get("x") or (gains[0] if gains else None)
    y = sweep.map.get("y") or next((a for a in ("noise", "quantization") if isinstance(sweep.axes.get(a), list)
                                    and len(sweep.axes[a]) > 1), None)
    return (x, y) if x and y else None


def write(out, sweep):
    """map.png and best.txt of a finished sweep in its folder (when it has a gain axis and a
    noise or quantisation axis, or a [map] table).

    Parameters
    ----------
    out : path
        The sweep's output folder (a ``Store``).
    sweep : plan.Sweep
        The sweep (axes and [map] table).

    Returns
    -------
    list of Path
        The files written (empty when the sweep has no such pair of axes)."""
    from .store import Store
    axes = default_axes(sweep)
    if axes is None:
        return []
    store = Store(out)
    frame, designed = store.read(), store.get("designed.json")
    metric, method = sweep.map.get("metric", "rms"), sweep.map.get("method")
    x, y = axes
    window = (f"{metric} of ||qd - qd_hat|| over t >= {sweep.steady:g} s of each {sweep.T:g} s run"
              if metric in ("rms", "max") else f"{metric} at level {sweep.level:g} rad/s")
    fig = heatmap(frame, x, y, store.out / "map.png", metric, method, designed,
                  title=f"{sweep.name}: {sweep.robot} ({sweep.plant} plant), median {label(metric)}",
                  note=f"{window}, median over the seeds; x: the best swept {x} per row, o: the designed "
                       f"one; {cites(_observer(frame, method)[1]['family'].iloc[0])}")
    text = best_gain(frame, x, y, metric, method, designed).to_string(index=False, float_format="%.4g")
    (store.out / "best.txt").write_text(text + "\n")
    return [fig, store.out / "best.txt"]
