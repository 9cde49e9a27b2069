"""Studies behind the docs: runs that write a page of docs/ rather than a scenario's figures.

    quadrature_study    the quadrature order of the I&I observers' beta (S003 (12), (14), (15))
                        against an adaptive reference -> docs/quadrature.md
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

QUADRATURE_NOTES = """## Why the reduction, and the defaults (N = 16, N_period = N)

The integrands are analytic in sigma and 2 pi-periodic for revolute joints, with complex
singularities where det M vanishes (seed-003 arm: phi = y1 - y2 at +-0.94 i, the strip half-width
d). Gauss-Legendre on [0, y_i] converges at a rate set by |y_i|: once a link has gone round
(seed-003 scenario: y2 = 9.3 rad at t = 2 s) N = 16 leaves ~5e-3 relative error in beta and its
AD derivatives dbeta/ds_y, dbeta/ds_x, while dbeta/dy is exact (fundamental theorem of
calculus); the mismatch enters the z dynamics times the velocity and the observer drifted
(||xhat - x|| = 0.65 at 2 s). With the reduction the Gauss-Legendre part has |rho| <= pi and the
whole periods use the periodic trapezoidal rule, which converges like exp(-N d) (one full period,
worst of 3 random (s_y, s_x), relative, stacked beta / dbeta/ds_y / dbeta/ds_x integrands):

| N | 2R trapezoid | 2R Gauss-Legendre | ur5 trapezoid | ur5 Gauss-Legendre |
|---:|---:|---:|---:|---:|
| 8 | 8.0e-03 | 7.4e-02 | 2.0e-02 | 4.1e-02 |
| 16 | 8.3e-06 | 1.2e-03 | 4.8e-04 | 2.4e-03 |
| 24 | 6.7e-09 | 1.5e-05 | 1.2e-05 | 2.5e-04 |
| 32 | 4.5e-12 | 1.9e-07 | 2.8e-07 | 2.0e-05 |

Defaults: N = 16 Gauss-Legendre nodes on [0, rho] and N_period = N trapezoid nodes per period
(`codegen.families.observers.ii_speed.DEFAULT_N`, `ii_speed.build(..., wrap="auto", N_period=None)`).
In the seed-003 scenario N_period = 32 and 16 give ||xhat - x|| = 1.97e-6 at t = 2 s either way
(xhat agrees to 5e-11 from t = 1 s on; the largest difference, 6.6e-4, is at t = 0.61 s during
the transient, just after y2 passes pi): the residual is the time discretisation, not the
quadrature, so the cheaper N_period = N is the default; pass N_period = 2 N for ~1e-11 on the
2R arm. The reduction doubles the quadrature points of a periodic column (N + N_period instead
of N); a column whose integrand does not depend on sigma (column 1 of a serial arm: M and C do
not depend on q_1) is y_i H_i exactly, with no nodes at all. The 6-DoF ur5 has nearer
singularities (slower convergence, ~1e-3 at N = 8 for |rho| <= pi); N = 8 there is a
documented cost/accuracy trade (see `codegen.evaluate.bench.seed003_ii_ur5`), not an accuracy claim.
`wrap=False` restores the plain [0, y_i] quadrature (fine while every |y_i| stays below ~pi).

## Known gap in the seed's proof (S003 (37))

(37) bounds the term -(r'/r) eta^T M eta of d/dt(1/2 eta^T M eta), eta = z / r, by
-(r'/r) k_m ||eta||^2. That holds only while r' >= 0; when r decays (r' < 0, the term is
positive) the valid bound is -(r'/r) k_M ||eta||^2, and the decrease of the eta part of the
Lyapunov function is not guaranteed by the printed argument. Observed in our runs: in the
seed-003 scenario r falls from 0.1 to c_r = 1e-3 within ~50 ms (r' < 0 on 78 % of the 2 s) and
1/2 eta^T M eta grows from 4.9e3 (t = 5 ms) to 5.2e5 (t = 45 ms) while ||z|| = ||xhat - x||
keeps decreasing (9.5 -> 1.4); afterwards r sits at c_r and everything converges. So the gap
is real in the proof (eta is not monotone) but has not shown up as a loss of convergence of z.
"""


def adaptive_beta(robot, y, s_y, s_x, k1, epsabs=1e-14, epsrel=1e-13):
    """beta, dbeta/ds_y, dbeta/ds_x of the I&I observers by adaptive quadrature
    (scipy.integrate.quad_vec) of the exact integrands on the whole [0, y_i]  [S003 (12), (14), (15)].

    Parameters
    ----------
    robot : reference robot (codegen.reference.reference_robot)
    y, s_y, s_x : (n,) measured angle, filter states (rad, rad/s)
    k1 : gain of H = M^{-1} (k1 I - C)
    epsabs, epsrel : absolute and relative tolerances of quad_vec

    Returns
    -------
    (n + 2 n^2,) array: [beta, dbeta/ds_y (row-major n x n), dbeta/ds_x (row-major n x n)]
    """
    from scipy.integrate import quad_vec

    from ...reference.families import ii_speed as ref

    def integrand(sig, i):
        z = np.array(s_y, dtype=float)
        z[i] = sig
        Hi, dq, dx = ref.h_column_derivatives(robot, z, s_x, k1, i)
        dq[:, i] = 0.0
        return np.concatenate([Hi, dq.ravel(), dx.ravel()])
    return sum(quad_vec(lambda s, i=i: integrand(s, i), 0.0, y[i], epsabs=epsabs, epsrel=epsrel,
                        limit=1000)[0] for i in range(len(y)))


def quadrature_study(robots=("seed003_2r_abs", "ur5"), Ns=range(2, 17), samples=4, seed=0,
                     write=None, y_range=3 * np.pi):
    """Errors of the quadrature of beta, dbeta/ds_y, dbeta/ds_x against an adaptive reference.

    The reference formulas (N nodes, interval reduction of the periodic joints: N-node
    Gauss-Legendre on [0, rho], |rho| <= pi, plus m periods by the N-node trapezoid) against an
    adaptive reference (``adaptive_beta``: scipy.integrate.quad_vec, epsabs 1e-14, epsrel 1e-13)
    of the same integrands on the whole [0, y_i] (so the reduction itself is checked).

    Parameters
    ----------
    robots : sequence of str
        Catalog names.
    Ns : iterable of int
        Node counts N.
    samples : int
        Random (y, s_y, s_x) per robot; y ~ U(-y_range, y_range)^n.
    seed : int
        Seed of ``numpy.random.default_rng``.
    write : path-like, optional
        Write the markdown page there (``write_quadrature_doc``).
    y_range : float
        rad (default 3 pi: up to 1.5 turns, m in {-1, 0, 1}).

    Returns
    -------
    dict
        {robot: {N: (err_beta, err_dsy, err_dsx, err_beta_nowrap)}}: worst relative errors over
        the samples, the last one without reduction (N-node Gauss-Legendre on [0, y_i]).
    """
    from models import load_robot

    from ...reference import reference_robot
    from ...reference.families import ii_speed as ref
    rng = np.random.default_rng(seed)
    k1 = 40.0
    table = {}
    for name in robots:
        robot = reference_robot(load_robot(name).source)
        n = robot.n
        periodic = list(np.asarray(robot.periodic, dtype=bool))
        rows = {N: [0.0, 0.0, 0.0, 0.0] for N in Ns}
        for _ in range(samples):
            y = rng.uniform(-y_range, y_range, n)
            s_y = np.mod(y + rng.normal(scale=0.5, size=n) + np.pi, 2 * np.pi) - np.pi
            s_x = rng.normal(scale=2.0, size=n)

            exact = adaptive_beta(robot, y, s_y, s_x, k1)
            eb, esy, esx = exact[:n], exact[n:n + n * n].reshape(n, n), exact[n + n * n:].reshape(n, n)
            for N in Ns:
                b, _, dsy, dsx = ref.beta_and_derivatives(robot, y, s_y, s_x, k1, N, True, periodic)
                b0, *_ = ref.beta_and_derivatives(robot, y, s_y, s_x, k1, N, False)
                for k, (a, e) in enumerate(((b, eb), (dsy, esy), (dsx, esx), (b0, eb))):
                    rows[N][k] = max(rows[N][k], float(np.linalg.norm(a - e) / np.linalg.norm(e)))
        table[name] = rows
    if write is not None:
        write_quadrature_doc(table, write, samples, y_range)
    return table


def write_quadrature_doc(table, path, samples, y_range=3 * np.pi):
    """docs/quadrature.md from a ``quadrature_study`` ``table``: the method, one table per robot,
    the notes; written to ``path`` (returned), citing the study's ``samples`` and ``y_range``
    (rad)."""
    lines = ["# Quadrature order of the I&I speed observers (seed 003)", "",
             "beta (12) and its derivatives (14), (15) are quadratures of the columns of H. For a "
             "2 pi-periodic (revolute) joint the interval is reduced (`wrap`, default \"auto\"): "
             "y_i = 2 pi m + rho, m = floor(y_i / 2 pi + 1/2), |rho| <= pi, and "
             "int_0^{y_i} = m int_{-pi}^{pi} + int_0^{rho}, the period by the N_period-node "
             "trapezoidal rule (default N_period = N), [0, rho] by N-node Gauss-Legendre. The "
             "table gives the worst relative error (2-norm, Frobenius for matrices) over "
             f"{samples} random y ~ U(-{y_range / np.pi:g} pi, {y_range / np.pi:g} pi)^n "
             "(up to 1.5 turns), s_y = y + N(0, 0.5^2) wrapped to [-pi, pi), s_x ~ N(0, 2^2), "
             "k1 = 40, against scipy.integrate.quad_vec (adaptive, epsabs 1e-14, epsrel 1e-13) "
             "of the same exact integrands on the whole [0, y_i] (so the reduction itself is "
             "checked); the last column is N-node Gauss-Legendre on [0, y_i] without the "
             "reduction. Generated by "
             "`codegen.evaluate.sim.studies.quadrature_study(write='docs/quadrature.md')`.", ""]
    for name, rows in table.items():
        lines += [f"## {name}", "", "| N | beta | dbeta/ds_y | dbeta/ds_x | beta, no reduction |",
                  "|---:|---:|---:|---:|---:|"]
        for N, (a, b, c, d) in rows.items():
            lines.append(f"| {N} | {a:.2e} | {b:.2e} | {c:.2e} | {d:.2e} |")
        lines.append("")
    lines += [QUADRATURE_NOTES]
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text("\n".join(lines))
    return path


