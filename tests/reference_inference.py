"""The dense inference :mod:`topomap.core.map.inference` replaced: every step multiplies an S x S
table.  Kept as the reference the compiled, pruned, chunked kernels are checked against."""

import numpy as np

LOG2PI = np.log(2 * np.pi)


def log_obs(m, X):
    """(T, S) Gaussian log-densities, computed directly (no matmul form)."""
    if m.covariance_type == "diag":
        var = m.covariances
        d = X[:, None, :] - m.means[None]
        return -0.5 * ((d**2 / var[None]).sum(-1) + np.log(var).sum(-1)[None]
                       + m.n_features * LOG2PI)
    out = np.empty((X.shape[0], m.n_states))
    for s in range(m.n_states):
        chol = np.linalg.cholesky(m.covariances[s])
        z = np.linalg.solve(chol, (X - m.means[s]).T)
        out[:, s] = -0.5 * ((z**2).sum(0) + 2 * np.log(np.diag(chol)).sum()
                            + m.n_features * LOG2PI)
    return out


def tables(m, X, u, g, smoothing):
    """Emissions (observation, GDS clamp, action term), log transitions and initial logs."""
    S, A = m.n_states, m.n_actions
    log_act = np.log((1 - smoothing) * m.action_probs + smoothing / A)
    emit = log_obs(m, X)
    if g is not None:
        is_gds = m.state_gds >= 0
        allowed = np.where(g[:, None] >= 0, m.state_gds[None] == g[:, None], ~is_gds[None])
        emit = np.where(allowed, emit, -np.inf)
    log_trans = np.log((1 - smoothing) * m.transition_probs + smoothing / S)
    log_init = np.log((1 - smoothing) * m.state_probs + smoothing / S)
    return emit, log_act, log_trans, log_init


def score(m, X, u, g=None, lengths=None, smoothing=1e-6):
    emit, log_act, log_trans, log_init = tables(m, X, u, g, smoothing)
    emit = emit + log_act[:, u].T
    total, start = 0.0, 0
    for n in ([len(u)] if lengths is None else list(lengths)):
        alpha = log_init + emit[start]
        for t in range(1, n):
            top = alpha.max()
            alpha = top + np.log(np.exp(alpha - top) @ np.exp(log_trans[:, u[start + t - 1], :]))
            alpha = alpha + emit[start + t]
        top = alpha.max()
        total += top + np.log(np.exp(alpha - top).sum())
        start += n
    return total / len(u)


def predict(m, X, u, g=None, lengths=None, smoothing=1e-6):
    emit, log_act, log_trans, log_init = tables(m, X, u, g, smoothing)
    emit = emit + log_act[:, u].T
    path, start, S = np.empty(len(u), dtype=np.int64), 0, m.n_states
    for n in ([len(u)] if lengths is None else list(lengths)):
        back = np.zeros((n, S), dtype=np.int64)
        delta = log_init + emit[start]
        for t in range(1, n):
            cand = delta[:, None] + log_trans[:, u[start + t - 1], :]
            back[t] = np.argmax(cand, axis=0)
            delta = cand[back[t], np.arange(S)] + emit[start + t]
        s = int(np.argmax(delta))
        for t in range(n - 1, -1, -1):
            path[start + t] = s
            s = back[t, s]
        start += n
    return path


def filter_beliefs(m, X, u, g=None, lengths=None, smoothing=1e-6):
    emit, log_act, log_trans, log_init = tables(m, X, u, g, smoothing)
    moves = np.exp(log_act[:, :, None] + log_trans)
    out, start = np.empty_like(emit), 0
    for n in ([len(u)] if lengths is None else list(lengths)):
        for t in range(start, start + n):
            prior = np.exp(log_init) if t == start else out[t - 1] @ moves[:, u[t - 1], :]
            b = np.log(prior) + emit[t]
            b = np.exp(b - b.max())
            out[t] = b / b.sum()
        start += n
    return out
