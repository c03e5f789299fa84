"""The grid method: the improved RBPMF plus a harmonic-comb evidence, smoothed offline.

``vibrospeed estimate -m grid`` = :mod:`vibrospeed.estimators.rbpmf` with re-acquisition jumps,
the "no line" state, a tempered per-sample likelihood and, every ``comb_hop`` s, the log-evidence
of a longer window's spectrum for the *comb* of M harmonics of each grid point; offline the
forward-backward smoother (:mod:`.grid_smoother`) runs on top (``smooth="fb"``, the default;
``smooth="none"`` is the causal filter, ``"lag"`` the fixed-lag smoother).

Streaming: ``step`` keeps the last ``W`` s of samples in a ring buffer and computes the frame
evidence when a frame ends (:mod:`vibrospeed.estimators.grid.comb`); ``run`` gives exactly the
numbers of repeated ``step``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

import vibrospeed.estimators.grid.app as _app
import vibrospeed.estimators.grid.config as _cfg
import vibrospeed.estimators.grid.filter as _filt
from vibrospeed.config import config_from_params, parse_flag, parse_value
from vibrospeed.errors import ParameterError
from vibrospeed.estimators.grid.comb import frame_evidence  # noqa: F401 (API)
from vibrospeed.estimators.grid.frames import evidence, frame_ends_at, step_evidence
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.types import Estimate, Recording, Track

#: with several ``comb_axes`` the summed comb evidence is weighted ``A ** -AXES_EXPONENT``
#: (3 axes: 0.4; simulated car, benchmarks/trackers/RESULTS.md)
AXES_EXPONENT = 0.834

#: most samples in one comb frame (``comb_window``): 4 Mi samples (32 MiB a frame and axis,
#: 11.6 h at 100 Hz), far above any window the comb's stationary line can hold
MAX_FRAME = 1 << 22

#: tracker settings of the product on top of the paper's Config (benchmarks/beyond/RESULTS.md,
#: "grid"):
#: jumps 0.05/s, "no line" in 0.01/s out 0.5/s, noise from the marginal-likelihood fits
#: (r 0.15, q_amp 0.002; q_omega 16 (rad/s)^2/s follows car accelerations of ~8 rad/s^2 on
#: a car's 10-120 rad/s range; for other ranges see :func:`q_omega_for`),
#: likelihood tempered to 0.2 per 0.01 s of data (``temper_fs`` 100 Hz: 0.05 per sample at
#: 400 Hz, so the time-domain evidence per second does not grow with the sample rate; the
#: time-domain model, which must explain a vehicle's body motion and resonances with
#: harmonics, misleads where the whitened comb does not, yet it accumulates a weak line
#: coherently over many seconds: benchmarks/robustness/RESULTS.md),
#: adaptive pre-whitening instead of the paper's 8 Hz high-pass (which removes a slow
#: wheel's fundamental).
#: The random walk's kernel on the grid is variance-matched (``kernel_var="matched"``): the
#: paper's sampled Gaussian loses most of its variance once the per-sample step is below a
#: grid spacing (a 20-300 rad/s range at 200 Hz: the walk froze, omega moved by jumps only),
#: so ``q_omega`` now means the same at every sample rate and range.
#: The "no line" state's time-domain emission is the signal part's predictive mixture
#: (``null_model="mixture"``): only the comb evidence decides whether a wheel comb is there.
#: The reported omega is the mean of the MAP mode (``point="mode"``): on a
#: line where the posterior is split (acquisition, an interfering line), the posterior mean
#: (in ``extras["omega_mean"]``) is the MMSE choice but lies between the lines.
#: A line is claimed (``has_signal``) where its posterior probability is at least
#: :data:`CLAIM_LEVEL` for the way the posterior was computed (``claim_level`` unless given).
GRID_DEFAULTS = {
    "jump_rate": 0.05, "off_rate": 0.01, "on_rate": 0.5, "r": 0.15, "q_amp": 0.002,
    "q_omega": 16.0, "temper": 0.2, "temper_fs": 100.0, "prefilter": "whiten",
    "smooth": "fb", "null_model": "mixture", "point": "mode", "kernel_var": "matched",
}

#: ``(q_omega, omega_max)`` of the reference range: the default walk is ``q_omega`` times
#: ``omega_max / 120 rad/s`` (:func:`q_omega_for`)
Q_OMEGA_REF = (16.0, 120.0)


def q_omega_for(omega_max: float) -> float:
    """(rad/s)^2/s, the default omega walk for a search range up to ``omega_max`` rad/s:
    ``q = 16 omega_max / 120``, in proportion to the range (a car's 10-120 rad/s: 16; a
    cart's or forklift's 2-30: 4; a kart's 20-300: 40).

    Why: the walk sets how far omega may move per second against the evidence, and what it
    must not do is hop between a wheel's harmonics, which lie ``omega`` apart. A range a
    user gives scales with the speeds the wheel reaches, so a walk in proportion to it keeps
    the same agility relative to the lines: a fixed 16 lets a slow cart's estimate wander
    across its closely spaced harmonics, and holds a kart's fast wheel back in its corners.
    Measured on the randomised family (carts and forklifts: 4 against 16 and 8) and on the
    GoPro kart (40 against 16): benchmarks/robustness/RESULTS.md, "levers measured in stop
    25"."""
    q_ref, om_ref = Q_OMEGA_REF
    if not (math.isfinite(omega_max) and omega_max > 0):  # named here, before q_omega is
        raise ParameterError(f"omega_max must be a finite number > 0 rad/s, got {omega_max}")
    return q_ref * (float(omega_max) / om_ref)


#: ``claim_level`` per ``smooth``: the line probability at which each claims a line
#: (``has_signal``), chosen so that every mode's claims are within tolerance about 90 % of the
#: time on the randomised family. The causal filter's line probability is over-confident (its
#: claims at 0.9 are right 80 % of the time, at 0.99 90 %), the fixed-lag smoother's less so
#: (0.87 at 0.9, 0.90 at 0.95), the whole-log smoother's hardly (0.92 at 0.9);
#: benchmarks/robustness/RESULTS.md, "claims per mode".
CLAIM_LEVEL = {"fb": 0.9, "lag": 0.95, "none": 0.99}


def _default_tracker(dt: float = 0.01) -> _cfg.Config:
    """The streaming tracker of :class:`Config` (causal: ``smooth="none"``)."""
    return _cfg.improved(_cfg.Config.from_paper_table1(dt), claim_level=CLAIM_LEVEL["none"],
                         **{k: v for k, v in GRID_DEFAULTS.items() if k not in ("smooth",)})


@dataclass(frozen=True)
class Config:
    """Grid tracker parameters.

    tracker : the RBPMF (:class:`vibrospeed.estimators.rbpmf.Config`; grid, model, jumps, "no
        line" state, ``temper``, ``smooth``), defaults :data:`GRID_DEFAULTS`.
    comb_weight : weight of the comb evidence per frame (0: none, the improved RBPMF alone).
    comb_window, comb_hop : s, frame length and spacing of the spectrum.
    comb_snr : SNR ``a`` of a harmonic in the per-harmonic likelihood ratio (module docstring);
        1 scores a weak comb's harmonics (S of 1.5-3 times the background) as present, where 2
        would score them as empty; whether a line is claimed is ``claim_level``'s decision.
    comb_cap : nats, largest evidence one harmonic can contribute.
    comb_bg : Hz, width of the running-median background of the spectrum; a frame of ``w`` s
        uses at least ``6 / w`` Hz (1.5 Hann main lobes, :meth:`background_hz`): with a
        narrower window a line fills the median and whitens itself away (a 1 s start frame's
        main lobe is 4 Hz wide).
    comb_lead : nats, largest lead of the best harmonic's term over the second best (M >= 2):
        ``E = sum_k l_k - l_(1) + min(l_(1), l_(2) + comb_lead)``, so that a hypothesis needs
        at least two harmonics to score; ``inf``: no such limit.
    comb_min_window : s; before ``comb_window`` s of data have been seen (the start, e.g. a
        tracker switched on while driving), frames grow: every ``comb_hop`` s from
        ``comb_min_window`` s on, a frame over all samples seen so far. Without them the comb
        evidence would first arrive after ``comb_window`` s and acquisition from an uninformed
        prior would rest on the time-domain likelihood alone until then (it may take an
        interfering line first). ``>= comb_window``: no growing frames.
    comb_rates : 1/s, relative rates ``(d omega / dt) / omega`` for which each frame is also
        warped (module docstring, "Accelerating combs"); 0 is always included; rates with
        ``beta >= 0.9 / W`` (the warp would fold over the frame) are skipped. Default: +-0.07,
        +-0.15, -0.3, +0.25 (car: 2.5 m/s^2 at 10 m/s is 0.25/s).
    comb_rate_p0 : prior weight of beta = 0 (the others share the rest).
    comb_axes : accelerometer axes whose spectra make the comb evidence together (``x``,
        ``y``, ``z`` or channel names; ``"xyz"``, ``"x:z"`` or ``"all"``: every accelerometer
        axis of the recording); empty: the tracked axis alone. The time-domain likelihood
        stays on the tracked axis. A wheel harmonic reaches each axis with its own slowly
        varying gain, so one axis can lose a harmonic that another still sees: per harmonic
        the A axes' terms are summed before the cap (``A comb_cap``) and the lead
        (``A comb_lead``), and the comb evidence is weighted by :meth:`axes_weight`.
        :func:`estimate` / :func:`config_for` resolve the names against the recording with
        the tracked axis first; :func:`step` then takes one sample per axis in that order.
    """

    tracker: _cfg.Config = field(default_factory=_default_tracker)
    comb_weight: float = 0.5
    comb_window: float = 3.0
    comb_hop: float = 0.25
    comb_snr: float = 1.0
    comb_cap: float = 3.0
    comb_bg: float = 2.0
    comb_lead: float = 0.5
    comb_min_window: float = 1.0
    comb_rates: tuple[float, ...] = (-0.3, -0.15, -0.07, 0.07, 0.15, 0.25)
    comb_rate_p0: float = 0.5
    comb_axes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "comb_rates", _as_rates(self.comb_rates))
        object.__setattr__(self, "comb_axes", _as_axes(self.comb_axes))
        if not 0 < self.comb_rate_p0 <= 1:
            raise ParameterError(f"comb_rate_p0 must be in (0, 1], got {self.comb_rate_p0}")
        for name in ("comb_window", "comb_hop", "comb_snr", "comb_cap", "comb_bg",
                     "comb_min_window"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be > 0, got {getattr(self, name)}")
        # frame lengths and the background median are sample / bin counts: inf died in int(),
        # 1e12 allocating TiB or in a median over 1e12 bins
        dt = self.tracker.model.dt
        for name in ("comb_window", "comb_min_window"):
            if not getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be a finite number > 0 s, got "
                                     f"{getattr(self, name)}")
        if self.comb_window / dt > MAX_FRAME:
            raise ParameterError(f"comb_window must be at most {MAX_FRAME} samples "
                                 f"({MAX_FRAME * dt:.4g} s at {1 / dt:.4g} Hz), got "
                                 f"{self.comb_window} s")
        if not self.comb_bg * dt <= 0.5 + 1e-9:  # Nyquist, read through dt's rounding
            raise ParameterError(f"comb_bg must be > 0 Hz and at most the Nyquist frequency "
                                 f"{0.5 / dt:.4g} Hz (the whole spectrum), got {self.comb_bg}")
        if not self.comb_lead >= 0:
            raise ParameterError(f"comb_lead must be >= 0, got {self.comb_lead}")
        if not self.comb_weight >= 0:
            raise ParameterError(f"comb_weight must be >= 0, got {self.comb_weight}")
        if self.comb_hop > self.comb_window:
            raise ParameterError("comb_hop must be <= comb_window")

    def rates_in_frame(self, L: int, centre: bool = False) -> np.ndarray:
        """The relative rates usable for an ``L``-sample frame: 0 first, and those whose warp
        is monotone over it (``1 + beta s >= 0.1`` on the frame: ``beta < 0.9 / W`` referred to
        its end, ``|beta| < 1.8 / W`` referred to its centre)."""
        W = L * self.tracker.model.dt
        if centre:
            keep = [b for b in self.comb_rates if b != 0.0 and abs(b) < 1.8 / W]
        else:
            keep = [b for b in self.comb_rates if b != 0.0 and b < 0.9 / W]
        return np.concatenate([[0.0], np.array(keep, np.float64)])

    def rate_prior(self, rates: np.ndarray) -> np.ndarray:
        """Prior weights of ``rates`` (0 first): ``comb_rate_p0`` on 0, the rest shared."""
        if rates.size == 1:
            return np.ones(1)
        return np.r_[self.comb_rate_p0,
                     np.full(rates.size - 1, (1.0 - self.comb_rate_p0) / (rates.size - 1))]

    @property
    def n_axes(self) -> int:
        """Axes per sample that :func:`step` / :func:`run` expect (1: a scalar signal)."""
        return max(1, len(self.comb_axes))

    def axes_weight(self, A: int) -> float:
        """Weight of the comb evidence summed over ``A`` axes: ``A ** -AXES_EXPONENT``
        (1 for one axis; between independent axes, 1, and one signal seen A times, 1 / A)."""
        return 1.0 if A <= 1 else float(A) ** -AXES_EXPONENT

    def background_hz(self, L: int) -> float:
        """Hz, running-median width for an ``L``-sample frame: ``comb_bg``, but at least 1.5
        Hann main lobes (``6 / w`` Hz for a frame of ``w`` s)."""
        return max(self.comb_bg, 6.0 / (L * self.tracker.model.dt))

    @property
    def min_frame_len(self) -> int:
        """Samples of the shortest growing (start) or shrinking (end) frame."""
        return max(8, int(round(self.comb_min_window / self.tracker.model.dt)))

    @property
    def frame_len(self) -> int:
        """Samples per frame (at the tracker's sample period)."""
        return max(8, int(round(self.comb_window / self.tracker.model.dt)))

    @property
    def hop_len(self) -> int:
        """Samples between frame ends."""
        return max(1, int(round(self.comb_hop / self.tracker.model.dt)))

    def to_dict(self) -> dict:
        out = self.tracker.to_dict()
        for f in dataclasses.fields(self):
            if f.name != "tracker":
                out[f.name] = getattr(self, f.name)
        return out


def _as_rates(v) -> tuple[float, ...]:
    """Relative rates (1/s) from a tuple or a string separated by ":" or "," (CLI
    ``-p comb_rates=-0.1:0:0.1``)."""
    if isinstance(v, str):
        v = [x for x in v.replace(";", ",").replace(":", ",").split(",") if x.strip()]
    try:
        out = tuple(float(x) for x in np.atleast_1d(v))
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"comb_rates: expected numbers (1/s), got {v!r}") from exc
    if not all(np.isfinite(out)):
        raise ParameterError(f"comb_rates must be finite, got {v!r}")
    return out


def _as_axes(v) -> tuple[str, ...]:
    """Axis names from a tuple or a string (``"xyz"``, ``"x:y:z"``, ``"all"``)."""
    if isinstance(v, str):
        v = (v,)
    out: list[str] = []
    for item in v:
        item = str(item).strip()
        parts = [p.strip() for p in item.replace(",", ":").split(":") if p.strip()]
        for p in parts:
            if len(p) > 1 and set(p) <= set("xyz"):
                out.extend(p)  # "xyz" = x, y, z
            else:
                out.append(p)
    if "all" in out and len(out) > 1:
        raise ParameterError(f"comb_axes: 'all' cannot be combined with other axes, got {v!r}")
    if len(set(out)) != len(out):
        raise ParameterError(f"comb_axes: an axis is named twice in {v!r}")
    return tuple(out)


class State(NamedTuple):
    """``grid``: the RBPMF state; ``buf`` (L,) the last ``frame_len`` samples (ring buffer,
    oldest at ``count % L``; (L, A) with several comb axes); ``count`` samples seen."""

    grid: _filt.State
    buf: np.ndarray
    count: int


class Result(NamedTuple):
    """``filt``: the RBPMF's batch result (with ``grid_loglik`` when asked for);
    ``frames`` (F,) sample indices and ``evidence`` (F, N + 1) of the comb evidence used."""

    filt: _filt.Result
    frames: np.ndarray
    evidence: np.ndarray
    final: State

    def __getattr__(self, name: str):
        # the per-sample columns (omega, omega_std, p_null, ...) are the tracker's
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(tuple.__getitem__(self, 0), name)


# ------------------------------------------------------------------------------------------
# comb evidence

def _push(state_buf: np.ndarray, count: int, y: np.ndarray) -> np.ndarray:
    L = state_buf.shape[0]
    buf = state_buf.copy()
    if y.shape[0] >= L:
        last = y[-L:]
        p = (count + y.shape[0] - L) % L
        buf[p:] = last[: L - p]
        buf[:p] = last[L - p:]
        return buf
    pos = (count + np.arange(y.shape[0])) % L
    buf[pos] = y
    return buf


# ------------------------------------------------------------------------------------------
# filter interface
# ------------------------------------------------------------------------------------------
def init(config: Config, *, n_axes: int | None = None) -> State:
    """RBPMF prior and an empty (zero) frame buffer, (L,) or (L, A) for ``config.n_axes``
    (or ``n_axes``) > 1 comb axes."""
    A = config.n_axes if n_axes is None else n_axes
    L = config.frame_len
    return State(_filt.init(config.tracker), np.zeros(L if A == 1 else (L, A)), 0)


def step(config: Config, state: State, y) -> tuple[State, Estimate]:
    """One sample (pre-filtered, scaled; with several comb axes one per axis, the tracked axis
    first): the frame evidence when a frame ends here, then the RBPMF step with it."""
    buf = state.buf
    count = state.count
    if buf.ndim == 1 and isinstance(y, float):  # one axis, a plain number: no arrays
        ex = (step_evidence(config, buf, count, np.array([y])) if frame_ends_at(config, count)
              else None)
        g, est = _filt.step(config.tracker, state.grid, y, extra=ex)
        nxt = buf.copy()
        nxt[count % nxt.shape[0]] = y
        return tuple.__new__(State, (g, nxt, count + 1)), est  # State(...) without its __new__
    yy = np.asarray(y, dtype=np.float64).reshape(-1)
    A = 1 if buf.ndim == 1 else buf.shape[1]
    if yy.size != A:
        raise ValueError(f"expected {A} sample(s) per step (one per comb axis), got {yy.size}")
    g, est = _filt.step(config.tracker, state.grid, float(yy[0]),
                        extra=step_evidence(config, buf, count, yy))
    buf = buf.copy()
    buf[count % buf.shape[0]] = yy if A > 1 else yy[0]
    return State(g, buf, count + 1), est


def run(config: Config, y: np.ndarray, state: State | None = None, *,
        return_posterior: bool = False, return_grid_loglik: bool = False) -> Result:
    """Batch over ``y`` (n,), or (n, A) with several comb axes (the tracked axis in column
    0); the numbers of repeated :func:`step`."""
    y = np.asarray(y, dtype=np.float64)
    st = init(config, n_axes=1 if y.ndim == 1 else y.shape[1]) if state is None else state
    idx, vals = evidence(config, y, st)
    y0 = np.ascontiguousarray(y if y.ndim == 1 else y[:, 0])
    res = _filt.run(config.tracker, y0, st.grid, return_posterior=return_posterior,
                  return_grid_loglik=return_grid_loglik, extra=(idx, vals))
    return Result(res, idx, vals, State(res.final, _push(st.buf, st.count, y),
                                        st.count + y.shape[0]))


# ------------------------------------------------------------------------------------------
# entry point
# ------------------------------------------------------------------------------------------
_COMB = tuple(f.name for f in dataclasses.fields(Config) if f.name != "tracker")


def _grid_model(dt: float) -> HarmonicModel:
    return _default_tracker(dt).model


def comb_channels(recording: Recording, axis: str, names: tuple[str, ...]) -> tuple[str, ...]:
    """The channels of ``comb_axes`` ``names`` in ``recording``, the tracked ``axis`` first
    (``"all"``: every accelerometer axis ``ax ay az`` present with at least one finite sample);
    empty ``names``: ``()``."""
    from vibrospeed.estimators.common import axis_channel

    if not names:
        return ()
    tracked = axis_channel(axis)
    if names == ("all",):
        chans = [c for c in ("ax", "ay", "az")
                 if c in recording and np.isfinite(recording.channel(c)).any()]
    else:
        chans = [axis_channel(a) for a in names]
        for c in chans:
            if c not in recording:
                raise ParameterError(
                    f"{recording.source or 'recording'}: comb_axes: channel '{c}' is missing "
                    f"(have: {', '.join(sorted(recording.channels))})")
    return (tracked, *[c for c in chans if c != tracked])


def _prepare(recording: Recording, axis: str, params: dict | None):
    """``(config, y, rms, notes)``; ``y`` (n,), or (n, A) with the tracked axis in column 0
    when ``comb_axes`` names other axes too."""
    params = dict(params or {})
    # read as rbpmf reads it (-p improved=perhaps is refused alike); either value is this
    # filter: the grid tracker is the improved RBPMF (GRID_DEFAULTS) whatever it says
    parse_flag(params.pop("improved", True), "improved")
    comb_kw = {k: params.pop(k) for k in list(params) if k in _COMB}
    model_names = {f.name for f in dataclasses.fields(HarmonicModel)}
    params = {**{k: v for k, v in GRID_DEFAULTS.items() if k not in model_names}, **params}
    if "q_omega" not in params:
        params["q_omega"] = q_omega_for(parse_value(params.get("omega_max", _cfg.Config.omega_max),
                                                     float, "omega_max"))
    params.setdefault("claim_level", CLAIM_LEVEL.get(str(params["smooth"]), CLAIM_LEVEL["fb"]))
    config_t, y, rms, notes = _app.prepare(recording, axis, _cfg.Config, params, _grid_model)
    config = config_from_params(Config, comb_kw, tracker=config_t)
    chans = comb_channels(recording, axis, config.comb_axes)
    if config.comb_axes == ("all",):
        left = [c for c in ("ax", "ay", "az") if c in recording and c not in chans]
        if left:
            notes.append(f"comb_axes=all: {', '.join(left)} all NaN, left out")
    config = dataclasses.replace(config, comb_axes=chans if len(chans) > 1 else ())
    if len(chans) > 1:
        # each axis pre-filtered and normalised as the tracked one (same parameters)
        others = [_app.prepare(recording, c, _cfg.Config, params, _grid_model)[1]
                  for c in chans[1:]]
        y = np.column_stack([y, *others])
        notes.append(f"comb evidence from axes {', '.join(chans)} (per harmonic summed, "
                     f"weight {config.axes_weight(len(chans)):.3g}); time-domain likelihood "
                     f"on {chans[0]}")
    return config, y, rms, notes


def config_for(recording: Recording, *, axis: str = "y", params: dict | None = None) -> Config:
    """The :class:`Config` that :func:`estimate` builds for ``recording`` and ``params``: hand it
    to :class:`vibrospeed.estimators.online.OnlineTracker` to run the causal tracker on a
    device (smoothing needs the whole log and is not applied by ``step``)."""
    return _prepare(recording, axis, params)[0]


def estimate(
    recording: Recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool | np.ndarray = False,
) -> Track:
    """Track omega on axis ``axis`` with the grid tracker (offline: smoothed).

    ``params``: any :class:`Config` comb field, any :class:`vibrospeed.estimators.rbpmf.Config`
    or :class:`vibrospeed.models.harmonic.HarmonicModel` field (defaults
    :data:`GRID_DEFAULTS` over the paper's); ``smooth=none`` gives the causal filter. Columns
    and extras as :func:`vibrospeed.estimators.rbpmf.estimate` (``p_half``, ``p_double``,
    ``p_third``, ``p_triple``, ``ambiguous``, ``confidence``, ``has_signal``, ...), and
    ``standstill`` (1 where the vehicle stands: :func:`with_standstill` sets omega, speed,
    their bands and ``has_signal`` to 0 there; ``omega_mode``, ``omega_mean``, ``omega_map``
    and the ``p_*`` columns stay the tracker's, what it would say were the vehicle moving).
    ``return_posterior``: the grid posterior in ``extras["posterior"]`` (float32 rows, the
    signal part) and ``extras["grid"]``: True for every sample, or an increasing array of
    sample indices for those rows only (``extras["posterior_index"]``; a consumer that reads
    the posterior at a few samples then holds those rows alone).

    Examples
    --------
    >>> import numpy as np
    >>> from vibrospeed.types import Recording
    >>> t = np.arange(0, 30, 0.01)
    >>> rng = np.random.default_rng(0)
    >>> ay = np.sin(50 * t) + 0.5 * np.sin(100 * t) + 0.3 * np.sin(150 * t)
    >>> tr = estimate(Recording(t, {"ay": ay + 0.3 * rng.normal(size=t.size)}))
    >>> bool(abs(np.median(tr.omega[1000:]) - 50) < 1)
    True
    """
    config, Y, rms, notes = _prepare(recording, axis, params)
    y = Y if Y.ndim == 1 else np.ascontiguousarray(Y[:, 0])  # the tracked axis
    L = config.frame_len
    # smoothing: each frame's evidence where it describes the comb, at its middle; the
    # fixed-lag smoother then runs blocks of lag - W/2 s, so that a sample still uses data up
    # to lag..2 lag s after it (evidence at c covers data up to c + W/2)
    tr = config.tracker
    half = 0.5 * config.frame_len * tr.model.dt
    centre = tr.smooth == "fb" or (tr.smooth == "lag" and tr.lag >= half + tr.model.dt)
    comb = {k: getattr(config, k) for k in _COMB}
    if tr.fit_names and centre:
        # the marginal likelihood is the causal filter's: fit with end-referred evidence
        tr = dataclasses.replace(_app.fit_for_track(tr, y, evidence(config, Y), notes), fit="")
        config = dataclasses.replace(config, tracker=tr)
    if tr.smooth == "lag" and centre:
        comb["lag"] = tr.lag  # the delay the user asked for, recorded as such
        config = dataclasses.replace(config, tracker=dataclasses.replace(tr, lag=tr.lag - half))
        notes.append(f"comb evidence placed mid-frame: fixed-lag blocks of {tr.lag - half:g} s "
                     f"(= lag - {half:g} s), each sample uses data up to {tr.lag:g}.."
                     f"{2 * tr.lag - half:g} s after it")
    idx, vals = evidence(config, Y, centre=centre)
    if config.comb_weight > 0:
        notes.append(f"harmonic-comb evidence: {config.comb_window:g} s frames every "
                     f"{config.comb_hop:g} s, weight {config.comb_weight:g}, SNR "
                     f"{config.comb_snr:g}, cap {config.comb_cap:g} nats ({idx.size} frames; "
                     f"full {L}-sample frames, growing ones from {config.comb_min_window:g} s "
                     "before)")
    tr = _app.track(recording, config.tracker, y, rms, notes, axis=axis,
                   wheel_radius=wheel_radius, progress=progress,
                   return_posterior=return_posterior, method="grid", extra=(idx, vals),
                   extra_params=comb)
    return with_standstill(tr, recording, axis, config, causal=config.tracker.smooth != "fb",
                           lag=comb.get("lag", config.tracker.lag)
                           if config.tracker.smooth == "lag" else 0.0)


def apply_standstill(track: Track, still: np.ndarray) -> None:
    """The standstill decision ``still`` (per sample) into ``track`` in place: the
    ``standstill`` column, omega / speed and their bands 0 and ``has_signal`` 0 there."""
    track.extras["standstill"] = still.astype(np.float64)
    if still.any():
        for name in ("omega", "omega_std", "omega_lo", "omega_hi", "speed", "speed_std",
                     "speed_lo", "speed_hi"):
            arr = getattr(track, name)
            arr[still & np.isfinite(arr)] = 0.0
        if "has_signal" in track.extras:  # none without a "no line" state (off_rate=0)
            track.extras["has_signal"][still] = 0.0


def detector_name(causal: bool, lag: float) -> str:
    """How the stops were decided, for the notes."""
    if not causal:
        return "whole-log"
    return f"causal, {lag:g} s lag" if lag > 0 else "causal"


def with_standstill(track: Track, recording: Recording, axis: str, config: Config, *,
                    causal: bool, lag: float = 0.0) -> Track:
    """``track`` with the vehicle's stops: where the broadband vibration and the body motion
    sit at their floors on the tracked axis and on every other accelerometer axis of the
    recording (:mod:`vibrospeed.signal.standstill`), omega and its band are 0, ``has_signal``
    0 and the extra ``standstill`` 1; causal filters use the causal detector, the fixed-lag
    smoother the causal one with the same delay (``lag`` s: each decision uses data at most
    that far after its sample). The tracker's
    "no line" state is not asked: an idling engine's orders 1 and 2 make a comb at a
    standstill, and where the vibration misleads (a slow roll near the floor) the comb is as
    weak."""
    from vibrospeed.estimators.common import axis_channel
    from vibrospeed.signal import standstill as ss

    tr = config.tracker
    fs = 1.0 / tr.model.dt
    band = (tr.omega_min, min(tr.model.M * tr.omega_max, np.pi * fs))
    chans = [axis_channel(axis)] + [c for c in ("ax", "ay", "az")
                                    if c != axis_channel(axis) and c in recording
                                    and np.isfinite(recording.channel(c)).any()]
    X = np.column_stack([recording.channel(c) for c in chans])
    still = ss.standstill(X, tr.model.dt, band, causal=causal, lag=lag)
    apply_standstill(track, still)
    if still.any():
        share = still.mean()
        track.notes.append(f"standstill on {100 * share:.1f} % of the samples (vibration and "
                           f"body motion at their floors on {', '.join(chans)}; "
                           f"{detector_name(causal, lag)} detector): omega = 0 there")
    return track
