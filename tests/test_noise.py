"""Tests of the sensor noise models."""

import numpy as np
import pytest

from topomap.worlds.noise import DropoutNoise, GaussianNoise, MultiplicativeNoise, NoNoise

MODELS = [NoNoise(), GaussianNoise(0.05), DropoutNoise(0.2), MultiplicativeNoise(0.2)]


@pytest.fixture
def X():
    return np.random.default_rng(1).uniform(0.2, 1.0, size=(2000, 15))


@pytest.mark.parametrize("model", MODELS, ids=repr)
def test_input_not_mutated_and_shape_kept(model, X):
    before = X.copy()
    out = model.apply(X, np.random.default_rng(0))
    assert np.array_equal(X, before)
    assert out.shape == X.shape and out is not X and np.all(out >= 0)


@pytest.mark.parametrize("model", MODELS, ids=repr)
def test_reproducible(model, X):
    a = model.apply(X, np.random.default_rng(5))
    b = model.apply(X, np.random.default_rng(5))
    assert np.array_equal(a, b)


def test_no_noise_identity(X):
    assert np.array_equal(NoNoise().apply(X, np.random.default_rng(0)), X)


def test_gaussian_preserves_mean_and_has_sigma(X):
    out = GaussianNoise(0.05).apply(X, np.random.default_rng(0))
    diff = out - X
    assert abs(diff.mean()) < 0.002
    assert diff.std() == pytest.approx(0.05, rel=0.05)


def test_gaussian_clips_at_zero():
    out = GaussianNoise(0.1).apply(np.zeros((100, 5)), np.random.default_rng(0))
    assert np.all(out >= 0) and (out == 0).mean() == pytest.approx(0.5, abs=0.1)


def test_dropout_fraction(X):
    out = DropoutNoise(0.1).apply(X, np.random.default_rng(0))
    zeroed = out == 0
    assert zeroed.mean() == pytest.approx(0.1, abs=0.01)
    assert np.array_equal(out[~zeroed], X[~zeroed])
    assert np.array_equal(DropoutNoise(0.0).apply(X, np.random.default_rng(0)), X)


def test_multiplicative_gain(X):
    out = MultiplicativeNoise(0.1).apply(X, np.random.default_rng(0))
    logs = np.log(out / X)
    assert abs(logs.mean()) < 0.01 and logs.std() == pytest.approx(0.1, rel=0.05)
    zeros = MultiplicativeNoise(0.3).apply(np.zeros((3, 4)), np.random.default_rng(0))
    assert np.array_equal(zeros, np.zeros((3, 4)))


@pytest.mark.parametrize(
    "make, word",
    [
        (lambda: GaussianNoise(-0.1), "sigma"),
        (lambda: GaussianNoise(float("nan")), "sigma"),
        (lambda: MultiplicativeNoise(-1), "sigma"),
        (lambda: DropoutNoise(1.0), "p"),
        (lambda: DropoutNoise(-0.1), "p"),
        (lambda: DropoutNoise("a"), "p"),
    ],
)
def test_bad_parameters(make, word):
    with pytest.raises(ValueError, match=word):
        make()
