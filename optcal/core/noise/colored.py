"""Power-law sensor noise of given Allan-deviation coefficients: white (N), flicker (B) and random walk (K).

The three terms are those the Allan-variance fit of :mod:`optcal.core.noise.fit` reads (IEEE Std 952-1997,
Annex C; El-Sheimy, Hou & Niu, IEEE Trans. Instrum. Meas. 57(1), 2008), with the same two-sided power
spectral densities, so that what this module draws is what ``optcal noise`` reports back:

* white, density N (units/√Hz): S(f) = N², σ_A(τ) = N/√τ; per sample an SD of N·√f_s;
* flicker, bias instability B (units): S(f) = B²/(2π|f|), σ_A(τ) = √(2 ln 2/π)·B ≈ 0.664·B at every τ;
* random walk, K (units/√s): S(f) = K²/(2πf)², σ_A(τ) = K·√(τ/3).

White noise is drawn sample by sample (independent normal draws are white exactly). Flicker and random walk
are shaped in the frequency domain: complex normal coefficients of amplitude √(S(f)·f_s·M/2) per rfft bin
(the Nyquist bin real, the mean bin zero), inverted by one ``numpy.fft.irfft`` for all axes at once. The
inverse transform is periodic, so the series is generated over M ≥ 2n samples and its first n kept: the
end does not wrap onto the start, and the lowest frequency present, f_s/M, lies below the 1/T of the
kept stretch, which is all an Allan deviation at τ ≤ T/4 sees of it.
"""

from __future__ import annotations

import math

import numpy as np

from optcal.core.errors import InputError


def _check(name: str, value, *, positive: bool = False) -> float:
    v = float(value)
    if not math.isfinite(v) or v < 0 or (positive and v == 0):
        raise InputError(f"`{name}` must be a {'positive' if positive else 'non-negative'} finite number; "
                         f"got {value!r}")
    return v


def colored_noise(n: int, rate_hz: float, rng: np.random.Generator, *, white: float = 0.0,
                  flicker: float = 0.0, random_walk: float = 0.0, axes: int = 3) -> np.ndarray:
    """``n`` samples at ``rate_hz`` Hz on ``axes`` independent axes, shape (n, axes): white noise of density
    ``white`` = N (units/√Hz), flicker noise of bias instability ``flicker`` = B (units) and a random walk
    of coefficient ``random_walk`` = K (units/√s), summed; zero mean in expectation. Every draw comes from
    ``rng``."""
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise InputError(f"`n` must be a positive whole number of samples; got {n!r}")
    if isinstance(axes, bool) or int(axes) != axes or axes < 1:
        raise InputError(f"`axes` must be a positive whole number; got {axes!r}")
    n, axes = int(n), int(axes)
    fs = _check("rate_hz", rate_hz, positive=True)
    N, B, K = _check("white", white), _check("flicker", flicker), _check("random_walk", random_walk)
    out = np.zeros((n, axes))
    if N > 0:
        out += rng.standard_normal((n, axes)) * (N * math.sqrt(fs))
    if B > 0 or K > 0:
        import scipy.fft

        m = scipy.fft.next_fast_len(2 * n, real=True)
        f = np.fft.rfftfreq(m, 1.0 / fs)[1:]
        S = B**2 / (2.0 * math.pi * f) + K**2 / (2.0 * math.pi * f) ** 2  # two-sided PSD, units²/Hz
        amp = np.sqrt(S * fs * m / 2.0)
        X = np.zeros((f.size + 1, axes), complex)
        X[1:] = amp[:, None] * (rng.standard_normal((f.size, axes)) + 1j * rng.standard_normal((f.size, axes)))
        if m % 2 == 0:  # the Nyquist bin is real: its one coefficient carries the bin's whole variance
            X[-1] = math.sqrt(2.0) * amp[-1] * rng.standard_normal(axes)
        out += np.fft.irfft(X, m, axis=0)[:n]
    return out
