"""Chassis vibration physics: wheel harmonics and the disturbances that are not wheel harmonics.

Per accelerometer axis ``j`` (x, y, z) the vibration is (all terms in m/s^2)::

    s_j(t) = sum_m A_mj(t) cos(m theta(t) + phi_mj)          wheel harmonics, m = 1..M
           + E_j(t) cos(k_e theta_e(t) + phi_ej)              engine order k_e
           + sum_i g_j B_i(t)                                 body resonances (narrow-band noise)
           + g_j N(t)                                         broadband road noise
           + D_j(t)                                           body motion below ~2 Hz

* ``theta(t) = x(t) / r`` is the exact wheel angle (``int omega dt``), so the instantaneous
  frequency of harmonic m is exactly ``m omega(t)``.
* Harmonic amplitude law (a modelling choice; no seed gives one)::

      A_mj(t) = a_m * g_j * (omega / omega_ref)^gamma * exp(u_mj(t)) * f_m(t) * H_aa(m omega)

  ``a_m`` amplitude at ``omega_ref``; ``g_j`` the axis gain; ``gamma`` the speed exponent
  (0: amplitude independent of speed, 2: a pure unbalance force ``m e omega^2`` on a stiff mount;
  the default 1 sits between, as a suspension passes less of the force at higher frequencies);
  ``u_mj`` an Ornstein-Uhlenbeck process in log-amplitude (std ``amp_log_std``, time constant
  ``amp_tau``); ``f_m`` fades: random intervals in which harmonic m drops to ``fade_depth`` with
  raised-cosine ramps (the fundamental has its own, usually higher, rate: "sometimes the
  fundamental vanishes for a while"); ``H_aa`` the sensor's anti-alias low-pass (Butterworth
  magnitude of order ``aa_order`` at ``aa_cutoff * fs``; order 0 disables it, then components
  above Nyquist alias).
* Engine order line: engine speed ``omega_e = max(idle, omega * G[gear] * final_drive)`` (rad/s),
  gear chosen by up/down-shift engine speeds with hysteresis, so the ratio of the line to the
  wheel speed jumps at each shift and is unrelated to the wheel when idling. Amplitude
  ``engine_amp * (omega_e / omega_idle)^engine_gamma``.
* Body resonances: white noise through a resonator (``scipy.signal.iirpeak``, quality
  ``resonance_q``) at fixed frequencies, normalised to unit variance and scaled by the road
  excitation level ``ell(v) = (v / v_ref)^road_gamma + floor``.
* Road noise: white Gaussian, standard deviation ``road_noise * (v / v_ref)^road_gamma``.
* Phase jitter (``phase_jitter`` D, rad^2/s): each harmonic's phase is a random walk,
  ``phi_m(t) = phi_m0 + sqrt(D) W(t)``, so its line has a Lorentzian width of ``D / 2`` rad/s
  (a tyre that slips a little, a mount that is not rigid).
* Body motion (``lowfreq_std`` per axis): pitch, roll, bounce and the driver's corrections
  that a real car adds to turns and braking: white noise through a Butterworth low-pass of
  order 2 at ``lowfreq_cutoff`` Hz, scaled to ``lowfreq_std`` m/s^2 at ``v >= lowfreq_v`` and
  faded in linearly below it. Measured on a phone in a car at 20-30 m/s: 0.2-1.5 m/s^2 std
  below 2 Hz on the horizontal axes (``benchmarks/calibration``), 10-20x a wheel harmonic.
* Extra engine orders (``EngineConfig.extra_orders``): ``(order, relative amplitude)`` pairs
  added to the main order line, e.g. the firing order 2 of a four-cylinder engine.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal as sps

from vibrospeed.errors import ParameterError
from vibrospeed.sim.knobs import check

AXES = ("x", "y", "z")


@dataclass(frozen=True)
class EngineConfig:
    """Engine-order disturbance line (car scenarios)."""

    gear_ratios: tuple[float, ...] = (3.6, 2.1, 1.4, 1.0, 0.8)
    """Gearbox ratios, first gear first (engine turns / output shaft turns)."""
    final_drive: float = 3.7
    """Differential ratio (output shaft turns / wheel turn)."""
    idle_rpm: float = 800.0
    """Idle engine speed (rev/min); the engine never turns slower (clutch slips below it)."""
    upshift_rpm: float = 2500.0
    """Shift up when the engine would exceed this speed (rev/min)."""
    downshift_rpm: float = 1300.0
    """Shift down when the engine would fall below this speed (rev/min). upshift/downshift must
    exceed the largest ratio step between neighbouring gears (hysteresis)."""
    order: float = 1.0
    """Engine order of the line (1: crank rotation; 2: firing frequency of a 4-cylinder)."""
    amp: float = 0.03
    """Amplitude at idle (m/s^2) on an axis of gain 1."""
    gamma: float = 1.0
    """Amplitude grows as (omega_engine / omega_idle)^gamma."""
    extra_orders: tuple[tuple[float, float], ...] = ()
    """Further engine-order lines as ``(order, amplitude relative to amp)`` pairs."""

    def __post_init__(self) -> None:
        check(self, "vibration.engine.",
              positive=("final_drive", "idle_rpm", "upshift_rpm", "downshift_rpm", "order"),
              nonnegative=("amp", "gamma"))
        if not self.gear_ratios or not all(g > 0 for g in self.gear_ratios):
            raise ParameterError("vibration.engine.gear_ratios: need one or more ratios > 0, "
                                 f"got {self.gear_ratios!r}")
        if not self.downshift_rpm < self.upshift_rpm:
            raise ParameterError("vibration.engine: need downshift_rpm < upshift_rpm, got "
                                 f"{self.downshift_rpm} and {self.upshift_rpm}")


@dataclass(frozen=True)
class VibrationConfig:
    """Knobs of the vibration model (module docstring gives the equations)."""

    harmonic_amps: tuple[float, ...] = (0.25, 0.2, 0.1)
    """a_m: amplitude (m/s^2) of harmonic m = 1..M at omega_ref on an axis of gain 1; M = len."""
    omega_ref: float = 10.0
    """rad/s, wheel speed at which the amplitudes a_m hold."""
    gamma: float = 1.0
    """Speed exponent of the harmonic amplitudes, A ~ (omega/omega_ref)^gamma."""
    axis_gain: tuple[float, float, float] = (0.3, 1.0, 0.5)
    """Gains g_x, g_y, g_z applied to every vibration term on each axis."""
    amp_log_std: float = 0.25
    """Stationary std of the OU log-amplitude u (dimensionless; 0.25 ~ +-25 %)."""
    amp_tau: float = 5.0
    """s, correlation time of the OU log-amplitude."""
    fade_rate: float = 0.5
    """Fades per minute of driving for harmonics m >= 2."""
    fundamental_fade_rate: float = 1.0
    """Fades per minute for the fundamental m = 1."""
    fade_duration: tuple[float, float] = (2.0, 8.0)
    """s, uniform range of a fade's length (including its ramps)."""
    fade_depth: float = 0.0
    """Gain during a fade (0: the harmonic vanishes)."""
    fade_ramp: float = 0.5
    """s, raised-cosine ramp into and out of a fade."""
    resonance_freqs: tuple[float, ...] = (13.0,)
    """Hz, fixed body resonances (narrow-band noise)."""
    resonance_q: float = 20.0
    """Quality factor of each resonance (bandwidth = f / Q)."""
    resonance_amp: float = 0.04
    """m/s^2 rms of each resonance at road level 1 (v = v_ref) on an axis of gain 1."""
    road_noise: float = 0.05
    """m/s^2 std of broadband road noise at v = v_ref on an axis of gain 1."""
    v_ref: float = 0.8
    """m/s, reference speed of the road-excited terms (resonances, road noise)."""
    road_gamma: float = 1.0
    """Road excitation grows as (v/v_ref)^road_gamma."""
    road_floor: float = 0.0
    """Excitation of the body resonances at standstill (engine idling), in road-level units."""
    idle_noise: float = 0.0
    """m/s^2 std of broadband noise present whether moving or not (an idling engine's shaking)
    on an axis of gain 1."""
    engine: EngineConfig | None = None
    """Engine-order line; None for vehicles without an engine (the cart)."""
    aa_cutoff: float = 0.45
    """Anti-alias low-pass cut-off as a fraction of fs (sensor bandwidth)."""
    aa_order: int = 4
    """Butterworth order of the anti-alias magnitude response; 0 disables it."""
    phase_jitter: float = 0.0
    """rad^2/s, diffusion of each harmonic's phase (random walk); 0: rigid phase."""
    lowfreq_std: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """m/s^2, std of the body motion below ``lowfreq_cutoff`` on x, y, z (not axis-gained)."""
    lowfreq_cutoff: float = 1.0
    """Hz, cut-off of the body motion's low-pass (Butterworth order 2)."""
    lowfreq_v: float = 5.0
    """m/s, speed from which the body motion has its full level (linear below, 0 at rest)."""

    def __post_init__(self) -> None:
        if len(self.harmonic_amps) < 1:
            raise ParameterError("vibration.harmonic_amps: need at least one harmonic")
        if len(self.axis_gain) != 3:
            raise ParameterError("vibration.axis_gain: need three gains (x, y, z)")
        if len(self.lowfreq_std) != 3:
            raise ParameterError("vibration.lowfreq_std: need three values (x, y, z)")
        check(self, "vibration.",
              positive=("omega_ref", "amp_tau", "v_ref", "resonance_q", "fade_ramp",
                        "lowfreq_cutoff", "lowfreq_v", "aa_cutoff"),
              nonnegative=("gamma", "road_gamma", "amp_log_std", "resonance_amp", "road_noise",
                           "phase_jitter", "idle_noise", "fade_rate", "fundamental_fade_rate",
                           "road_floor"),
              fractions=("fade_depth",), intervals=("fade_duration",),
              nonnegative_each=("lowfreq_std",), counts=("aa_order",))

    @property
    def M(self) -> int:
        """Number of wheel harmonics."""
        return len(self.harmonic_amps)


@dataclass
class VibrationOutput:
    """Per-axis vibration (3, n) m/s^2 plus truth about the disturbances."""

    accel: np.ndarray
    harmonic_amp: np.ndarray  # (M, 3, n) instantaneous amplitudes A_mj
    gear: np.ndarray  # (n,) int, 0-based gear index (-1 without engine)
    engine_omega: np.ndarray  # (n,) rad/s engine crank speed (NaN without engine)
    fades: list[dict]


def aa_gain(freq_hz: np.ndarray, fs: float, cfg: VibrationConfig) -> np.ndarray:
    """Butterworth magnitude ``1 / sqrt(1 + (f / fc)^(2 n))`` of the sensor's anti-alias filter."""
    if cfg.aa_order == 0:
        return np.ones_like(freq_hz)
    fc = cfg.aa_cutoff * fs
    return 1.0 / np.sqrt(1.0 + (np.abs(freq_hz) / fc) ** (2 * cfg.aa_order))


def ou_process(n: int, dt: float, tau: float, std: float, rng: np.random.Generator,
               size: tuple[int, ...] = ()) -> np.ndarray:
    """Stationary Ornstein-Uhlenbeck samples, shape ``size + (n,)``, exact discretisation.

    ``u_{k+1} = phi u_k + std sqrt(1 - phi^2) xi_k``, ``phi = exp(-dt / tau)``,
    ``u_0 ~ N(0, std^2)``.
    """
    phi = np.exp(-dt / tau)
    xi = rng.standard_normal(size + (n,))
    xi[..., 0] *= std
    xi[..., 1:] *= std * np.sqrt(1.0 - phi * phi)
    return sps.lfilter([1.0], [1.0, -phi], xi, axis=-1)


def fade_gain(t: np.ndarray, moving_time: float, rate_per_min: float, cfg: VibrationConfig,
              rng: np.random.Generator) -> tuple[np.ndarray, list[dict]]:
    """Gain (n,) in [fade_depth, 1] with Poisson-placed fades of random length."""
    g = np.ones_like(t)
    events: list[dict] = []
    if rate_per_min <= 0 or t.size < 2:
        return g, events
    span = float(t[-1] - t[0])
    count = rng.poisson(rate_per_min * moving_time / 60.0)
    starts = np.sort(rng.uniform(t[0], t[-1], count)) if span > 0 else np.zeros(0)
    lengths = rng.uniform(cfg.fade_duration[0], cfg.fade_duration[1], count)
    for t_s, length in zip(starts, lengths, strict=True):
        ramp = min(cfg.fade_ramp, length / 2.0)
        s = t - t_s
        # 1 -> depth over [0, ramp], depth until length - ramp, back to 1 at length
        w = np.clip(np.minimum(s, length - s) / ramp, 0.0, 1.0)
        w = 0.5 - 0.5 * np.cos(np.pi * w)  # raised cosine, 0 outside, 1 in the middle
        g = np.minimum(g, 1.0 - (1.0 - cfg.fade_depth) * w)
        events.append({"t_start": float(t_s), "duration": float(length)})
    return g, events


def select_gears(omega: np.ndarray, eng: EngineConfig) -> np.ndarray:
    """Gear index per sample from shift speeds with hysteresis (play operator).

    Allowed range at each sample: the lowest gear whose engine speed stays <= upshift_rpm up to
    the highest gear whose engine speed stays >= downshift_rpm; the gear is held while allowed
    and clipped into the range otherwise. The range changes only at a few samples, so the loop
    runs over those change points.
    """
    ratios = np.asarray(eng.gear_ratios, dtype=np.float64) * eng.final_drive
    rpm = np.abs(omega)[:, None] * ratios[None, :] * 60.0 / (2.0 * np.pi)  # (n, G)
    G = ratios.size
    lo = np.minimum(np.sum(rpm > eng.upshift_rpm, axis=1), G - 1)  # gears that would over-rev
    hi = np.maximum(np.sum(rpm >= eng.downshift_rpm, axis=1) - 1, lo)
    gear = np.empty(omega.size, dtype=np.int64)
    change = np.flatnonzero((np.diff(lo) != 0) | (np.diff(hi) != 0)) + 1
    edges = np.concatenate(([0], change, [omega.size]))
    g = int(lo[0])
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        g = int(np.clip(g, lo[a], hi[a]))
        gear[a:b] = g
    return gear


def _resonator_noise(n: int, fs: float, f0: float, q: float, rng: np.random.Generator,
                     size: int) -> np.ndarray:
    """(size, n) unit-variance narrow-band noise around f0 Hz (iirpeak resonator)."""
    b, a = sps.iirpeak(f0, q, fs=fs)
    # noise power gain = sum of the squared impulse response (decays within ~Q/f0 periods)
    m = int(min(max(50 * q * fs / f0, 64), 200_000))
    imp = np.zeros(m)
    imp[0] = 1.0
    gain = np.sqrt(np.sum(sps.lfilter(b, a, imp) ** 2))
    burn = m
    x = rng.standard_normal((size, n + burn))
    return sps.lfilter(b, a, x, axis=-1)[:, burn:] / gain


def vibration(t: np.ndarray, theta: np.ndarray, omega: np.ndarray, speed: np.ndarray, fs: float,
              cfg: VibrationConfig, rng: np.random.Generator) -> VibrationOutput:
    """Vibration on the three accelerometer axes.

    Parameters
    ----------
    t : (n,) s, uniform at ``fs``; theta : (n,) rad exact wheel angle; omega : (n,) rad/s;
    speed : (n,) m/s; cfg : model knobs; rng : the only source of randomness.
    """
    n = t.size
    dt = 1.0 / fs
    M = cfg.M
    gains = np.asarray(cfg.axis_gain, dtype=np.float64)
    moving = float(np.sum(speed > 0) * dt)
    streams = rng.spawn(8)

    # wheel harmonics -----------------------------------------------------------------------
    m = np.arange(1, M + 1, dtype=np.float64)
    # (omega / omega_ref)^gamma, and 0 at standstill whatever gamma (no rotation, no vibration)
    law = np.where(omega > 0, (np.maximum(omega, 0.0) / cfg.omega_ref) ** cfg.gamma, 0.0)
    u = ou_process(n, dt, cfg.amp_tau, cfg.amp_log_std, streams[0], (M, 3))  # (M, 3, n)
    fades = []
    f = np.ones((M, n))
    for k in range(M):
        rate = cfg.fundamental_fade_rate if k == 0 else cfg.fade_rate
        f[k], ev = fade_gain(t, moving, rate, cfg, streams[1])
        fades += [dict(e, harmonic=k + 1) for e in ev]
    aa = aa_gain(m[:, None] * omega[None, :] / (2 * np.pi), fs, cfg)  # (M, n)
    amp = (np.asarray(cfg.harmonic_amps)[:, None, None] * gains[None, :, None]
           * (law * f * aa)[:, None, :] * np.exp(u))
    phi0 = streams[2].uniform(0, 2 * np.pi, (M, 3))
    phase = m[:, None, None] * theta[None, None, :] + phi0[:, :, None]
    if cfg.phase_jitter > 0:  # one random walk per harmonic, shared by the axes
        walk = np.cumsum(streams[5].normal(0.0, np.sqrt(cfg.phase_jitter * dt), (M, n)), axis=1)
        phase = phase + walk[:, None, :]
    acc = np.sum(amp * np.cos(phase), axis=0)

    # engine order line ---------------------------------------------------------------------
    if cfg.engine is not None:
        eng = cfg.engine
        gear = select_gears(omega, eng)
        ratio = np.asarray(eng.gear_ratios)[gear] * eng.final_drive
        w_idle = eng.idle_rpm * 2 * np.pi / 60.0
        w_eng = np.maximum(w_idle, omega * ratio)
        # engine phase by trapezoidal integration (the line need not be exact)
        th_e = np.concatenate(([0.0], np.cumsum((w_eng[1:] + w_eng[:-1]) * 0.5 * np.diff(t))))
        e_amp = eng.amp * (w_eng / w_idle) ** eng.gamma * aa_gain(
            eng.order * w_eng / (2 * np.pi), fs, cfg)
        ph = streams[3].uniform(0, 2 * np.pi, 3)
        acc += gains[:, None] * e_amp[None, :] * np.cos(eng.order * th_e[None, :] + ph[:, None])
        for order, rel in eng.extra_orders:
            e_k = rel * eng.amp * (w_eng / w_idle) ** eng.gamma * aa_gain(
                order * w_eng / (2 * np.pi), fs, cfg)
            ph = streams[3].uniform(0, 2 * np.pi, 3)
            acc += gains[:, None] * e_k[None, :] * np.cos(order * th_e[None, :] + ph[:, None])
    else:
        gear = np.full(n, -1, dtype=np.int64)
        w_eng = np.full(n, np.nan)

    # road-excited terms ----------------------------------------------------------------------
    level = (np.maximum(speed, 0.0) / cfg.v_ref) ** cfg.road_gamma
    res_level = level + cfg.road_floor
    rs = streams[4]
    for f0 in cfg.resonance_freqs:
        if not 0 < f0 < fs / 2:
            raise ParameterError(f"vibration.resonance_freqs: {f0} Hz is outside (0, fs/2)")
        if cfg.resonance_amp > 0:
            b = _resonator_noise(n, fs, f0, cfg.resonance_q, rs, 3)
            acc += cfg.resonance_amp * gains[:, None] * res_level[None, :] * b
    if cfg.road_noise > 0:
        acc += cfg.road_noise * gains[:, None] * level[None, :] * rs.standard_normal((3, n))
    if cfg.idle_noise > 0:
        acc += cfg.idle_noise * gains[:, None] * streams[7].standard_normal((3, n))
    lf = np.asarray(cfg.lowfreq_std, dtype=np.float64)
    if np.any(lf > 0):
        if not cfg.lowfreq_cutoff < fs / 2:
            raise ParameterError(f"vibration.lowfreq_cutoff {cfg.lowfreq_cutoff} Hz >= fs/2")
        sos = sps.butter(2, cfg.lowfreq_cutoff, fs=fs, output="sos")
        burn = int(10 * fs / cfg.lowfreq_cutoff)
        d = sps.sosfilt(sos, streams[6].standard_normal((3, n + burn)), axis=-1)[:, burn:]
        d /= np.maximum(d.std(axis=-1, keepdims=True), 1e-12)
        ramp = np.clip(np.maximum(speed, 0.0) / cfg.lowfreq_v, 0.0, 1.0)
        acc += lf[:, None] * ramp[None, :] * d
    return VibrationOutput(accel=acc, harmonic_amp=amp, gear=gear, engine_omega=w_eng,
                           fades=fades)
