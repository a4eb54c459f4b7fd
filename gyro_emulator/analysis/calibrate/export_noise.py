"""
Noise exports for Kalibr, OpenVINS, VINS-Fusion, ORB-SLAM3, Gazebo and this emulator.

Each writer returns the text of one file, with the provenance comments of
:mod:`.provenance` and the continuous-to-discrete convention its target
documents. N (angle random walk, two-sided white-noise density) and K (rate
random walk) are IEEE Std 952 continuous-time coefficients; sampled at
f_s = 1 / dt the white noise has per-sample sigma N sqrt(f_s) and the bias
walk per-sample increment K / sqrt(f_s) (Kalibr wiki "IMU Noise Model"):

=========  =====================================  ======================================
target     gyro white noise                       gyro bias walk
=========  =====================================  ======================================
kalibr     gyroscope_noise_density = N            gyroscope_random_walk = K
           rad/s/sqrt(Hz), continuous             rad/s^2/sqrt(Hz), continuous
openvins   same keys and units (kalibr_imu_chain.yaml)
vins       gyr_n = N sqrt(f_s), rad/s per sample  gyr_w = K sqrt(f_s) (its pre-integration
           (integration_base.h propagates them    adds (gyr_w dt)^2 per sample)
           as per-sample standard deviations)
orbslam3   IMU.NoiseGyro = N, continuous          IMU.GyroWalk = K, continuous (it
           (ORB-SLAM3 multiplies by sqrt(f_s))    divides by sqrt(f_s)); orbslam3-settings:
                                                  the same in a whole v1.0 settings file
gazebo     stddev = N sqrt(f_s), per sample       dynamic_bias_stddev sigma_b with
                                                  dynamic_bias_correlation_time T: a
                                                  Gauss-Markov bias driven by sigma_b
                                                  (gz-sensors GaussianNoiseModel), fitted
                                                  to the B and K part of the curve
preset     electronics_arw_deg_sqrt_h, bias_instability_deg_h, rate_random_walk_deg_h_sqrt_h
=========  =====================================  ======================================

The first comment line of each file says whether it is a whole file or a
block to paste (after ``%YAML:1.0`` where ``cv::FileStorage`` opens it).

The accelerometer's N_a and K_a (:mod:`.accel_figures`) come from the
log's own accelerometer when it has one, identified as the gyro is, or from
the user (they override the log's, and the file says so). Without either no
file loads a wrong value silently; each one makes its consumer stop and
name the field (docs/calibrate.md cites each consumer's parser): kalibr,
openvins and both orbslam3 formats leave the keys out (their own
missing-key checks fire), gazebo writes ``FILL_IN`` where sdformat parses a
double (:mod:`.export_gazebo`), and vins is refused (VINS-Fusion checks
nothing). Kalibr's ``rostopic`` and OpenVINS's are the ``topic`` given (the
command line's ``--rostopic``: by default the bag's Imu topic, or /imu0 for
a CSV log), else the bag's, else left out.

Numbers are written by :func:`gyro_emulator.yaml_text.float_text`, a
float to PyYAML and a real to ``cv::FileStorage``; the YAML files (kalibr,
openvins) are written by PyYAML with the comments added around it, the
VINS-Fusion and ORB-SLAM3 text by hand, and ``preset`` is a
:class:`~gyro_emulator.sensor.config.SensorConfig` (:func:`twin_config`)
written by :func:`gyro_emulator.sensor.config.config_yaml`.
"""

from dataclasses import dataclass, replace

from gyro_emulator import units
from gyro_emulator.analysis.calibrate.accel_figures import (  # noqa: F401 (the API)
    ACCEL_OPTIONS, AccelFigures, given_accel_config, given_accel_layout, require_accel)
from gyro_emulator.analysis.calibrate.export_gazebo import (  # noqa: F401 (the API)
    ACCEL_CORRELATION_TIME_S, gauss_markov_match, gazebo)
from gyro_emulator.analysis.calibrate.lowpass import identify_output_filter
from gyro_emulator.analysis.calibrate.noise import export_noise
from gyro_emulator.analysis.calibrate.provenance import as_comments, CONTINUOUS, noise_lines
from gyro_emulator.analysis.calibrate.twin import emulator_fit, PER_DECADE
from gyro_emulator.sensor.accel import accel_from_mapping, AccelTerms
from gyro_emulator.sensor.config import config_from_mapping, config_yaml, ErrorTerms, YamlKey
from gyro_emulator.units import AXES
from gyro_emulator.validation import check_rate_hz
from gyro_emulator.yaml_text import as_written, dump as dump_yaml, Figure, float_text, Flow, Quoted
import numpy as np

FORMATS = ('kalibr', 'openvins', 'vins', 'orbslam3', 'orbslam3-settings', 'gazebo', 'preset')

_CONTINUOUS = CONTINUOUS


_ACCEL_WHY = f'NOT MEASURED by this gyro log (give {ACCEL_OPTIONS} to write them)'
_TOPIC_WHY = 'a CSV log has no topic: add the IMU topic of your bag'


def _not_written(missing, stop):
    """Comment lines for keys left out, so that the consumer's own check names them."""
    if not missing:
        return []
    return [f'Not written: {"; ".join(f"{names}: {why}" for names, why in missing)}. '
            f'Until they are added, {stop}.']


def _kalibr_missing(topic, accel, stop):
    missing = [] if topic else [('rostopic', _TOPIC_WHY)]
    if accel is None:
        missing.append(('accelerometer_noise_density (m/s^2/sqrt(Hz)) and '
                        'accelerometer_random_walk (m/s^3/sqrt(Hz))', _ACCEL_WHY))
    return _not_written(missing, stop)


def _num(value):
    return float_text(value)


def _identity(size, scale=1.0):
    return [Flow(scale if i == j else 0.0 for j in range(size)) for i in range(size)]


def _update_rate(calibration, rate_hz):
    return float(calibration.rate_hz if rate_hz is None else rate_hz)


def _topic(calibration, topic=None):
    """
    Return (the IMU topic to write or None, a comment line on it or None).

    The line goes into the header: cv::FileStorage (OpenVINS) reads a
    comment after a plain text value as part of the value.

    ``topic`` is the one given (``--rostopic``); else the bag's Imu topic
    the gyro came from; a CSV log has none.
    """
    column = calibration.axes[0].column
    own = column.split(' ')[0] if ' angular_velocity' in column else None
    if not topic or topic == own:
        return own, None
    if own is None:
        return topic, f'rostopic {topic}: a CSV log has no topic (--rostopic; default /imu0).'
    return topic, f"rostopic {topic}: --rostopic (the log's Imu topic is {own})."


def _kalibr_keys(ex, accel):
    """Return the four noise keys of Kalibr's imu.yaml (and OpenVINS's imu0) and comments."""
    data, comments = {}, {}
    if accel is not None:
        for key in ('noise_density', 'random_walk'):
            data[f'accelerometer_{key}'] = Figure(accel.value(key))
            comments[f'accelerometer_{key}'] = accel.comment(key)
    data['gyroscope_noise_density'] = Figure(ex.arw_rad_s_sqrt_hz)
    data['gyroscope_random_walk'] = Figure(ex.rrw_rad_s_sqrt_s)
    comments['gyroscope_noise_density'] = 'rad/s/sqrt(Hz), N'
    comments['gyroscope_random_walk'] = 'rad/s^2/sqrt(Hz), K' + (
        ' (upper bound)' if ex.rrw_is_bound else '')
    return data, comments


def kalibr(calibration, inflate=1.0, rate_hz=None, accel=None, topic=None):
    """
    Kalibr ``imu.yaml``, a whole file (rostopic, update_rate and the four noise densities).

    A key this log cannot give (the accelerometer's without ``accel``, the
    rostopic of a CSV log) is left out: Kalibr's ``ImuParameters`` getters
    (``@catch_keyerror``, kalibr_common/ConfigReader.py) then stop with
    ``[ImuConfig Reader]: Field 'accelerometer_noise_density' missing in
    file: ...``. A text placeholder would instead reach its ``<=`` checks
    and end in a TypeError.
    """
    ex = export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    convention = (_CONTINUOUS + ' Kalibr uses gyroscope_noise_density / sqrt(dt) and '
                  'gyroscope_random_walk * sqrt(dt) with dt = 1 / update_rate.')
    topic, topic_note = _topic(calibration, topic)
    lines = ['Kalibr imu.yaml: a whole file (kalibr_calibrate_imu_camera --imu FILE).']
    lines += noise_lines(calibration, ex, 'kalibr', convention, accel)
    keys, comments = _kalibr_keys(ex, accel)
    data = ({'rostopic': topic} if topic else {}) | {'update_rate': Figure(rate)} | keys
    comments['update_rate'] = 'Hz'
    lines += [topic_note] if topic_note else []
    lines += _kalibr_missing(topic, accel, 'Kalibr stops with "[ImuConfig Reader]: Field '
                                           '\'<name>\' missing in file: ..."')
    return as_comments(lines) + dump_yaml(data, comments)


def openvins(calibration, inflate=1.0, rate_hz=None, accel=None, topic=None):
    """
    Write OpenVINS's ``kalibr_imu_chain.yaml``, a whole file (Kalibr's keys, its intrinsics).

    OpenVINS reads it with ``cv::FileStorage`` (ov_core YamlParser): a key
    left out prints ``the node accelerometer_noise_density of type [d] was
    not found...`` and the estimator exits with ``unable to parse all
    parameters, please fix``. A ``FILL_IN   # ...: ...`` line would instead
    be read as a nested map, and a text value as 1.8e308 without a word.
    """
    ex = export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    convention = (_CONTINUOUS + ' OpenVINS reads the Kalibr keys in the same continuous '
                  'units and discretises with the IMU sample period.')
    topic, topic_note = _topic(calibration, topic)
    keys, comments = _kalibr_keys(ex, accel)
    imu = {'T_i_b': _identity(4)} | keys
    if topic:
        imu['rostopic'] = topic
    imu |= {'time_offset': 0.0, 'update_rate': Figure(rate), 'model': Quoted('kalibr'),
            'Tw': _identity(3), 'R_IMUtoGYRO': _identity(3), 'Ta': _identity(3),
            'R_IMUtoACC': _identity(3), 'Tg': _identity(3, 0.0)}
    lines = ['OpenVINS kalibr_imu_chain.yaml: a whole file (relative_config_imu of '
             'estimator_config.yaml); cv::FileStorage needs %YAML:1.0 as its first line.']
    lines += noise_lines(calibration, ex, 'openvins', convention, accel)
    lines += [topic_note] if topic_note else []
    lines += _kalibr_missing(topic, accel, 'OpenVINS prints "the node <name> of type [...] '
                                           'was not found..." and exits with "unable to '
                                           'parse all parameters, please fix"')
    lines += ['Intrinsics (T_i_b, Tw, R_IMUtoGYRO, Ta, R_IMUtoACC, Tg) and time_offset are '
              "OpenVINS's uncalibrated defaults (identity, zero): this log does not give them."]
    body = dump_yaml({'imu0': imu}, comments, gap='  ')
    return '%YAML:1.0\n' + as_comments(lines) + '\n' + body


def vins(calibration, inflate=1.0, rate_hz=None, accel=None, topic=None):
    """
    VINS-Fusion's IMU block (not a whole file): acc_n, gyr_n, acc_w, gyr_w per sample.

    VINS-Fusion reads them as ``ACC_N = fsSettings["acc_n"]``
    (vins_estimator/src/estimator/parameters.cpp) and checks nothing: a
    missing key is 0 and a text one 1.8e308 (``FileNode::real()``), so a
    block without the accelerometer figures would load a wrong value
    silently. It is refused instead (``ValueError`` naming the options).
    ``topic`` is not used (the block has no topic key).
    """
    require_accel('vins', accel)
    ex = export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    gyr_n = float(units.density_to_sample_sigma(ex.arw_rad_s_sqrt_hz, rate))
    gyr_w = ex.rrw_rad_s_sqrt_s * np.sqrt(rate)
    acc_n = float(units.density_to_sample_sigma(accel.noise_density_m_s2_sqrt_hz, rate))
    acc_w = accel.random_walk_m_s3_sqrt_hz * np.sqrt(rate)
    where = ('the accelerometer figures given' if accel.given
             else "the log's accelerometer")
    convention = (
        _CONTINUOUS + ' VINS-Fusion documents gyr_n and gyr_w as standard deviations and '
        'its pre-integration (integration_base.h) adds (gyr_n dt / 2)^2 twice and '
        '(gyr_w dt)^2 per sample: per-sample values, so gyr_n = N sqrt(f) and '
        f'gyr_w = K sqrt(f) at f = {rate:g} Hz (acc_n, acc_w alike from {where}). The '
        f'continuous N = {_num(ex.arw_rad_s_sqrt_hz)} rad/s/sqrt(Hz) '
        f'and K = {_num(ex.rrw_rad_s_sqrt_s)} rad/s^2/sqrt(Hz) are what imu_utils and '
        'Kalibr-style configs enter instead.')
    lines = ['VINS-Fusion IMU block, not a whole file: paste it into your config (which starts '
             'with %YAML:1.0) in place of its acc_n, gyr_n, acc_w and gyr_w lines.']
    lines += noise_lines(calibration, ex, 'vins', convention, accel)
    if accel.given:
        lines.append(f'Accelerometer: N_a {_num(accel.noise_density_m_s2_sqrt_hz)} '
                     f'm/s^2/sqrt(Hz), K_a {_num(accel.random_walk_m_s3_sqrt_hz)} '
                     'm/s^3/sqrt(Hz), given by the user (not inflated).')
    bound = ' (upper bound of K)' if ex.rrw_is_bound else ''
    bound_a = ' (upper bound of K_a)' if accel.random_walk_is_bound else ''
    return as_comments(lines) + (
        f'acc_n: {_num(acc_n)}   # m/s^2 per sample at {rate:g} Hz\n'
        f'gyr_n: {_num(gyr_n)}   # rad/s per sample at {rate:g} Hz\n'
        f'acc_w: {_num(acc_w)}   # K_a sqrt(f), m/s^3 per sample at {rate:g} Hz{bound_a}\n'
        f'gyr_w: {_num(gyr_w)}   # K sqrt(f), rad/s^2 per sample at {rate:g} Hz{bound}\n')


_ORBSLAM3_CONVENTION = (_CONTINUOUS + ' ORB-SLAM3 reads IMU.NoiseGyro in rad/s/sqrt(Hz) and '
                        'IMU.GyroWalk in rad/s^2/sqrt(Hz) and builds its discrete noise as '
                        'NoiseGyro sqrt(IMU.Frequency), GyroWalk / sqrt(IMU.Frequency).')
#: How ORB-SLAM3 v1.0 stops on a key left out (Settings::readParameter, src/Settings.cc).
_ORBSLAM3_STOP = ('ORB-SLAM3 v1.0 stops with "<name> required parameter does not exist, '
                  'aborting..."')


def _orbslam3_imu(ex, rate, accel):
    """Return the IMU keys of ORB-SLAM3 v1.0, every number a real (``readParameter<float>``)."""
    bound = ' (upper bound)' if ex.rrw_is_bound else ''
    text = f'IMU.NoiseGyro: {_num(ex.arw_rad_s_sqrt_hz)}   # rad/s/sqrt(Hz)\n'
    if accel is not None:
        text += (f'IMU.NoiseAcc: {_num(accel.noise_density_m_s2_sqrt_hz)}   # '
                 f'{_orbslam3_acc_comment(accel, "noise_density")}\n')
    text += f'IMU.GyroWalk: {_num(ex.rrw_rad_s_sqrt_s)}   # rad/s^2/sqrt(Hz){bound}\n'
    if accel is not None:
        text += (f'IMU.AccWalk: {_num(accel.random_walk_m_s3_sqrt_hz)}   # '
                 f'{_orbslam3_acc_comment(accel, "random_walk")}\n')
    return text + f'IMU.Frequency: {_num(rate)}   # Hz\n'


def _orbslam3_acc_comment(accel, key):
    """Return an accelerometer figure's unit, and where it came from when not given alone."""
    return accel.comment(key) if accel.calibration is not None else accel.comment(key).split(
        ';')[0]


def _orbslam3_missing(accel):
    if accel is not None:
        return []
    return _not_written([('IMU.NoiseAcc (m/s^2/sqrt(Hz)) and IMU.AccWalk (m/s^3/sqrt(Hz))',
                          _ACCEL_WHY)],
                        _ORBSLAM3_STOP + ' (before v1.0: "*IMU.NoiseAcc parameter doesn\'t '
                        'exist or is not a real number*")')


def orbslam3(calibration, inflate=1.0, rate_hz=None, accel=None, topic=None):
    """
    ORB-SLAM3's IMU block (not a whole file): IMU.NoiseGyro, IMU.GyroWalk, IMU.Frequency.

    Every number is a real, as v1.0's ``Settings::readParameter<float>``
    requires (``node.isReal()``, else "IMU.Frequency parameter must be a
    real number, aborting..."). Settings files without ``File.version:
    "1.0"`` go through the older ``Tracking::ParseIMUParamFile``, which wants
    IMU.Frequency as an integer: the block says so.
    """
    ex = export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    lines = ['ORB-SLAM3 IMU block, not a whole file: paste it into your v1.0 settings file '
             '(which starts with %YAML:1.0 and has File.version: "1.0") in place of its '
             'IMU.Noise*, IMU.*Walk and IMU.Frequency lines.',
             'An older settings file (no File.version) reads IMU.Frequency as an integer: '
             f'there write IMU.Frequency: {int(round(rate))} (it stops with "*IMU.Frequency '
             'parameter doesn\'t exist or is not an integer*" otherwise).']
    lines += noise_lines(calibration, ex, 'orbslam3', _ORBSLAM3_CONVENTION, accel)
    lines += _orbslam3_missing(accel)
    return as_comments(lines) + _orbslam3_imu(ex, rate, accel)


_ORBSLAM3_CAMERA_TEMPLATE = """\
# --- Camera: fill in from your camera calibration, then remove the leading "# ".
# Until then ORB-SLAM3 stops with "Camera.type required parameter does not exist,
# aborting..." (a FILL_IN left in a number stops it with "<name> parameter must be a
# real number" or "... an integer number").
# Camera.type: "PinHole"
# Camera1.fx: FILL_IN
# Camera1.fy: FILL_IN
# Camera1.cx: FILL_IN
# Camera1.cy: FILL_IN
# Camera1.k1: FILL_IN
# Camera1.k2: FILL_IN
# Camera1.p1: FILL_IN
# Camera1.p2: FILL_IN
# Camera.width: FILL_IN
# Camera.height: FILL_IN
# Camera.fps: FILL_IN
# Camera.RGB: 1
# Stereo: Camera2.* as Camera1.*, Stereo.T_c1_c2 (4x4) and Stereo.ThDepth: 60.0
#
# --- Camera-IMU extrinsics: the camera's pose in the IMU (body) frame. Until it is
# here ORB-SLAM3 stops with "IMU.T_b_c1 required parameter does not exist, aborting...".
# IMU.T_b_c1: !!opencv-matrix
#    rows: 4
#    cols: 4
#    dt: f
#    data: [FILL_IN, FILL_IN, FILL_IN, FILL_IN,
#           FILL_IN, FILL_IN, FILL_IN, FILL_IN,
#           FILL_IN, FILL_IN, FILL_IN, FILL_IN,
#           0.0, 0.0, 0.0, 1.0]
"""

_ORBSLAM3_REST = """\

# --- ORB extractor and viewer: the values of ORB-SLAM3's own EuRoC examples.
ORBextractor.nFeatures: 1000
ORBextractor.scaleFactor: 1.2
ORBextractor.nLevels: 8
ORBextractor.iniThFAST: 20
ORBextractor.minThFAST: 7

Viewer.KeyFrameSize: 0.05
Viewer.KeyFrameLineWidth: 1.0
Viewer.GraphLineWidth: 0.9
Viewer.PointSize: 2.0
Viewer.CameraSize: 0.08
Viewer.CameraLineWidth: 3.0
Viewer.ViewpointX: 0.0
Viewer.ViewpointY: -0.7
Viewer.ViewpointZ: -1.8
Viewer.ViewpointF: 500.0
"""


def orbslam3_settings(calibration, inflate=1.0, rate_hz=None, accel=None, topic=None):
    """
    Write a whole ORB-SLAM3 v1.0 settings file: ``%YAML:1.0``, ``File.version: "1.0"``, the IMU.

    What a gyro log cannot give is left out, so ORB-SLAM3's own checks
    (Settings.cc, read in the order camera, image, IMU, ORB, viewer) stop
    on it by name: the camera (``Camera.type`` first), ``IMU.T_b_c1``, and
    the accelerometer figures without ``accel``. Its template is in comments.
    """
    ex = export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    lines = ['ORB-SLAM3 v1.0 settings: a whole file (./mono_inertial_euroc VOC SETTINGS ...). '
             'The camera and the camera-IMU extrinsics are yours to fill in (below).']
    lines += noise_lines(calibration, ex, 'orbslam3-settings', _ORBSLAM3_CONVENTION, accel)
    lines += _orbslam3_missing(accel)
    return ('%YAML:1.0\n' + as_comments(lines) + '\nFile.version: "1.0"\n\n'
            + _ORBSLAM3_CAMERA_TEMPLATE + '\n# --- IMU, from the log\n'
            + _orbslam3_imu(ex, rate, accel) + _ORBSLAM3_REST)


def flicker_band(calibration):
    """Return the flicker correlation-time band that keeps B flat over the taus used, s."""
    lo, hi = calibration.tau_range_s
    low = float(np.clip(lo / 3.0, 1e-3, 0.03))
    high = float(min(max(3.0 * hi, 1000.0), 1e6))
    return low, high


@dataclass(frozen=True)
class TwinNoise:
    """
    The sensor YAML noise fields of a calibration (what ``--format preset`` writes).

    ``per_axis`` maps each calibrated axis to its fields in datasheet units
    (``electronics_arw_deg_sqrt_h``, ``bias_instability_deg_h``,
    ``rate_random_walk_deg_h_sqrt_h``, ``turn_on_bias_deg_s``); ``shared``
    holds the fields of every axis (the flicker band, terms per decade, the
    LSB when found, the output filter's cut-off and order when one is
    identified); ``terms_on`` the :class:`ErrorTerms` switched on (every
    other noise term off); ``twin`` the emulator fit behind them;
    ``output_filter`` the identified low-pass
    (:class:`~gyro_emulator.analysis.calibrate.lowpass.OutputFilter`) or None.
    """

    per_axis: dict
    shared: dict
    terms_on: frozenset
    twin: object
    output_filter: object = None


#: Noise terms of :class:`ErrorTerms` a noise calibration decides (on or off).
NOISE_SWITCHES = ('mechanical_noise', 'electronics_noise', 'bias_instability',
                  'rate_random_walk', 'turn_on_bias', 'quantization')


def twin_noise(calibration, inflate=1.0):
    """
    Return the emulator's noise fields of a calibration (:class:`TwinNoise`).

    The values come from :func:`~gyro_emulator.analysis.calibrate.twin.emulator_fit`
    (the emulator's own noise model fitted to the log's Allan curves, over
    the flicker band of :func:`flicker_band`), times ``inflate``; the
    turn-on bias is the axis's mean. The measured N carries the whole white
    noise, so ``mechanical_noise`` is off. The part's output low-pass, when
    its PSD shows one (:func:`~gyro_emulator.analysis.calibrate.lowpass.identify_output_filter`),
    is the ``output_filter`` term: the twin's Allan deviation then follows
    the log's at the band-limited taus the fit left out.
    """
    export_noise(calibration, inflate)          # checks inflate
    twin = emulator_fit(calibration, flicker_band(calibration))
    per_axis = {}
    for item in calibration.axes:
        n, b, k = twin.per_axis[item.axis]
        per_axis[item.axis] = {
            'electronics_arw_deg_sqrt_h': units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(n * inflate),
            'bias_instability_deg_h': units.rad_s_to_deg_h(b * inflate),
            'rate_random_walk_deg_h_sqrt_h': units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h(k * inflate),
            'turn_on_bias_deg_s': units.rad_s_to_deg_s(item.mean_rad_s)}
    on = {'electronics_noise', 'bias_instability', 'rate_random_walk', 'turn_on_bias'}
    shared = {'bias_instability_band_s': tuple(twin.band_s),
              'bias_instability_per_decade': PER_DECADE}
    if calibration.lsb_rad_s > 0.0:
        on.add('quantization')
        shared['lsb_deg_s'] = units.rad_s_to_deg_s(calibration.lsb_rad_s)
    return _twin_noise(calibration, per_axis, shared, on, twin)


def _twin_noise(calibration, per_axis, shared, on, twin):
    """Return the TwinNoise of either channel, with the output low-pass its PSD shows, if any."""
    lowpass = identify_output_filter(calibration)
    if lowpass is not None:
        on = on | {'output_filter'}
        shared = dict(shared, output_filter_hz=lowpass.cutoff_hz,
                      output_filter_order=lowpass.order)
    return TwinNoise(per_axis, shared, frozenset(on), twin, lowpass)


def preset(calibration, inflate=1.0, rate_hz=None, accel=None, topic=None):
    """
    Write this emulator's sensor YAML: the twin's N, B, K per axis, flicker band, LSB.

    The values come from :func:`twin_noise` (the emulator's own noise model
    fitted to the log); the IEEE Std 952 values are in the comments. Every
    term the log does not measure is off. The log's accelerometer, when it
    has one, is the ``accelerometer:`` of the file (:func:`accel_twin_noise`);
    figures given for a log without one are its white noise and random walk
    (:func:`~gyro_emulator.analysis.calibrate.accel_figures.given_accel_config`).
    """
    fields = twin_noise(calibration, inflate)
    twin = fields.twin
    logged = accel is not None and accel.calibration is not None
    convention = (_CONTINUOUS + ' The emulator discretises exactly at the rate given to '
                  'simulate or the node: white sigma N / sqrt(dt), walk K sqrt(dt), flicker '
                  'as Gauss-Markov terms across bias_instability_band_s.')
    lines = ["gyro_emulator sensor YAML: a whole file (simulate --config FILE, the node's "
             'sensor_config); ' + _preset_accel_words(logged, accel)]
    lines += noise_lines(calibration, export_noise(calibration, inflate), 'preset', convention,
                         accel)
    lines += [f"Twin: the emulator's noise model (white + flicker over correlation times "
              f'{twin.band_s[0]:.3g} .. {twin.band_s[1]:.4g} s + rate random walk) fitted to '
              'the same Allan curves'
              + (f'; the shorter flicker band saves {twin.saving:.1f} in the weighted sum of '
                 'squares (bias correlation times end there)' if twin.saving > 0 else '')
              + '. Its N excludes the quantisation noise of the LSB, which the quantiser adds.',
              'Only the fitted terms are on: the measured N carries the whole white noise '
              '(mechanical_noise off), no temperature terms; '
              + ('output filter (the band-limited taus the fit left out): '
                 + fields.output_filter.describe() + '.' if fields.output_filter is not None
                 else 'no output filter (the PSD shows no low-pass below Nyquist).'),
              'turn_on_bias_deg_s is the mean of this run (it includes the projection of '
              "Earth's rate); its run-to-run spread is not measured.",
              f"Simulate it at the log's rate: --rate-hz {calibration.rate_hz:g}."]
    if len(twin.per_axis) < 3:
        lines.append(f'Axes {", ".join(n for n in AXES if n not in twin.per_axis)} copy '
                     f"axis {next(iter(twin.per_axis))}'s noise (not in the calibration); "
                     "their turn-on bias is 0: a bias is the axis's own, not measured.")
    config, layout = twin_config(fields), preset_layout(fields)
    if logged:
        accel_fields = accel_twin_noise(accel, inflate)
        lines += accel_twin_lines(accel, accel_fields)
        config = replace(config, accelerometer=accel_config(accel_fields))
        layout += (accel_layout(accel_fields),)
    elif accel is not None:
        config = replace(config, accelerometer=given_accel_config(accel))
        layout += (given_accel_layout(),)
    return config_yaml(config, layout, as_comments(lines))


def _preset_accel_words(logged, accel):
    """Say what the preset's accelerometer is: the log's, the user's figures, the paper's."""
    if logged:
        return 'the gyro and the accelerometer of the log.'
    if accel is not None:
        return ('the gyro of the log, which has no accelerometer: its white noise and random '
                'walk are the figures given by the user (--accel-noise-density, '
                '--accel-random-walk) on every axis, no other accelerometer term.')
    return ('a gyro log, so no accelerometer figures: simulate and the node run the paper '
            "device's accelerometer (the proof mass's Brownian noise only), not this part's.")


#: The measured keys of ``--format preset``, in order: 6-digit figures in datasheet units.
_PRESET_FIGURES = ('electronics_arw_deg_sqrt_h', 'bias_instability_deg_h',
                   'bias_instability_band_s', 'bias_instability_per_decade',
                   'rate_random_walk_deg_h_sqrt_h', 'turn_on_bias_deg_s')


#: The output filter's keys, written when the PSD shows a low-pass (:mod:`.lowpass`).
_FILTER_FIGURES = ('output_filter_hz', 'output_filter_order')


def preset_layout(fields):
    """Return the keys ``--format preset`` writes (:class:`.sensor.config.YamlKey`)."""
    lsb = (YamlKey('lsb_deg_s', '.6g', scalar=True),) if 'lsb_deg_s' in fields.shared else ()
    lowpass = tuple(YamlKey(name, '.6g', scalar=True) for name in _FILTER_FIGURES
                    if name in fields.shared)
    return ((YamlKey('device'), YamlKey('terms'))
            + tuple(YamlKey(name, '.6g') for name in _PRESET_FIGURES) + lsb + lowpass)


def twin_config(fields):
    """
    Return the sensor configuration of a :class:`TwinNoise`, as ``--format preset`` writes it.

    Every figure is the 6-digit value the file holds (the configuration reads
    back from its text exactly); axes the calibration lacks copy its first
    axis's noise (N, B, K) and get no turn-on bias (a bias is the axis's own:
    not measured); every term the log does not measure is off.
    """
    first = next(iter(fields.per_axis.values()))
    axes = [fields.per_axis.get(name) or dict(first, turn_on_bias_deg_s=0.0) for name in AXES]
    figures = {name: [as_written(a[name]) for a in axes] for name in _PRESET_FIGURES
               if name in axes[0]}
    figures['bias_instability_band_s'] = [as_written(t) for t in
                                          fields.shared['bias_instability_band_s']]
    figures['bias_instability_per_decade'] = as_written(
        fields.shared['bias_instability_per_decade'])
    for name in ('lsb_deg_s',) + _FILTER_FIGURES:
        if name in fields.shared:
            figures[name] = as_written(fields.shared[name])
    terms = {name: name in fields.terms_on for name in ErrorTerms.names()}
    return config_from_mapping({'device': 'paper', 'terms': terms, **figures})


#: The accelerometer's measured keys of ``--format preset``, in order (SI, 6-digit figures).
_ACCEL_FIGURES = ('electronics_noise_m_s2_sqrt_hz', 'bias_instability_m_s2',
                  'bias_instability_band_s', 'bias_instability_per_decade',
                  'random_walk_m_s3_sqrt_hz', 'turn_on_bias_m_s2')


def accel_twin_noise(accel, inflate=1.0):
    """
    Return the accelerometer's twin (:class:`TwinNoise`, SI AccelConfig field names).

    ``accel`` is an :class:`AccelFigures` with the log's calibration. As
    :func:`twin_noise` for the gyro: the emulator's model fitted to the
    accelerometer's Allan curves (its own flicker band), times ``inflate``;
    the turn-on bias is the mean less gravity
    (:meth:`~gyro_emulator.analysis.calibrate.noise.NoiseCalibration.turn_on_bias`).
    Figures the user gave replace the fitted N and K on every axis. Its
    output low-pass, when its PSD shows one, is identified as the gyro's
    (:func:`~gyro_emulator.analysis.calibrate.lowpass.identify_output_filter`).
    """
    cal = accel.calibration
    twin = emulator_fit(cal, flicker_band(cal))
    per_axis = {}
    for item in cal.axes:
        n, b, k = (value * inflate for value in twin.per_axis[item.axis])
        if accel.given:                 # as given, not inflated
            n, k = accel.noise_density_m_s2_sqrt_hz, accel.random_walk_m_s3_sqrt_hz
        per_axis[item.axis] = {'electronics_noise_m_s2_sqrt_hz': n, 'bias_instability_m_s2': b,
                               'random_walk_m_s3_sqrt_hz': k,
                               'turn_on_bias_m_s2': cal.turn_on_bias(item)}
    on = {'electronics_noise', 'bias_instability', 'random_walk', 'turn_on_bias'}
    shared = {'bias_instability_band_s': tuple(twin.band_s),
              'bias_instability_per_decade': PER_DECADE}
    if cal.lsb > 0.0:
        on.add('quantization')
        shared['lsb_m_s2'] = cal.lsb
    return _twin_noise(cal, per_axis, shared, on, twin)


def accel_config(fields):
    """
    Return the AccelConfig of an accelerometer twin: the 6-digit figures the file holds.

    As the gyro's (:func:`twin_config`): axes the calibration lacks copy its
    first axis's noise (N, B, K) and get no turn-on bias (a bias is the
    axis's own: not measured).
    """
    first = next(iter(fields.per_axis.values()))
    axes = [fields.per_axis.get(name) or dict(first, turn_on_bias_m_s2=0.0) for name in AXES]
    mapping = {'terms': {name: name in fields.terms_on for name in AccelTerms.names()}}
    for name in _ACCEL_FIGURES:
        if name in fields.shared:
            value = fields.shared[name]
            mapping[name] = ([as_written(v) for v in value] if isinstance(value, tuple)
                             else as_written(value))
        else:
            mapping[name] = [as_written(a[name]) for a in axes]
    for name in ('lsb_m_s2',) + _FILTER_FIGURES:
        if name in fields.shared:
            mapping[name] = as_written(fields.shared[name])
    return accel_from_mapping(mapping, 'the accelerometer twin')


def accel_layout(fields):
    """Return the ``accelerometer:`` key of ``--format preset`` (its switches and figures)."""
    scalars = tuple(YamlKey(name, '.6g', scalar=True) for name in ('lsb_m_s2',) + _FILTER_FIGURES
                    if name in fields.shared)
    return YamlKey('accelerometer', parts=(YamlKey('terms'),) + tuple(
        YamlKey(name, '.6g') for name in _ACCEL_FIGURES) + scalars)


def accel_twin_lines(accel, fields):
    """Provenance of the accelerometer twin: its fit, the gravity taken off, the override."""
    cal, twin = accel.calibration, fields.twin
    g = np.asarray(cal.gravity_m_s2)
    lines = [f"Accelerometer twin: the emulator's model (white + flicker over "
             f'{twin.band_s[0]:.3g} .. {twin.band_s[1]:.4g} s + random walk) fitted to its '
             'Allan curves; mechanical_noise off (the measured N_a is the whole white noise), '
             'no temperature, scale-factor or misalignment terms; '
             + (f'output filter: {fields.output_filter.describe()}.'
                if fields.output_filter is not None else 'no output filter (the PSD shows no '
                                                         'low-pass below Nyquist).'),
             'turn_on_bias_m_s2 is the mean less gravity. The log is taken as static with '
             'the attitude along its mean: gravity is g = 9.80665 m/s^2 along the mean '
             f'direction ({", ".join(f"{v:.5g}" for v in g)} m/s^2), so the bias along gravity '
             'is the magnitude of the mean minus g and a bias across gravity, which one '
             'attitude cannot tell from a tilt, is taken as none. The twin simulates its '
             'own attitude (level unless set: gravity on +z).']
    if accel.given:
        lines.append('Accelerometer N_a and K_a: the figures given by the user on every axis, '
                     "in place of the twin's.")
    if len(fields.per_axis) < 3:
        lines.append(f'Accelerometer axes {", ".join(n for n in AXES if n not in fields.per_axis)}'
                     f" copy axis {next(iter(fields.per_axis))}'s noise (not in the log); their "
                     "turn-on bias is 0: a bias is the axis's own, not measured.")
    return lines


WRITERS = {'kalibr': kalibr, 'openvins': openvins, 'vins': vins, 'orbslam3': orbslam3,
           'orbslam3-settings': orbslam3_settings, 'gazebo': gazebo, 'preset': preset}


def write_noise(calibration, fmt, inflate=1.0, rate_hz=None, accel=None, topic=None):
    """
    Return the text of format ``fmt`` (one of :data:`FORMATS`).

    ``accel`` (:class:`AccelFigures`, or None: :func:`.accel_figures.accel_figures`)
    gives the accelerometer figures; without them each format leaves them so
    that its consumer stops on them by name, and ``vins`` is refused (its
    consumer would not). ``topic`` is the IMU topic Kalibr and OpenVINS read
    (default: the bag's, none for a CSV log).
    """
    if fmt not in WRITERS:
        raise ValueError(f'format = {fmt!r} is not allowed: choose {", ".join(FORMATS)}')
    check_rate_hz(rate_hz)
    return WRITERS[fmt](calibration, inflate, rate_hz, accel, topic)
