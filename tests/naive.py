"""Plain NumPy references of every BSR sampler update (slow, written for clarity).

Each function follows the corrected conditionals of docs/model.md one formula at a time, with Python
loops where the kernels use fused or blocked loops, and consumes the ``numpy.random.Generator`` in exactly the
order documented in :mod:`bsrbench.models._bsr_kernels`, so the kernels must reproduce these results draw for
draw (up to floating-point rounding).
"""

import math

import numpy as np
from scipy.linalg import solve_triangular

MASK64 = (1 << 64) - 1


def sigmoid(x):
    return 1.0 / (1.0 + np.exp(-x))


def log_sigmoid(x):
    return -np.logaddexp(0.0, -x)


def update_codes(R, D, norms, B, S, W, g_s, g_xy, rng):
    """(b_ki, s_ki) block update, i outer and k inner; drawn first: K x N uniforms, then K x N normals, atom-major
    (``[k, i]`` for atom k and point i)."""
    N, K = B.shape
    U_all = rng.random((K, N))
    Z_all = rng.standard_normal((K, N))
    for i in range(N):
        U = U_all[:, i]
        Zn = Z_all[:, i]
        for k in range(K):
            d = D[k]
            a_old = S[i, k] * B[i, k]
            r_minus = R[i] + d * a_old  # residual without atom k
            tau = g_s + g_xy * np.dot(d, d)
            mu = g_xy * np.dot(d, r_minus) / tau
            logit = W[i, k] + 0.5 * np.log(g_s / tau) + 0.5 * tau * mu**2
            on = U[k] < sigmoid(logit)
            z = Zn[k]
            s = mu + z / np.sqrt(tau) if on else z / np.sqrt(g_s)
            B[i, k] = int(on)
            S[i, k] = s
            R[i] = r_minus - d * (s if on else 0.0)
    norms[:] = np.sum(D * D, axis=1)


def update_codes_separate(R, D, B, S, W, g_s, g_nx, g_ny, Mx, rng):
    """(b_ki, s_ki) block update with noise precision g_nx on the feature rows and g_ny on the output rows,
    written with the weighted inner products (no rescaling); same draw order as update_codes."""
    N, K = B.shape
    c = np.where(np.arange(D.shape[1]) < Mx, g_nx, g_ny)  # noise precision per row of v
    U_all = rng.random((K, N))
    Z_all = rng.standard_normal((K, N))
    for i in range(N):
        U = U_all[:, i]
        Zn = Z_all[:, i]
        for k in range(K):
            d = D[k]
            a_old = S[i, k] * B[i, k]
            r_minus = R[i] + d * a_old
            tau = g_s + np.sum(c * d * d)
            mu = np.sum(c * d * r_minus) / tau
            logit = W[i, k] + 0.5 * np.log(g_s / tau) + 0.5 * tau * mu**2
            on = U[k] < sigmoid(logit)
            z = Zn[k]
            s = mu + z / np.sqrt(tau) if on else z / np.sqrt(g_s)
            B[i, k] = int(on)
            S[i, k] = s
            R[i] = r_minus - d * (s if on else 0.0)


def update_atoms(V, R, D, norms, B, S, g_xy, g_x, g_y, Mx, rng, g_ny=None):
    """All atoms given the codes: the rows of D^x (D^y) share the precision g_x I + g_xy A A^T
    (g_y I + g_ny A A^T with separate noise precisions; g_xy is then g_nx)."""
    g_ny = g_xy if g_ny is None else g_ny
    K, M = D.shape
    A = (B * S).T  # K x N
    E = rng.standard_normal((K, M))
    N = A.shape[1]
    if (
        N * N * K + 2 * N**3 / 3 + 4 * N * N * M < N * K * K + 2 * K**3 / 3 + 2 * K * K * M
    ):  # N x N form
        E2 = rng.standard_normal((N, M))
        for lo, hi, g, gn in ((0, Mx, g_x, g_xy), (Mx, M, g_y, g_ny)):
            if hi > lo:
                D[:, lo:hi] = atoms_woodbury(A, V[:, lo:hi], g, gn, E[:, lo:hi], E2[:, lo:hi])
        norms[:] = np.sum(D * D, axis=1)
        R[:, :] = V - A.T @ D
        return
    for lo, hi, g, gn in ((0, Mx, g_x, g_xy), (Mx, M, g_y, g_ny)):
        if hi == lo:
            continue
        P = g * np.eye(K) + gn * A @ A.T
        L = np.linalg.cholesky(P)  # P = L L^T
        mean_part = solve_triangular(L, gn * A @ V[:, lo:hi], lower=True)
        D[:, lo:hi] = solve_triangular(L.T, mean_part + E[:, lo:hi], lower=False)
    norms[:] = np.sum(D * D, axis=1)
    R[:, :] = V - A.T @ D


def atoms_woodbury(A, X, g, gn, E1, E2):
    """A draw of the atoms' rows (K, p) with precision ``P = g I_K + gn A A^T`` and mean ``P^-1 gn A X`` (A: K x N
    codes, X: N x p data columns) from standard normals E1 (K, p) and E2 (N, p), by the N x N form of
    Bhattacharya, Chakraborty & Mallick (2016, Algorithm 1) with ``Phi = sqrt(gn) A^T`` and prior covariance
    ``I / g``: ``u = E1 / sqrt(g)``, ``v = Phi u + E2``, ``w = (Phi Phi^T / g + I)^-1 (sqrt(gn) X - v)``,
    ``u + Phi^T w / g``. Linear in (E1, E2), so its mean and covariance can be checked exactly."""
    N = A.shape[1]
    Phi = np.sqrt(gn) * A.T
    u = E1 / np.sqrt(g)
    v = Phi @ u + E2
    w = np.linalg.solve(Phi @ Phi.T / g + np.eye(N), np.sqrt(gn) * X - v)
    return u + Phi.T @ w / g


def update_atoms_single(R, D, norms, B, S, g_xy, g_x, g_y, Mx, rng, g_ny=None):
    """One atom at a time: d_k | rest with precision g + g_xy sum_i alpha_ki^2 and mean
    g_xy sum_i alpha_ki r_i^(-k) / precision (docs/model.md, section "Atoms"), then the residual without and with
    the new atom
    (g_ny in place of g_xy on the output rows with separate noise precisions)."""
    g_ny = g_xy if g_ny is None else g_ny
    K, M = D.shape
    E = rng.standard_normal((K, M))
    A = B * S
    for k in range(K):
        a = A[:, k]
        r_minus = R + np.outer(a, D[k])
        for lo, hi, g, gn in ((0, Mx, g_x, g_xy), (Mx, M, g_y, g_ny)):
            p = g + gn * (a @ a)
            D[k, lo:hi] = gn * (a @ r_minus[:, lo:hi]) / p + E[k, lo:hi] / np.sqrt(p)
        R[:, :] = r_minus - np.outer(a, D[k])
    norms[:] = np.einsum("km,km->k", D, D)


def update_precisions(R, D, S, prec, Mx, a0, b0, rng, a_xy=None, b_xy=None, separate=False):
    """Gamma(shape, rate) conditionals of g_s, g_xy (or g_nx, g_ny), g_x, g_y, in that order.
    prec = [g_s, g_xy, g_x, g_y, g_nx, g_ny]; with separate noise g_xy is M / (Mx / g_nx + My / g_ny)."""
    a_xy = a0 if a_xy is None or a_xy < 0 else a_xy
    b_xy = b0 if b_xy is None or b_xy < 0 else b_xy
    N, K = S.shape
    M = D.shape[1]
    prec[0] = rng.gamma(a0 + N * K / 2, 1.0 / (b0 + 0.5 * np.sum(S**2)))
    if separate:
        prec[4] = rng.gamma(a_xy + N * Mx / 2, 1.0 / (b_xy + 0.5 * np.sum(R[:, :Mx] ** 2)))
        if M > Mx:
            prec[5] = rng.gamma(
                a_xy + N * (M - Mx) / 2, 1.0 / (b_xy + 0.5 * np.sum(R[:, Mx:] ** 2))
            )
            prec[1] = M / (Mx / prec[4] + (M - Mx) / prec[5])
        else:
            prec[1] = prec[4]
    else:
        prec[1] = prec[4] = prec[5] = rng.gamma(a_xy + N * M / 2, 1.0 / (b_xy + 0.5 * np.sum(R**2)))
    prec[2] = rng.gamma(a0 + Mx * K / 2, 1.0 / (b0 + 0.5 * np.sum(D[:, :Mx] ** 2)))
    if M > Mx:
        prec[3] = rng.gamma(a0 + (M - Mx) * K / 2, 1.0 / (b0 + 0.5 * np.sum(D[:, Mx:] ** 2)))


def log_target_w(w, z, Sigma_inv, w_mean=0.0):
    """log N(w; m 1, Sigma) + sum_i log sigmoid(z_i w_i), up to a constant."""
    u = w - w_mean
    return -0.5 * u @ Sigma_inv @ u + np.sum(log_sigmoid(z * w))


def update_w_mh(W, B, Sigma, Lw, rng, ratio="exact", w_mean=0.0):
    """MH with proposal N(m + Sigma Lambda(w), Sigma), written with explicit Gaussian densities.

    ratio "exact": p(w') q(w | w') / (p(w) q(w' | w)); "printed": the paper's printed ratio
    prod_i sig(z w'_i)/sig(z w_i) exp(-Lambda(w) . (w' - w)) with lambda = sigmoid(-z w); "literal": the printed
    ratio with lambda = sigmoid(+z w), as the appendix prints both.
    """
    N, K = W.shape
    Z = 2.0 * B - 1.0
    eps = rng.standard_normal((K, N)).T  # column k drives atom k
    U = rng.random(K)
    Sigma_inv = np.linalg.inv(Sigma)
    sign = 1.0 if ratio == "literal" else -1.0
    accepted = 0
    for k in range(K):
        z, w = Z[:, k], W[:, k].copy()
        lam = z * sigmoid(sign * z * w)
        mu = w_mean + Sigma @ lam
        wp = mu + Lw @ eps[:, k]
        lamp = z * sigmoid(sign * z * wp)
        mup = w_mean + Sigma @ lamp
        if ratio in ("printed", "literal"):
            lr = np.sum(log_sigmoid(z * wp) - log_sigmoid(z * w)) - lam @ (wp - w)
        else:

            def log_q(x, m):  # log N(x; m, Sigma) up to a constant
                return -0.5 * (x - m) @ Sigma_inv @ (x - m)

            lr = (
                log_target_w(wp, z, Sigma_inv, w_mean)
                - log_target_w(w, z, Sigma_inv, w_mean)
                + log_q(w, mup)
                - log_q(wp, mu)
            )
        if np.log(U[k]) < lr:
            W[:, k] = wp
            accepted += 1
    return accepted


def update_w_ess(W, B, Lw, rng, w_mean=0.0):
    """Elliptical slice sampling (Murray, Adams & MacKay 2010, Fig. 2) of each w_k - m (prior N(0, Sigma));
    returns the number of logit vectors that changed."""
    N, K = W.shape
    Z = 2.0 * B - 1.0
    Nu = Lw @ rng.standard_normal((K, N)).T  # column k: atom k's ellipse
    moved = 0
    for k in range(K):
        z, w, nu = Z[:, k], W[:, k].copy(), Nu[:, k]
        log_y = np.sum(log_sigmoid(z * w)) + np.log(rng.random())
        theta = rng.random() * 2 * np.pi
        lo, hi = theta - 2 * np.pi, theta
        while True:
            wp = w_mean + (w - w_mean) * np.cos(theta) + nu * np.sin(theta)
            if np.sum(log_sigmoid(z * wp)) > log_y:
                break
            if theta < 0:
                lo = theta
            else:
                hi = theta
            theta = lo + rng.random() * (hi - lo)
        moved += int(np.any(wp != w))
        W[:, k] = wp
    return moved


def gibbs_sweep(state, data, hyper, rng, w_update="mh", atom_update="block"):
    """codes, atoms (+ residual), precisions, logits; returns [log-lik, active atoms, acceptance]."""
    D, norms, B, S, W, R, prec = state
    V, Mx, Sigma, Lw = data
    a0, b0, a_xy, b_xy, w_mean, noise = hyper
    separate = noise == "separate"
    if separate:
        update_codes_separate(R, D, B, S, W, prec[0], prec[4], prec[5], Mx, rng)
    else:
        update_codes(R, D, norms, B, S, W, prec[0], prec[1], rng)
    g_nx, g_ny = prec[4], prec[5]
    if atom_update == "single":
        update_atoms_single(R, D, norms, B, S, g_nx, prec[2], prec[3], Mx, rng, g_ny)
    else:
        update_atoms(V, R, D, norms, B, S, g_nx, prec[2], prec[3], Mx, rng, g_ny)
    update_precisions(R, D, S, prec, Mx, a0, b0, rng, a_xy, b_xy, separate)
    if w_update == "ess":
        acc = update_w_ess(W, B, Lw, rng, w_mean)
    else:
        ratio = {"mh": "exact", "paper-printed-ratio": "printed", "paper-literal": "literal"}[
            w_update
        ]
        acc = update_w_mh(W, B, Sigma, Lw, rng, ratio, w_mean)
    loglik = 0.0
    for cols, g in ((slice(0, Mx), prec[4]), (slice(Mx, None), prec[5])):
        r = R[:, cols]
        if r.size:
            loglik += 0.5 * r.size * np.log(g / (2 * np.pi)) - 0.5 * g * np.sum(r**2)
    return np.array([loglik, np.sum(B.any(axis=0)), acc / W.shape[1]])


def redraw_data(V, R, D, B, S, g_xy, rng, g_ny=None, Mx=0):
    E = rng.standard_normal(V.shape)
    if g_ny is None:
        E /= np.sqrt(g_xy)
    else:
        E[:, :Mx] /= np.sqrt(g_xy)
        E[:, Mx:] /= np.sqrt(g_ny)
    V[:, :] = (B * S) @ D + E
    R[:, :] = E


# --- prediction ------------------------------------------------------------------------------------------
def _splitmix(state):
    state = (state + 0x9E3779B97F4A7C15) & MASK64
    z = state
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK64
    return state, z ^ (z >> 31)


def _ziggurat_tables(n=256, r=3.6541528853610088, v=4.92867323399e-3):
    """Marsaglia & Tsang (2000): x[0] = v / f(r), x[1] = r, f(x[i + 1]) = f(x[i]) + v / x[i], x[n] = 0."""
    f = lambda x: math.exp(-0.5 * x * x)  # noqa: E731
    x = [v / f(r), r]
    for i in range(1, n - 1):
        x.append(math.sqrt(-2.0 * math.log(f(x[i]) + v / x[i])))
    x.append(0.0)
    return x, [f(xi) for xi in x]


ZIG_X, ZIG_F = _ziggurat_tables()


class SplitMix:
    """The prediction stream: splitmix64 uniforms (53 bits) and ziggurat normals."""

    def __init__(self, seed):
        self.state = int(seed)

    def uniform(self):
        self.state, z = _splitmix(self.state)
        return (z >> 11) / 9007199254740992.0

    def normal(self):
        """Ziggurat: layer from bits 0-7, sign from bit 8, abscissa from bits 11-63 of one output."""
        r = ZIG_X[1]
        while True:
            self.state, z = _splitmix(self.state)
            i, sign = z & 255, -1.0 if (z >> 8) & 1 else 1.0
            x = (z >> 11) / 9007199254740992.0 * ZIG_X[i]
            if x < ZIG_X[i + 1]:
                return sign * x
            if i == 0:
                while True:
                    e1, e2 = -math.log1p(-self.uniform()) / r, -math.log1p(-self.uniform())
                    if 2.0 * e2 > e1 * e1:
                        return sign * (r + e1)
            if ZIG_F[i] + self.uniform() * (ZIG_F[i + 1] - ZIG_F[i]) < math.exp(-0.5 * x * x):
                return sign * x


def point_seed(x, seed):
    h = int(seed)
    for v in np.ascontiguousarray(x, dtype=np.float64).view(np.uint64):
        _, h = _splitmix(h ^ int(v))
    return h


def predict_draws(Xt, Xtr, j, Dx, Dy, Ws, gs, gxy, n_sweeps, seed):
    """Per test point and sample: y = D^y alpha_t after n_sweeps block sweeps on the x rows from zero codes."""
    T, Mx = Xt.shape
    L, K, _ = Dx.shape
    out_y = np.empty((T, L, Dy.shape[2]))
    out_ll = np.empty((T, L))
    for t in range(T):
        dist = np.sum((Xtr - Xt[t]) ** 2, axis=1)
        J = np.argsort(dist, kind="stable")[:j]
        rs = SplitMix(point_seed(Xt[t], seed))
        for l in range(L):
            wt = Ws[l][J].mean(axis=0)
            alpha = np.zeros(K)
            for _ in range(n_sweeps):
                for k in range(K):
                    d = Dx[l, k]
                    r_minus = Xt[t] - Dx[l].T @ alpha + d * alpha[k]
                    tau = gs[l] + gxy[l] * d @ d
                    mu = gxy[l] * d @ r_minus / tau
                    logit = wt[k] + 0.5 * np.log(gs[l] / tau) + 0.5 * tau * mu**2
                    if logit > 37.0 or rs.uniform() < sigmoid(
                        logit
                    ):  # P(on) = 1 in float64: no draw
                        alpha[k] = mu + rs.normal() / np.sqrt(tau)
                    else:
                        alpha[k] = 0.0
            out_y[t, l] = Dy[l].T @ alpha
            r = Xt[t] - Dx[l].T @ alpha
            out_ll[t, l] = 0.5 * Mx * np.log(gxy[l] / (2 * np.pi)) - 0.5 * gxy[l] * r @ r
    return out_y, out_ll


def predict_draws_prior_codes(Xt, Xtr, j, Dx, Dy, Ws, gs, gxy, seed):
    """The paper's text: z_t ~ Bernoulli(sigmoid(w_t)) from the neighbours' mean logits (K uniforms per sample),
    then s_A | x_t, z_t ~ N(g_xy P^-1 D^x_A x_t, P^-1), P = g_s I + g_xy D^x_A D^x_A^T (one normal per active atom)."""
    T, Mx = Xt.shape
    L, K, _ = Dx.shape
    out_y = np.empty((T, L, Dy.shape[2]))
    out_ll = np.empty((T, L))
    for t in range(T):
        dist = np.sum((Xtr - Xt[t]) ** 2, axis=1)
        J = np.argsort(dist, kind="stable")[:j]
        rs = SplitMix(point_seed(Xt[t], seed))
        for l in range(L):
            wt = Ws[l][J].mean(axis=0)
            on = np.array([rs.uniform() < sigmoid(wt[k]) for k in range(K)], dtype=bool)
            A = Dx[l][on]  # active atoms' feature parts, one per row
            alpha = np.zeros(K)
            if on.any():
                P = gs[l] * np.eye(A.shape[0]) + gxy[l] * A @ A.T
                Lc = np.linalg.cholesky(P)
                mean = np.linalg.solve(P, gxy[l] * A @ Xt[t])
                eps = np.array([rs.normal() for _ in range(A.shape[0])])
                alpha[on] = mean + solve_triangular(Lc.T, eps, lower=False)
            out_y[t, l] = Dy[l].T @ alpha
            r = Xt[t] - Dx[l].T @ alpha
            out_ll[t, l] = 0.5 * Mx * np.log(gxy[l] / (2 * np.pi)) - 0.5 * gxy[l] * r @ r
    return out_y, out_ll


def fista_codes(Z, D, alpha, C0=None, n_iter=200, tol=1e-7):
    """DDL's Lasso codes ``argmin_C 0.5 ||Z - C D||^2 + alpha ||C||_1`` of all rows at once: FISTA (Beck &
    Teboulle 2009) in whole-array NumPy, the reference of :func:`bsrbench.models._ddl_kernels.fista_codes`."""
    G = D @ D.T
    L = float(np.linalg.eigvalsh(G)[-1]) if G.size else 1.0
    L = L if L > 0 else 1.0
    ZD = Z @ D.T
    C = np.zeros((Z.shape[0], D.shape[0])) if C0 is None else C0.copy()
    V = C.copy()
    t = 1.0
    thr = alpha / L
    for _ in range(n_iter):
        W = V - (V @ G - ZD) / L
        C_new = np.sign(W) * np.maximum(np.abs(W) - thr, 0.0)
        t_new = 0.5 * (1.0 + np.sqrt(1.0 + 4.0 * t * t))
        V = C_new + ((t - 1.0) / t_new) * (C_new - C)
        change = np.max(np.abs(C_new - C)) if C.size else 0.0
        C, t = C_new, t_new
        if change < tol:
            break
    return C


def coupled_dictionary_learning(Z, n_components, alpha, max_iter, tol, rng):
    """DDL's dictionary learning in whole-array NumPy (reference of bsrbench.models.ddl's): FISTA codes, then
    Mairal et al.'s (JMLR 2010) block-coordinate atom update, unused atoms re-drawn from the data."""
    n, p = Z.shape
    idx = rng.choice(n, size=n_components, replace=n_components > n)
    D = Z[idx] + 1e-3 * rng.standard_normal((n_components, p)) * (np.std(Z) + 1e-12)
    D /= np.maximum(np.linalg.norm(D, axis=1, keepdims=True), 1e-12)
    C = None
    prev = np.inf
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is returned
        C = fista_codes(Z, D, alpha, C0=C, n_iter=60)
        A = C.T @ C
        B = Z.T @ C
        for k in range(n_components):
            if A[k, k] < 1e-12:
                d = Z[rng.integers(n)] + 1e-3 * rng.standard_normal(p)
            else:
                d = D[k] + (B[:, k] - D.T @ A[:, k]) / A[k, k]
            D[k] = d / max(np.linalg.norm(d), 1.0)
        obj = 0.5 * np.sum((Z - C @ D) ** 2) + alpha * np.abs(C).sum()
        if abs(prev - obj) <= tol * max(abs(obj), 1e-12):
            break
        prev = obj
    C = fista_codes(Z, D, alpha, C0=C, n_iter=300)
    return D, C, it


def similarity_align_per_pose(P_pred, P_true):
    """PA-MPJPE's alignment one pose at a time: SciPy's Kabsch rotation (``Rotation.align_vectors``), then the
    least-squares scale given that rotation; a pose with all joints at one point only translated."""
    from scipy.spatial.transform import Rotation

    out = []
    for A, B in zip(np.asarray(P_pred, float), np.asarray(P_true, float)):
        a0, b0 = A.mean(axis=0), B.mean(axis=0)
        Ac, Bc = A - a0, B - b0
        norm = float(np.sum(Ac * Ac))
        if norm == 0.0:
            out.append(np.broadcast_to(b0, B.shape).copy())
            continue
        RA = Rotation.align_vectors(Bc, Ac)[0].apply(Ac)
        out.append(float(np.sum(RA * Bc)) / norm * RA + b0)
    return np.stack(out)
