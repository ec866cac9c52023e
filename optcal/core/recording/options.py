"""How a raw recording is read and its rests found, in one object (issue #30): the options of ``optcal calibrate
--raw`` (and ``imu``, ``discover``, ``noise``), the keyword arguments of :func:`optcal.calibrate` with
``raw=True`` and of :func:`optcal.app.workflows.recording.positions_from_raw`, and the options the library's
errors name.
Each field carries the command-line option that sets it, so that the list of options, the API's accepted
keywords and the errors' option names are this one definition."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

from optcal.core.errors import InputError


def _option(flag: str, default=None):
    return field(default=default, metadata={"flag": flag})


@dataclass(frozen=True)
class RawOptions:
    """A raw recording's reading (the first seven, :func:`optcal.core.recording.read_recording`'s) and the choice of
    its rests (the others, :func:`optcal.app.workflows.recording.positions_from_raw_recording`'s).

    - ``columns``: the columns' roles ("ax,ay,az", "t=0,ax=1,...", or a list); ``rate``: the sample rate, Hz,
      when the file has no time column; ``units``: the outputs' (g, m/s2, counts, volts, mg; None: as the
      accelerometer's columns' names give them, ``ax(g)``, ``Acc X [m/s^2]``, else g); ``saturation``:
      the outputs' rail, in ``units``; ``adc``: the counts' format ("uint16", ...); ``time_unit``: the time
      column's (s, ms, us, ns); ``topic``: a ROS bag's or a ULog's IMU topic.
    - ``intervals``: a file of the rests ([start, end) samples), else ``labels``, a label column whose runs of
      ``label_values`` (all labels if None) are the rests, else a detector: ``method`` "segment" (the default)
      or "variance" (which ``threshold_k``, a multiplier or a range "2:10", or ``init_s``, s, select);
      ``window_s`` and ``min_static_s``, s (docs/segmentation.md).
    """

    columns: str | Sequence[str] | None = _option("--columns")
    rate: float | None = _option("--rate")
    units: str | None = _option("--units")
    saturation: float | None = _option("--saturation")
    adc: str | None = _option("--adc")
    time_unit: str | None = _option("--time-unit")
    topic: str | None = _option("--topic")
    intervals: str | Path | None = _option("--intervals")
    labels: str | None = _option("--labels")
    label_values: Sequence[str] | None = _option("--labels")
    method: str | None = _option("--method")
    threshold_k: float | str | Sequence[float] | None = _option("--threshold-k")
    window_s: float | None = _option("--window")
    min_static_s: float | None = _option("--min-static")
    init_s: float | None = _option("--init-s")

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    @classmethod
    def flags(cls) -> dict[str, str]:
        """{parameter: the command-line option that sets it}."""
        return {f.name: f.metadata["flag"] for f in fields(cls)}

    @classmethod
    def of(cls, function: str, **kw) -> RawOptions:
        """The options from keyword arguments, an unknown one refused in one line naming the known ones."""
        unknown = sorted(set(kw) - set(cls.names()))
        if unknown:
            raise InputError(f"{function}() got unknown keyword(s) {', '.join(unknown)}; the recording options are "
                             f"{', '.join(cls.names())}")
        return cls(**kw)

    def but(self, function: str = "RawOptions", **kw) -> RawOptions:
        """These options with some replaced, an unknown name refused as :meth:`of` refuses it."""
        if not kw:
            return self
        RawOptions.of(function, **kw)
        return replace(self, **kw)

    def read(self, path, *, refuse_positions: bool = True):
        """The recording at ``path`` (:func:`optcal.core.recording.read_recording`)."""
        from optcal.core.recording.reading import read_recording

        return read_recording(path, self.columns, self.rate, self.units, saturation=self.saturation,
                              labels=self.labels, adc=self.adc, time_unit=self.time_unit,
                              refuse_positions=refuse_positions, topic=self.topic)
