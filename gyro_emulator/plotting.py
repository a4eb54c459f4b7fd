"""
Matplotlib on the Agg backend, and the finishing touches every plot shares.

Plots are written to files (no display is needed, CI included): take
``pyplot()``, draw, then :func:`label` each axes and :func:`save` the figure.
Every plot is written whole or not at all (:func:`gyro_emulator.atomic.staged`).
"""

import os

from gyro_emulator import atomic


def pyplot():
    """Return ``matplotlib.pyplot`` on the Agg backend (imported on first use)."""
    # pyplot costs 1.1 s, and most runs write no plot.
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def label(ax, xlabel, ylabel, title=None, legend_loc='best'):
    """Name the axes, title them, add a light grid and a small legend."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc=legend_loc, fontsize=8)


def image_path(path):
    """
    Return ``(path, format)`` as ``Figure.savefig`` reads a file name.

    The format is the extension, lower case; a name without one gets the
    default format (``savefig.format``, PNG) appended, as matplotlib does.
    """
    path = os.fspath(path)
    fmt = os.path.splitext(path)[1][1:].lower()
    if not fmt:
        fmt = pyplot().rcParams['savefig.format']
        path = path.rstrip('.') + '.' + fmt
    return path, fmt


def image_formats():
    """Return the image formats ``savefig`` writes (extensions, lower case)."""
    pyplot()
    from matplotlib.backend_bases import FigureCanvasBase
    return tuple(sorted(FigureCanvasBase.get_supported_filetypes()))


def save(fig, path, dpi=120):
    """
    Lay the figure out, write it to ``path`` (complete or absent) and free it.

    The figure is drawn into a temporary beside ``path`` and renamed over it
    (:func:`gyro_emulator.atomic.staged`); the format is given explicitly
    (:func:`image_path`), since the temporary's name ends in ``.tmp``.
    """
    fig.tight_layout()
    target, fmt = image_path(path)
    try:
        with atomic.staged(target) as tmp:
            fig.savefig(tmp, dpi=dpi, format=fmt)
    finally:
        pyplot().close(fig)
