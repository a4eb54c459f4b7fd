"""
What goes into the driver at one sample and what comes out (no ROS imports).

One :class:`Inputs` per sample (what the part senses), one :class:`Output`
per sample the driver hands out. A sense channel has its own record inside
the output (:class:`GyroChannel`: the published rate, its covariance and its
truth), so a second channel (an accelerometer) is one more field beside
``gyro``, not a change of the shared fields (stamps, die temperature,
fault). The driver's counters are not per sample: :meth:`Driver.situation
<gyro_emulator.emulation.driver.core.Driver.situation>` and its report give
them.

The per-sample records (:class:`Inputs`, :class:`GyroChannel`,
:class:`Output`) are plain slotted dataclasses, made once per sample on the
node's hot path (1 kHz): a frozen dataclass's ``__init__`` costs about five
times as much (0.6 us for eight fields). Nothing changes them after the
driver made them. The rarer records are frozen.
"""

from dataclasses import dataclass


@dataclass(slots=True)
class Inputs:
    """
    What the part senses at one sample.

    Attributes
    ----------
    rate_rad_s : tuple of float
        True angular rate (x, y, z), rad/s, sensor frame.
    ambient_temp_c : float
        Ambient temperature, deg C (already inside the model's range).
    accel_m_s2 : tuple of float or None
        Applied linear acceleration (x, y, z), m/s^2, body frame (behind a
        simulator: its specific force; None where it gave none, REP 145).

    """

    rate_rad_s: tuple
    ambient_temp_c: float
    accel_m_s2: tuple


@dataclass(slots=True)
class GyroChannel:
    """
    The gyro's part of one output sample.

    Attributes
    ----------
    rate_rad_s : tuple of float
        The angular velocity to publish (after any injected fault), rad/s.
    covariance : tuple of float
        ``angular_velocity_covariance``: diag(sigma^2) of the model's white
        noise at this rate, 9 numbers row-major, rad^2/s^2. The same tuple
        object until the noise changes.
    true_rate_rad_s, bias_rad_s : numpy.ndarray, shape (3,)
        True rate and total bias of the sample, rad/s.
    scale_factor : numpy.ndarray, shape (3,)
        Total gain of the sample, ratio.
    saturated : numpy.ndarray of bool, shape (3,)
        Axes at the range limit (the model's, or pinned by a ``saturate`` fault).

    """

    rate_rad_s: tuple
    covariance: tuple
    true_rate_rad_s: object
    bias_rad_s: object
    scale_factor: object
    saturated: object


@dataclass(slots=True)
class AccelChannel:
    """
    The accelerometer's part of one output sample.

    Attributes
    ----------
    accel_m_s2 : tuple of float
        The linear acceleration to publish (the model's output), m/s^2.
    covariance : tuple of float
        ``linear_acceleration_covariance``: diag(sigma^2) of the model's white
        noise at this rate, 9 numbers row-major, m^2/s^4. The same tuple
        object until the noise changes.
    true_specific_force_m_s2 : tuple of float
        The specific force the part sensed, m/s^2.

    """

    accel_m_s2: tuple
    covariance: tuple
    true_specific_force_m_s2: tuple


@dataclass(frozen=True)
class FaultReport:
    """
    The injected fault and its state, at a change (``~/truth/fault``).

    Attributes
    ----------
    stamp_ns : int
        Sample instant (or parameter time) of the change, ns.
    fault : gyro_emulator.sensor.faults.Fault
        The fault in force.
    state : str
        ``none``, ``pending``, ``active`` or ``ended``.
    level : int
        0 unless active, else the fault's severity (1 WARN, 2 ERROR).
    since_ns : int
        Clock time of the change, ns.

    """

    stamp_ns: int
    fault: object
    state: str
    level: int
    since_ns: int


@dataclass(slots=True)
class Output:
    """
    One sample the driver hands out.

    Attributes
    ----------
    sample_ns : int
        The sample instant, ns (the stamp of the truth and the die temperature).
    stamp_ns : int
        The output stamp: the instant plus the model's output delay (latency,
        clipped jitter, clock drift), strictly increasing, ns.
    published : bool
        False in a dropout fault: nothing of this sample goes out.
    die_temp_c : float
        Die temperature, deg C.
    temperature_due : bool
        This sample carries the die temperature (``temperature_rate_hz``).
    gyro : GyroChannel
        The rate channel.
    accel : AccelChannel
        The accelerometer channel (its truth is published either way).
    accel_shown : bool
        Publish the accelerometer (``publish_linear_acceleration``; else absent).
    attitude_wxyz : tuple of float
        The true attitude (w, x, y, z), sensor frame to ENU world (REP 103).
    fault : FaultReport or None
        The fault state, when it changed at this sample.

    """

    sample_ns: int
    stamp_ns: int
    published: bool
    die_temp_c: float
    temperature_due: bool
    gyro: GyroChannel
    accel: AccelChannel
    accel_shown: bool
    attitude_wxyz: tuple
    fault: FaultReport = None


@dataclass(frozen=True)
class ParameterChange:
    """
    A validated set of parameter values, ready to apply whole (:meth:`Driver.prepare`).

    Attributes
    ----------
    values : dict
        Every node parameter value after the change.
    sensor_values : dict
        Every ``sensor.*`` parameter value after the change.
    config : gyro_emulator.sensor.config.SensorConfig
        The error model they give.
    limits : gyro_emulator.emulation.driver.commands.InputLimits
        The input checks they give.
    fault : gyro_emulator.sensor.faults.Fault or None
        The fault to put in force (None: no ``fault.*`` parameter was set).

    """

    values: dict
    sensor_values: dict
    config: object
    limits: object
    fault: object = None


@dataclass(frozen=True)
class Applied:
    """
    What applying a :class:`ParameterChange` did.

    Attributes
    ----------
    model_changed : bool
        The error model changed (its sample period may have: a clock drift).
    faults : tuple of FaultReport
        Fault states to publish, in order (a replaced fault ending, the new one).

    """

    model_changed: bool
    faults: tuple = ()
