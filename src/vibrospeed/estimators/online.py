"""Online (device) use: raw accelerometer sample in, omega estimate out.

:class:`OnlineTracker` chains the same stages as ``estimate()`` does in batch: pre-filter
(:mod:`vibrospeed.signal.prefilter`), running-RMS normalisation
(:mod:`vibrospeed.signal.normalize`, times a target RMS) and an estimator's ``step``. Feeding a
recording sample by sample gives the numbers of the batch path (tested for the EKF, the RBPMF and
the causal grid tracker), so a tracker tuned offline behaves the same on a device. The object is
the only mutable thing here; its ``state`` is a tuple of the stages' immutable states and can be
saved and restored. With ``standstill`` it also runs the causal standstill detector
(:func:`vibrospeed.signal.standstill_stream.stream_step`) that ``estimate()`` applies after the
causal grid tracker, so the stops are those of the batch run too (omega and its band 0 there). With
``wheel_radius`` it converts omega to speed as the batch Track does (``speed = r * omega``).
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

import numpy as np

from vibrospeed.signal import normalize as nz
from vibrospeed.signal import prefilter as pf
from vibrospeed.signal import standstill_stream as sst
from vibrospeed.signal import whiten as wh


def _pipeline_of(config: Any) -> tuple[Any, str, float | None, float, tuple | None]:
    """(harmonic model, pre-filter, normalisation tau, target RMS, search range) that
    ``estimate()`` uses."""
    inner = getattr(config, "tracker", config)  # grid.Config wraps an rbpmf.Config
    model = inner.model
    if hasattr(inner, "signal_rms"):  # rbpmf / grid: their own pre-filter and scaling
        tau = inner.rms_tau if getattr(inner, "scaling", "rms") == "rms" else None
        return model, inner.prefilter, tau, inner.signal_rms, (inner.omega_min, inner.omega_max)
    return model, "thesis-hp", 5.0, 1.0, None  # ekf.estimate's defaults


class OnlineTracker:
    """Streaming pipeline ``raw sample -> pre-filter -> normalise -> estimator.step``.

    Parameters
    ----------
    estimator : an estimator module with ``init(config)`` and ``step(config, state, y)``
        (:mod:`~vibrospeed.estimators.ekf`, :mod:`~vibrospeed.estimators.rbpmf`,
        :mod:`~vibrospeed.estimators.grid` (causal: smoothing needs the whole log)).
    config : that estimator's ``Config`` (its model's ``dt`` is the sample period). The
        pre-filter and scaling default to what that estimator's ``estimate()`` uses.
    prefilter : pre-filter preset name. normalize_tau : s, 0 or None = off. target_rms : the
        RMS the normalised signal is scaled to.
    level : resting level of the raw signal (e.g. the mean of a first second buffered on the
        device; :func:`vibrospeed.estimators.common.start_level` computes it as ``estimate()``
        does), one per axis with several comb axes; None = the first sample.
    standstill : 0 (default): no stops (``standstill`` NaN, as the tracker's ``step``); k: the
        causal standstill detector on k raw accelerometer axes, the samples given to
        :meth:`update` and its ``others``. ``estimate()`` reads every accelerometer axis of the
        recording (``ax``, ``ay``, ``az``): give them all (k = 3) for its numbers. Where it
        decides the vehicle stands, omega, its band and ``speed`` are 0, ``has_signal`` 0 and
        ``standstill`` 1; elsewhere ``standstill`` is 0. Only for trackers with a search range:
        grid (whose causal ``estimate()`` applies the same detector) and rbpmf (whose
        ``estimate()`` has no stops: these are added). The ``state`` then has a third part,
        the detectors' states.
    wheel_radius : m, as the batch ``estimate(..., wheel_radius=)`` takes it: ``speed``,
        ``speed_std`` and the extras ``speed_lo``, ``speed_hi`` (the speed band) are then r
        times omega, its std and its band, the numbers of the batch Track's speed columns
        (:meth:`vibrospeed.types.Track.from_omega`); None (default): the estimator's own
        ``speed`` (NaN for the wheel trackers: they measure omega only).

    Examples
    --------
    >>> from vibrospeed import sim
    >>> from vibrospeed.estimators import ekf
    >>> rec = sim.simulate("cart", seed=1, duration=5)
    >>> trk = OnlineTracker(ekf, ekf.config_for(rec, params={"omega0": 10.5}))
    >>> est = trk.update(0.01)

    (``ekf.config_for`` / ``grid.config_for`` / ``rbpmf.config_for``: the config ``estimate``
    would run on that recording; a bare ``ekf.Config()`` is the thesis' model at 100 Hz, whose
    noise values are for the raw signal, not the normalised one the tracker is fed.)
    """

    def __init__(
        self,
        estimator: ModuleType,
        config: Any,
        *,
        prefilter: str | None = None,
        normalize_tau: float | None | bool = True,
        target_rms: float | None = None,
        level: float | None = None,
        standstill: int = 0,
        wheel_radius: float | None = None,
    ) -> None:
        from vibrospeed.types import check_wheel_radius

        self.wheel_radius = check_wheel_radius(wheel_radius)  # a bad one: one line, here
        model, pre, tau, target, omega_range = _pipeline_of(config)
        self.estimator = estimator
        self.config = config
        self.dt = model.dt
        self.fs = 1.0 / model.dt
        self.sos = pf.design(prefilter or pre, 1.0 / model.dt, M=model.M,
                             omega_range=omega_range)
        self.whiten = (prefilter or pre) in pf.ADAPTIVE
        self.tau = (tau if normalize_tau is True else normalize_tau) or None
        self.target = target if target_rms is None else target_rms
        self.n_axes = int(getattr(config, "n_axes", 1))
        levels = np.broadcast_to(np.asarray(np.nan if level is None else level, float),
                                 (self.n_axes,))
        front = tuple((pf.init(self.sos, None if np.isnan(lv) else float(lv)), nz.init(),
                       wh.init()) for lv in levels)
        self.state = (front, estimator.init(config))
        self.n_still = int(standstill)
        self.still_plan = None
        if self.n_still:
            if omega_range is None or self.n_still < self.n_axes:
                raise ValueError(
                    "standstill needs a tracker with a search range (grid, rbpmf) and at least "
                    f"its {self.n_axes} comb axis/axes, got {standstill} axes")
            band = (omega_range[0], min(model.M * omega_range[1], math.pi * self.fs))
            self.still_plan = sst.stream_plan(self.dt, band)
            self.state += (tuple(sst.stream_init(self.still_plan) for _ in range(self.n_still)),)

    def __getstate__(self) -> dict:
        """The estimator module by its name (a module does not pickle): a tracker saved
        mid-stream and loaded continues with the same numbers."""
        est = self.estimator
        return {**self.__dict__,
                "estimator": est.__name__ if isinstance(est, ModuleType) else est}

    def __setstate__(self, state: dict) -> None:
        import importlib

        est = state["estimator"]
        self.__dict__.update(state, estimator=importlib.import_module(est)
                             if isinstance(est, str) else est)

    def _front(self, st: tuple, sample: float) -> tuple[tuple, float, float]:
        """One axis' pre-filter, whitener and scaling: (state, scaled sample, rms) with the
        rms the running RMS the sample was divided by (NaN where the sample is missing; the
        target RMS without scaling), the batch Track's ``rms`` column."""
        fs, ns, ws = st
        fs, y = pf.step(self.sos, fs, sample)
        if self.whiten:
            ws, y = wh.step(ws, y, self.fs)
        rms = self.target
        if self.tau:
            ns, yn = nz.step(ns, y, self.dt, self.tau)
            rms = abs(y / yn) if (math.isfinite(yn) and yn != 0) else math.nan
            y = self.target * yn
        return (fs, ns, ws), (y if math.isfinite(y) else math.nan), rms

    def update(self, sample, others=()) -> Any:
        """Process one raw sample (NaN = missing), or with a grid config of several
        ``comb_axes`` one sample per axis in ``config.comb_axes`` order; returns the
        estimator's estimate. ``others``: with ``standstill`` k, the raw samples of the k -
        (comb axes) further accelerometer axes the standstill detector reads."""
        front, es = self.state[:2]
        if self.n_axes == 1 and isinstance(sample, (float, int)):
            st, y, _ = self._front(front[0], float(sample))  # one axis: no arrays
            es, est = self.estimator.step(self.config, es, y)
            self.state = ((st,), es) + self.state[2:]
            est = self._stops(est, (sample,), others) if self.n_still else est
            return self._speed(est) if self.wheel_radius else est
        xs = np.atleast_1d(np.asarray(sample, dtype=np.float64))
        if xs.size != self.n_axes:
            raise ValueError(f"expected {self.n_axes} sample(s) per update, got {xs.size}")
        out = [self._front(st, float(x)) for st, x in zip(front, xs, strict=True)]
        ys = [y for _, y, _ in out]
        es, est = self.estimator.step(self.config, es, ys[0] if self.n_axes == 1 else ys)
        self.state = (tuple(st for st, _, _ in out), es) + self.state[2:]
        est = self._stops(est, xs, others) if self.n_still else est
        return self._speed(est) if self.wheel_radius else est

    def _speed(self, est: Any) -> Any:
        """``est`` with speed, its std and band (extras ``speed_lo``, ``speed_hi``) r times
        omega's, as :meth:`vibrospeed.types.Track.from_omega` computes the batch columns."""
        r = self.wheel_radius
        return est._replace(speed=r * est.omega, speed_std=r * est.omega_std,
                            extras={**est.extras, "speed_lo": r * est.omega_lo,
                                    "speed_hi": r * est.omega_hi})

    def _stops(self, est: Any, xs, others) -> Any:
        """``est`` with the standstill detectors' decision at this sample (as
        :func:`vibrospeed.estimators.grid.apply_standstill` does in batch)."""
        if len(self.state) != 3 or len(self.state[2]) != self.n_still:
            raise ValueError(f"state has no standstill part for {self.n_still} axes (a state "
                             "saved from a tracker made with another standstill)")
        raw = [*(float(x) for x in xs), *(float(x) for x in np.atleast_1d(others))]
        if len(raw) != self.n_still:
            raise ValueError(f"standstill reads {self.n_still} axes: expected "
                             f"{self.n_still - self.n_axes} sample(s) in others, got "
                             f"{len(raw) - self.n_axes}")
        out = [sst.stream_step(self.still_plan, st, x)
               for st, x in zip(self.state[2], raw, strict=True)]
        self.state = self.state[:2] + (tuple(st for st, _ in out),)
        if not all(f for _, f in out):
            return est._replace(standstill=0.0)
        zero = {k: 0.0 for k in ("omega", "omega_std", "omega_lo", "omega_hi", "speed",
                                 "speed_std") if math.isfinite(getattr(est, k))}
        return est._replace(has_signal=0.0, standstill=1.0, **zero)
