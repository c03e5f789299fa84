"""vibrospeed: vehicle speed from the sensors a vehicle already has.

Conventions (used by every module)
----------------------------------
Units
    SI everywhere, float64. Time ``t`` in seconds from one clock per recording, angles in rad,
    angular rates in rad/s, accelerations in m/s^2. ``omega`` is the wheel angular speed (rad/s);
    vehicle speed ``v = r * omega`` (m/s) for a wheel radius ``r`` (m).
Axes
    Body frame: x longitudinal (direction of travel, forward +), y lateral, z vertical (up +).
    Vibrations are usually read from one axis (thesis: y), speed changes from x.
Symbols (``../shared/METHODS.md``)
    ``T`` sample period (s), ``fs = 1/T`` (Hz), ``M`` number of harmonics, ``alpha^(m), beta^(m)``
    phasor states of harmonic m. The harmonic linear state has shape ``(2M,)`` ordered
    ``[alpha_1, beta_1, alpha_2, beta_2, ...]``; stacked filters carry a leading axis, e.g. the
    RBPMF covariance is ``(N, 2M, 2M)``.
Data
    :class:`vibrospeed.types.Recording` holds a uniform or non-uniform time line ``t`` (n,) and
    named channels (n,) with canonical names (:data:`vibrospeed.types.CHANNEL_UNITS`); irregular
    event streams (cog-wheel tick times) live in ``Recording.events``.
    Estimators return a :class:`vibrospeed.types.Track`: ``omega`` with its standard deviation
    and a credible band, and ``speed`` where the wheel radius is known.
Estimators
    Each estimator module offers a frozen ``Config`` dataclass, a small immutable ``State``,
    ``init(config) -> state``, ``step(config, state, y) -> (state, estimate)`` for one sample
    (online use) and ``run(config, y) -> arrays`` over a whole recording with identical numbers.
Layers
    Subpackages are layered; a module imports only from its own layer or a lower one (checked
    by ``tests/test_import_graph.py``, together with "no import cycles"), lowest first:

    0. the package root and types, errors, config, presets
    1. models, signal, io
    2. sim, estimators
    3. eval
    4. batch
    5. cli (and ``__main__``)
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("vibrospeed")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"

from vibrospeed.errors import InputError, ParameterError, ReaderError, VibrospeedError
from vibrospeed.types import CHANNEL_UNITS, Recording, Track

__all__ = [
    "CHANNEL_UNITS",
    "InputError",
    "ParameterError",
    "ReaderError",
    "Recording",
    "Track",
    "VibrospeedError",
    "__version__",
]
