"""
What the sensor configurations share: switches, checked fields, YAML keys and numbers.

The gyro's :class:`~gyro_emulator.sensor.config.SensorConfig` and the
accelerometer's :class:`~gyro_emulator.sensor.accel.AccelConfig` are frozen
dataclasses of the same kinds of field (module :mod:`.config`, ``_RANGES``):

* ``axis``: 3 numbers (x, y, z) or one for all axes;
* ``scalar``: one number; ``pair``: 2 numbers; ``optional``: a number or None;
* ``matrix``: 3x3 (a number fills the off-diagonal of ``misalignment`` or
  the diagonal of any other matrix; 3 numbers give a diagonal).

:func:`checked` turns a value of a kind into its tuple form or raises a
one-line ``ValueError`` naming the owner, the field, the value and the
range. :class:`Switches` is the base of the term switches (``ErrorTerms``,
``AccelTerms``). :class:`YamlKey` and :func:`spell` are how the one sensor
YAML writer (:func:`gyro_emulator.sensor.config.config_yaml`) spells a key
and its numbers; :func:`converter` makes the datasheet-unit converters of
the YAML aliases from a function of :mod:`gyro_emulator.units`.
"""

from dataclasses import dataclass, fields

from gyro_emulator.validation import check_range, quote
import numpy as np


class Switches:
    """
    Base of a frozen dataclass of on/off switches (every field a bool).

    Subclasses: :class:`~gyro_emulator.sensor.config.ErrorTerms` (the gyro)
    and :class:`~gyro_emulator.sensor.accel.AccelTerms` (the accelerometer).
    """

    def __post_init__(self):
        """Check that every switch is a bool."""
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (bool, np.bool_)):
                raise ValueError(
                    f'{type(self).__name__}.{f.name} = {quote(value)} is not allowed: '
                    'choose true or false')
            object.__setattr__(self, f.name, bool(value))

    @classmethod
    def none(cls):
        """Return switches with every term off (the ideal sensor)."""
        return cls(**dict.fromkeys(cls.names(), False))

    @classmethod
    def names(cls):
        """Return the term names in model order."""
        return tuple(f.name for f in fields(cls))

    def enabled(self):
        """Return the names of the terms that are on."""
        return tuple(n for n in self.names() if getattr(self, n))

    @classmethod
    def from_mapping(cls, value, source):
        """Return switches from a YAML mapping ``term: true/false`` (unknown terms refused)."""
        if not isinstance(value, dict):
            raise ValueError(f'{source}: terms = {quote(value)} must be a mapping of '
                             'term: true/false')
        unknown = sorted(set(value) - set(cls.names()))
        if unknown:
            raise ValueError(
                f'{source}: unknown term(s) {", ".join(map(str, unknown))} in terms;'
                f' allowed: {", ".join(cls.names())}')
        return cls(**value)


#: Shape of each kind of field.
SHAPES = {'axis': (3,), 'scalar': (), 'pair': (2,), 'matrix': (3, 3)}


def checked(owner, name, value, kind, limits, low_open=False):
    """
    Return ``value`` of ``kind`` in its tuple (or float) form, every element in range.

    Parameters
    ----------
    owner, name : str
        Class and field named in the message.
    value : object
        The given value.
    kind : str
        ``axis``, ``scalar``, ``pair``, ``matrix`` or ``optional``.
    limits : tuple
        (low, high, unit) of every element.
    low_open : bool
        Whether ``low`` itself is excluded.

    Raises
    ------
    ValueError
        One line naming ``owner.name``, the value and the allowed range or shape.

    """
    low, high, unit = limits
    if kind == 'optional':
        if value is None:
            return None
        return check_range(owner, name, value, low, high, unit, low_open)
    shape = SHAPES[kind]
    if has_non_number(value):
        raise ValueError(f'{owner}.{name} = {quote(value)} is not a number or a list of '
                         'numbers (true/false and text are not numbers)')
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f'{owner}.{name} = {quote(value)} is not a number or a list '
                         'of numbers') from None
    if kind == 'axis' and arr.ndim == 0:
        arr = np.full(3, float(arr))
    if kind == 'matrix' and arr.ndim == 0:
        check_range(owner, name, float(arr), low, high, unit, low_open)    # before inf * 0
        arr = np.full((3, 3), float(arr)) * (1.0 - np.eye(3)) \
            if name == 'misalignment' else np.eye(3) * float(arr)
    if kind == 'matrix' and arr.shape == (3,) and name != 'misalignment':
        arr = np.diag(arr)
    if arr.shape != shape:
        what = {(3,): 'a number or a list of 3 (x, y, z)', (): 'a number',
                (2,): 'a list of 2 numbers', (3, 3): 'a 3x3 matrix'}[shape]
        raise ValueError(f'{owner}.{name} = {quote(value)} has shape {arr.shape}: '
                         f'expected {what}')
    check_elements(owner, name, arr, low, high, unit, low_open)
    if kind == 'scalar':
        return float(arr)
    if kind == 'matrix':
        return tuple(tuple(float(v) for v in row) for row in arr)
    return tuple(float(v) for v in arr)


def has_non_number(value):
    """Return True if ``value`` is, or holds at any depth, a bool or a string."""
    if isinstance(value, (bool, str, bytes, np.bool_)):
        return True
    if isinstance(value, (list, tuple)):
        return any(has_non_number(v) for v in value)
    if isinstance(value, np.ndarray):
        return value.dtype.kind in 'bSUO' and (value.dtype.kind != 'O' or any(
            has_non_number(v) for v in value.ravel()))
    return False


def check_elements(owner, name, arr, low, high, unit, low_open):
    """check_range per element, so the message shows a plain number and its index."""
    flat = arr.ravel()
    for i, value in enumerate(flat):
        try:
            check_range(owner, name, float(value), low, high, unit, low_open)
        except ValueError as exc:
            if flat.size == 1:
                raise
            where = f'[{i // 3}][{i % 3}]' if arr.ndim == 2 else f'[{i}]'
            raise ValueError(str(exc).replace(f'{owner}.{name} =',
                                              f'{owner}.{name}{where} =', 1)) from None


def check_lsb(owner, name, values, minimum, high, unit):
    """Refuse a quantisation step above 0 but below ``minimum`` (0 = no quantisation)."""
    for i, lsb in enumerate(values):
        if 0.0 < lsb < minimum:
            raise ValueError(f'{owner}.{name}[{i}] = {quote(lsb)} is out of range: allowed 0 '
                             f'(no quantisation) or [{minimum:g}, {high:g}] {unit}')


def check_zero_diagonal(owner, matrix):
    """Refuse a misalignment matrix with a non-zero diagonal (that is a gain error)."""
    diag = [matrix[i][i] for i in range(3)]
    if any(d != 0.0 for d in diag):
        raise ValueError(
            f'{owner}.misalignment has diagonal {quote(diag)}: allowed only '
            '0 (a gain error belongs in scale_factor_error)')


def converter(function):
    """Return a YAML alias converter: ``function`` of numbers, as a float or nested lists."""
    def convert(value):
        arr = np.array(value, dtype=float)
        out = function(arr)
        return out.tolist() if np.ndim(out) else float(out)
    return convert


@dataclass(frozen=True)
class YamlKey:
    """
    One key of a sensor YAML file as :func:`~gyro_emulator.sensor.config.config_yaml` writes it.

    ``name``: at the top a :class:`~gyro_emulator.sensor.config.SensorConfig`
    field, an alias of :data:`~gyro_emulator.sensor.config.YAML_ALIASES` (the
    field in the alias's unit), ``device``, ``terms``, ``extended`` or
    ``accelerometer``; below, a switch, ``start_time_s``, a cause id, a
    term's field, or an :class:`~gyro_emulator.sensor.accel.AccelConfig`
    field or alias. ``spec``: format of its numbers, ``''`` the shortest
    text that reads back exactly, ``'.6g'`` a measured figure. ``scalar``:
    a per-axis field as one number. ``parts``: the keys written inside
    ``terms``, ``extended``, a term or ``accelerometer`` (default all).
    ``given``: the value as the caller spells it (parsed YAML, ``Figure``,
    ``Flow``), written as it is; it must denote the configuration's value
    (the file is checked).
    """

    name: str
    spec: str = ''
    scalar: bool = False
    parts: tuple = None
    given: object = None


def spell(value, key):
    """Spell a number, a per-axis triple or a matrix (rows in flow style) with ``key.spec``."""
    from gyro_emulator.yaml_text import Figure, Flow   # PyYAML waits for a file

    if value is None or isinstance(value, (bool, str, int)):
        return value
    if isinstance(value[0] if isinstance(value, (list, tuple)) else None, (list, tuple)):
        return [Flow(Figure(v, key.spec) for v in row) for row in value]
    if not isinstance(value, (list, tuple)):
        return Figure(value, key.spec)
    if key.scalar and len(set(value)) == 1:
        return Figure(value[0], key.spec)
    if key.scalar:
        raise ValueError(f'{key.name} = {value!r}: one number cannot spell three')
    return Flow(Figure(v, key.spec) for v in value)
