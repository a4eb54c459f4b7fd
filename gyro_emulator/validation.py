"""
Validation of parameters and inputs: one-line errors naming field, value and range.

Every check raises ``ValueError`` with a message such as::

    Geometry.thickness_m = -2e-06 is out of range: allowed (0, 0.0001] m
"""

from gyro_emulator.units import ZERO_CELSIUS_K
import numpy as np

#: Die temperatures the physics model is meant for, deg C. Eq 22 (linear E(T))
#: and the gas model are trusted over this span; outside it the node clamps.
MODEL_TEMP_RANGE_C = (-60.0, 200.0)
#: Largest gyro reading a record may hold, rad/s (57,000 deg/s): beyond the
#: full-scale range of any MEMS gyro (+-20,000 deg/s for the widest, the ADXRS649).
#: A reading beyond it is a bad cell, not a rate.
GYRO_LIMIT_RAD_S = 1000.0


def check_range(owner, name, value, low, high, unit='',
                low_open=True, high_open=False):
    """
    Raise ValueError unless every element of ``value`` lies in the range.

    Parameters
    ----------
    owner : str
        Class or function name used in the message.
    name : str
        Field name used in the message.
    value : float or array_like
        Value(s) to check; NaN and inf always fail.
    low, high : float
        Bounds; ``None`` for unbounded.
    unit : str
        Unit shown in the message.
    low_open, high_open : bool
        Whether the bound itself is excluded.

    Returns
    -------
    numpy.ndarray or float
        The value, unchanged (a float for scalars).

    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(
            f'{owner}.{name} = {value!r} is not a number') from None
    if _all_inside(arr, low, high, low_open, high_open):
        return float(arr) if arr.ndim == 0 else arr
    bad = outside(arr, low, high, low_open, high_open)
    if np.any(bad):
        first = float(arr[bad].flat[0]) if arr.ndim else float(arr)
        lo = '-inf' if low is None else repr(low)
        hi = 'inf' if high is None else repr(high)
        bracket = ('(' if low_open or low is None else '[') + lo + ', ' + hi + (
            ')' if high_open or high is None else ']')
        where = '' if arr.ndim == 0 else f' (element {int(np.flatnonzero(bad)[0])})'
        raise ValueError(
            f'{owner}.{name} = {first!r}{where} is out of range: allowed '
            f'{bracket}{" " + unit if unit else ""}')
    return float(arr) if arr.ndim == 0 else arr


def outside(arr, low, high, low_open=True, high_open=False):
    """
    Mask of the elements of ``arr`` outside the range; NaN and inf are outside.

    ``low`` / ``high``: bounds, ``None`` for unbounded; ``low_open`` /
    ``high_open``: whether the bound itself is excluded.
    """
    bad = ~np.isfinite(arr)
    if low is not None:
        bad |= (arr <= low) if low_open else (arr < low)
    if high is not None:
        bad |= (arr >= high) if high_open else (arr > high)
    return bad


def _all_inside(arr, low, high, low_open, high_open):
    """
    Whether every element is finite and inside the bounds, from its min and max.

    Two reductions, then :func:`outside` on those two values, instead of an
    element mask (the common, passing case of large parameter arrays); NaN
    propagates through min and max, so it fails here and the mask in
    :func:`check_range` finds it.
    """
    if arr.size == 0:
        return True
    ends = np.array([arr.min(), arr.max()], dtype=float)
    return not np.any(outside(ends, low, high, low_open, high_open))


def check_choice(owner, name, value, choices):
    """Raise ValueError unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise ValueError(
            f'{owner}.{name} = {value!r} is not allowed: choose one of '
            f'{", ".join(repr(c) for c in choices)}')
    return value


def check_temperature_c(temp_c, owner='temperature', name='temp_c'):
    """Validate a die temperature against :data:`MODEL_TEMP_RANGE_C`."""
    low, high = MODEL_TEMP_RANGE_C
    arr = np.asarray(temp_c, dtype=float)
    if np.any(arr <= -ZERO_CELSIUS_K):
        first = float(arr[arr <= -ZERO_CELSIUS_K].flat[0])
        raise ValueError(
            f'{owner}.{name} = {first!r} is below absolute zero; allowed '
            f'[{low}, {high}] C')
    return check_range(owner, name, temp_c, low, high, 'C',
                       low_open=False, high_open=False)
