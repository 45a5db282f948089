import pytest

from topomap_gainratio import GainRatio


def test_stops_when_gain_drops_below_the_ratio():
    rule = GainRatio(ratio=0.5)
    rule.check(10)
    assert [rule.should_stop(n, g) for n, g in [(10, 1.0), (11, 0.6), (12, 0.49)]] == [False, False, True]
    rule.check(10)  # a new fit forgets the first score
    assert rule.should_stop(10, 0.2) is False


def test_max_states_and_validation():
    rule = GainRatio(ratio=0.1, max_states=12)
    rule.check(10)
    assert rule.should_stop(12, 5.0)
    with pytest.raises(ValueError, match="stop.max_states=5"):
        GainRatio(max_states=5).check(10)
    with pytest.raises(ValueError, match="stop.ratio"):
        GainRatio(ratio=0)
