"""The convergence monitor alone: when an iterative fit stops."""

import pytest

from topomap.core.refine.convergence import ConvergenceMonitor


def run(monitor, values):
    """Report ``values`` until the monitor says stop; returns how many were reported."""
    for value in values:
        monitor.report(value)
        if monitor.converged:
            break
    return monitor.iter


def test_it_stops_once_the_gain_is_below_tol():
    m = ConvergenceMonitor(tol=0.5, n_iter=100)
    assert not m.converged and m.history == []
    assert run(m, [-10.0, -8.0, -7.0, -6.6, -6.5, -6.0]) == 4  # -6.6 gains 0.4 < 0.5
    assert m.stalled and m.converged and m.history == [-10.0, -8.0, -7.0, -6.6]


def test_a_gain_of_exactly_tol_goes_on():
    m = ConvergenceMonitor(tol=1.0, n_iter=100)
    m.report(0.0)
    m.report(1.0)
    assert not m.stalled and not m.converged


def test_tol_zero_stops_when_the_value_falls():
    m = ConvergenceMonitor(tol=0.0, n_iter=100)
    assert run(m, [1.0, 2.0, 2.0, 3.0, 2.5, 4.0]) == 5  # equal values go on, a drop stops


def test_it_stops_after_n_iter_reports():
    m = ConvergenceMonitor(tol=0.0, n_iter=3)
    assert run(m, [1.0, 2.0, 3.0, 4.0]) == 3
    assert m.converged and not m.stalled


def test_no_gain_is_judged_before_min_iter():
    m = ConvergenceMonitor(tol=1.0, n_iter=100, min_iter=3)
    assert run(m, [0.0, 0.0, 0.0, 0.0, 0.0]) == 4  # judged from the 4th report on
    m = ConvergenceMonitor(tol=1.0, n_iter=100, min_iter=0)
    assert run(m, [0.0, 0.0, 0.0]) == 2  # a gain needs two values


def test_relative_tolerance_stops_when_the_value_does_not_rise_by_rtol():
    m = ConvergenceMonitor(n_iter=100, rtol=1e-3)
    m.report(-1000.0)
    m.report(-999.5)  # rose 0.5 <= 1e-3 * 1000
    assert m.stalled
    m = ConvergenceMonitor(n_iter=100, rtol=1e-3)
    assert run(m, [-1000.0, -998.0, -997.0, -996.999]) == 4
    assert m.history[-1] == -996.999 and m.stalled
    m = ConvergenceMonitor(n_iter=100, rtol=1e-9)
    assert run(m, [0.0, 0.0]) == 2  # no rise at all stops, also at 0


def test_zero_iterations_are_converged_from_the_start():
    assert ConvergenceMonitor(n_iter=0).converged


@pytest.mark.parametrize("kw", [dict(tol=1e-3), dict(rtol=1e-9)])
def test_repr_names_the_settings(kw):
    m = ConvergenceMonitor(n_iter=5, **kw)
    m.report(1.0)
    assert repr(m).startswith("ConvergenceMonitor(") and "n_iter=5" in repr(m) and "iter=1" in repr(m)
