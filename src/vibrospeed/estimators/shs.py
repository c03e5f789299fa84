"""Subharmonic summation per batch (Hermes 1988; chassis-vibration paper II-B eq. 6;
METHODS.md 1.4), and the paper's favourable scoring of it.

For every batch of ``batch`` samples (paper: 200 = 2 s at 100 Hz):

1. remove the mean, Hann window, zero-pad to ``n_fft`` and take the magnitude spectrum
   ``|Y(omega)|`` (Hermes smooths the spectrum; the zero-padded Hann spectrum is smooth);
2. interpolate it onto a logarithmic frequency axis ``s = log2(omega)`` with
   ``points_per_octave`` points (Hermes: 48), linearly in omega between FFT bins;
3. sum the shifted, scaled spectra ``H(s) = sum_{k=1..K} h^(k-1) |Y|(s + log2 k)`` (paper eq. 6,
   ``c_k = h^(k-1)``, Hermes ``h = 0.84``); components above Nyquist count as 0;
4. ``omega_hat = 2^argmax_s H(s)`` over ``[omega_min, omega_max]``, refined by a parabola
   through the peak and its neighbours on the log axis.

The paper omits Hermes' peak-enhancement step ("counterproductive in this application"), and
the auditory arc-tangent weighting is meaningless for vibrations: both are left out here.
``K = 5`` harmonics by default (Hermes used 15): with fewer than ~4 terms a missing fundamental
loses to its second harmonic.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np

from vibrospeed.config import is_count
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.types import Estimate, Recording, Track

#: the paper's batch in seconds (200 samples at 100 Hz, paper IV-B)
BATCH_S = 2.0

#: upper bounds of the counts, far above use (defaults 5 harmonics, 4096, 192), so that a typo
#: (1e12) is refused rather than running for hours or allocating TiB: harmonics (one pass over
#: the log axis each), the FFT length (2^24 samples: 128 MiB of spectrum), points per octave
MAX_HARMONICS = 1000
MAX_FFT = 1 << 24
MAX_PER_OCTAVE = 100_000


def default_batch(dt: float, params: dict) -> tuple[int, str]:
    """``(batch, note)``: the samples of :data:`BATCH_S` at period ``dt`` s (200 at 100 Hz, the
    paper's), raised to one period of ``params``' ``omega_min`` (a batch must hold one); the
    note says when the batch is longer than 2 s. A value that is no number is left to
    :class:`Config`'s checks."""
    batch = round(BATCH_S / dt)
    try:
        omega_min = float(params.get("omega_min", Config.omega_min))
    except (TypeError, ValueError):
        return batch, ""
    if not 0 < omega_min < np.inf:
        return batch, ""
    period = int(np.ceil(2 * np.pi / omega_min / dt - 1e-9))
    if period <= batch:
        return batch, ""
    return period, (f"SHS: batches of {period} samples ({period * dt:.3g} s), one period of "
                    f"omega_min = {omega_min:g} rad/s (the paper's 2 s hold less)")


@dataclass(frozen=True)
class Config:
    """SHS parameters.

    dt : sample period T in s (set from the data by :func:`estimate`).
    batch : samples per estimate (paper: 200; :func:`estimate` takes 2 s of the data's rate
        unless given, :func:`default_batch`). n_fft : FFT length (zero padding), >= batch.
    n_harmonics : K. compression : h in ``c_k = h^(k-1)`` (Hermes: 0.84).
    omega_min, omega_max : search range in rad/s (paper grid: [10, 120]).
    points_per_octave : resolution of the log-frequency axis (Hermes: 48; default 192).
    prefilter : pre-filter preset used by :func:`estimate` (paper HP).
    """

    dt: float = 0.01
    batch: int = 200
    n_fft: int = 4096
    n_harmonics: int = 5
    compression: float = 0.84
    omega_min: float = 10.0
    omega_max: float = 120.0
    points_per_octave: int = 192
    prefilter: str = "paper-hp"

    def __post_init__(self) -> None:
        if not 0 < self.dt < np.inf:
            raise ParameterError(f"dt must be finite and > 0 s, got {self.dt}")
        # counts are integers: numpy's buffers, FFT length and the harmonic loop take no float,
        # and a NaN count failed there (points_per_octave <= 0 left one or no candidate)
        for name, least in (("batch", 8), ("n_fft", 8), ("n_harmonics", 1),
                            ("points_per_octave", 1)):
            v = getattr(self, name)
            if not is_count(v, least):
                raise ParameterError(f"{name} must be an integer >= {least}, got {v}")
        if self.n_fft < self.batch:
            raise ParameterError(f"n_fft ({self.n_fft}) must be >= batch ({self.batch})")
        if not 0 < self.compression <= 1:
            raise ParameterError(f"compression must be in (0, 1], got {self.compression}")
        if not 0 < self.omega_min < self.omega_max:
            raise ParameterError(
                f"need 0 < omega_min < omega_max, got [{self.omega_min}, {self.omega_max}]"
            )
        if self.omega_max >= np.pi / self.dt:
            raise ParameterError(
                f"omega_max = {self.omega_max:.4g} rad/s is above the Nyquist limit "
                f"{np.pi / self.dt:.4g} rad/s of fs = {1 / self.dt:.4g} Hz"
            )
        if self.n_harmonics > MAX_HARMONICS:
            raise ParameterError(f"n_harmonics must be at most {MAX_HARMONICS}, got "
                                 f"{self.n_harmonics}")
        if self.n_fft > MAX_FFT:
            raise ParameterError(f"n_fft must be at most {MAX_FFT} (2^24), got {self.n_fft}")
        if self.points_per_octave > MAX_PER_OCTAVE:
            raise ParameterError(f"points_per_octave must be at most {MAX_PER_OCTAVE}, got "
                                 f"{self.points_per_octave}")
        period = 2 * np.pi / self.omega_min
        if self.batch * self.dt < period:
            raise ParameterError(
                f"batch of {self.batch} samples ({self.batch * self.dt:.3g} s) holds less than "
                f"one period ({period:.3g} s) of omega_min = {self.omega_min} rad/s; "
                f"raise batch to >= {int(np.ceil(period / self.dt))}"
            )

    @classmethod
    def from_paper_table1(cls, dt: float = 0.01) -> Config:
        """Paper IV-B: batches of 200 samples, search range of the RBPMF grid [10, 120] rad/s;
        the log axis and compression the paper leaves to Hermes (48 points per octave, 0.84),
        as ``--preset paper``."""
        return cls(dt=dt, batch=200, omega_min=10.0, omega_max=120.0, compression=0.84,
                   points_per_octave=48)

    @property
    def log_axis(self) -> np.ndarray:
        """(L,) candidate omegas in rad/s, log-spaced on [omega_min, omega_max]."""
        octaves = np.log2(self.omega_max / self.omega_min)
        L = int(np.ceil(octaves * self.points_per_octave)) + 1
        return self.omega_min * 2.0 ** np.linspace(0.0, octaves, L)


class State(NamedTuple):
    """Samples of the batch being filled: ``buf`` (batch,), ``count`` in it, batches done."""

    buf: np.ndarray
    count: int
    n_batches: int


class Result(NamedTuple):
    """Batch output: ``omega`` (B,) rad/s per batch (NaN where a batch has < half its samples),
    ``score`` (B,) the summed spectrum at the peak, ``start`` (B,) first sample index."""

    omega: np.ndarray
    score: np.ndarray
    start: np.ndarray
    final: State


def init(config: Config) -> State:
    """Empty batch buffer."""
    return State(np.zeros(config.batch), 0, 0)


def summed_spectrum(config: Config, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(omega_axis (L,), H (L,))``: the subharmonic sum of one batch ``x`` (steps 1-3)."""
    x = np.asarray(x, dtype=np.float64)
    ok = np.isfinite(x)
    xx = np.where(ok, x - (np.mean(x[ok]) if ok.any() else 0.0), 0.0)
    win = np.hanning(x.size)
    mag = np.abs(np.fft.rfft(xx * win, config.n_fft))
    freqs = 2.0 * np.pi * np.fft.rfftfreq(config.n_fft, config.dt)  # rad/s
    axis = config.log_axis
    H = np.zeros(axis.size)
    for k in range(1, config.n_harmonics + 1):
        # |Y|(s + log2 k) = |Y|(k omega): linear interpolation, 0 above Nyquist
        H += config.compression ** (k - 1) * np.interp(k * axis, freqs, mag, right=0.0)
    return axis, H


def batch_estimate(config: Config, x: np.ndarray) -> tuple[float, float]:
    """``(omega_hat, peak value)`` of one batch (step 4); NaN if fewer than half the samples
    are finite."""
    x = np.asarray(x, dtype=np.float64)
    if np.count_nonzero(np.isfinite(x)) < 0.5 * x.size:
        return float("nan"), float("nan")
    axis, H = summed_spectrum(config, x)
    j = int(np.argmax(H))
    s = np.log2(axis)
    if 0 < j < H.size - 1:
        a, b, c = H[j - 1], H[j], H[j + 1]
        den = a - 2 * b + c
        off = 0.5 * (a - c) / den if den < 0 else 0.0
        return float(2.0 ** (s[j] + off * (s[1] - s[0]))), float(b - 0.25 * (a - c) * off)
    return float(axis[j]), float(H[j])


def _check_state(config: Config, state: State) -> None:
    """A state of another batch length gave batches of the wrong length (or numpy's
    broadcast error) instead of the config's."""
    if np.shape(state.buf) != (config.batch,) or not 0 <= state.count < config.batch:
        raise ParameterError(f"shs state: buffer {np.shape(state.buf)} holding {state.count} "
                             f"samples does not match the config's batch = {config.batch}")


def step(config: Config, state: State, y: float) -> tuple[State, Estimate]:
    """Add one sample. The estimate's omega is the batch estimate (rad/s) when this sample
    completes a batch, else NaN (extras ``score``: the summed spectrum at the peak)."""
    _check_state(config, state)
    buf = state.buf.copy()
    buf[state.count] = y
    count = state.count + 1
    if count == config.batch:
        om, sc = batch_estimate(config, buf)
        return (State(np.zeros(config.batch), 0, state.n_batches + 1),
                Estimate(om, extras={"score": sc}))
    return State(buf, count, state.n_batches), Estimate(extras={"score": float("nan")})


def run(config: Config, y: np.ndarray, state: State | None = None) -> Result:
    """All complete batches of ``y`` (a trailing partial batch stays in ``final``); the
    estimates equal those :func:`step` returns."""
    st = init(config) if state is None else state
    _check_state(config, st)
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 1:  # numpy's broadcast error before
        raise InputError(f"shs.run: y must be one-dimensional (n,), got shape {y.shape}")
    L = config.batch
    first = min(L - st.count, y.size)
    buf = st.buf.copy()
    buf[st.count : st.count + first] = y[:first]
    oms, scores, starts = [], [], []
    count = st.count + first
    nb = st.n_batches
    if count == L:
        om, sc = batch_estimate(config, buf)
        oms.append(om)
        scores.append(sc)
        starts.append(-st.count)
        count = 0
        nb += 1
        k = first
        while k + L <= y.size:
            om, sc = batch_estimate(config, y[k : k + L])
            oms.append(om)
            scores.append(sc)
            starts.append(k)
            nb += 1
            k += L
        buf = np.zeros(L)
        count = y.size - k
        buf[:count] = y[k:]
    return Result(np.array(oms), np.array(scores), np.array(starts, dtype=np.int64),
                  State(buf, count, nb))


def estimate(
    recording: Recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool = False,
) -> Track:
    """SHS estimates held over each batch's samples (the trailing partial batch is NaN).

    ``params`` may set any :class:`Config` field except ``dt``. Extras: ``batch_id`` (index of
    the batch each sample belongs to, NaN in the trailing part), ``score``. SHS has no
    uncertainty: ``omega_std`` and the band are NaN.
    """
    from vibrospeed.config import config_from_params
    from vibrospeed.estimators.common import prepare_axis

    params = dict(params or {})
    params.pop("dt", None)
    pre = params.get("prefilter", Config.prefilter)
    y, dt, notes = prepare_axis(recording, axis, prefilter=pre, M=1, normalize_tau=None)
    if "batch" not in params:
        params["batch"], note = default_batch(dt, params)
        if note:
            notes.append(note)
        if "n_fft" not in params:  # zero padding to at least the batch
            params["n_fft"] = max(Config.n_fft, 1 << (params["batch"] - 1).bit_length())
    config = config_from_params(Config, params, dt=dt)
    res = run(config, y)
    n = y.size
    omega = np.full(n, np.nan)
    score = np.full(n, np.nan)
    bid = np.full(n, np.nan)
    for b, k0 in enumerate(res.start):
        omega[k0 : k0 + config.batch] = res.omega[b]
        score[k0 : k0 + config.batch] = res.score[b]
        bid[k0 : k0 + config.batch] = b
    notes.append(f"SHS: one estimate per {config.batch} samples, K = {config.n_harmonics}")
    return Track.from_omega(
        recording.t, omega, None, wheel_radius=wheel_radius or recording.wheel_radius,
        method="shs", params={**asdict(config), "axis": axis}, extras={"batch_id": bid,
                                                                       "score": score},
        notes=notes,
    )


# ------------------------------------------------------------------------------------------
# the paper's favourable scoring (paper IV-C)
# ------------------------------------------------------------------------------------------
class FavourableScore(NamedTuple):
    """rmse (rad/s) over kept detections; kept / total counts; halved: how many were
    corrected from omega/2; corrected (B,) estimates after correction, NaN where dropped."""

    rmse: float
    kept: int
    total: int
    halved: int
    corrected: np.ndarray


def favourable_score(
    omega_est: np.ndarray, omega_true: np.ndarray, *, tol: float = 5.0
) -> FavourableScore:
    """The paper's scoring of SHS: detections within ``tol`` rad/s (paper: 5) of the truth are
    kept; a detection that doubled is within ``tol`` of the truth (within ``tol / 2`` of half
    the truth) is doubled and kept ("we correct for missed detections due to detecting half the
    true fundamental"): every kept value is then within ``tol``; the rest are dropped.

    ``omega_est``, ``omega_true`` : paired (B,) arrays, e.g. batch estimates and the batch
    means of the truth (:func:`batch_means`).
    """
    est = np.asarray(omega_est, dtype=np.float64)
    tru = np.asarray(omega_true, dtype=np.float64)
    if est.shape != tru.shape:
        raise ParameterError(f"estimate shape {est.shape} differs from truth shape {tru.shape}")
    valid = np.isfinite(est) & np.isfinite(tru)
    direct = valid & (np.abs(est - tru) <= tol)
    halved = valid & ~direct & (np.abs(2.0 * est - tru) <= tol)
    corr = np.full(est.shape, np.nan)
    corr[direct] = est[direct]
    corr[halved] = 2.0 * est[halved]
    keep = direct | halved
    rmse = float(np.sqrt(np.mean((corr[keep] - tru[keep]) ** 2))) if keep.any() else float("nan")
    return FavourableScore(rmse, int(keep.sum()), int(valid.sum()), int(halved.sum()), corr)


def batch_means(x: np.ndarray, starts: np.ndarray, batch: int) -> np.ndarray:
    """(B,) NaN-ignoring means of ``x`` over ``[start, start + batch)`` (to compare a filter's
    per-sample estimate with SHS over the same batches, as the paper does)."""
    x = np.asarray(x, dtype=np.float64)
    out = np.full(len(starts), np.nan)
    for b, k0 in enumerate(starts):
        seg = x[max(int(k0), 0) : int(k0) + batch]
        seg = seg[np.isfinite(seg)]
        if seg.size:
            out[b] = seg.mean()
    return out
