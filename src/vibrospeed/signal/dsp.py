"""The few ``scipy.signal`` routines the default estimate path uses, reproduced bit for bit in
numpy (and one numba loop), so that the path does not import ``scipy.signal``.

Why: ``import scipy.signal`` costs ~1 s of CPU (it imports ``scipy.stats``,
``scipy.interpolate``, ``scipy.spatial`` and ``scipy.ndimage`` on the way), a third of a warm
``vibrospeed estimate`` on a short file, for a Butterworth design, a filter loop and a window.

What, each the same numpy operations in the same order as scipy's (``scipy/signal/
_filter_design.py``, ``_signaltools.py``, ``_sosfilt.pyx``, ``windows/_windows.py``,
``_short_time_fft.py``), so the results are the same bits (``tests/test_scale_butter.py``
checks them against the installed scipy):

* :func:`butter_sos`: ``scipy.signal.butter(N, Wn, btype, fs=fs, output="sos")`` for low-, high-
  and band-pass: the analog prototype's poles ``-exp(j pi m / 2N)``, ``m = -N+1, -N+3, .., N-1``;
  the pre-warped corners ``4 tan(pi Wn / 2)`` (``Wn`` in half-cycles per sample); the
  frequency transform (``lp2lp_zpk``, ``lp2hp_zpk``, ``lp2bp_zpk``); the bilinear transform
  ``z = (4 + s) / (4 - s)`` (``bilinear_zpk`` with ``fs = 2``); and ``zpk2sos`` with the
  ``'nearest'`` pairing (the pole nearest the unit circle goes last, each with its nearest zero).
* :func:`sosfilt_zi`: the steady state of a unit step, section by section (``lfilter_zi``:
  ``(I - A^T) zi = b[1:] - a[1:] b[0]`` with ``A`` the companion matrix of ``a``, solved by
  LAPACK's ``gesv`` as numpy's ``linalg.solve``), each section's scaled by the DC gain of the
  sections before it.
* :func:`sosfilt`: transposed direct form II per section (``_sosfilt.pyx``'s loop).
* :func:`sosfreqz`: ``scipy.signal.sosfreqz(sos, worN=f, fs=fs)`` at given frequencies (Horner
  on ``exp(-j w)`` per section, the product of the sections).
* :func:`median_filter`: ``scipy.ndimage.median_filter(x, size, mode="nearest")`` of a finite
  1-D signal, odd ``size`` (``signal.quality``'s spike detector; ``scipy.ndimage`` ~0.1 s).
* :func:`hann`, :func:`get_window`: ``scipy.signal.get_window("hann", M)`` (periodic: the
  symmetric window of ``M + 1`` points, last one dropped) and :func:`psd_window`: a window
  scaled as
  ``ShortTimeFFT(..., scale_to="psd").win`` (by ``1 / sqrt(sum(w^2) fs)``, the sum taken in
  Python's order).
"""

from __future__ import annotations

import numpy as np
from numba import njit

BTYPES = ("lowpass", "highpass", "bandpass")


# ---- Butterworth design (scipy.signal.butter, output="sos") -------------------------------
def butter_sos(N: int, Wn, btype: str, fs: float) -> np.ndarray:
    """Digital Butterworth filter of order ``N`` as second-order sections ``(n_sections, 6)``.

    ``Wn``: the corner in Hz (a pair for ``'bandpass'``), ``0 < Wn < fs / 2``; ``btype`` in
    :data:`BTYPES`. The numbers of ``scipy.signal.butter(N, Wn, btype=btype, fs=fs,
    output="sos")``.
    """
    if btype not in BTYPES:
        raise ValueError(f"btype must be one of {BTYPES}, not {btype!r}")
    if int(N) != N or N < 1:
        raise ValueError("filter order must be a positive integer")
    Wn = np.asarray(Wn, dtype=np.float64)
    fs = float(fs)
    Wn = Wn / (fs / 2)
    if np.any(Wn <= 0) or np.any(Wn >= 1):
        raise ValueError(f"digital filter critical frequencies must be 0 < Wn < fs/2 "
                         f"(fs={fs} -> fs/2={fs / 2})")
    if Wn.size > 1 and not Wn[0] < Wn[1]:
        raise ValueError("Wn[0] must be less than Wn[1]")
    if (Wn.size == 1) != (btype != "bandpass"):
        raise ValueError("one corner for lowpass/highpass, two for bandpass")

    # analog prototype (buttap): no zeros, poles on the left unit half-circle, gain 1
    z = np.asarray([], dtype=np.float64)
    m = np.arange(-N + 1, N, 2, dtype=np.float64)
    p = -np.exp(1j * np.pi * m / (2 * N))  # the middle value 0 gives an exactly real pole
    k = 1.0

    # pre-warp for the bilinear transform with fs = 2 (iirfilter)
    fs2 = 2.0
    warped = 2 * fs2 * np.tan(np.pi * Wn / fs2)

    degree = p.shape[0] - z.shape[0]
    if btype == "lowpass":  # lp2lp_zpk
        wo = float(warped)
        z = wo * z
        p = wo * p
        k = k * wo**degree
    elif btype == "highpass":  # lp2hp_zpk
        wo = float(warped)
        z_hp = np.concatenate((wo / z, np.zeros(degree)))
        p_hp = wo / p
        k = k * np.real(np.prod(-z) / np.prod(-p))
        z, p = z_hp, p_hp
    else:  # lp2bp_zpk
        bw = float(warped[1] - warped[0])
        wo = float(np.sqrt(warped[0] * warped[1]))
        z = z.astype(np.complex128)  # (xp_promote of z with the complex p)
        z_lp = (z * bw / 2).astype(np.complex128)
        p_lp = (p * bw / 2).astype(np.complex128)
        z_bp = np.concatenate((z_lp + np.sqrt(z_lp**2 - wo**2), z_lp - np.sqrt(z_lp**2 - wo**2)))
        p = np.concatenate((p_lp + np.sqrt(p_lp**2 - wo**2), p_lp - np.sqrt(p_lp**2 - wo**2)))
        z = np.concatenate((z_bp, np.zeros(degree)))
        k = k * bw**degree

    # bilinear_zpk, fs = 2
    degree = p.shape[0] - z.shape[0]
    f2 = 2.0 * fs2
    z_z = (f2 + z) / (f2 - z)
    p_z = (f2 + p) / (f2 - p)
    z_z = np.concatenate((z_z, -np.ones(degree)))
    k_z = k * np.real(np.prod(f2 - z) / np.prod(f2 - p))
    return _zpk2sos_nearest(z_z, p_z, k_z)


def _cplxreal(z: np.ndarray, tol: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The complex values of ``z`` with positive imaginary part (each pair's average) and its
    real values, sorted as ``scipy.signal._filter_design._cplxreal``."""
    z = np.atleast_1d(z)
    if z.size == 0:
        return z, z
    if tol is None:
        tol = 100 * np.finfo((1.0 * z).dtype).eps
    z = z[np.lexsort((abs(z.imag), z.real))]
    real_indices = abs(z.imag) <= tol * abs(z)
    zr = z[real_indices].real
    if len(zr) == len(z):
        return np.array([]), zr
    z = z[~real_indices]
    zp = z[z.imag > 0]
    zn = z[z.imag < 0]
    if len(zp) != len(zn):
        raise ValueError("Array contains complex value with no matching conjugate.")
    same_real = np.diff(zp.real) <= tol * abs(zp[:-1])
    diffs = np.diff(np.concatenate(([0], same_real, [0])))
    run_starts = np.nonzero(diffs > 0)[0]
    run_stops = np.nonzero(diffs < 0)[0]
    for i in range(len(run_starts)):
        start = run_starts[i]
        stop = run_stops[i] + 1
        for chunk in (zp[start:stop], zn[start:stop]):
            chunk[...] = chunk[np.lexsort([abs(chunk.imag)])]
    if any(abs(zp - zn.conj()) > tol * abs(zn)):
        raise ValueError("Array contains complex value with no matching conjugate.")
    zc = (zp + zn.conj()) / 2
    return zc, zr


def _nearest_idx(fro: np.ndarray, to, which: str) -> int:
    """Index into ``fro`` of the element nearest ``to`` among the real, complex or any."""
    order = np.argsort(np.abs(fro - to))
    if which == "any":
        return order[0]
    mask = np.isreal(fro[order])
    if which == "complex":
        mask = ~mask
    return order[np.nonzero(mask)[0][0]]


def _poly(zeros: np.ndarray) -> np.ndarray:
    """Coefficients of ``prod (x - zeros)`` by repeated convolution (scipy's ``_pu.poly``);
    real when the zeros are conjugate-symmetric."""
    zeros = np.atleast_1d(np.asarray(zeros))
    if zeros.shape[0] == 0:
        return np.asarray(1.0, dtype=np.real(zeros).dtype)
    a = np.ones((1,), dtype=zeros.dtype)
    one = np.ones_like(zeros[0])
    for zero in zeros:
        a = np.convolve(a, np.stack((one, -zero)), mode="full")
    if np.iscomplexobj(a):
        roots = np.asarray(zeros, dtype=np.complex128)
        if np.all(np.sort(np.imag(roots)) == np.sort(np.imag(np.conj(roots)))):
            a = np.array(np.real(a), copy=True)
    return a


def _section(z: list, p: list) -> np.ndarray:
    """One section ``[b0, b1, b2, 1, a1, a2]`` from up to two zeros and poles, gain 1
    (``_single_zpksos`` through ``zpk2tf``)."""
    sos = np.zeros(6)
    zz = np.asarray(z)
    pp = np.asarray(p)
    k = np.asarray(1, dtype=np.result_type(np.real(zz), np.real(pp), 1))
    b = np.multiply(np.atleast_1d(k), _poly(zz))
    a = np.atleast_1d(_poly(pp))
    sos[3 - len(b):3] = b
    sos[6 - len(a):6] = a
    return sos


def _zpk2sos_nearest(z: np.ndarray, p: np.ndarray, k) -> np.ndarray:
    """``scipy.signal.zpk2sos(z, p, k)`` of a digital filter (pairing ``'nearest'``)."""
    z, p = np.asarray(z), np.asarray(p)
    k = np.asarray(k)
    if len(z) == len(p) == 0:
        return np.asarray([[k, 0.0, 0.0, 1.0, 0.0, 0.0]])
    p = np.concatenate((p, np.zeros(max(len(z) - len(p), 0))))
    z = np.concatenate((z, np.zeros(max(len(p) - len(z), 0))))
    n_sections = (max(len(p), len(z)) + 1) // 2
    if len(p) % 2 == 1:
        p = np.concatenate((p, [0.0]))
        z = np.concatenate((z, [0.0]))
    z = np.concatenate(_cplxreal(z))
    p = np.concatenate(_cplxreal(p))
    if not np.isreal(k):
        raise ValueError("k must be real")
    k = k.real

    def idx_worst(p):  # the pole nearest the unit circle
        return np.argmin(np.abs(1 - np.abs(p)))

    sos = np.zeros((n_sections, 6))
    for si in range(n_sections - 1, -1, -1):
        p1_idx = idx_worst(p)
        p1 = p[p1_idx]
        p = np.delete(p, p1_idx)
        if np.isreal(p1) and np.isreal(p).sum() == 0:
            # the last real pole, with the nearest real zero
            z1_idx = _nearest_idx(z, p1, "real")
            z1 = z[z1_idx]
            z = np.delete(z, z1_idx)
            sos[si] = _section([z1, 0], [p1, 0])
        elif (len(p) + 1 == len(z) and not np.isreal(p1)
              and np.isreal(p).sum() == 1 and np.isreal(z).sum() == 1):
            # one real pole and one real zero left: this complex pole takes a complex zero
            z1_idx = _nearest_idx(z, p1, "complex")
            z1 = z[z1_idx]
            z = np.delete(z, z1_idx)
            sos[si] = _section([z1, z1.conj()], [p1, p1.conj()])
        else:
            if np.isreal(p1):
                prealidx = np.flatnonzero(np.isreal(p))
                p2_idx = prealidx[idx_worst(p[prealidx])]
                p2 = p[p2_idx]
                p = np.delete(p, p2_idx)
            else:
                p2 = p1.conj()
            if len(z) > 0:
                z1_idx = _nearest_idx(z, p1, "any")
                z1 = z[z1_idx]
                z = np.delete(z, z1_idx)
                if not np.isreal(z1):
                    sos[si] = _section([z1, z1.conj()], [p1, p2])
                elif len(z) > 0:
                    z2_idx = _nearest_idx(z, p1, "real")
                    z2 = z[z2_idx]
                    z = np.delete(z, z2_idx)
                    sos[si] = _section([z1, z2], [p1, p2])
                else:
                    sos[si] = _section([z1], [p1, p2])
            else:
                sos[si] = _section([], [p1, p2])
    if len(p) or len(z):
        raise AssertionError("zpk2sos: poles or zeros left unpaired")
    sos[0][:3] *= k
    return sos


# ---- steady state, filter, response ---------------------------------------------------------
def _lfilter_zi(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Steady state of ``lfilter(b, a)`` for a unit step (scipy's ``lfilter_zi``)."""
    b = np.atleast_1d(np.asarray(b))
    a = np.atleast_1d(np.asarray(a))
    while a.shape[0] > 1 and a[0] == 0.0:
        a = a[1:]
    if a.size < 1:
        raise ValueError("There must be at least one nonzero `a` coefficient.")
    if a[0] != 1.0:
        b = b / a[0]
        a = a / a[0]
    n = max(a.shape[0], b.shape[0])
    if a.shape[0] < n:
        a = np.concatenate((a, np.zeros(n - a.shape[0], dtype=a.dtype)))
    elif b.shape[0] < n:
        b = np.concatenate((b, np.zeros(n - b.shape[0], dtype=b.dtype)))
    dt = np.result_type(a, b)
    # companion matrix of a (scipy.linalg.companion): first row -a[1:] / a[0], ones below
    comp = np.zeros((n - 1, n - 1), dtype=np.result_type(a.dtype, 1.0))
    comp[0] = -a[1:] / (1.0 * a[0])
    comp[list(range(1, n - 1)), list(range(0, n - 2))] = 1
    IminusA = np.asarray(np.eye(n - 1) - comp.T, dtype=dt)
    B = b[1:] - a[1:] * b[0]
    return np.linalg.solve(IminusA, B)


def sosfilt_zi(sos: np.ndarray) -> np.ndarray:
    """``(n_sections, 2)``: the state of ``sosfilt`` at rest on a unit constant input
    (``scipy.signal.sosfilt_zi``); multiply by the level."""
    sos = np.asarray(sos)
    if sos.ndim != 2 or sos.shape[1] != 6:
        raise ValueError("sos must be shape (n_sections, 6)")
    if sos.dtype.kind in "biu":
        sos = sos.astype(np.float64)
    zi = np.empty((sos.shape[0], 2), dtype=sos.dtype)
    scale = 1.0
    for section in range(sos.shape[0]):
        b = sos[section, :3]
        a = sos[section, 3:]
        zi[section, ...] = scale * _lfilter_zi(b, a)
        # b.sum() / a.sum(): this section's gain at DC, the steady state of its step response
        scale *= np.sum(b) / np.sum(a)
    return zi


@njit(cache=True)
def _sosfilt_run(sos, x, zi):
    """``x`` through the sections in place from the state ``zi`` (updated in place):
    transposed direct form II, the operations of scipy's ``_sosfilt``."""
    for s in range(x.shape[0]):
        x_n = x[s]
        for i in range(sos.shape[0]):
            x[s] = sos[i, 0] * x_n + zi[i, 0]
            zi[i, 0] = sos[i, 1] * x_n - sos[i, 4] * x[s] + zi[i, 1]
            zi[i, 1] = sos[i, 2] * x_n - sos[i, 5] * x[s]
            x_n = x[s]


def sosfilt(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(y, zf)``: the 1-D float64 signal ``x`` through ``sos`` from the state ``zi``
    ``(n_sections, 2)``, as ``scipy.signal.sosfilt(sos, x, zi=zi)``; neither input is changed."""
    sos = np.ascontiguousarray(sos, dtype=np.float64)
    if sos.ndim != 2 or sos.shape[1] != 6:
        raise ValueError("sos must be shape (n_sections, 6)")
    if not np.all(sos[:, 3] == 1):
        raise ValueError("sos[:, 3] should be all ones")
    y = np.array(x, dtype=np.float64, order="C")
    if y.ndim != 1:
        raise ValueError("x must be 1-D")
    zf = np.array(zi, dtype=np.float64, order="C")
    if zf.shape != (sos.shape[0], 2):
        raise ValueError(f"zi must have shape {(sos.shape[0], 2)}, got {zf.shape}")
    _sosfilt_run(sos, y, zf)
    return y, zf


def sosfreqz(sos: np.ndarray, worN, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """``(f, h)``: the complex response ``h`` of ``sos`` at the frequencies ``worN`` (Hz, an
    array-like; not a number of points), as ``scipy.signal.sosfreqz(sos, worN=worN, fs=fs)``."""
    if isinstance(worN, int | np.integer):
        raise TypeError("worN: give the frequencies (a number of points is not supported)")
    sos = np.atleast_2d(np.asarray(sos))
    if sos.ndim != 2 or sos.shape[1] != 6 or sos.shape[0] == 0:
        raise ValueError("sos must be shape (n_sections, 6), n_sections >= 1")
    fs = float(fs)
    h = 1.0
    for j in range(sos.shape[0]):
        b, a = sos[j, :3], sos[j, 3:]
        w = np.atleast_1d(np.asarray(worN, dtype=np.result_type(b, a)))
        w = 2 * np.pi * w / fs
        zm1 = np.exp(-1j * w)
        h *= _polyval(zm1, b) / _polyval(zm1, a)
        w = w * (fs / (2 * np.pi))
    return w, h


def _polyval(x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``c[0] + c[1] x + c[2] x^2 + ...`` by Horner from the last coefficient
    (``numpy.polynomial.polynomial.polyval``, scipy's ``npp_polyval``)."""
    c0 = np.broadcast_to(np.asarray(c[-1], dtype=np.result_type(c.dtype, x.dtype)), x.shape)
    for i in range(2, c.shape[0] + 1):
        c0 = c[-i, ...] + c0 * x
    return c0


# ---- windows ------------------------------------------------------------------------------
def hann(M: int, sym: bool = False) -> np.ndarray:
    """Hann window of ``M`` points, ``0.5 - 0.5 cos(2 pi n / (M - 1))`` (``sym``) or the
    periodic one, ``0.5 - 0.5 cos(2 pi n / M)`` (the symmetric window of ``M + 1`` points, the
    last one dropped), as scipy's ``windows.hann``: its generalised cosine window on
    ``linspace(-pi, pi)``."""
    if int(M) != M or M < 1:
        raise ValueError(f"window length must be a positive integer, got {M}")
    if M == 1:
        return np.ones(1)
    n = M if sym else M + 1
    a = np.asarray([0.5, 1.0 - 0.5], dtype=np.float64)
    fac = np.linspace(-np.pi, np.pi, n, dtype=np.float64)
    w = np.zeros(n, dtype=np.float64)
    for k in range(a.shape[0]):
        w += a[k] * np.cos(k * fac)
    return w if sym else w[:-1]


def get_window(window: str, Nx: int, fftbins: bool = True) -> np.ndarray:
    """``scipy.signal.get_window`` for ``window = "hann"`` (periodic unless ``fftbins`` is
    False); other windows are not reproduced here."""
    if window not in ("hann", "han"):
        raise ValueError(f"window {window!r}: only 'hann' is reproduced here (scipy.signal has "
                         "the others)")
    if not (Nx > 0 and int(Nx) == Nx):
        raise ValueError(f"Parameter {Nx=} is not a positive integer")
    return hann(Nx, sym=not fftbins)


def psd_window(win: np.ndarray, fs: float) -> np.ndarray:
    """``win`` scaled to a power spectral density, as ``ShortTimeFFT(win, hop, fs,
    scale_to="psd").win``: ``win / sqrt(T^-1 sum win^2)``, ``T = 1 / fs``."""
    T = 1 / fs
    fac = 1 / np.sqrt(sum(win.real**2 + win.imag**2) / T)
    return win * fac


# ---- running median (scipy.ndimage.median_filter, 1-D, mode "nearest") ----------------------
@njit(cache=True)
def _median_nearest(x, size, out):
    """Running median of ``x`` over ``size`` (odd) samples centred on each, the ends extended
    by their first / last value: a sorted copy of the window, the outgoing value removed and
    the incoming one inserted at each step (O(size) per sample)."""
    n = x.shape[0]
    h = size // 2
    buf = np.empty(size)
    for j in range(size):
        v = x[min(max(j - h, 0), n - 1)]
        m = j
        while m > 0 and buf[m - 1] > v:
            buf[m] = buf[m - 1]
            m -= 1
        buf[m] = v
    out[0] = buf[h]
    for i in range(1, n):
        old = x[min(max(i - 1 - h, 0), n - 1)]
        new = x[min(i + h, n - 1)]
        k = 0
        while buf[k] != old:
            k += 1
        for m in range(k, size - 1):
            buf[m] = buf[m + 1]
        m = size - 1
        while m > 0 and buf[m - 1] > new:
            buf[m] = buf[m - 1]
            m -= 1
        buf[m] = new
        out[i] = buf[h]


def median_filter(x: np.ndarray, size: int) -> np.ndarray:
    """Running median of the finite 1-D ``x`` over ``size`` (odd) samples centred on each,
    the ends extended by the edge values: the values of ``scipy.ndimage.median_filter(x,
    size=size, mode="nearest")`` (each output is an input sample, the window's middle order
    statistic, so any exact selection gives the same numbers; of equal zeros either sign)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError("x must be 1-D")
    if int(size) != size or size < 1 or size % 2 == 0:
        raise ValueError(f"size must be a positive odd integer, got {size}")
    if not np.all(np.isfinite(x)):
        raise ValueError("median_filter: x must be finite")
    out = np.empty_like(x)
    if x.size:
        _median_nearest(x, int(size), out)
    return out

