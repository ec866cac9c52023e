"""What a gyroscope fit determines: observability (through :mod:`optcal.analysis`, on the whitened
residuals' Jacobian) and the likelihood-ratio test for g-sensitivity.

The residuals are whitened (:mod:`optcal.gyro.data`), so twice the negative log-likelihood is the cost
up to a constant, and the drop of the cost from the model without G to the model with it is, when the
sensor has no g-sensitivity, χ²-distributed with 9 degrees of freedom (Wilks). G is reported only when
the drop exceeds the χ²₉ quantile at 1 − ``alpha``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import analysis
from ..errors import InputError

ALPHA = 1e-3  # false-detection probability of the g-sensitivity test


@dataclass(frozen=True)
class GSensitivityTest:
    statistic: float  # cost(without G) − cost(with G), χ² units
    dof: int
    p_value: float
    detected: bool

    def to_dict(self) -> dict:
        return {"statistic": self.statistic, "dof": self.dof, "p_value": self.p_value, "detected": self.detected}


def g_sensitivity_test(cost_without: float, cost_with: float, alpha: float = ALPHA) -> GSensitivityTest:
    """Likelihood-ratio test of G = 0 from the optimal costs of the two nested fits on the same data."""
    from scipy.stats import chi2  # at first use: scipy.stats costs about a second to import

    stat = max(float(cost_without) - float(cost_with), 0.0)
    p = float(chi2.sf(stat, 9))
    return GSensitivityTest(stat, 9, p, p < alpha)


def check_observable(problem, x_full: np.ndarray) -> analysis.Observability:
    """The observability of ``problem`` at ``x_full``; an InputError naming the parameters the motions
    leave undetermined, and the way out, when any are."""
    obs = analysis.observability(problem, x_full)
    if obs.rank < obs.n_parameters:
        # the parameters that carry each undetermined direction (weight 0.1 or more of its unit vector; the
        # others in it move by a few thousandths, through the correlations of the fit)
        lead = {w["name"] for d in obs.unobservable for w in d if abs(w["weight"]) >= 0.1}
        names = [n for n in obs.names if n in lead]
        raise InputError(f"the motions do not determine gyroscope parameter(s) {', '.join(names)} "
                         f"(rank {obs.rank} of {obs.n_parameters}): rotate the sensor about all three axes "
                         "between rests")
    return obs
