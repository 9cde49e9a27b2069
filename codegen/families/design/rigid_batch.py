"""M(q) and Coriolis products of a kinematic tree, numerically, for many configurations at once.

The design's sups over configurations (``configurations``) need lambda(M(q)) and
c0(q) = max_{|v|=1} ||C(q, v) v|| at thousands of configurations. Evaluating the symbolic
model there (the CasADi virtual machine, ~0.1 us per instruction) or forming the Christoffel
tensor (n^3 entries per configuration) does not scale to 50 joints; this module computes the
same quantities from the robot's own ``models.tree.SpatialTree`` (the snapped constants the
symbolic algorithms read) in world-frame spatial algebra (Featherstone ch. 2, 5, 6), vectorised
over configurations, vectors and bodies:

    S_j  = [a_j; p_j x a_j] (revolute), [0; a_j] (prismatic)   joint axis a_j through p_j (world)
    I_i (w, u) = (J_i w + h_i x u, m_i u - h_i x w)             body inertia about the world origin
    V_i  = sum_{j <= i} S_j v_j                                 (j <= i: j is i or an ancestor)
    dS_j = V_j x S_j                                            (the rate of S_j along v)
    c(v) = C(q, v) v:  A_i = sum_{j <= i} dS_j v_j,   f_i = I_i A_i + V_i x* I_i V_i,
                       c_j = S_j . sum_{i >= j} f_i             (RNEA, no gravity, qdd = 0)
    h = C(q, v)^T c = grad_v (c . C(q, v) v) / 2, with W_i = sum_{j <= i} S_j c_j (the adjoint
        of the RNEA: c . C(q, v) v = sum_i W_i . f_i):
        E_j = S_j x* sum_{i >= j} I_i W_i,
        h_k = (V_k . E_k + S_k . sum_{i >= k} [v_i E_i + I_i (W_i x V_i) - W_i x* I_i V_i]) / 2
    M(q)_jk = S_j . IC_k S_k  for j <= k, IC_k = sum_{i >= k} I_i   (CRBA, plus the armature)
    g(q)_j  = -S_j . (H_j x g0, m_j g0),  m_j, H_j = sum_{i >= j} (m_i, m_i com_i)   (RNEA at rest)
    dg_j/dq_k from dS_j/dq_k = S_k x S_j (k <= j), dH_j/dq_k = a_k x H_a + m_a v_k (a the deeper
              of j, k; S_k = [a_k; v_k]), O(n^2) per configuration in (n, 3) (3, n) products

C is the Christoffel one (C(q, a) b = C(q, b) a, docs/papers/seed000.md §0). Each
(configuration, vector) pair costs O(n) (chains: cumulative sums; trees: ancestor masks,
O(n^2)); memory is linear in the batch, which the callers chunk.
"""
from __future__ import annotations

import numpy as np


def cross(a, b):
    """a x b for 3-vectors stored component-first: (3, ...) arrays."""
    out = np.empty(a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape))
    np.multiply(a[1], b[2], out=out[0])
    out[0] -= a[2] * b[1]
    np.multiply(a[2], b[0], out=out[1])
    out[1] -= a[0] * b[2]
    np.multiply(a[0], b[1], out=out[2])
    out[2] -= a[1] * b[0]
    return out


def dot(a, b):
    """a . b for component-first 3-vectors: (...) array."""
    out = a[0] * b[0]
    out += a[1] * b[1]
    out += a[2] * b[2]
    return out


def _inertia(J, h, m, w, u):
    """I (w, u) = (J w + h x u, m u - h x w): the spatial inertia of mass m, first moment h and
    rotational inertia J (components xx, yy, zz, xy, xz, yz) about the world origin, applied to
    the motion (w, u), all component-first."""
    ang = cross(h, u)
    ang[0] += J[0] * w[0] + J[3] * w[1] + J[4] * w[2]
    ang[1] += J[3] * w[0] + J[1] * w[1] + J[5] * w[2]
    ang[2] += J[4] * w[0] + J[5] * w[1] + J[2] * w[2]
    lin = m * u
    lin -= cross(h, w)
    return ang, lin


class TreeBatch:
    """World-frame kinematics of a ``models.tree.SpatialTree`` at S configurations.

    Parameters
    ----------
    tree : models.tree.SpatialTree (n bodies in topological order)
    Q : (S, n) joint positions [rad or m]
    """

    def __init__(self, tree, Q):
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        S, n = Q.shape
        bodies = tree.bodies
        self.n, self.S = n, S
        self.parent = np.array([b.parent for b in bodies])
        self.chain = bool(np.all(self.parent == np.arange(n) - 1))
        anc = np.eye(n, dtype=bool)                  # anc[j, i]: j is i or an ancestor of i
        for i, b in enumerate(bodies):
            if b.parent >= 0:
                anc[:, i] |= anc[:, b.parent]
        self.anc, self._ancf = anc, anc.astype(float)
        self.mass = np.array([b.mass for b in bodies])
        self.g0 = np.array(tree.gravity, dtype=float)
        self.armature = np.array([b.armature for b in bodies])
        R = np.empty((S, n, 3, 3))
        p = np.empty((S, n, 3))
        cq, sq = np.cos(Q), np.sin(Q)
        for i, b in enumerate(bodies):
            E, r = np.array(b.E), np.array(b.r)
            if b.parent >= 0:
                Rl = R[:, b.parent]
                RE = Rl @ E
                p[:, i] = p[:, b.parent] + Rl @ r
            else:
                RE = np.broadcast_to(E, (S, 3, 3))
                p[:, i] = r
            if b.kind == "R":                                              # R = RE R_z(q)
                c, s = cq[:, i, None], sq[:, i, None]
                R[:, i, :, 0] = c * RE[:, :, 0] + s * RE[:, :, 1]
                R[:, i, :, 1] = c * RE[:, :, 1] - s * RE[:, :, 0]
                R[:, i, :, 2] = RE[:, :, 2]
            else:
                R[:, i] = RE
                p[:, i] += RE[:, :, 2] * Q[:, i, None]
        a = R[..., :, 2]                                                   # axes (S, n, 3)
        revolute = np.array([b.kind == "R" for b in bodies])
        sw = np.where(revolute[:, None], a, 0.0)                           # S_j = [sw; sv]
        sv = np.where(revolute[:, None], np.cross(p, a), a)
        c_body = np.array([b.com for b in bodies])                         # (n, 3) body frame
        Io = np.array([b.Io for b in bodies])                              # about the body origin
        m = self.mass
        Ic = Io - m[:, None, None] * (np.einsum("nk,nk->n", c_body, c_body)[:, None, None] * np.eye(3)
                                      - np.einsum("ni,nj->nij", c_body, c_body))
        com = p + np.einsum("snij,nj->sni", R, c_body)                    # (S, n, 3) world
        J = R @ Ic @ R.transpose(0, 1, 3, 2)                               # world, about the com
        J += m[:, None, None] * (np.einsum("snk,snk->sn", com, com)[..., None, None] * np.eye(3)
                                 - com[..., :, None] * com[..., None, :])  # about the world origin
        # component-first, bodies then configurations: (3, n, S) vectors, J as (6, n, S) (xx, yy,
        # zz, xy, xz, yz), so that the sums over bodies run on contiguous rows
        self.sw, self.sv = (np.ascontiguousarray(x.transpose(2, 1, 0)) for x in (sw, sv))
        self.hm = np.ascontiguousarray((m[:, None] * com).transpose(2, 1, 0))
        self.J6 = np.ascontiguousarray(np.stack([J[..., 0, 0], J[..., 1, 1], J[..., 2, 2], J[..., 0, 1],
                                                 J[..., 0, 2], J[..., 1, 2]]).transpose(0, 2, 1))
        self._m = m[:, None]

    # ------------------------------------------------------------ tree sums
    def _down(self, x):
        """sum over j <= i (i and its ancestors) of x[..., j, :], bodies on the axis before last."""
        if self.chain:
            return np.cumsum(x, axis=-2)
        return self._ancf.T @ x

    def _up(self, x):
        """sum over i >= j (j and its descendants) of x[..., i, :], bodies on the axis before last."""
        if self.chain:
            return np.cumsum(x[..., ::-1, :], axis=-2)[..., ::-1, :]
        return self._ancf @ x

    # ------------------------------------------------------------ spatial algebra
    def _spatial(self, rows=slice(None)):
        """(S_j (S, n, 6), the composite inertias IC_k = sum_{i >= k} I_i (S, n, 6, 6)) at the
        configurations ``rows``, world frame, motion (w, v) and force (moment, force) coordinates:
        I_i = [[J, h x], [-h x, m]]."""
        J6, h = self.J6[..., rows].transpose(2, 1, 0), self.hm[..., rows].transpose(2, 1, 0)   # (S, n, 6), (S, n, 3)
        J = J6[..., [[0, 3, 4], [3, 1, 5], [4, 5, 2]]]
        hx = np.zeros(h.shape + (3,))
        hx[..., 0, 1], hx[..., 0, 2], hx[..., 1, 2] = -h[..., 2], h[..., 1], -h[..., 0]
        hx[..., 1, 0], hx[..., 2, 0], hx[..., 2, 1] = h[..., 2], -h[..., 1], h[..., 0]
        mm = self.mass[:, None, None]
        I6 = np.concatenate([np.concatenate([J, hx], -1),
                             np.concatenate([-hx, np.broadcast_to(mm * np.eye(3), J.shape)], -1)], -2)
        IC = np.einsum("ik,skab->siab", self._ancf, I6)                   # sum over descendants
        return np.concatenate([self.sw[..., rows], self.sv[..., rows]]).transpose(2, 1, 0), IC

    def mass_matrix(self, rows=slice(None)):
        """M(q) (S, n, n) at the configurations ``rows`` (CRBA in world frame, armature on the
        diagonal): M_jk = S_j . IC_k S_k for j <= k, IC_k S_k from the composite mass, first
        moment and rotational inertia (O(n) per configuration, then one (n, 6) (6, n) product)."""
        n = self.n
        sw, sv = self.sw[..., rows], self.sv[..., rows]
        Fw, Fv = _inertia(self._up(self.J6[..., rows]), self._up(self.hm[..., rows]), self._up(self._m), sw, sv)
        U = np.concatenate([sw, sv]).transpose(2, 1, 0) @ np.concatenate([Fw, Fv]).transpose(2, 0, 1)
        U *= self.anc
        M = U + U.transpose(0, 2, 1)
        d = np.arange(n)
        M[:, d, d] = U[:, d, d] + self.armature
        return M
    def gravity(self, rows=slice(None)):
        """(g(q) (S, n), dg/dq (S, n, n)) at the configurations ``rows`` (module docstring):
        dg_j/dq_k = -[k <= j] ((a_k x a_j) . (H_j x g0) + m_j ((a_k x v_j + v_k x a_j) . g0))
                    - [a = j] ((a_j . H_j)(a_k . g0) - (a_j . a_k)(H_j . g0) + m_j a_j . (v_k x g0))
                    - [a = k != j] ((a_j . H_k)(a_k . g0) - (a_j . a_k)(H_k . g0) + m_k a_j . (v_k x g0))."""
        sw, sv = (x[..., rows].transpose(2, 1, 0) for x in (self.sw, self.sv))    # (S, n, 3)
        H = self._up(self.hm[..., rows]).transpose(2, 1, 0)
        mc, g0 = self._up(self._m)[:, 0], self.g0
        g = -(np.einsum("snd,snd->sn", sw, np.cross(H, g0)) + mc * (sv @ g0))
        T = lambda x: x.transpose(0, 2, 1)                                 # noqa: E731
        R = mc[:, None] * np.cross(sv, g0)                                 # m_k v_k x g0
        # k <= j: (a_k x a_j) . (H_j x g0) = a_k . (a_j x (H_j x g0)), m_j (a_k x v_j + v_k x a_j) . g0
        below = (np.cross(sw, np.cross(H, g0)) + R) @ T(sw) + (mc[:, None] * np.cross(sw, g0)) @ T(sv)
        gram, beta, gamma = sw @ T(sw), sw @ g0, H @ g0
        alpha = np.einsum("snd,snd->sn", sw, H)
        at_j = alpha[:, :, None] * beta[:, None, :] - gamma[:, :, None] * gram + (mc[:, None] * np.cross(g0, sw)) @ T(sv)
        at_k = (sw @ T(H)) * beta[:, None, :] - gram * gamma[:, None, :] + sw @ T(R)
        anc = self.anc
        dg = -(anc.T * (below + at_j) + (anc & ~np.eye(self.n, dtype=bool)) * at_k)
        return g, dg

    def christoffel(self, rows=slice(None)):
        """The Christoffel tensor T (S, n, n, n) at the configurations ``rows``,
        T[s, i, j, k] = C(q_s, e_k)_ij = B(e_j, e_k)_i.

        For j <= k (the only non-zero pairs with k <= j, by symmetry), with a = the deeper of i
        and k (0 unless one is the other's ancestor):
            B(e_j, e_k)_i = S_i . (IC_a (S_j x S_k) + S_j x* IC_a S_k + S_k x* IC_a S_j) / 2
                          = (Y_ai . X_jk - X_ji . Y_ak - X_ki . Y_aj) / 2,
            X_jk = S_j x S_k,  Y_ak = IC_a S_k                  (m . (s x* f) = -(s x m) . f)
        (the RNEA of the module docstring with v = e_j, w = e_k: A = (S_j x S_k) / 2 on the
        bodies i >= k, and the symmetrised velocity product on the same bodies). n^3 entries and
        O(n^3) work per configuration: for small n."""
        n = self.n
        Sj, IC = self._spatial(rows)                                        # (S, n, 6), (S, n, 6, 6)
        w, v = Sj[..., None, :, :3], Sj[..., None, :, 3:]                   # S_k on axis 2
        wj, vj = Sj[..., :, None, :3], Sj[..., :, None, 3:]                 # S_j on axis 1
        X = np.concatenate([np.cross(wj, w), np.cross(wj, v) + np.cross(vj, w)], -1)   # (S, j, k, 6)
        Y = IC @ Sj.transpose(0, 2, 1)[:, None]                             # (S, m, 6, k): IC_m S_k
        a = np.where(self.anc, np.arange(n)[None, :], np.arange(n)[:, None])   # a[i, k]
        idx = np.arange(n)
        Yt = Y.transpose(0, 1, 3, 2)                                        # (S, m, k, 6)
        ai = Yt[:, a, idx[:, None]]                                         # [s, i, k] = Y_{a(i,k) i}
        ak = Yt[:, a, idx[None, :]]                                         # [s, i, k] = Y_{a(i,k) k}
        aj = Y[:, a]                                                        # [s, i, k, :, j] = Y_{a(i,k) j}
        T = (np.einsum("sikd,sjkd->sijk", ai, X) - np.einsum("sjid,sikd->sijk", X, ak)
             - np.einsum("skid,sikdj->sijk", X, aj))
        related = self.anc | self.anc.T
        T *= 0.5 * (self.anc[None, None] & related.T[None, :, None, :])
        return T + T.transpose(0, 1, 3, 2) * (1 - np.eye(n))[None, None]

    def coriolis_products(self, rows, v):
        """(C(q, v) v, C(q, v)^T C(q, v) v) for the pairs (configuration rows[k], vector v[k]):
        the RNEA c(v) and its adjoint h (module docstring).

        Parameters
        ----------
        rows : (P,) indices into the configurations;  v : (P, n) vectors

        Returns
        -------
        (c (P, n), h (P, n))."""
        sw, sv, J, hm, m = self.sw[..., rows], self.sv[..., rows], self.J6[..., rows], self.hm[..., rows], self._m
        down, up = self._down, self._up
        v = np.ascontiguousarray(np.asarray(v, dtype=float).T)
        Vw, Vv = down(sw * v), down(sv * v)                                # body velocities V_i
        dSw, dSv = cross(Vw, sw), cross(Vw, sv)                            # dS_j = V_j x S_j
        dSv += cross(Vv, sw)
        pw, pv = _inertia(J, hm, m, Vw, Vv)                                # I V
        fw, fv = _inertia(J, hm, m, down(dSw * v), down(dSv * v))          # I A
        fw += cross(Vw, pw)                                                # + V x* I V
        fw += cross(Vv, pv)
        fv += cross(Vw, pv)
        c = dot(sw, up(fw))
        c += dot(sv, up(fv))
        Ww, Wv = down(sw * c), down(sv * c)                                # W_i
        Gw, Gv = (up(x) for x in _inertia(J, hm, m, Ww, Wv))               # sum_{i >= j} I_i W_i
        Ew, Ev = cross(sw, Gw), cross(sw, Gv)                              # E_j = S_j x* G_j
        Ew += cross(sv, Gv)
        Xv = cross(Ww, Vv)                                                 # W x V
        Xv += cross(Wv, Vw)
        rw, rv = _inertia(J, hm, m, cross(Ww, Vw), Xv)                     # I (W x V)
        rw -= cross(Ww, pw)                                                # - W x* I V
        rw -= cross(Wv, pv)
        rv -= cross(Ww, pv)
        rw += Ew * v
        rv += Ev * v
        h = dot(Vw, Ew)
        h += dot(Vv, Ev)
        h += dot(sw, up(rw))
        h += dot(sv, up(rv))
        h *= 0.5
        return c.T, h.T
