"""The fitted calibration (:class:`Calibration`): what a fit found, documented field by field, and its
versioned file (:meth:`Calibration.write`, :meth:`Calibration.read`; the format in
:mod:`optcal.core.calfile`). Computing it is the application's (:func:`optcal.app.fit.calibrate` runs a
solver); holding, writing and reading it is the core's, as imucal keeps its calibration-info classes apart
from the procedures that compute them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optcal.core.analysis import GoodnessOfFit, Observability, PositionDiagnostics
from optcal.core.model import Model
from optcal.core.problem import CalibrationProblem


@dataclass
class Calibration:
    """A fitted calibration: parameters, standard errors and diagnostics (what
    :func:`optcal.app.fit.calibrate` and :func:`optcal.calibrate` return). :meth:`write` writes its
    calibration file, :meth:`read` reads one back as the :class:`~optcal.core.calfile.CalibrationFile` that
    applies it (the file holds the record, not the fit's data and diagnostics).

    - ``model``: the :class:`~optcal.core.model.Model` fitted (its parameter names, units and terms).
    - ``x`` (p,): the parameters in the model's order and units (docs/design.md, "The sensor model"); ``parameters``:
    the same
      as {name: value}.
    - ``stderr`` (p,): each parameter's Cramér-Rao standard error at ``x`` (Birge-scaled when the residuals
      exceed the noise; inf for an unobservable direction), same units.
    - ``observability``: the rank of the fit's Jacobian and the unobservable directions, by name.
    - ``fit``: the goodness of fit (:class:`~optcal.core.analysis.GoodnessOfFit`): residual RMS (g), cost, degrees of
      freedom, the noise it was judged against (g) and where that came from, χ² and its p-value.
    - ``problem``: the :class:`~optcal.core.problem.CalibrationProblem` fitted (data, presets, local gravity).
    - ``solver``: the registered solver's name; ``result``: its :class:`optcal.solvers.base.SolverResult`.
    - ``notes``: what the user should know about these numbers, one line each.
    - ``diagnostics``: per-position residuals, leverages and outliers (design.md, "Per-position residuals, outliers,
    the robust loss, what the data determine and weak fits"); ``positions``: them as rows.
    - ``loss``, ``f_scale_g``: the robust loss and its scale in g (``linear``, None: plain least squares).
    - ``forced``: the reasons a ``force_weak`` fit would have been refused for (empty: not forced).
    - ``requested_model``: the default model when the data determined only a smaller one (the fallback).
    """

    model: Model
    x: np.ndarray
    stderr: np.ndarray
    observability: Observability
    fit: GoodnessOfFit
    problem: CalibrationProblem
    solver: str
    result: object  # the SolverResult
    notes: list = field(default_factory=list)  # what the user should know about these numbers
    diagnostics: PositionDiagnostics | None = None  # per-position residuals and outliers (design.md, "Per-position
                                                    # residuals, outliers, the robust loss, what the data determine
                                                    # and weak fits")
    loss: str = "linear"
    f_scale_g: float | None = None
    forced: list = field(default_factory=list)  # the reasons a `force_weak` fit would have been refused for
    requested_model: str | None = None  # the default model when a smaller one was fitted instead (fallback)

    @property
    def parameters(self) -> dict[str, float]:
        return self.model.to_dict(self.x)

    @property
    def positions(self) -> list[dict]:
        """One row per position: index, position, label, residual_ug, sigma_ug, standardised (r/σ), leverage,
        statistic_sigma (|r|/(σ√(1−h))), p_value, weight (robust), outlier (docs/design.md, "Per-position residuals,
        outliers, the robust loss, what the data determine and weak fits")."""
        return self.diagnostics.rows() if self.diagnostics is not None else []

    def residual_table(self) -> str:
        """The per-position residuals as fixed-width text, residuals and noise in µg. ``test σ`` is the statistic
        the outlier flag judges, |r|/(σ√(1−h)): a position of leverage h near 1 pulls the fit onto itself, so a
        small r/σ can still be far off the fit of the others; "-" where it is not tested (a leverage so near 1 that the
        position alone pins part of the model and the others cannot check it)."""
        head = (f"{'#':>3} {'position':>8} {'label':<8} {'residual µg':>12} {'σ µg':>9} {'r/σ':>7} {'lever.':>6} "
                f"{'test σ':>7} {'weight':>6}  flag")
        lines = [head, "-" * len(head)]
        for r in self.positions:
            def f(v, spec):
                return format(v, spec) if v is not None else format("-", ">" + spec.split(".")[0])
            lines.append(f"{r['index']:>3} {r['position']:>8} {str(r['label'] or ''):<8} "
                         f"{f(r['residual_ug'], '12.3f')} {f(r['sigma_ug'], '9.3f')} {f(r['standardised'], '7.2f')} "
                         f"{f(r['leverage'], '6.3f')} {f(r['statistic_sigma'], '7.2f')} {f(r['weight'], '6.3f')}  "
                         f"{'OUTLIER' if r['outlier'] else ''}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        r = self.result
        return {
            "model": self.model.name,
            "terms": list(self.model.terms),
            "parameters": self.parameters,
            "stderr": {n: (None if not np.isfinite(s) else float(s)) for n, s in zip(self.model.names, self.stderr)},
            "rms_residual_g": self.fit.rms_g,
            "cost": self.fit.cost,
            "goodness_of_fit": self.fit.to_dict(),  # noise in g; chi2 and p-value only when the noise is known
            "n_positions": len(self.problem.data),
            "g_local": self.problem.g_local,
            "solver": self.solver,
            "observability": self.observability.to_dict(),
            "loss": self.loss, "f_scale_g": self.f_scale_g,
            "positions": self.positions,
            "notes": list(self.notes),
            "forced": list(self.forced),
            "requested_model": self.requested_model,
            "nfev": r.nfev, "nit": r.nit, "runtime_s": r.runtime_s, "success": r.success, "message": r.message,
        }

    # -- its file (docs/design.md, "Calibration file": the versioned JSON record, optcal.core.calfile)
    # -----------------------
    def file_record(self, *, units_out: str | None = None, source=None) -> dict:
        """The calibration file's content: ``format``, ``format_version``, model, parameters, standard errors,
        units (``raw``: ``units_out``, the data's by default; ``calibrated``: g), local gravity, ...
        (:func:`optcal.core.calfile.calibration_to_dict`)."""
        from optcal.core.calfile import calibration_to_dict

        return calibration_to_dict(self, units_out=units_out, source=source)

    def write(self, path, *, units_out: str | None = None, source=None, overwrite: bool = False) -> None:
        """Write the calibration file, whole or not at all; an existing file is kept unless ``overwrite``."""
        from optcal.core.calfile import write_calibration

        write_calibration(self, path, units_out=units_out, source=source, overwrite=overwrite)

    @staticmethod
    def read(path):
        """The calibration file at ``path``, validated (any version this optcal reads), as the
        :class:`~optcal.core.calfile.CalibrationFile` that applies it to raw outputs."""
        from optcal.core.calfile import read_calibration

        return read_calibration(path)
