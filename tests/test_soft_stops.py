"""The soft rounds' optional shortcuts: the forward pass that drops the confusions its message
makes negligible (``reading.read_share``) and the stop once the decoded path settles
(``soft.label_every`` / ``soft.label_tol``)."""

import numpy as np
import pytest

from topomap.core.refine.methods import EMRefinement
from topomap.core.refine.settings import SoftRounds
from topomap.core.refine.soft import soft_round
from topomap.core.refine.soft_kernels import (SoftData, SoftModel, read_tables, soft_candidates,
                                              soft_forward, soft_forward_read, soft_offsets)

from test_soft_refine import RING, _checked, _gapped, _ring_walk, _seq, _tiny

TINY_SYMBOL = np.array([0, 0, 1])    # the clones of _tiny
GAPPED_SYMBOL = np.array([0, 1, 0, 1])


@pytest.mark.parametrize("make, clone_symbol", [(_tiny, TINY_SYMBOL), (_gapped, GAPPED_SYMBOL)])
@pytest.mark.parametrize("prune", [0.0, 0.3])
def test_no_share_is_the_plain_forward_pass_bit_for_bit(make, clone_symbol, prune):
    data, model = make(3)
    pos = soft_offsets(data, model)
    tables = read_tables(model, clone_symbol, model.emit.shape[1])
    got = soft_forward_read(data, model, pos, prune, clone_symbol, tables, 0.0)
    want = soft_forward(data, model, pos, prune)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])


def _two_steps():
    """Clone 0 (symbol 0) moves to clone 1 (symbol 0) with 0.9, to clone 2 (symbol 1) with 0.1;
    both steps read 0, which clone 2 reads with 0.2 and the clones of symbol 0 with 0.8."""
    trans = np.array([[[0.0, 0.9, 0.1], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5]]])
    emit = np.array([[0.8, 0.2], [0.8, 0.2], [0.2, 0.8]])
    init = np.array([1.0, 0.0, 0.0])
    cptr, cidx = soft_candidates(emit)
    data = SoftData(np.array([0, 0]), np.array([0, 0]), np.array([True, False]))
    return data, SoftModel(trans, emit, init, cptr, cidx)


def test_a_symbol_below_the_share_of_the_evidence_is_dropped():
    """At step 1 symbol 1's share of the evidence is 0.1 x 0.2 / (0.9 x 0.8 + 0.1 x 0.2) =
    0.02 / 0.74: above that share its clone gets 0 and clone 1 all the mass; below it, the
    plain pass (0.72 and 0.02 of 0.74)."""
    data, model = _two_steps()
    pos = soft_offsets(data, model)
    tables = read_tables(model, TINY_SYMBOL, 2)
    share = 0.02 / 0.74
    alpha, log_c = soft_forward_read(data, model, pos, 0.0, TINY_SYMBOL, tables, share * 1.01)
    np.testing.assert_allclose(alpha[pos[1]:pos[2]], [0.0, 1.0, 0.0])
    assert log_c[1] == pytest.approx(np.log(0.72))
    alpha, log_c = soft_forward_read(data, model, pos, 0.0, TINY_SYMBOL, tables, share * 0.99)
    np.testing.assert_allclose(alpha[pos[1]:pos[2]], [0.0, 0.72 / 0.74, 0.02 / 0.74])
    assert log_c[1] == pytest.approx(np.log(0.74))


def test_a_small_share_leaves_the_ring_fit_as_it_was():
    """On the ring with 12 % misreads a share of 1e-9 drops nothing that counts: the same map."""
    seq = _seq(*_ring_walk(misread=0.12)[:3])
    plain = EMRefinement(reading={"read_share": 0.0}).fit(seq, RING, 0)
    fit = EMRefinement(reading={"read_share": 1e-9}).fit(seq, RING, 0)
    np.testing.assert_array_equal(fit.labels_, plain.labels_)
    assert fit.n_states_ == plain.n_states_


def test_a_soft_round_stops_once_its_path_settles():
    """``label_tol=1`` stops at the second decoding (``label_every`` 2: the 4th iteration), as
    no two paths differ at every step; ``label_tol=0`` only on a path that did not move."""
    sym, u, lengths, _, _ = _ring_walk(misread=0.12)
    seq = _seq(sym, u, lengths)
    hard = _checked(EMRefinement(evidence="hard"))._hard_round(seq, RING, 0)
    run = {tol: soft_round(seq, hard.labels, hard.state_symbol,
                           soft=SoftRounds(tol=0.0, max_iter=20, label_every=2,
                                           label_tol=tol))
           for tol in (0.0, 1.0)}
    assert run[1.0].info["em_iterations"] == 4
    assert run[0.0].info["em_iterations"] > 4


@pytest.mark.parametrize("group, value, field", [
    ("reading", {"read_share": 1.0}, "reading.read_share"),
    ("soft", {"label_tol": -0.1}, "soft.label_tol"),
    ("soft", {"label_every": -1}, "soft.label_every")])
def test_bad_soft_shortcuts_rejected(group, value, field):
    with pytest.raises(ValueError, match=f"^{field}"):
        EMRefinement(**{group: value}).fit(_seq(*_ring_walk(T=30)[:3]), RING, 0)


def _ring_model(floor_off):
    """A 3-clone model of the ring's symbols whose clones read the other symbols with
    ``floor_off`` each: at 0 every step has one candidate (sparse), at 0.1 three (dense)."""
    emit = np.full((3, 3), floor_off) + np.eye(3) * (1 - 3 * floor_off)
    emit = np.where(emit > 0, emit, 0.0)
    trans = np.full((3, 3, 3), 1 / 3)
    cptr, cidx = soft_candidates(emit)
    return SoftModel(trans, emit, np.full(3, 1 / 3), cptr, cidx)


@pytest.mark.parametrize("floor_off, dense", [(0.0, False), (0.1, True)])
def test_the_share_acts_only_where_candidates_are_dense(monkeypatch, floor_off, dense):
    """``read_share`` runs :func:`soft_forward_read` only where a step's candidates are at least
    ``READ_DENSE`` of the clones on average (1 of 3 is not, 3 of 3 is)."""
    from topomap.core.refine import evidence
    calls = []
    monkeypatch.setattr(evidence, "soft_forward_read",
                        lambda *a: calls.append(1) or soft_forward(*a[:4]))
    sym, u, _, _, _ = _ring_walk(T=60)
    data = SoftData(sym.astype(np.int64), u.astype(np.int64), np.r_[np.ones(59, bool), False])
    evidence.soft_estep(data, _ring_model(floor_off), np.arange(3), prune=1e-6,
                        read_share=1e-3)
    assert bool(calls) == dense
