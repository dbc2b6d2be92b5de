"""Fuzzification: three Gaussian memberships per raw feature (LEARNER.md "State").

mu_j(x) = exp(-(x - c_j)^2 / (2 sigma^2)) with centres c = (0, 0.5, 1) and sigma = 0.2123, so
(rho_global, rho_local, m) becomes the 9-vector
[g_low, g_mid, g_high, l_low, l_mid, l_high, m_low, m_mid, m_high].
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

FEATURES = 3
"""Raw features per state."""
MEMBERSHIPS = 3
"""Gaussian sets per feature."""
STATE_SIZE = FEATURES * MEMBERSHIPS
"""Length of the fuzzy state vector."""


def fuzzify(
    features: torch.Tensor, centres: Sequence[float] = (0.0, 0.5, 1.0), sigma: float = 0.2123
) -> torch.Tensor:
    """Memberships of raw features.

    Args:
        features: (..., 3) raw features in [0, 1].
        centres: membership centres c_j.
        sigma: membership width.

    Returns:
        (..., 9) memberships, feature-major (all three sets of feature 0 first).
    """
    c = torch.as_tensor(centres, dtype=features.dtype, device=features.device)
    diff = features.unsqueeze(-1) - c  # (..., 3 features, 3 sets)
    mu = torch.exp(-(diff * diff) / (2.0 * sigma * sigma))
    return mu.flatten(-2)
