"""Analysis of logged signals: the amplitude spectrum of a uniformly sampled quantity, with its Nyquist limit
stated and a warning when a caller asks about frequencies the samples cannot resolve.

A log row every ``log_every`` steps of ``dt`` samples at ``1 / (log_every dt)`` Hz: it resolves frequencies
up to half that (the Nyquist limit), and a component above it folds back (aliases) to ``|f - k fs|`` below
it, where it cannot be told from a real one. ``coopsim.Simulation(log_every=1)`` logs every step.
"""
from __future__ import annotations

import warnings
from typing import NamedTuple, Optional

import numpy as np

from . import _checks

__all__ = ["AliasingWarning", "Spectrum", "spectrum"]


class AliasingWarning(UserWarning):
    """A frequency asked about lies above the Nyquist limit of the samples (half their rate): what the
    samples show there is a folded image of a component, or nothing."""


class Spectrum(NamedTuple):
    """An amplitude spectrum: f (m,) Hz from 0 to the Nyquist limit, amplitude (m,) or (m, c) in the signal's
    units (a sine of amplitude A reads A at its frequency, to the window's resolution), rate (Hz) the
    samples' and nyquist (Hz) half of it."""

    f: np.ndarray
    amplitude: np.ndarray
    rate: float
    nyquist: float

    def peaks(self, count: int = 3, separation: float = 3.0) -> np.ndarray:
        """The `count` largest local maxima of a 1-D spectrum at least `separation` Hz apart, largest first:
        (k, 2) rows [frequency Hz, amplitude]. The zero-frequency bin is left out."""
        a = np.asarray(self.amplitude)
        if a.ndim != 1:
            raise ValueError(f"peaks: the spectrum of one signal, got amplitudes of shape {a.shape}")
        inner = np.r_[False, (a[1:-1] >= a[:-2]) & (a[1:-1] >= a[2:]), False] if len(a) > 2 else np.zeros(len(a), bool)
        order = [i for i in np.argsort(a)[::-1] if inner[i] and i > 0]
        chosen: list = []
        for i in order:
            if all(abs(self.f[i] - self.f[j]) >= separation for j in chosen):
                chosen.append(i)
            if len(chosen) == count:
                break
        return np.array([[self.f[i], a[i]] for i in chosen]).reshape(-1, 2)


def spectrum(t, x, *, f_max: Optional[float] = None, window: str = "hann") -> Spectrum:
    """The amplitude spectrum of x sampled at the uniform times t.

    t (k,) s, increasing, uniform (each interval within 1e-6 of their mean, relative), k >= 4; x (k,) or (k, c),
    finite. The mean is removed and the signal windowed (``window``: "hann", which keeps a sine's amplitude
    with a correction of 2, or "none"). f_max (Hz): the highest frequency the caller means to read; above the
    samples' Nyquist limit (half their rate) it is an :class:`AliasingWarning` naming both and the log rate
    that would resolve it. Returns a :class:`Spectrum`.
    """
    t, x = _checks.real_array(t, "t"), _checks.real_array(x, "x")
    for a, name in ((t, "t"), (x, "x")):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite (got NaN or inf)")
    if t.ndim != 1 or len(t) < 4:
        raise ValueError(f"t must be (k,) with k >= 4 samples, got shape {t.shape}")
    if x.ndim not in (1, 2) or x.shape[0] != len(t):
        raise ValueError(f"x must be ({len(t)},) or ({len(t)}, c) like t, got shape {x.shape}")
    dt = np.diff(t)
    h = float(dt.mean())
    if not h > 0 or np.abs(dt - h).max() > 1e-6 * h:
        raise ValueError(f"t must be increasing and uniform (intervals within 1e-6 of their mean {h:g} s), got "
                         f"intervals from {dt.min():g} to {dt.max():g} s")
    _checks.one_of(window, "window", ("hann", "none"))
    rate = 1.0 / h
    nyquist = rate / 2.0
    if f_max is not None:
        f_max = _checks.positive(f_max, "f_max", unit="Hz")
        if f_max > nyquist:
            warnings.warn(f"frequencies up to {f_max:g} Hz asked of samples at {rate:g} Hz, whose Nyquist limit is "
                          f"{nyquist:g} Hz: a component above it shows folded below it (at |f - k {rate:g}| Hz); "
                          f"sample at more than {2 * f_max:g} Hz (a log row every step: log_every=1)",
                          AliasingWarning, stacklevel=2)
    y = x - x.mean(axis=0)
    w = np.hanning(len(t)) if window == "hann" else np.ones(len(t))
    if y.ndim == 2:
        w = w[:, None]
    amp = np.abs(np.fft.rfft(y * w, axis=0)) * 2.0 / w.sum(axis=0)
    return Spectrum(np.fft.rfftfreq(len(t), h), amp, rate, nyquist)
