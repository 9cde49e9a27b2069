"""M(q) and Coriolis products of a kinematic tree, numerically, for many configurations at once.

The design's sups over configurations (``configurations``) need lambda(M(q)) and
c0(q) = max_{|v|=1} ||C(q, v) v|| at thousands of configurations. Evaluating the symbolic
model there (the CasADi virtual machine, ~0.1 us per instruction) or forming the Christoffel
tensor (n^3 entries per configuration) does not scale to 50 joints; this module computes the
same quantities from the robot's own ``models.tree.SpatialTree`` (the snapped constants the
symbolic algorithms read) in world-frame spatial algebra (Featherstone ch. 2, 5, 6), vectorised
over configurations, vectors and bodies:

    S_j  = [a_j; p_j x a_j] (revolute), [0; a_j] (prismatic)   joint axis a_j through p_j (world)
    V_i  = sum_{j <= i} S_j v_j                                 (j <= i: j is i or an ancestor)
    dS_j = V_j x S_j                                            (the rate of S_j along v)
    c(v) = C(q, v) v:  A_i = sum_{j <= i} dS_j v_j,   f_i = I_i A_i + V_i x* I_i V_i,
                       c_j = S_j . sum_{i >= j} f_i             (RNEA, no gravity, qdd = 0)
    B(v, w) = C(q, v) w, the symmetric bilinear form with B(v, v) = c(v) (polarisation; the
              Christoffel C is the one with C(q, a) b = C(q, b) a, docs/papers/seed000.md §0)
    Mdot(q, v) w = dS_j . G_j + S_j . dG_j,  G_j = sum_{i >= j} I_i W_i,  W_i = sum_{j <= i} S_j w_j,
              dG_j = sum_{i >= j} [V_i x* I_i W_i - I_i (V_i x W_i) + I_i sum_{k <= i} dS_k w_k]
    C(q, v)^T w = Mdot(q, v) w - C(q, v) w                      (Mdot = C + C^T [S000 (3)])
    M(q)_jk = S_j . (sum_{i >= k} I_i) S_k  for j <= k          (CRBA, plus the armature)

Each (configuration, vector) pair costs O(n) (chains: O(n) with cumulative sums; trees:
ancestor masks, O(n^2)); memory is linear in the batch, which the callers chunk.
"""
from __future__ import annotations

import numpy as np


def cross(a, b):
    """a x b for 3-vectors stored component-first: (3, ...) arrays."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    np.subtract(a[1] * b[2], a[2] * b[1], out=out[0])
    np.subtract(a[2] * b[0], a[0] * b[2], out=out[1])
    np.subtract(a[0] * b[1], a[1] * b[0], out=out[2])
    return out


def dot(a, b):
    """a . b for component-first 3-vectors: (...) array."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _rz(q):
    """R_z(q) for an array of angles: (..., 3, 3)."""
    c, s = np.cos(q), np.sin(q)
    R = np.zeros(q.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    return R


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
        self.anc = anc
        self.mass = np.array([b.mass for b in bodies])
        self.armature = np.array([b.armature for b in bodies])
        R = np.empty((S, n, 3, 3))
        p = np.empty((S, n, 3))
        for i, b in enumerate(bodies):
            E, r = np.array(b.E), np.array(b.r)
            Rl, pl = (R[:, b.parent], p[:, b.parent]) if b.parent >= 0 else (np.eye(3), np.zeros(3))
            RE = Rl @ E
            p[:, i] = pl + Rl @ r
            if b.kind == "R":
                R[:, i] = RE @ _rz(Q[:, i])
            else:
                R[:, i] = RE
                p[:, i] += RE[..., :, 2] * Q[:, i, None]
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
        Icw = R @ Ic @ R.transpose(0, 1, 3, 2)                             # (S, n, 3, 3) world, about com
        # component-first copies: (3, S, n) vectors, (3, 3, S, n) inertias
        self.sw, self.sv, self.com = (np.ascontiguousarray(x.transpose(2, 0, 1)) for x in (sw, sv, com))
        self.Ic = np.ascontiguousarray(Icw.transpose(2, 3, 0, 1))

    # ------------------------------------------------------------ tree sums
    def _down(self, x):
        """sum over j <= i (i and its ancestors) of x[..., j], bodies on the last axis."""
        if self.chain:
            return np.cumsum(x, axis=-1)
        return x @ self.anc.astype(float)

    def _up(self, x):
        """sum over i >= j (j and its descendants) of x[..., i], bodies on the last axis."""
        if self.chain:
            return np.cumsum(x[..., ::-1], axis=-1)[..., ::-1]
        return x @ self.anc.T.astype(float)

    # ------------------------------------------------------------ spatial algebra
    def _spatial(self):
        """(S_j (S, n, 6), the composite inertias IC_k = sum_{i >= k} I_i (S, n, 6, 6)), world
        frame, motion (w, v) and force (moment, force) coordinates."""
        c, m = self.com.transpose(1, 2, 0), self.mass
        Ic = self.Ic.transpose(2, 3, 0, 1)
        cx = np.zeros(c.shape + (3,))
        cx[..., 0, 1], cx[..., 0, 2], cx[..., 1, 2] = -c[..., 2], c[..., 1], -c[..., 0]
        cx[..., 1, 0], cx[..., 2, 0], cx[..., 2, 1] = c[..., 2], -c[..., 1], c[..., 0]
        mm = m[:, None, None]
        I6 = np.concatenate([np.concatenate([Ic - mm * (cx @ cx), mm * cx], -1),
                             np.concatenate([-mm * cx, np.broadcast_to(mm * np.eye(3), Ic.shape)], -1)], -2)
        IC = np.einsum("ik,skab->siab", self.anc.astype(float), I6)          # sum over descendants
        return np.concatenate([self.sw, self.sv]).transpose(1, 2, 0), IC

    def mass_matrix(self):
        """M(q) (S, n, n) at the configurations (CRBA in world frame, armature on the diagonal):
        M_jk = S_j . IC_k S_k for j <= k."""
        n = self.n
        Sj, IC = self._spatial()
        U = np.einsum("sjd,skde,ske->sjk", Sj, IC, Sj) * self.anc
        M = U + U.transpose(0, 2, 1)
        M[:, np.arange(n), np.arange(n)] *= 0.5
        M[:, np.arange(n), np.arange(n)] += self.armature
        return M

    def christoffel(self):
        """The Christoffel tensor T (S, n, n, n), T[s, i, j, k] = C(q_s, e_k)_ij = B(e_j, e_k)_i.

        For j <= k (the only non-zero pairs with k <= j, by symmetry), with a = the deeper of i
        and k (0 unless one is the other's ancestor):
            B(e_j, e_k)_i = S_i . (IC_a (S_j x S_k) + S_j x* IC_a S_k + S_k x* IC_a S_j) / 2
        (the RNEA of the module docstring with v = e_j, w = e_k: A = (S_j x S_k) / 2 on the
        bodies i >= k, and the symmetrised velocity product on the same bodies). n^3 entries and
        O(n^3) work per configuration: for small n."""
        n = self.n
        Sj, IC = self._spatial()

        w, v = Sj[..., :3].transpose(2, 0, 1), Sj[..., 3:].transpose(2, 0, 1)   # (3, S, n)
        F = np.einsum("smab,skb->asmk", IC, Sj)                             # IC_m S_k: (6, S, m, k)
        Xw = cross(w[:, :, :, None], w[:, :, None, :])                      # S_j x S_k: (3, S, j, k)
        Xv = cross(w[:, :, :, None], v[:, :, None, :]) + cross(v[:, :, :, None], w[:, :, None, :])
        X = np.concatenate([Xw, Xv]).reshape(6, self.S, n * n).transpose(1, 0, 2)
        G = (IC @ X[:, None]).reshape(self.S, n, 6, n, n).transpose(2, 0, 1, 3, 4)   # (6, S, m, j, k)
        for (wj, vj), (fw, fv) in ((((w[:, :, None, :, None], v[:, :, None, :, None]),   # S_j x* IC_m S_k
                                     (F[:3, :, :, None, :], F[3:, :, :, None, :]))),
                                   (((w[:, :, None, None, :], v[:, :, None, None, :]),   # S_k x* IC_m S_j
                                     (F[:3, :, :, :, None], F[3:, :, :, :, None])))):
            G[:3] += cross(wj, fw) + cross(vj, fv)
            G[3:] += cross(wj, fv)
        G = G.transpose(1, 2, 3, 4, 0)                                      # (S, m, j, k, 6)
        # a(i, k): k if i <= k, i if k < i, none otherwise
        a = np.where(self.anc, np.arange(n)[None, :], np.arange(n)[:, None])   # a[i, k]
        related = self.anc | self.anc.T
        jk = self.anc                                                       # j <= k
        idx = np.arange(n)
        H = G[:, a[:, None, :], idx[None, :, None], idx[None, None, :]]      # G[a(i, k), j, k]
        T = 0.5 * np.einsum("sid,sijkd->sijk", Sj, H)
        T = T * (jk[None, None] & related.T[None, :, None, :])
        return T + T.transpose(0, 1, 3, 2) * (1 - np.eye(n))[None, None]

    def _inertia(self, w, v, rows=slice(None), cols=slice(None)):
        """I_i (w, v) = (Ic w + com x m v_c, m v_c), v_c = v + w x com, for the spatial inertias of
        the bodies ``cols`` at the configurations ``rows`` (component-first motion (w, v))."""
        com, Ic, m = self.com[:, rows][..., cols], self.Ic[:, :, rows][..., cols], self.mass[cols]
        lin = m * (v + cross(w, com))
        ang = np.einsum("ij...,j...->i...", Ic, np.broadcast_to(w, lin.shape)) + cross(com, lin)
        return ang, lin

    def coriolis_products(self, rows, v):
        """(C(q, v) v, C(q, v)^T C(q, v) v) for the pairs (configuration rows[k], vector v[k]).

        Parameters
        ----------
        rows : (P,) indices into the configurations;  v : (P, n) vectors

        Returns
        -------
        (c (P, n), h (P, n))."""
        sw, sv = self.sw[:, rows], self.sv[:, rows]
        com, Ic, m = self.com[:, rows], self.Ic[:, :, rows], self.mass
        down, up = self._down, self._up

        def inertia(w, u):
            lin = m * (u + cross(w, com))
            return np.einsum("ij...,j...->i...", Ic, w) + cross(com, lin), lin

        def forces(Aw, Av, Xw, Xv, Yw, Yv):
            """I A + (X x* I Y + Y x* I X) / 2 per body (the symmetrised velocity product)."""
            fw, fv = inertia(Aw, Av)
            for (aw, av), (bw, bv) in (((Xw, Xv), (Yw, Yv)), ((Yw, Yv), (Xw, Xv))):
                nw, nv = inertia(bw, bv)
                fw += 0.5 * (cross(aw, nw) + cross(av, nv))
                fv += 0.5 * cross(aw, nv)
            return fw, fv

        def torque(fw, fv):
            return dot(sw, up(fw)) + dot(sv, up(fv))

        Vw, Vv = down(sw * v), down(sv * v)                                # body velocities V_i
        dSw, dSv = cross(Vw, sw), cross(Vw, sv) + cross(Vv, sw)            # dS_j = V_j x S_j
        c = torque(*forces(down(dSw * v), down(dSv * v), Vw, Vv, Vw, Vv))
        Ww, Wv = down(sw * c), down(sv * c)                                # W_i for w = c
        dcw, dcv = down(dSw * c), down(dSv * c)                            # sum dS_j c_j
        # B(v, c): A = (sum dS_j c_j + sum dS^c_j v_j) / 2 with dS^c_j = W_j x S_j
        Aw = 0.5 * (dcw + down(cross(Ww, sw) * v))
        Av = 0.5 * (dcv + down((cross(Ww, sv) + cross(Wv, sw)) * v))
        B = torque(*forces(Aw, Av, Vw, Vv, Ww, Wv))
        # Mdot(q, v) c = dS . G + S . dG
        gw, gv = inertia(Ww, Wv)
        iw, iv = inertia(cross(Vw, Ww), cross(Vw, Wv) + cross(Vv, Ww))     # I (V x W)
        kw, kv = inertia(dcw, dcv)
        dgw = cross(Vw, gw) + cross(Vv, gv) - iw + kw
        dgv = cross(Vw, gv) - iv + kv
        Mdc = dot(dSw, up(gw)) + dot(dSv, up(gv)) + dot(sw, up(dgw)) + dot(sv, up(dgv))
        return c, Mdc - B
