"""The algebraic estimator as a filter: :func:`step` (one sample) and :func:`run` (a signal) on
the same compiled core, so the two give the same numbers; :class:`Result` names the output
columns."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from vibrospeed.config import check_state
from vibrospeed.errors import ParameterError
from vibrospeed.estimators.algebraic.config import INPUTS, OUTPUTS, Config, State, init
from vibrospeed.estimators.algebraic.core import _NS, _core, _run
from vibrospeed.types import Estimate


class Result(NamedTuple):
    """:func:`run`'s output: ``final`` the state after the last sample and ``outputs`` (n,
    len(:data:`OUTPUTS`)) the per-sample columns, also readable by name (``res.vy``,
    ``res.slip_mode``; ``speed`` and ``speed_std`` are ``vx`` and ``vx_std``). In this order,
    so ``state, outputs = run(...)`` unpacks it."""

    final: State
    outputs: np.ndarray

    def __getattr__(self, name: str) -> np.ndarray:
        if name.startswith("__"):
            raise AttributeError(name)
        col = _ALIAS.get(name, name)
        if col not in OUTPUTS:
            raise AttributeError(f"algebraic.Result has no column '{name}'")
        return tuple.__getitem__(self, 1)[:, OUTPUTS.index(col)]


#: the Estimate's and Track's names of the outputs ``vx``, ``vx_std``
_ALIAS = {"speed": "vx", "speed_std": "vx_std"}


def _estimate(out: np.ndarray) -> Estimate:
    vals = dict(zip(OUTPUTS, out, strict=True))
    return Estimate(speed=vals.pop("vx"), speed_std=vals.pop("vx_std"), extras=vals)


def _check_state(config: Config, state: State, n_taps: int) -> None:
    """A state made for other windows or another backtracking depth gave NaN or shifted
    numbers: the compiled core indexes its buffers by the config's lengths."""
    check_state("algebraic", "windows and backtracking", buf=(state.buf, (4, n_taps)),
                hist=(state.hist, (4, config.n_back + 2)), s=(state.s, (_NS,)))


def step(config: Config, state: State, y, taps=None) -> tuple[State, Estimate]:
    """One sample ``y = (gz, ax, ay, omega_mean)``; returns the new state and the estimate
    (``speed`` = vx, ``speed_std`` = vx_std, the other :data:`OUTPUTS` as extras). Pass
    ``taps = config.taps()`` to avoid recomputing kernels."""
    z = np.asarray(y, dtype=np.float64)
    if z.shape != (4,):  # the compiled core reads 4 values whatever it is given
        raise ParameterError(f"algebraic.step expects 4 inputs {INPUTS}, got shape {z.shape}")
    b0, b1 = config.taps() if taps is None else taps
    _check_state(config, state, b0.size)
    buf = state.buf.copy()
    hist = state.hist.copy()
    s = state.s.copy()
    out = np.empty(len(OUTPUTS))
    _core(b0, b1, config.scalars(), buf, hist, s, z, out)
    return State(buf, hist, s), _estimate(out)


def run(config: Config, y: np.ndarray, state: State | None = None) -> Result:
    """All samples ``y`` (n, 4) (columns :data:`INPUTS`); outputs (n, len(OUTPUTS)),
    identical to repeated :func:`step`."""
    st = init(config) if state is None else state
    Z = np.ascontiguousarray(y, dtype=np.float64)
    if Z.ndim != 2 or Z.shape[1] != 4:
        raise ParameterError(f"algebraic.run expects (n, 4) inputs {INPUTS}, got {Z.shape}")
    b0, b1 = config.taps()
    _check_state(config, st, b0.size)
    buf = st.buf.copy()
    hist = st.hist.copy()
    s = st.s.copy()
    outs = np.empty((Z.shape[0], len(OUTPUTS)))
    _run(b0, b1, config.scalars(), buf, hist, s, Z, outs)
    return Result(State(buf, hist, s), outs)
