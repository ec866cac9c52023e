"""Options shared by every command that reads data (calibrate, discover, apply): the positions CSV or a
raw recording, its units and local gravity."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from ..gravity import local_gravity_g

if TYPE_CHECKING:
    from ..data import PositionsData


def add_gravity_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("local gravity (default 1 g)")
    g.add_argument("--gravity", type=float, metavar="M_PER_S2", help="local gravity in m/s²")
    g.add_argument("--latitude", type=float, metavar="DEG", help="latitude for WGS84 normal gravity")
    g.add_argument("--height", type=float, default=0.0, metavar="M", help="ellipsoidal height, m (with --latitude)")


def add_data_options(p: argparse.ArgumentParser, *, units_default: str | None = "g") -> None:
    d = p.add_argument_group("data")
    units_help = "output units of the data: g, m/s2, counts, volts, mg"
    units_help += f" (default {units_default})" if units_default else " (default: the calibration file's)"
    d.add_argument("--units", default=units_default, help=units_help)
    d.add_argument("--raw", action="store_true", help="DATA is a raw recording (t, ax, ay, az per sample)")
    r = p.add_argument_group("raw recordings (with --raw; docs/design.md §9.2)")
    r.add_argument("--columns", help="columns by name or 0-based index: t,ax,ay,az or ax,ay,az (with --rate), "
                   "t,ax,ay,az,temp, or role=column items")
    r.add_argument("--rate", type=float, metavar="HZ", help="sample rate when the recording has no time column")
    r.add_argument("--saturation", type=float, metavar="VALUE",
                   help="|output| at which a sample is saturated (default for counts: the int16 rails)")
    r.add_argument("--intervals", metavar="FILE", help="static intervals by hand: JSON or CSV of start,end "
                   "sample indices (end exclusive), or imucal's section list")
    r.add_argument("--labels", metavar="COLUMN[=L1,L2,...]",
                   help="static intervals from a label column: runs of the listed labels (all if none)")
    r.add_argument("--min-static", type=float, default=1.0, metavar="S", help="shortest static interval, s (1)")
    r.add_argument("--window", type=float, default=1.0, metavar="S", help="variance window, s (default 1)")
    r.add_argument("--init-s", type=float, default=2.0, metavar="S",
                   help="initial rest period whose variance sets the threshold, s (default 2)")
    r.add_argument("--threshold-k", metavar="K|A:B", help="threshold multiplier(s) of the initial-rest variance; "
                   "a range is searched and the best fit kept (default 2:10, as imu_tk)")
    add_gravity_options(p)


def gravity_from_args(args) -> float:
    lat = getattr(args, "latitude", None)
    return local_gravity_g(getattr(args, "gravity", None), lat, getattr(args, "height", 0.0) or 0.0)


def load_positions(args, path) -> PositionsData:
    """Positions from a positions CSV, or (``--raw``) from a raw recording via static-interval detection."""
    if getattr(args, "raw", False):
        from .. import recording  # the raw-recording path (static detection)

        return recording.positions_from_args(args, path)
    from ..data import check_units, read_positions

    data = read_positions(path, units=args.units)
    check_units(data, args.units)
    return data
