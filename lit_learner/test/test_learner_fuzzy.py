"""Fuzzification: memberships at the centres and where neighbours cross."""

from __future__ import annotations

import math

import pytest
import torch
from lit_learner.fuzzy import STATE_SIZE, fuzzify

SIGMA = 0.2123


def gauss(d: float) -> float:
    return math.exp(-d * d / (2 * SIGMA * SIGMA))


@pytest.mark.parametrize(
    ("x", "expected"),
    [
        (0.0, (1.0, gauss(0.5), gauss(1.0))),
        (0.5, (gauss(0.5), 1.0, gauss(0.5))),
        (1.0, (gauss(1.0), gauss(0.5), 1.0)),
    ],
)
def test_memberships_at_the_centres(x: float, expected: tuple[float, float, float]) -> None:
    mu = fuzzify(torch.tensor([[x, x, x]], dtype=torch.float64))
    assert mu.shape == (1, STATE_SIZE)
    for feature in range(3):
        got = mu[0, 3 * feature : 3 * feature + 3].tolist()
        assert got == pytest.approx(expected, rel=1e-12)


def test_state_is_feature_major() -> None:
    """(g_low, g_mid, g_high, l_low, ..., m_high): with three different inputs every entry is
    one of its own (a set-major order passes a test whose inputs sit on the diagonal)."""
    x = (0.0, 0.25, 1.0)
    mu = fuzzify(torch.tensor(x, dtype=torch.float64))
    assert mu.shape == (9,)
    expected = [gauss(value - centre) for value in x for centre in (0.0, 0.5, 1.0)]
    assert mu.tolist() == pytest.approx(expected, rel=1e-12)


def test_neighbours_cross_half_way_between_centres() -> None:
    mu = fuzzify(torch.tensor([0.25, 0.75, 0.5], dtype=torch.float64))
    assert mu[0] == pytest.approx(mu[1])  # g_low = g_mid at 0.25
    assert mu[4] == pytest.approx(mu[5])  # l_mid = l_high at 0.75
    assert float(mu[0]) == pytest.approx(0.5, abs=1e-3)  # sigma 0.2123: crossing at about 0.5
