"""Tiny hand-made worlds whose right answers can be worked out on paper."""

import numpy as np


def ring(n_steps=400, noise=0.01, seed=0, aliased=((1, 4),), n_places=6, two_way=True):
    """Places ``0..n_places-1`` on a ring; action 0 moves forward, action 1 back (if ``two_way``).

    Each place emits a one-hot observation, except that the places of every pair in ``aliased``
    share theirs.  Returns ``(X, actions, places)``.
    """
    rng = np.random.default_rng(seed)
    symbol = np.arange(n_places)
    for a, b in aliased:
        symbol[b] = symbol[a]
    _, symbol = np.unique(symbol, return_inverse=True)
    emit = np.eye(symbol.max() + 1)[symbol]
    p = 0
    places, actions = [], []
    for _ in range(n_steps):
        places.append(p)
        a = int(rng.integers(2)) if two_way else 0
        actions.append(a)
        p = (p + 1) % n_places if a == 0 else (p - 1) % n_places
    places = np.array(places)
    X = emit[places] + rng.normal(0, noise, (n_steps, emit.shape[1]))
    return X, np.array(actions), places
