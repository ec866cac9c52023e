from pathlib import Path

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)

# The shared data folder sits beside the repository (../shared), on a developer's machine and in CI.
REAL_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
