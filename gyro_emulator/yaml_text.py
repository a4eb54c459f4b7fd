"""
YAML text with comments: PyYAML writes the data, comments go around it.

The one writer of YAML files with comments: the calibration exports
(:mod:`gyro_emulator.analysis.calibrate`) and the sensor YAML
(:func:`gyro_emulator.sensor.config.config_yaml`) use it. PyYAML writes no
comments, so :func:`dump` adds a comment after the line of a key. Measured
figures (:class:`Figure`) are written to 6 significant digits as text that
both readers of these files take as a float (:func:`float_text`): ``100.0``,
``1.0e-05``, ``2.31665e-05``. ``100`` would be an integer to
``cv::FileStorage`` (ORB-SLAM3 v1.0 stops on it), and ``1e-05`` a *string*
to PyYAML (YAML 1.1 floats need a dot and a signed exponent), hence to
Kalibr. It lives at layer 0 so that the sensor layer and the analysis share it.
"""

import math

import yaml


def float_text(value, spec='.6g'):
    """
    Return ``value`` as ``format(value, spec)`` with a dot: a float to YAML 1.1 and OpenCV.

    YAML 1.1's float pattern (PyYAML's resolver) needs a dot in the mantissa
    and a sign in the exponent. ``cv::FileStorage`` reads that text as a real
    (``FileNode::isReal()``). Python's exponent always carries a sign; the
    dot is added where ``format`` leaves it out (``1e-05`` -> ``1.0e-05``,
    ``100`` -> ``100.0``).

    Raises
    ------
    ValueError
        For a value that is not finite (no consumer of these files takes one).

    """
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f'value = {value!r} is not finite: an exported figure must be')
    mantissa, mark, exponent = format(value, spec).partition('e')
    if '.' not in mantissa:
        mantissa += '.0'
    return mantissa + mark + exponent


def as_written(value, spec='.6g'):
    """Return the float that ``float_text(value, spec)`` reads back as (a figure as written)."""
    return float(float_text(value, spec))


class Figure(float):
    """A measured figure, written as ``format(value, spec)``: 6 significant digits by default."""

    def __new__(cls, value, spec='.6g'):
        """Return ``value`` to be written with the format ``spec``."""
        figure = super().__new__(cls, value)
        figure.spec = spec
        return figure


class Flow(list):
    """A sequence written on one line, ``[a, b, c]``."""


class Quoted(str):
    """A string written in double quotes."""


class _Dumper(yaml.SafeDumper):
    """PyYAML's safe dumper with block sequences indented under their key."""

    def increase_indent(self, flow=False, indentless=False):
        """Indent every block sequence (PyYAML leaves those in a mapping unindented)."""
        return super().increase_indent(flow, False)


def _represent_figure(dumper, data):
    text = float_text(data, data.spec)
    # tagged as YAML resolves the plain text (a float), so that no explicit tag is written
    return dumper.represent_scalar(dumper.resolve(yaml.ScalarNode, text, (True, False)), text)


_Dumper.add_representer(Figure, _represent_figure)
_Dumper.add_representer(Flow, lambda dumper, data: dumper.represent_sequence(
    'tag:yaml.org,2002:seq', data, flow_style=True))
_Dumper.add_representer(Quoted, lambda dumper, data: dumper.represent_scalar(
    'tag:yaml.org,2002:str', data, style='"'))


def dump(data, comments=None, gap='   '):
    """
    Return ``data`` as block YAML: keys in their order, no line wrapping.

    Parameters
    ----------
    data : dict
        The document (``Figure``, ``Flow`` and ``Quoted`` values as above).
    comments : dict
        Key -> comment written after the line of that key.
    gap : str
        The spaces between a value and its comment.

    Returns
    -------
    str

    """
    text = yaml.dump(data, Dumper=_Dumper, sort_keys=False, default_flow_style=False,
                     width=float('inf'))
    if not comments:
        return text
    lines = []
    for line in text.splitlines():
        key = line.lstrip().partition(':')[0]
        lines.append(line + f'{gap}# {comments[key]}' if key in comments else line)
    return '\n'.join(lines) + '\n'
