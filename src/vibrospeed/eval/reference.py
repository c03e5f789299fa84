"""Reference speeds from bump crossings and steady turns, for checking a tracker: the
detectors live in :mod:`vibrospeed.signal.reference` (a measurement source that the aided
tracker also uses); this module keeps the evaluation's import path."""

from vibrospeed.signal.reference import (  # noqa: F401
    Fixes,
    bump_events,
    bump_fixes,
    detect,
    fixes_to_omega,
    turn_fixes,
)
