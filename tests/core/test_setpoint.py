"""The setpoint record's helpers (core/setpoint.py)."""

from __future__ import annotations

from itertools import combinations

import numpy as np

from swarmscene.core.setpoint import Mode, is_mode


def test_is_mode_is_the_enum_comparison_for_every_set_of_modes():
    """``is_mode`` compares with plain ints for speed; it must select what comparing with the
    enum members selects, for every non-empty set of modes, at every length (none included)."""
    rng = np.random.default_rng(7)
    for n in (0, 1, 6, 50):
        mode = rng.integers(0, len(Mode), size=n).astype(np.int8)
        for k in range(1, len(Mode) + 1):
            for modes in combinations(Mode, k):
                expected = np.zeros(n, dtype=bool)
                for m in modes:
                    expected |= mode == m
                got = is_mode(mode, *modes)
                assert got.dtype == bool and got.shape == (n,)
                np.testing.assert_array_equal(got, expected, err_msg=str(modes))
