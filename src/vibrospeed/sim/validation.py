"""The thesis' validation signal (thesis eq. 2.2-2.6; METHODS.md 1.1)::

    S_k = sum_{n=1..3} (A_n + e_k1) cos(n w0 t_k + e_k2) + e_k3

    w0 = 1.45 * 2 pi rad/s (9.11 rad/s), A_n = 0.4 + n/10 (0.5, 0.6, 0.7), t_k = k / fs,
    e_k1 ~ U(-0.2, 0.2), e_k2 ~ N(0, 0.01), e_k3 ~ N(0, 0.04)   (second arguments: variances)

The thesis indexes ``e_k1`` and ``e_k2`` by sample only, i.e. the same draw for the three
cosines of one sample; that literal reading is the default (``shared_noise=True``). With
``shared_noise=False`` each harmonic gets its own draws. Either way the least-squares amplitude
of harmonic n is ``A_n E[cos e_k2] = A_n exp(-0.01 / 2)`` ~ 0.995 A_n.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from vibrospeed.errors import ParameterError

W0 = 1.45 * 2.0 * np.pi  # rad/s, thesis eq. 2.2
AMPLITUDES = (0.5, 0.6, 0.7)  # thesis eq. 2.4: 0.4 + n/10


class ValidationSignal(NamedTuple):
    """Samples of eq. 2.6: ``t`` (n,) s and ``y`` (n,) signal units."""

    t: np.ndarray
    y: np.ndarray


def validation_signal(
    n: int,
    rng: np.random.Generator,
    fs: float = 100.0,
    *,
    omega0: float = W0,
    amplitudes: tuple[float, ...] = AMPLITUDES,
    amp_noise: float = 0.2,
    phase_var: float = 0.01,
    noise_var: float = 0.04,
    shared_noise: bool = True,
) -> ValidationSignal:
    """``n`` samples of the thesis eq. 2.6 signal at ``fs`` Hz.

    Parameters
    ----------
    n : number of samples; rng : source of the noise; fs : Hz.
    omega0 : rad/s fundamental (thesis 1.45 * 2 pi); amplitudes : A_1..A_N.
    amp_noise : half-width of the uniform amplitude noise e_k1; phase_var : variance of e_k2
        (rad^2); noise_var : variance of the additive noise e_k3.
    shared_noise : one e_k1, e_k2 per sample for all harmonics (thesis' literal indexing).

    Examples
    --------
    >>> import numpy as np
    >>> t, y = validation_signal(500, np.random.default_rng(0))
    >>> t[1], y.shape
    (np.float64(0.01), (500,))
    """
    if int(n) != n or n < 1:
        raise ParameterError(f"validation signal: n must be a positive integer, got {n}")
    if not fs > 0:
        raise ParameterError(f"validation signal: fs must be > 0 Hz, got {fs}")
    t = np.arange(int(n)) / fs
    amps = np.asarray(amplitudes, dtype=np.float64)[:, None]  # (N, 1)
    harm = np.arange(1, amps.shape[0] + 1, dtype=np.float64)[:, None]
    rows = 1 if shared_noise else amps.shape[0]
    e1 = rng.uniform(-amp_noise, amp_noise, (rows, t.size))
    e2 = rng.normal(0.0, np.sqrt(phase_var), (rows, t.size))
    e3 = rng.normal(0.0, np.sqrt(noise_var), t.size)
    y = np.sum((amps + e1) * np.cos(harm * omega0 * t[None, :] + e2), axis=0) + e3
    return ValidationSignal(t, y)
