"""Figures, one module per kind, all drawn with matplotlib's object API: each function builds a
``matplotlib.figure.Figure`` itself (no pyplot state, no backend switch) and saves it to the path given.
matplotlib is imported inside the functions, so importing optcal stays light.

Here: the checks every figure file shares, so that a command can refuse a figure path before it writes
anything (:func:`check_figure_path`), and writing a figure whole or not at all, with one-line errors
(:func:`save_figure`)."""

from __future__ import annotations

from pathlib import Path

from optcal.core.errors import InputError


def check_figure_path(path) -> Path:
    """``path`` as a Path, after checking that its folder exists and that matplotlib writes its suffix."""
    from matplotlib.backend_bases import FigureCanvasBase

    path = Path(path)
    if not path.parent.is_dir():
        raise InputError(f"figure {path}: folder {path.parent} does not exist; create it or choose another path")
    formats = FigureCanvasBase.get_supported_filetypes()
    if path.suffix.lower().lstrip(".") not in formats:
        raise InputError(f"figure {path}: give the file a suffix naming its format, one of "
                         f"{', '.join('.' + f for f in sorted(formats))}")
    return path


def save_figure(fig, path, dpi: int = 110, **kwargs) -> None:
    """Write the matplotlib Figure ``fig`` to ``path`` (the suffix names the format; none: matplotlib's
    ``savefig.format``, appended to the name as ``savefig`` does) at ``dpi`` dots per inch, whole or not at all
    (:func:`optcal.core.atomicfile.atomic_write`: rendered into a temporary file beside ``path``, in that format, and
    renamed over it; an existing ``path`` is replaced: the commands refuse it without --force before they compute
    anything). ``kwargs`` go to ``savefig`` (e.g. ``bbox_inches``). A path that cannot be written is one line
    naming it."""
    from matplotlib import rcParams

    from optcal.core.atomicfile import atomic_write

    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if not fmt:  # savefig("name") writes name.png
        fmt = rcParams["savefig.format"]
        path = path.with_name(path.name.rstrip(".") + "." + fmt)
    with atomic_write(path, overwrite=True, binary=True) as fh:
        try:
            fig.savefig(fh, format=fmt, dpi=dpi, **kwargs)
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot write the figure {path}: {getattr(exc, 'strerror', None) or exc}") from None
