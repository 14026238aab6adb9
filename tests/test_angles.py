"""The compiled ``wrap`` is ``wrap_angle`` of one number, bit for bit, on its fast path and off it."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sensact.core.angles import TWO_PI, wrap, wrap_angle


def _same(a: float) -> bool:
    got, want = wrap(a), float(wrap_angle(a))
    return (np.isnan(got) and np.isnan(want)) or np.float64(got).tobytes() == np.float64(want).tobytes()


@settings(deadline=None)  # the first call compiles
@given(st.floats(allow_nan=True, allow_infinity=True))
def test_wrap_is_wrap_angle_bit_for_bit(a):
    assert _same(a)


def test_wrap_at_the_edges_of_its_fast_path():
    """Just inside and just outside [-pi, pi), where ``a + pi`` rounds onto 0 or 2 pi."""
    edges = [-np.pi, np.pi, TWO_PI - np.pi, 3 * np.pi, -3 * np.pi, 0.0, -0.0, 1e-300, -1e-300]
    for e in edges:
        for a in (np.nextafter(e, -np.inf), e, np.nextafter(e, np.inf)):
            assert _same(float(a)), a
    assert -np.pi <= wrap(np.nextafter(np.pi, -np.inf)) < np.pi
    assert wrap(np.pi) == -np.pi
