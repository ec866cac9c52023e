"""Options shared by every command that reads data (calibrate, discover, apply): the positions CSV or a
raw recording, its units and local gravity."""

from __future__ import annotations

import argparse

from ..data import PositionsData, check_units, read_positions
from ..gravity import local_gravity_g


def add_gravity_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("local gravity (default 1 g)")
    g.add_argument("--gravity", type=float, metavar="M_PER_S2", help="local gravity in m/s²")
    g.add_argument("--latitude", type=float, metavar="DEG", help="latitude for WGS84 normal gravity")
    g.add_argument("--height", type=float, default=0.0, metavar="M", help="ellipsoidal height, m (with --latitude)")


def add_data_options(p: argparse.ArgumentParser) -> None:
    d = p.add_argument_group("data")
    d.add_argument("--units", default="g", help="output units of the data: g, m/s2, counts, volts (default g)")
    d.add_argument("--raw", action="store_true", help="DATA is a raw recording (t, ax, ay, az per sample)")
    d.add_argument("--columns", help="raw recording columns by name or index, e.g. t,ax,ay,az or 0,4,5,6")
    d.add_argument("--rate", type=float, help="sample rate in Hz when the recording has no time column")
    add_gravity_options(p)


def gravity_from_args(args) -> float:
    lat = getattr(args, "latitude", None)
    return local_gravity_g(getattr(args, "gravity", None), lat, getattr(args, "height", 0.0) or 0.0)


def load_positions(args, path) -> PositionsData:
    """Positions from a positions CSV, or (``--raw``) from a raw recording via static-interval detection."""
    if getattr(args, "raw", False):
        from .. import recording  # the raw-recording path (static detection)

        return recording.positions_from_args(args, path)
    data = read_positions(path, units=args.units)
    check_units(data, args.units)
    return data
