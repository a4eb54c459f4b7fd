"""
Matplotlib on the Agg backend, and the finishing touches every plot shares.

Plots are written to files (no display is needed, CI included): take
``pyplot()``, draw, then :func:`label` each axes and :func:`save` the figure.
"""


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


def save(fig, path, dpi=120):
    """Lay the figure out, write it to ``path`` and free it."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    pyplot().close(fig)
