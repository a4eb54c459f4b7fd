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
#: Largest |time| of a record, s (about 300 years; epoch seconds are 1.7e9): a
#: record's ``time_s`` and every record time a configuration holds (the extended
#: terms' ``start_time_s``, ``step_time_s``, ``time_origin_s``).
RECORD_TIME_LIMIT_S = 1e10
#: Longest quotation of a value in an error message, characters.
QUOTE_CHARS = 200
#: The physical limits of a measured record's values, one rule for every command
#: (``diagnose``, ``simulate --profile``, ``replay``): kind -> (low, high, unit, why).
RECORD_LIMITS = {
    'rate': (-GYRO_LIMIT_RAD_S, GYRO_LIMIT_RAD_S, 'rad/s', 'the widest MEMS full scale'),
    'temp': MODEL_TEMP_RANGE_C + ('C', 'the physics model range'),
}


def shorten(text, limit=QUOTE_CHARS):
    """Return ``text``, cut to ``limit`` characters with its length said when longer."""
    text = str(text)
    if len(text) <= limit:
        return text
    return f'{text[:limit]}... ({len(text)} characters)'


def _small(value, budget=2000):
    """Whether ``value`` holds fewer than ``budget`` items at any depth (counted lazily)."""
    stack, count = [value], 0
    while stack:
        item = stack.pop()
        count += 1
        if count > budget:
            return False
        if isinstance(item, dict):
            stack.extend(item.keys())
            stack.extend(item.values())
        elif isinstance(item, (list, tuple, set, frozenset)):
            stack.extend(item)
        elif isinstance(item, np.ndarray) and item.size > budget:
            return False
    return True


def quote(value, limit=QUOTE_CHARS):
    """
    Return ``repr(value)``, cut to about ``limit`` characters with its length said.

    Every error message that shows a value the user gave uses it, so a
    huge value (a nested list of millions of items) gives a short message;
    the repr of a large value is built only as far as it is shown
    (``reprlib``).
    """
    if _small(value):
        return shorten(repr(value), limit)
    import reprlib

    short = reprlib.Repr()
    short.maxlevel, short.maxlist, short.maxtuple, short.maxdict = 3, 10, 10, 8
    short.maxstring = short.maxother = short.maxlong = limit
    return short.repr(value)[:limit] + '... (a large value, shown in part)'


def check_record_values(owner, name, values, kind):
    """
    Raise ValueError naming the first value beyond :data:`RECORD_LIMITS` ``[kind]`` and its row.

    ``owner.name`` names the column or channel in the message; ``values`` is a
    1-D array (sample i is data row i + 1) or (N, 3). Returns ``values``.
    """
    low, high, unit, why = RECORD_LIMITS[kind]
    arr = np.asarray(values, dtype=float)
    beyond = (arr < low) | (arr > high)
    if beyond.ndim > 1:
        beyond = beyond.any(axis=tuple(range(1, beyond.ndim)))
    outside_rows = np.flatnonzero(beyond)
    if len(outside_rows):
        i = int(outside_rows[0])
        row = arr[i]
        value = float(row) if np.ndim(row) == 0 else float(row[(row < low) | (row > high)][0])
        raise ValueError(
            f'{owner}.{name} = {value!r} at sample {i} (data row {i + 1}) is beyond '
            f'[{low:g}, {high:g}] {unit} ({why}; {len(outside_rows)} of {len(arr)} samples '
            'beyond)')
    return values


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
    except (TypeError, ValueError, OverflowError):
        raise ValueError(
            f'{owner}.{name} = {quote(value)} is not a number') from None
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


def check_rate_hz(rate_hz):
    """
    Return a sample rate as a float (None as None); ValueError unless in (0, 1e6] Hz.

    The one check of a rate a command takes as ``--rate-hz`` (a replay's
    model rate, given or from the stamps; an export's IMU rate). The message
    names the field alone (``rate_hz = 0.0 is out of range``), which the
    command line names as the option typed.
    """
    if rate_hz is None:
        return None
    rate_hz = float(rate_hz)
    if not (np.isfinite(rate_hz) and 0.0 < rate_hz <= 1e6):
        raise ValueError(f'rate_hz = {rate_hz!r} is out of range: allowed (0, 1e6] Hz')
    return rate_hz


def check_ambient_c(temp_c):
    """
    Return an ambient temperature as a float (None as None); ValueError outside the model's.

    The one check of an ambient a command takes as ``--temp-c`` (simulate's
    scripted profiles, a replay's model ambient), before any work: the
    message names the field alone (``temp_c = nan is out of range``), which
    the command line names as the option typed, not the model field that
    would have refused it later (``Segment.temp_start_c``).
    """
    if temp_c is None:
        return None
    temp_c = float(temp_c)
    low, high = MODEL_TEMP_RANGE_C
    if not low <= temp_c <= high:
        raise ValueError(f'temp_c = {temp_c!r} is out of range: allowed [{low:g}, {high:g}] C '
                         '(the physics model range)')
    return temp_c


def check_seed(owner, seed):
    """
    Return ``seed``, a seed of ``numpy.random.default_rng``; ValueError unless an integer >= 0.

    The message names ``owner.seed``, the value and the range (numpy's own
    says only "expected non-negative integer").
    """
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) \
            or seed < 0:
        raise ValueError(f'{owner}.seed = {quote(seed)} is out of range: allowed integers '
                         '>= 0')
    return seed


def check_choice(owner, name, value, choices):
    """Raise ValueError unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise ValueError(
            f'{owner}.{name} = {quote(value)} is not allowed: choose one of '
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
