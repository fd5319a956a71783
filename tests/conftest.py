"""Shared fixtures. Tests point at the source tree; strict invariant checks are on."""
import os

import numpy as np
import pytest

os.environ.setdefault("FABKIT_STRICT", "1")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
