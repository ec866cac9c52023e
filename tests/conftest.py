from pathlib import Path

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)

# Real recordings made by others, kept in the repository with their licences (tests/data/README.md).
REAL_DATA = Path(__file__).resolve().parent / "data"
