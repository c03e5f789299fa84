"""Named parameter sets per method (``vibrospeed estimate --preset NAME``) and each method's
documented parameters.

A preset is a set of ``-p NAME=VALUE`` parameters written as a user would type them; it is
applied before the explicit ``-p`` flags, so ``--preset lock -p q_omega=8`` is the lock preset
with ``q_omega`` changed. Every method has ``default`` (its own defaults, nothing set) and
``online`` (a causal estimate: each output uses only samples up to it, as on a device; for the
methods that are causal anyway it sets nothing); ``paper`` is the seed document's settings
where the method comes from one (``../shared/METHODS.md`` names the section).

:data:`PARAMETERS` is each method's small documented surface: the parameters a user is
expected to set, with an example value and what it does. Every other Config field keeps its
default (the reference pages list them all).

This module holds data only (no estimator imports), so the CLI and the docs can list it
without loading numba code.
"""

from __future__ import annotations

from typing import NamedTuple

from vibrospeed.config import suggest
from vibrospeed.errors import ParameterError


class Preset(NamedTuple):
    """A named parameter set: ``params`` as ``-p`` text, ``about`` one line on when to use it."""

    params: dict[str, str]
    about: str


class Parameter(NamedTuple):
    """A documented parameter: an ``example`` value (text, as typed after ``-p NAME=``) and
    ``about``, one line with its unit."""

    example: str
    about: str


_CAUSAL = "the method is causal already: the same as default"

#: the strict comb: the harmonic comb scored at SNR 2 (``comb_snr``; a weak comb scores as
#: empty), a wheel line claimed (``has_signal``) at line probability 0.5 (``claim_level``) and
#: the per-sample likelihood tempered to 0.05 per 10 ms (``temper``), where the grid's own
#: defaults are SNR 1, 0.9 and 0.2: a tracker that claims at 0.5 needs the weaker time-domain
#: weight, or it claims the weak lines that the stronger weight places omega on. The grid's
#: ``lock`` preset sets it, and :mod:`vibrospeed.estimators.fuse` runs its tracker with it
#: (``fuse.TRACKER_DEFAULTS``).
STRICT_COMB: dict[str, str] = {"comb_snr": "2", "claim_level": "0.5", "temper": "0.05"}

#: method -> preset name -> :class:`Preset`
PRESETS: dict[str, dict[str, Preset]] = {
    "grid": {
        "default": Preset({}, "smoothed over the whole log (offline; the most accurate)"),
        "online": Preset({"smooth": "none"}, "causal filter: each estimate from past samples "
                         "only (live use, a device)"),
        "lag": Preset({"smooth": "lag", "lag": "2"}, "fixed-lag smoother: each estimate from "
                      "the samples up to 2-2.5 s after it (a device that can wait; -p lag= "
                      "for another delay)"),
        "lock": Preset({"smooth": "none", "comb_axes": "all", "q_omega": "4", **STRICT_COMB,
                        "amb_rel": "0.02", "amb_abs": "1", "mode_hold": "4"},
                       "causal filter switched on while the vehicle moves: comb evidence from "
                       "every axis, a steady-speed walk, a narrow mode window held against "
                       "hops"),
    },
    "rbpmf": {
        "default": Preset({}, "the paper's filter (causal)"),
        "paper": Preset({"M": "3", "q_omega": "4", "q_amp": "0.001", "p0_amp": "0.1",
                         "n_grid": "200", "omega_min": "10", "omega_max": "120",
                         "spacing": "linear", "prefilter": "paper-hp", "smooth": "none"},
                        "paper III-D, Table I / IV-B: M = 3, 200 points on 10-120 rad/s, "
                        "high-pass at 8 Hz, causal"),
        "online": Preset({"smooth": "none"}, "causal filter (no smoothing)"),
    },
    "rbpf": {
        "default": Preset({}, "the paper's filter (causal)"),
        "paper": Preset({"M": "3", "q_omega": "4", "q_amp": "0.001", "p0_amp": "0.1",
                         "n_particles": "3000", "scheme": "multinomial", "omega_min": "10",
                         "omega_max": "120", "prefilter": "paper-hp"},
                        "paper III-C, Table I: 3000 particles, multinomial resampling"),
        "online": Preset({}, _CAUSAL),
    },
    "shs": {
        "default": Preset({}, "2 s batches (200 samples at 100 Hz) on 10-120 rad/s"),
        "paper": Preset({"batch": "200", "omega_min": "10", "omega_max": "120",
                         "compression": "0.84", "points_per_octave": "48",
                         "prefilter": "paper-hp"},
                        "paper IV-B batches and range with Hermes' compression 0.84 and "
                        "48 points per octave"),
        "online": Preset({}, "each batch's estimate uses that batch's samples only (one "
                         "batch late): the same as default"),
    },
    "ekf": {
        "default": Preset({}, "normalised input, acquisition from the harmonic comb check "
                          "(no --init-omega needed)"),
        "paper": Preset({"normalize_tau": "0", "comb": "false", "amp0": "10",
                         "omega_max": "100"},
                        "thesis ch. 2 (2.3.5): input in m/s^2 with the thesis' noise levels, "
                        "start from omega0 = 10.2 rad/s (--init-omega), no comb check; omega "
                        "clipped at 100 rad/s (3 harmonics below Nyquist at 100 Hz)"),
        "online": Preset({}, _CAUSAL),
    },
    "aided": {
        "default": Preset({}, "the grid tracker aided by the longitudinal acceleration of "
                          "the estimated mount (offline the aided smoother), whole-log stops"),
        "paper": Preset({"tracker": "ekf", "standstill": "window", "accel_offset": "none",
                         "comb": "false", "causal": "true"},
                        "thesis ch. 3: the aided EKF, window standstill test, a_x used as "
                        "measured, no comb check"),
        "online": Preset({"causal": "true"}, "the causal aided filter, causal standstill "
                         "detector and the mount from the data so far (as a device decides)"),
    },
    "gps-riss": {
        "default": Preset({}, "physical noise levels, GPS innovation gating"),
        "paper": Preset({"q_speed": "5", "q_accel": "4", "q_offset": "0.01", "q_gps": "1",
                         "r_acc_ins": "0.4", "r_acc_gps": "3.5", "r_gps": "40",
                         "r_gps_slope": "72", "r_gps_sq": "0", "error_mode": "kf2",
                         "offset_mode": "integrator", "p0_speed": "100", "p0_accel": "5",
                         "gps_lag_std": "0", "q_gps_lag": "0", "acc_psd": "0"},
                        "the GPS/RISS paper's constants (eq. 11-13, 18), KF2 error and drift "
                        "integrator"),
        "online": Preset({}, _CAUSAL),
    },
    "fuse": {
        "default": Preset({}, "smoothed grid tracker and an RTS smoother over the fusion "
                          "(offline)"),
        "online": Preset({"online": "true"}, "causal grid tracker and the forward filter "
                         "only"),
        "lag": Preset({"lag": "2"}, "the grid tracker's fixed-lag smoother (2 s) and the "
                      "forward filter: each speed 2-2.5 s late, nearer the offline accuracy"),
    },
    "algebraic": {
        "default": Preset({}, "Algorithms 1 and 2 of the algebraic velocity paper, slip found "
                          "by the wheel speed leaving the dead-reckoned speed (detect=window, "
                          "not the paper's test)"),
        "paper": Preset({"detect": "seed", "backtrack": "0"},
                        "Algorithm 1 as published: rolling while |dGx/dt| < eps1 over alpha "
                        "samples, integration restarted from the previous sample"),
        "online": Preset({}, _CAUSAL),
    },
}

_RANGE = "rad/s, lowest wheel speed searched (v / r for the slowest speed of interest)"
_RANGE_HI = "rad/s, highest wheel speed searched"

#: method -> parameter name -> :class:`Parameter` (the documented surface)
PARAMETERS: dict[str, dict[str, Parameter]] = {
    "grid": {
        "omega_min": Parameter("2", _RANGE + "; default 10, a car's wheels"),
        "omega_max": Parameter("30", _RANGE_HI + "; default 120"),
        "smooth": Parameter("none", "fb (whole log, default), lag (fixed delay) or none "
                            "(causal)"),
        "lag": Parameter("2", "s, delay of the fixed-lag smoother (smooth=lag)"),
        "comb_axes": Parameter("all", "axes read by the comb evidence: all, or e.g. x,y,z "
                               "(tracking stays on --axis)"),
        "M": Parameter("2", "harmonics of the wheel frequency in the model"),
        "q_omega": Parameter("8", "(rad/s)^2/s, how fast omega may wander (acceleration); "
                             "default 16 omega_max / 120: 16 on 10-120, 4 on 2-30"),
        "prefilter": Parameter("whiten", "pre-filter: whiten (default), thesis-hp, paper-hp, "
                               "range, none"),
        "fit": Parameter("q_omega,r", "noise parameters fitted to the recording by marginal "
                         "likelihood first"),
        "claim_level": Parameter("0.99", "line probability at which has_signal claims a "
                                 "line; default 0.9 offline, 0.95 with smooth=lag, 0.99 causal "
                                 "(higher: fewer, surer claims)"),
    },
    "rbpmf": {
        "omega_min": Parameter("2", _RANGE + "; default 10"),
        "omega_max": Parameter("30", _RANGE_HI + "; default 120"),
        "n_grid": Parameter("400", "grid points on [omega_min, omega_max]"),
        "smooth": Parameter("fb", "none (causal, default), fb (whole log) or lag"),
        "M": Parameter("2", "harmonics in the model"),
        "q_omega": Parameter("8", "(rad/s)^2/s, random-walk intensity of omega"),
        "omega0": Parameter("40", "rad/s, centre of the initial prior (--init-omega); "
                            "default: uniform"),
    },
    "rbpf": {
        "omega_min": Parameter("2", _RANGE + "; default 10"),
        "omega_max": Parameter("30", _RANGE_HI + "; default 120"),
        "n_particles": Parameter("1000", "particles (time grows linearly)"),
        "seed": Parameter("1", "seed of the particle filter's generator"),
        "q_omega": Parameter("8", "(rad/s)^2/s, random-walk intensity of omega"),
    },
    "shs": {
        "omega_min": Parameter("2", _RANGE + "; default 10"),
        "omega_max": Parameter("30", _RANGE_HI + "; default 120"),
        "batch": Parameter("400", "samples per estimate (at least one period of omega_min)"),
        "n_harmonics": Parameter("3", "harmonics summed"),
    },
    "ekf": {
        "omega0": Parameter("10", "rad/s, start value (--init-omega); without it the comb "
                            "check acquires omega"),
        "omega_max": Parameter("60", "rad/s, upper clip of omega (M omega_max < pi fs)"),
        "M": Parameter("2", "harmonics in the model"),
        "q_omega": Parameter("4", "(rad/s)^2/s, random-walk intensity of omega"),
        "comb": Parameter("false", "comb check for acquisition and re-lock (default true)"),
    },
    "aided": {
        "accel_axis": Parameter("ax", "longitudinal acceleration channel (default with "
                                "tracker=grid: the estimated mount); a leading - negates "
                                "(e.g. -ay)"),
        "standstill": Parameter("broadband", "standstill test: broadband (default), window, "
                                "cusum, none"),
        "causal": Parameter("true", "causal filter, standstill detector, a_x offset and "
                            "mount"),
        "tracker": Parameter("ekf", "vibration tracker aided: grid (default), ekf (the "
                             "thesis' filter), rbpmf"),
        "M": Parameter("2", "harmonics in the model"),
    },
    "gps-riss": {
        "min_sats": Parameter("5", "GPS fixes with fewer satellites are ignored"),
        "gps_delay": Parameter("0.2", "s, pure receiver delay before the lag model"),
        "q_accel": Parameter("10", "process noise of the acceleration state"),
        "r_gps": Parameter("0.02", "(m/s)^2, GPS speed variance per fix"),
    },
    "fuse": {
        "online": Parameter("true", "causal: the causal grid tracker and the forward filter"),
        "lag": Parameter("2", "s, a device that can wait that long: the grid tracker's "
                         "fixed-lag smoother read by the forward filter (lines that do not "
                         "trail the speed)"),
        "radius_from": Parameter("drive1_fuse.csv.json", "wheel radius learned on an earlier "
                                 "drive (its sidecar) as the radius prior"),
        "accel_axis": Parameter("ax", "longitudinal acceleration channel (forward +); a "
                                "leading - negates (e.g. -ay: a phone mounted backwards)"),
        "min_sats": Parameter("5", "GPS fixes with fewer satellites are ignored"),
    },
    "algebraic": {
        "L1": Parameter("1.2", "m, centre of gravity to front axle (needed unless the "
                        "recording has it)"),
        "window": Parameter("0.2", "s, algebraic filter window for values"),
        "window_d": Parameter("0.3", "s, algebraic filter window for derivatives"),
        "slip_tol": Parameter("0.5", "m/s, largest gap between the wheel speed and the "
                              "dead-reckoned speed taken as rolling; default 0.3"),
    },
}


def presets(method: str) -> dict[str, Preset]:
    """The presets of ``method`` (``default`` and ``online`` at least)."""
    return PRESETS.get(method, {"default": Preset({}, "the method's defaults")})


def preset_params(method: str, name: str | None) -> dict[str, str]:
    """The parameters of preset ``name`` of ``method`` (None: none). An unknown preset is a
    one-line :class:`ParameterError` listing the method's presets."""
    if name is None:
        return {}
    table = presets(method)
    if name not in table:
        raise ParameterError(f"unknown preset '{name}' for method '{method}'"
                             f"{suggest(name, table)} (choose from: {', '.join(table)})")
    return dict(table[name].params)


def apply(method: str, name: str | None, params: dict[str, str] | None) -> dict[str, str]:
    """Preset ``name``'s parameters overridden by the explicit ``params`` (``-p`` wins)."""
    return {**preset_params(method, name), **(params or {})}


def as_flags(params: dict[str, str]) -> str:
    """``{'smooth': 'none', 'M': '2'}`` -> ``-p smooth=none -p M=2`` (how to type it)."""
    return " ".join(f"-p {k}={v}" for k, v in params.items())
