"""coopsim.analysis.spectrum: a sine's amplitude and frequency read back, a component above the Nyquist
limit found where it folds (|f - rate|) with an AliasingWarning when asked about, several signals at once,
and bad input in one line."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from coopsim import analysis


def _signal(rate, seconds=2.0):
    t = np.arange(0.0, seconds, 1.0 / rate)
    return t, 0.5 * np.sin(2 * np.pi * 55.0 * t) + 0.2 * np.cos(2 * np.pi * 120.0 * t) + 3.0


def test_a_sines_amplitude_and_frequency_are_read_back():
    t, x = _signal(1000.0)
    s = analysis.spectrum(t, x, f_max=150.0)
    assert s.rate == pytest.approx(1000.0) and s.nyquist == pytest.approx(500.0)
    peaks = s.peaks(2)
    np.testing.assert_allclose(peaks[:, 0], [55.0, 120.0], atol=1e-9)
    np.testing.assert_allclose(peaks[:, 1], [0.5, 0.2], rtol=1e-5)
    assert s.amplitude[0] < 1e-6                        # the mean is removed (the window leaves 4e-9)


def test_a_component_above_nyquist_folds_and_asking_about_it_warns():
    t, x = _signal(1000.0)
    t5, x5 = t[::5], x[::5]                             # 200 Hz: Nyquist 100 Hz
    with pytest.warns(analysis.AliasingWarning, match=r"150 Hz.*200 Hz.*Nyquist limit is 100 Hz.*log_every=1"):
        s = analysis.spectrum(t5, x5, f_max=150.0)
    np.testing.assert_allclose(s.peaks(2)[:, 0], [55.0, 80.0], atol=1e-9)   # 120 Hz shows at 200 - 120
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        analysis.spectrum(t5, x5, f_max=100.0)          # at the limit: no warning


def test_several_signals_at_once_are_each_ones_spectrum():
    t, x = _signal(1000.0)
    both = analysis.spectrum(t, np.column_stack([x, 2 * x]))
    one = analysis.spectrum(t, x)
    np.testing.assert_allclose(both.amplitude[:, 0], one.amplitude, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(both.amplitude[:, 1], 2 * one.amplitude, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="one signal"):
        both.peaks()


@pytest.mark.parametrize("args, kw, words", [
    ((np.arange(3.0), np.zeros(3)), {}, "k >= 4"),
    ((np.r_[0.0, 0.1, 0.3, 0.4], np.zeros(4)), {}, "uniform"),
    ((np.arange(5.0), np.zeros(4)), {}, "x must be"),
    ((np.arange(5.0), np.r_[0, 1, np.nan, 0, 0]), {}, "x must be finite"),
    ((np.arange(5.0), np.zeros(5)), {"f_max": -1.0}, "f_max"),
    ((np.arange(5.0), np.zeros(5)), {"window": "kaiser"}, "window"),
    ((np.arange(5.0), np.array(list("abcde"))), {}, "x must be an array of real numbers"),
])
def test_bad_input_is_one_line(args, kw, words):
    with pytest.raises(ValueError) as e:
        analysis.spectrum(*args, **kw)
    assert "\n" not in str(e.value) and words in str(e.value)
