"""Brute-force reference of the comb background (a running order statistic), shared by tests."""

import numpy as np


def sorted_windows(row: np.ndarray, width: int, step: int, rank: int) -> np.ndarray:
    """The ``rank``-th smallest of each window of ``width`` bins about every ``step``-th bin
    (edges extended with the end values, the last centre clipped to the last bin), by a full
    sort of each window, linearly interpolated between the evaluated bins (numpy)."""
    n = row.size
    h = width // 2
    pp = np.concatenate([np.repeat(row[:1], h), row, np.repeat(row[-1:], h)])
    cent = np.minimum(np.arange(0, n + step - 1, step), n - 1)
    med = np.array([np.sort(pp[c : c + width])[rank] for c in cent])
    if step == 1:
        return med
    i = np.arange(n)
    j = np.minimum(i // step, cent.size - 2)
    fr = (i - cent[j]) / np.maximum(cent[j + 1] - cent[j], 1)
    return med[j] * (1.0 - fr) + med[j + 1] * fr
