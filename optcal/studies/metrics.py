"""Metrics per solver × scheme × model over a study's Monte-Carlo runs (docs/design.md, "Metrics").

Accuracy is scored against the Cramér-Rao bound at the truth with the simulation's noise
(:func:`optcal.studies.trial.projected_crlb`): per parameter, RMSE / CRLB over runs (1 is an efficient
estimator). With the norm cost some directions are unobservable (seed15 has three; docs/design.md, "Three directions
the norm cannot see"): the error's component along them is set by the presets, not by the data, so it is reported per
direction and not scored; parameters that have weight in those directions are scored by their observable part.
The one-number summary ``accuracy`` is the RMS over parameters of RMSE / CRLB.

With manufacturer presets a method may also use them as information (the staged procedure keeps the
last stages' parameters near them) and then beat the data-only bound. ``accuracy_presets`` scores the
whole error against the bound of data and presets together (:func:`optcal.studies.trial.crlb_with_presets`),
which no method beats: a ratio below 1 against the plain bound with one near 1 against this one means
the accuracy came from the presets.

A trial *converged* when its final cost is within the 99.9 % quantile of the χ² distribution of the
cost at the optimum (cost / σ² with m − rank degrees of freedom): it reached the noise floor. The
success rate is the fraction of a group's trials that converged (failed trials count as not).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np


def _mean(a) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.mean(a)) if a.size else float("nan")


def _pct(a, q):
    a = np.asarray([v for v in a if v is not None and np.isfinite(v)], float)
    return float(np.percentile(a, q)) if a.size else float("nan")


@dataclass
class Group:
    model: str
    scheme: str
    solver: str
    solver_name: str
    reference: bool
    reference_error_arcsec: float
    rows: list = field(default_factory=list)

    @property
    def ok(self) -> list[dict]:
        return [r for r in self.rows if r["status"] == "ok"]

    @property
    def n(self) -> int:
        return len(self.rows)

    @property
    def n_failed(self) -> int:
        return self.n - len(self.ok)

    @property
    def failures(self) -> list[str]:
        return sorted({r["message"] for r in self.rows if r["status"] != "ok"})

    @property
    def success_rate(self) -> float:
        return sum(r["converged"] for r in self.rows) / max(self.n, 1)

    @property
    def solver_success_rate(self) -> float:
        return sum(r["success"] for r in self.rows) / max(self.n, 1)

    def column(self, key: str) -> np.ndarray:
        return np.array([np.nan if r.get(key) is None else r[key] for r in self.ok], float)

    def matrix(self, key: str) -> np.ndarray:
        ok = self.ok
        return np.array([r[key] for r in ok], float) if ok else np.zeros((0, len(self.names)))

    @property
    def names(self) -> list[str]:
        return self.rows[0]["names"]

    # -- accuracy ---------------------------------------------------------------------------
    def parameters(self) -> list[dict]:
        """Per parameter: mean error, RMSE, SD (of the raw error), CRLB and RMSE/CRLB of the observable
        part, and whether the parameter is observable on its own."""
        E, Ep, C = self.matrix("err"), self.matrix("err_proj"), self.matrix("crlb")
        with_presets = bool(self.ok) and all(r.get("crlb_presets") for r in self.ok)
        Cp = self.matrix("crlb_presets") if with_presets else None
        obs = np.array(self.ok[0]["observable"], bool) if self.ok else np.ones(len(self.names), bool)
        out = []
        for j, name in enumerate(self.names):
            if not len(E):
                out.append({"name": name, "mean": np.nan, "rmse": np.nan, "sd": np.nan, "crlb": np.nan,
                            "ratio": np.nan, "observable": bool(obs[j])})
                continue
            crlb = float(np.sqrt(np.mean(C[:, j] ** 2)))
            rmse_p = float(np.sqrt(np.mean(Ep[:, j] ** 2)))
            out.append({
                "name": name, "mean": float(np.mean(E[:, j])), "rmse": float(np.sqrt(np.mean(E[:, j] ** 2))),
                "sd": float(np.std(E[:, j], ddof=1)) if len(E) > 1 else np.nan,
                "rmse_observable": rmse_p, "crlb": crlb, "ratio": rmse_p / crlb if crlb > 0 else np.nan,
                "observable": bool(obs[j]),
            })
            if Cp is not None:  # the whole error against the bound of data and presets together
                cp = float(np.sqrt(np.mean(Cp[:, j] ** 2)))
                out[-1].update(crlb_presets=cp, ratio_presets=out[-1]["rmse"] / cp)
        return out

    @property
    def accuracy_presets(self) -> float:
        """RMS over parameters of RMSE / (the bound with the presets as a measurement); NaN without presets."""
        r = np.array([p.get("ratio_presets", np.nan) for p in self.parameters()], float)
        return float(np.sqrt(np.mean(r**2))) if r.size and np.all(np.isfinite(r)) else float("nan")

    @property
    def accuracy(self) -> float:
        """RMS over parameters of RMSE / CRLB (observable parts); 1 means efficient."""
        r = np.array([p["ratio"] for p in self.parameters()], float)
        r = r[np.isfinite(r)]
        return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")

    def unobservable(self) -> list[dict]:
        """Each unobservable direction (as 'w·name + ...') with the RMS of the error along it."""
        ok = self.ok
        if not ok or not ok[0]["null_dirs"]:
            return []
        names = self.names

        def vectors(dirs):
            V = np.zeros((len(names), len(dirs)))
            for k, d in enumerate(dirs):
                for w in d:
                    V[names.index(w["name"]), k] = w["weight"]
            return V

        # Each run's basis comes from its own Jacobian: line its directions up with the first run's
        # (order and sign) before pooling the errors along them.
        V0 = vectors(ok[0]["null_dirs"])
        C = np.full((len(ok), V0.shape[1]), np.nan)
        for i, r in enumerate(ok):
            V = vectors(r["null_dirs"])
            if V.shape != V0.shape:
                continue
            M = V0.T @ V
            for k in range(V0.shape[1]):
                j = int(np.argmax(np.abs(M[k])))
                C[i, k] = np.sign(M[k, j]) * r["null_err"][j]
        C = C[np.all(np.isfinite(C), axis=1)]
        out = []
        for k, d in enumerate(ok[0]["null_dirs"]):
            text = " ".join(f"{w['weight']:+.3f}·{w['name']}" for w in d)
            out.append({"direction": text, "rms": float(np.sqrt(np.mean(C[:, k] ** 2)))})
        return out

    # -- the rest ---------------------------------------------------------------------------
    def summary(self) -> dict:
        fun, rt, nfev = self.column("fun"), self.column("runtime_s"), self.column("nfev")
        return {
            "model": self.model, "scheme": self.scheme, "solver": self.solver, "runs": self.n,
            "failed": self.n_failed, "success_rate": self.success_rate, "accuracy": self.accuracy,
            "accuracy_presets": self.accuracy_presets,
            "cost_min": _pct(fun, 0), "cost_median": _pct(fun, 50), "cost_max": _pct(fun, 100),
            "ver_mean_ug": _mean(self.column("ver_mean_ug")), "ver_sd_ug": _mean(self.column("ver_sd_ug")),
            "ver_truth_ug": _mean(self.column("ver_truth_mean_ug")),
            "runtime_median_s": _pct(rt, 50), "runtime_p10_s": _pct(rt, 10), "runtime_p90_s": _pct(rt, 90),
            "nfev_median": _pct(nfev, 50),
            # the solver's evaluation rate: every evaluation of the group over its summed solver time
            "evals_per_s": float(np.nansum(nfev) / np.nansum(rt)) if len(rt) and np.nansum(rt) > 0 else float("nan"),
            "nav_max_nmi": _pct(self.column("nav_max_nmi"), 50), "nav_mean_nmi": _pct(self.column("nav_mean_nmi"), 50),
        }

    def convergence(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Evaluation grid and the median, 10 % and 90 % of the best cost over runs (a trial that
        stopped keeps its final value)."""
        traces = [r["trace"] for r in self.ok if r["trace"]]
        if not traces:
            e = np.zeros(0)
            return e, e, e, e
        top = max(t[-1][0] for t in traces)
        grid = np.unique(np.round(10 ** (np.arange(0, 10 * np.log10(max(top, 1)) + 1) / 10)))
        grid = np.unique(np.append(grid[grid <= top], top))
        Y = np.full((len(traces), len(grid)), np.nan)
        for i, t in enumerate(traces):
            nf = np.array([p[0] for p in t], float)
            b = np.array([p[1] for p in t], float)
            idx = np.searchsorted(nf, grid, side="right") - 1
            Y[i, idx >= 0] = b[idx[idx >= 0]]
        with np.errstate(all="ignore"):
            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                return (grid, np.nanmedian(Y, 0), np.nanpercentile(Y, 10, 0), np.nanpercentile(Y, 90, 0))


def groups(rows: list[dict], order: list[str] | None = None) -> list[Group]:
    """Rows grouped by (model, scheme, solver), in the spec's solver order when given."""
    g: OrderedDict[tuple, Group] = OrderedDict()
    for r in sorted(rows, key=lambda r: (r["model"], r["scheme"], r["solver"], r["run"])):
        k = (r["model"], r["scheme"], r["solver"])
        if k not in g:
            g[k] = Group(r["model"], r["scheme"], r["solver"], r["solver_name"], bool(r["reference"]),
                         float(r["reference_error_arcsec"] or 0.0))
        g[k].rows.append(r)
    out = list(g.values())
    if order:
        rank = {s: i for i, s in enumerate(order)}
        out.sort(key=lambda x: (x.model, x.scheme, rank.get(x.solver, len(rank))))
    return out


def cells(gs: list[Group]) -> OrderedDict:
    """Groups by (model, scheme)."""
    out: OrderedDict[tuple, list[Group]] = OrderedDict()
    for g in gs:
        out.setdefault((g.model, g.scheme), []).append(g)
    return out
