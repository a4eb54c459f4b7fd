"""
Every noise and thermal export read as its consumer reads it (issue 25).

Each reader below restates its consumer's parsing, cited, on the real
parser where one installs from PyPI:

* ``cv::FileStorage`` (opencv-python-headless) typed as ORB-SLAM3 v1.0
  (src/Settings.cc ``Settings::readParameter``, the v1.0 release: a float
  must be ``isReal()``), ORB-SLAM3 before v1.0 (src/Tracking.cc
  ``ParseIMUParamFile``: IMU.Frequency ``isInt()``, the rest ``isReal()``),
  VINS-Fusion (vins_estimator/src/estimator/parameters.cpp:
  ``ACC_N = fsSettings["acc_n"]``, no check) and OpenVINS
  (ov_core/src/utils/opencv_yaml_parse.h ``YamlParser::parse``: a missing
  node is a warning and ``successful()`` false, and run_subscribe_msckf.cpp
  exits on that);
* PyYAML plus the checks of Kalibr's ``ImuParameters``
  (aslam_offline_calibration/kalibr/python/kalibr_common/ConfigReader.py);
* the SDF against the element tree and types of sdformat's sdf/1.9
  (same in 1.10 to 1.12) imu.sdf and noise.sdf;
* PX4's QGroundControl parameter rows (Tools/process_sensor_caldata.py).

The MPU-6050 log (gyro and accelerometer) is calibrated by real
``gyro-emulator calibrate noise`` processes without any hand-given figure,
and each file must load complete in its consumer's parser (issue 32).
"""

from dataclasses import replace
import os
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

import cv2
from gyro_emulator import cli, units
from gyro_emulator.analysis.calibrate import export_noise, export_thermal, noise, thermal
from gyro_emulator.analysis.calibrate.accel_figures import accel_figures
from gyro_emulator.recording.record import load_record, Record
from gyro_emulator.sensor.config import SensorConfig
from gyro_emulator.sensor.model import GyroModel
from gyro_emulator.yaml_text import dump, Figure, float_text
import numpy as np
import pytest
import yaml

RATE_HZ = 100.0
ACCEL = export_noise.AccelFigures(2.0e-3, 3.0e-3)
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MPU = os.path.join(ROOT, '..', 'shared', 'data', 'real', 'mpu6050_static',
                   'mpu6050_static_100hz.csv')


@pytest.fixture(scope='module')
def calibration():
    """Ten minutes of a static gyro at 100 Hz (N 0.5 deg/sqrt(h), K 40 deg/h/sqrt(h))."""
    config = replace(SensorConfig.ideal().with_terms(electronics_noise=True,
                                                     rate_random_walk=True),
                     electronics_noise_rad_s_sqrt_hz=float(
                         units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(0.5)),
                     rate_random_walk_rad_s_sqrt_s=float(
                         units.rrw_deg_h_sqrt_h_to_rad_s_sqrt_s(40.0)))
    out = GyroModel(config, RATE_HZ, np.random.default_rng(25)).run(
        np.zeros((60_000, 3)), 25.0).gyro_rad_s
    record = Record(np.arange(len(out)) / RATE_HZ, {a: out[:, i] for i, a in enumerate('xyz')},
                    {a: a for a in 'xyz'}, path='static.csv')
    return noise.calibrate_noise(record)


@pytest.fixture(scope='module')
def bag_calibration(calibration):
    """Return the same calibration as if read from a bag's Imu topic (the topic is known)."""
    axes = tuple(replace(a, column=f'/imu/data_raw angular_velocity.{a.axis}')
                 for a in calibration.axes)
    return replace(calibration, axes=axes)


class Stop(Exception):
    """The consumer stops; the message is what it prints."""


def _storage(text):
    return cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)


# --- ORB-SLAM3 ---------------------------------------------------------------

def _orb_read(fs, name, kind, required=True):
    """ORB-SLAM3 v1.0 ``Settings::readParameter<kind>`` (its release: no int for a float)."""
    node = fs.getNode(name)
    if node.empty():
        if required:
            raise Stop(f'{name} required parameter does not exist, aborting...')
        return None
    if kind == 'float' and not node.isReal():
        raise Stop(f'{name} parameter must be a real number, aborting...')
    if kind == 'int' and not node.isInt():
        raise Stop(f'{name} parameter must be an integer number, aborting...')
    if kind == 'string' and not node.isString():
        raise Stop(f'{name} parameter must be a string, aborting...')
    return {'float': node.real, 'int': lambda: int(node.real()), 'string': node.string,
            'mat': node.mat}[kind]()


def orbslam3_v1(text):
    """System.cc takes Settings on ``File.version: "1.0"``: camera, image, IMU, ORB, viewer."""
    fs = _storage(text)
    version = fs.getNode('File.version')
    if version.empty() or not version.isString() or version.string() != '1.0':
        raise Stop('not a v1.0 settings file: the legacy reader would take it')
    got = {'Camera.type': _orb_read(fs, 'Camera.type', 'string')}
    if got['Camera.type'] != 'PinHole':
        raise Stop(f'Error: {got["Camera.type"]} not known')
    for name in ('Camera1.fx', 'Camera1.fy', 'Camera1.cx', 'Camera1.cy'):
        got[name] = _orb_read(fs, name, 'float')
    if _orb_read(fs, 'Camera1.k1', 'float', required=False) is not None:
        for name in ('Camera1.k1', 'Camera1.k2', 'Camera1.p1', 'Camera1.p2'):
            got[name] = _orb_read(fs, name, 'float')
    for name in ('Camera.height', 'Camera.width', 'Camera.fps', 'Camera.RGB'):
        got[name] = _orb_read(fs, name, 'int')
    got.update(orbslam3_v1_imu(fs))
    for name in ('ORBextractor.nFeatures', 'ORBextractor.nLevels', 'ORBextractor.iniThFAST',
                 'ORBextractor.minThFAST'):
        got[name] = _orb_read(fs, name, 'int')
    got['ORBextractor.scaleFactor'] = _orb_read(fs, 'ORBextractor.scaleFactor', 'float')
    for name in ('KeyFrameSize', 'KeyFrameLineWidth', 'GraphLineWidth', 'PointSize',
                 'CameraSize', 'CameraLineWidth', 'ViewpointX', 'ViewpointY', 'ViewpointZ',
                 'ViewpointF'):
        got[f'Viewer.{name}'] = _orb_read(fs, f'Viewer.{name}', 'float')
    return got


def orbslam3_v1_imu(fs):
    """``Settings::readIMU``: four noise figures and the rate as reals, then IMU.T_b_c1."""
    got = {name: _orb_read(fs, name, 'float')
           for name in ('IMU.NoiseGyro', 'IMU.NoiseAcc', 'IMU.GyroWalk', 'IMU.AccWalk',
                        'IMU.Frequency')}
    got['IMU.T_b_c1'] = _orb_read(fs, 'IMU.T_b_c1', 'mat')
    return got


def orbslam3_legacy_imu(fs):
    """``Tracking::ParseIMUParamFile`` (no File.version): Frequency an int, noise reals."""
    got, messages = {}, []
    node = fs.getNode('IMU.Frequency')
    if not node.empty() and node.isInt():
        got['IMU.Frequency'] = int(node.real())
    else:
        messages.append("*IMU.Frequency parameter doesn't exist or is not an integer*")
    for name in ('IMU.NoiseGyro', 'IMU.NoiseAcc', 'IMU.GyroWalk', 'IMU.AccWalk'):
        node = fs.getNode(name)
        if not node.empty() and node.isReal():
            got[name] = node.real()
        else:
            messages.append(f"*{name} parameter doesn't exist or is not a real number*")
    if messages:
        raise Stop('\n'.join(messages))
    return got


CAMERA = """
Camera.type: "PinHole"
Camera1.fx: 458.654
Camera1.fy: 457.296
Camera1.cx: 367.215
Camera1.cy: 248.375
Camera1.k1: -0.28340811
Camera1.k2: 0.07395907
Camera1.p1: 0.00019359
Camera1.p2: 1.76187114e-05
Camera.width: 752
Camera.height: 480
Camera.fps: 20
Camera.RGB: 1
IMU.T_b_c1: !!opencv-matrix
   rows: 4
   cols: 4
   dt: f
   data: [1.0, 0.0, 0.0, 0.01, 0.0, 1.0, 0.0, 0.02, 0.0, 0.0, 1.0, 0.03, 0.0, 0.0, 0.0, 1.0]
"""


def _uncomment_camera(text):
    """Fill in the camera part as the user does (EuRoC's cam0 figures)."""
    return text + CAMERA


def test_orbslam3_settings_file_loads_once_the_camera_is_filled_in(calibration):
    ex = noise.export_noise(calibration)
    text = export_noise.write_noise(calibration, 'orbslam3-settings', accel=ACCEL)
    lines = text.splitlines()
    assert lines[0] == '%YAML:1.0' and 'a whole file' in lines[1]
    with pytest.raises(Stop, match=r'^Camera\.type required parameter does not exist'):
        orbslam3_v1(text)                      # as written: the camera part stops it by name
    got = orbslam3_v1(_uncomment_camera(text))
    assert got['IMU.NoiseGyro'] == pytest.approx(ex.arw_rad_s_sqrt_hz, rel=1e-5)
    assert got['IMU.GyroWalk'] == pytest.approx(ex.rrw_rad_s_sqrt_s, rel=1e-5)
    assert got['IMU.NoiseAcc'] == pytest.approx(ACCEL.noise_density_m_s2_sqrt_hz)
    assert got['IMU.AccWalk'] == pytest.approx(ACCEL.random_walk_m_s3_sqrt_hz)
    assert got['IMU.Frequency'] == RATE_HZ
    assert got['ORBextractor.nFeatures'] == 1000
    # a FILL_IN the user leaves in the camera template stops it by name too
    filled = _uncomment_camera(text).replace('Camera1.fx: 458.654', 'Camera1.fx: FILL_IN')
    with pytest.raises(Stop, match=r'^Camera1\.fx parameter must be a real number'):
        orbslam3_v1(filled)


def test_orbslam3_without_accelerometer_stops_on_imu_noise_acc(calibration):
    text = export_noise.write_noise(calibration, 'orbslam3-settings')
    assert 'IMU.NoiseAcc:' not in text.replace('# ', '#')
    with pytest.raises(Stop, match=r'^IMU\.NoiseAcc required parameter does not exist'):
        orbslam3_v1(_uncomment_camera(text))
    block = export_noise.write_noise(calibration, 'orbslam3')
    with pytest.raises(Stop, match=r"\*IMU\.NoiseAcc parameter doesn't exist"):
        orbslam3_legacy_imu(_storage('%YAML:1.0\n' + block.replace('100.0', '100')))


def test_orbslam3_block_reads_as_v1_and_as_the_legacy_reader_once_frequency_is_an_int(
        calibration):
    ex = noise.export_noise(calibration)
    block = export_noise.write_noise(calibration, 'orbslam3', accel=ACCEL)
    assert block.startswith('# ORB-SLAM3 IMU block, not a whole file')
    assert 'IMU.Frequency: 100.0   # Hz' in block
    settings = '%YAML:1.0\nFile.version: "1.0"\n' + block + CAMERA
    got = orbslam3_v1_imu(_storage(settings))
    assert got['IMU.Frequency'] == RATE_HZ
    assert got['IMU.NoiseGyro'] * np.sqrt(RATE_HZ) == pytest.approx(float(
        units.density_to_sample_sigma(ex.arw_rad_s_sqrt_hz, RATE_HZ)), rel=1e-5)
    np.testing.assert_allclose(got['IMU.T_b_c1'][:3, 3], [0.01, 0.02, 0.03], rtol=1e-6)
    # an integer rate is what stopped v1.0 before (issue 25): the reader says so
    with pytest.raises(Stop, match=r'^IMU\.Frequency parameter must be a real number'):
        orbslam3_v1_imu(_storage(settings.replace('IMU.Frequency: 100.0', 'IMU.Frequency: 100')))
    # the legacy reader wants the integer, as the block's second comment line says
    legacy = '%YAML:1.0\n' + block
    with pytest.raises(Stop, match=r"IMU\.Frequency parameter doesn't exist or is not an int"):
        orbslam3_legacy_imu(_storage(legacy))
    assert 'IMU.Frequency: 100 ' in block.splitlines()[1]
    got = orbslam3_legacy_imu(_storage(legacy.replace('IMU.Frequency: 100.0',
                                                      'IMU.Frequency: 100')))
    assert got['IMU.Frequency'] == 100
    assert got['IMU.GyroWalk'] == pytest.approx(ex.rrw_rad_s_sqrt_s, rel=1e-5)


# --- VINS-Fusion -----------------------------------------------------------

def vins_fusion_imu(text):
    """parameters.cpp: ``ACC_N = fsSettings["acc_n"]`` etc.: ``FileNode::real()``, unchecked."""
    fs = _storage(text)
    return {key: fs.getNode(key).real() for key in ('acc_n', 'acc_w', 'gyr_n', 'gyr_w')}


def test_vins_block_loads_per_sample_values_and_is_refused_without_accelerometer(calibration):
    ex = noise.export_noise(calibration)
    block = export_noise.write_noise(calibration, 'vins', accel=ACCEL)
    assert block.startswith('# VINS-Fusion IMU block, not a whole file')
    config = '%YAML:1.0\nimu: 1\nimu_topic: "/imu0"\n' + block + 'g_norm: 9.81007\n'
    fs = _storage(config)
    for key in ('acc_n', 'acc_w', 'gyr_n', 'gyr_w'):
        assert fs.getNode(key).isReal(), key
    got = vins_fusion_imu(config)
    sqrt_f = np.sqrt(RATE_HZ)
    assert got['gyr_n'] == pytest.approx(ex.arw_rad_s_sqrt_hz * sqrt_f, rel=1e-5)
    assert got['gyr_w'] == pytest.approx(ex.rrw_rad_s_sqrt_s * sqrt_f, rel=1e-5)
    assert got['acc_n'] == pytest.approx(ACCEL.noise_density_m_s2_sqrt_hz * sqrt_f, rel=1e-5)
    assert got['acc_w'] == pytest.approx(ACCEL.random_walk_m_s3_sqrt_hz * sqrt_f, rel=1e-5)
    # why it is refused: VINS-Fusion would take a left-out or text value without a word
    assert vins_fusion_imu('%YAML:1.0\ngyr_n: 0.1\n')['acc_n'] == 0.0
    assert vins_fusion_imu('%YAML:1.0\nacc_n: FILL_IN\n')['acc_n'] > 1e300
    with pytest.raises(ValueError, match='--format vins needs --accel-noise-density'):
        export_noise.write_noise(calibration, 'vins')


# --- OpenVINS --------------------------------------------------------------

OPENVINS_KEYS = ('gyroscope_noise_density', 'gyroscope_random_walk',
                 'accelerometer_noise_density', 'accelerometer_random_walk', 'rostopic')


def openvins_imu(text):
    """YamlParser::parse_external of imu0's keys, then run_subscribe_msckf's successful()."""
    fs = _storage(text)                        # kept: its nodes point into it
    imu0 = fs.getNode('imu0')
    got, warnings = {}, []
    for key in OPENVINS_KEYS:
        node = imu0.getNode(key)
        if node.empty():
            warnings.append(f'the node {key} of type [d] was not found...')
            continue
        got[key] = node.string() if key == 'rostopic' else node.real()
        if key != 'rostopic':
            assert node.isReal(), (key, node.type())   # a map or a string would load wrong
    if warnings:
        raise Stop('\n'.join(warnings + ['unable to parse all parameters, please fix']))
    return got


def test_openvins_file_loads_with_a_topic_and_accelerometer_else_names_each_gap(
        calibration, bag_calibration):
    ex = noise.export_noise(calibration)
    text = export_noise.write_noise(bag_calibration, 'openvins', accel=ACCEL)
    assert text.startswith('%YAML:1.0\n# OpenVINS kalibr_imu_chain.yaml: a whole file')
    got = openvins_imu(text)
    assert got['rostopic'] == '/imu/data_raw'
    assert got['gyroscope_noise_density'] == pytest.approx(ex.arw_rad_s_sqrt_hz, rel=1e-5)
    assert got['accelerometer_random_walk'] == pytest.approx(ACCEL.random_walk_m_s3_sqrt_hz)
    fs = _storage(text)
    assert fs.getNode('imu0').getNode('update_rate').isReal()
    with pytest.raises(Stop) as stop:
        openvins_imu(export_noise.write_noise(calibration, 'openvins'))
    for key in ('accelerometer_noise_density', 'accelerometer_random_walk', 'rostopic'):
        assert f'the node {key} of type' in str(stop.value)
    assert 'unable to parse all parameters' in str(stop.value)


# --- Kalibr ----------------------------------------------------------------

class KalibrImuParameters:
    """
    Kalibr's ``ImuParameters`` checks, restated (kalibr_common/ConfigReader.py).

    ``yaml.safe_load``; each getter wrapped by ``catch_keyerror``, which turns a
    KeyError into ``raiseError("Field {0} missing in file: {1}")``; the
    ``<= 0.0`` checks on update_rate and the four densities.
    """

    def __init__(self, text, path='imu.yaml'):
        self.data = yaml.safe_load(text)
        self.yamlFile = path

    def raiseError(self, message):               # noqa: N802 (Kalibr's name)
        raise RuntimeError(f'[ImuConfig Reader]: {message}')

    def _get(self, getter):
        try:
            return getter()
        except KeyError as e:
            self.raiseError(f'Field {e} missing in file: {self.yamlFile}')

    def getRosTopic(self):                      # noqa: N802
        def get():
            if not isinstance(self.data['rostopic'], str):
                self.raiseError('rostopic has to be a string')
            return self.data['rostopic']
        return self._get(get)

    def getUpdateRate(self):                    # noqa: N802
        def get():
            if self.data['update_rate'] <= 0.0:
                self.raiseError('invalid update_rate')
            return self.data['update_rate']
        return self._get(get)

    def _statistics(self, kind):
        def get():
            density = self.data[f'{kind}_noise_density']
            walk = self.data[f'{kind}_random_walk']
            if density <= 0.0:
                self.raiseError(f'invalid {kind}_noise_density')
            if walk <= 0.0:
                self.raiseError(f'invalid {kind}_random_walk')
            return density / np.sqrt(1.0 / self.getUpdateRate()), walk, density
        return self._get(get)

    def getAccelerometerStatistics(self):       # noqa: N802
        return self._statistics('accelerometer')

    def getGyroStatistics(self):                # noqa: N802
        return self._statistics('gyroscope')


def test_kalibr_file_passes_imu_parameters_or_names_the_missing_field(
        calibration, bag_calibration):
    ex = noise.export_noise(calibration)
    text = export_noise.write_noise(bag_calibration, 'kalibr', accel=ACCEL)
    assert text.startswith('# Kalibr imu.yaml: a whole file')
    imu = KalibrImuParameters(text)
    assert imu.getRosTopic() == '/imu/data_raw' and imu.getUpdateRate() == RATE_HZ
    discrete, walk, density = imu.getGyroStatistics()
    assert density == pytest.approx(ex.arw_rad_s_sqrt_hz, rel=1e-5)
    assert discrete == pytest.approx(ex.arw_rad_s_sqrt_hz * np.sqrt(RATE_HZ), rel=1e-5)
    assert imu.getAccelerometerStatistics()[1] == ACCEL.random_walk_m_s3_sqrt_hz
    bare = KalibrImuParameters(export_noise.write_noise(calibration, 'kalibr'))
    with pytest.raises(RuntimeError, match=r"Field 'accelerometer_noise_density' missing in"):
        bare.getAccelerometerStatistics()
    with pytest.raises(RuntimeError, match=r"Field 'rostopic' missing in file"):
        bare.getRosTopic()
    assert bare.getGyroStatistics()[2] == pytest.approx(ex.arw_rad_s_sqrt_hz, rel=1e-5)


# --- Gazebo (sdformat) -----------------------------------------------------

_NOISE = {'@type': ('none', 'gaussian', 'gaussian_quantized'), 'mean': None,
          'stddev': 0.0, 'bias_mean': None, 'bias_stddev': 0.0, 'dynamic_bias_stddev': 0.0,
          'dynamic_bias_correlation_time': None, 'precision': None}
_AXES = {name: {'noise': _NOISE} for name in 'xyz'}
#: sdformat sdf/1.9/imu.sdf with noise.sdf included under each axis: element -> children;
#: a leaf of noise.sdf is a double (its value: the min it allows, or None).
SDF_IMU = {'imu': {'orientation_reference_frame': {'localization': 'string',
                                                   'custom_rpy': 'vector3',
                                                   'grav_dir_x': 'vector3'},
                   'angular_velocity': _AXES, 'linear_acceleration': _AXES,
                   'enable_orientation': 'bool'}}


def sdf_errors(element, allowed, path=''):
    """Element names against SDF_IMU; doubles parsed as sdformat's Param does."""
    errors = []
    here = f'{path}/{element.tag}'
    for key, value in element.attrib.items():
        if value not in allowed.get(f'@{key}', ()):
            errors.append(f'{here}: attribute {key}="{value}" not allowed')
    for child in element:
        if child.tag not in allowed:
            errors.append(f'{here}: element <{child.tag}> not in sdformat imu.sdf/noise.sdf')
            continue
        spec = allowed[child.tag]
        if isinstance(spec, dict):
            errors += sdf_errors(child, spec, here)
        elif spec is None or isinstance(spec, float):
            try:
                value = float(child.text)
            except ValueError:
                errors.append(f'Invalid argument. Unable to set value [{child.text.strip()}] '
                              f'for key[{child.tag}].')
                continue
            if spec is not None and value < spec:
                errors.append(f'{here}/{child.tag} = {value} below its min {spec}')
    return errors


def test_gazebo_block_follows_sdformat_imu_and_noise(calibration):
    text = export_noise.write_noise(calibration, 'gazebo', accel=ACCEL)
    assert text.startswith('<!--\n  gz-sensors imu element, a block, not a whole file')
    root = ElementTree.fromstring(text[text.index('<imu>'):])
    assert sdf_errors(root, SDF_IMU['imu']) == []
    stddev = float(root.find('linear_acceleration/z/noise/stddev').text)
    assert stddev == pytest.approx(ACCEL.noise_density_m_s2_sqrt_hz * np.sqrt(RATE_HZ))
    bare = export_noise.write_noise(calibration, 'gazebo')
    errors = sdf_errors(ElementTree.fromstring(bare[bare.index('<imu>'):]), SDF_IMU['imu'])
    assert errors == ['Invalid argument. Unable to set value [FILL_IN] for key[stddev].',
                      'Invalid argument. Unable to set value [FILL_IN] for '
                      'key[dynamic_bias_stddev].'] * 3
    wrong = ElementTree.fromstring('<imu><angular_velocity><x><noise type="gaussian">'
                                   '<std_dev>1</std_dev></noise></x></angular_velocity></imu>')
    assert 'element <std_dev> not in' in sdf_errors(wrong, SDF_IMU['imu'])[0]


# --- numbers ---------------------------------------------------------------

MAGNITUDES = [m * 10.0 ** e for e in range(-30, 31) for m in (1.0, 2.0, 5.0, 1.2345678, 9.9999996)]


def test_every_figure_is_a_float_to_pyyaml_and_a_real_to_filestorage():
    """``1e+06`` and ``2e-05`` were strings to PyYAML, ``100`` an int to OpenCV: no more."""
    for value in MAGNITUDES + [-v for v in MAGNITUDES[::7]] + [0.0, 100.0]:
        text = dump({'v': Figure(value)})
        loaded = yaml.safe_load(text)['v']
        assert type(loaded) is float and loaded == pytest.approx(value, rel=1e-5), text
        fs = _storage('%YAML:1.0\n' + text)
        node = fs.getNode('v')
        assert node.isReal() and node.real() == pytest.approx(value, rel=1e-5), text
        assert float_text(value) == text.split(': ')[1].strip()
    with pytest.raises(ValueError, match='not finite'):
        float_text(float('inf'))


#: Keys whose value is text, or an integer by the consumer's own type.
TEXT_OR_INT = {'rostopic', 'model', 'File.version', 'device', 'ORBextractor.nFeatures',
               'ORBextractor.nLevels', 'ORBextractor.iniThFAST', 'ORBextractor.minThFAST'}


def _cv_leaves(node, name=''):
    if node.isMap():
        for key in node.keys():
            yield from _cv_leaves(node.getNode(key), key)
    elif node.isSeq():
        for i in range(node.size()):
            yield from _cv_leaves(node.at(i), name)
    else:
        yield name, node


def _yaml_leaves(value, name=''):
    if isinstance(value, dict):
        for key, item in value.items():
            yield from _yaml_leaves(item, key)
    elif isinstance(value, list):
        for item in value:
            yield from _yaml_leaves(item, name)
    else:
        yield name, value


@pytest.mark.parametrize('fmt', ['kalibr', 'openvins', 'vins', 'orbslam3', 'orbslam3-settings',
                                 'preset'])
def test_every_exported_number_is_a_float_and_a_real(bag_calibration, fmt):
    text = export_noise.write_noise(bag_calibration, fmt, accel=ACCEL)
    if fmt not in ('kalibr', 'preset'):
        body = text if text.startswith('%YAML:1.0') else '%YAML:1.0\n' + text
        fs = _storage(body)
        leaves = list(_cv_leaves(fs.root()))
        assert leaves
        for name, node in leaves:
            if name not in TEXT_OR_INT:
                assert node.isReal(), (fmt, name, node.type())
    if fmt in ('kalibr', 'openvins', 'preset'):
        doc = yaml.safe_load(text.replace('%YAML:1.0\n', ''))
        for name, value in _yaml_leaves(doc):
            if name not in TEXT_OR_INT and not isinstance(value, bool):
                assert type(value) is float, (fmt, name, value)


# --- PX4 -------------------------------------------------------------------

@pytest.fixture(scope='module')
def thermal_csv(tmp_path_factory):
    """Write a static part over 5 .. 45 C in 40 min at 10 Hz: bias slope 3e-4 rad/s/K."""
    t = np.arange(24_000) / 10.0
    temp = 5.0 + 40.0 * t / t[-1]
    rng = np.random.default_rng(8)
    path = tmp_path_factory.mktemp('thermal') / 'ramp.csv'
    columns = [t, temp] + [3e-4 * (temp - 25.0) + 1e-3 * rng.standard_normal(len(t))
                           for _ in 'xyz']
    np.savetxt(path, np.column_stack(columns), delimiter=',', comments='', fmt='%.9g',
               header='time_s,temp_c,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s')
    return str(path)


@pytest.fixture(scope='module')
def thermal_fit(thermal_csv):
    record = load_record(thermal_csv, required=thermal.REQUIRED_COLUMNS)
    return thermal.fit_thermal(thermal.thermal_log([record]), 1)


def test_px4_writes_tc_g0_id_as_an_int32_parameter(thermal_fit, capsys):
    text = export_thermal.write_thermal(thermal_fit, 'px4', px4_gyro_id=2621474)
    rows = [line.split('\t') for line in text.splitlines() if line and not line.startswith('#')]
    assert ['1', '1', 'TC_G0_ID', '2621474', '6'] in rows
    assert all(len(r) == 5 and r[4] in ('6', '9') for r in rows)
    assert export_thermal.read_px4_params(text)['TC_G0_ID'] == 2621474
    bare = export_thermal.write_thermal(thermal_fit, 'px4')
    assert '\tTC_G0_ID\t' not in bare and 'Not written: TC_G0_ID' in bare
    with pytest.raises(ValueError, match='px4_gyro_id = 0 is out of range'):
        export_thermal.write_thermal(thermal_fit, 'px4', px4_gyro_id=0)
    with pytest.raises(ValueError, match='--px4-gyro-id is for --format px4'):
        export_thermal.write_thermal(thermal_fit, 'ardupilot', px4_gyro_id=5)


def test_cli_px4_warns_without_the_gyro_id_and_vins_needs_the_accelerometer(
        thermal_csv, tmp_path, capsys):
    log = thermal_csv
    out = tmp_path / 'tc.params'
    assert cli.main(['calibrate', 'thermal', str(log), '--format', 'px4', '-o', str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == f'gyro-emulator calibrate: warning: {export_thermal.PX4_NO_ID}'
    assert cli.main(['calibrate', 'thermal', str(log), '--format', 'px4', '-o', str(out),
                     '--px4-gyro-id', '2621474', '--overwrite']) == 0
    assert 'TC_G0_ID is not' not in capsys.readouterr().err
    assert '\tTC_G0_ID\t2621474\t6' in out.read_text()
    vins = tmp_path / 'vins.yaml'
    assert cli.main(['calibrate', 'noise', str(log), '--format', 'vins', '-o', str(vins)]) == 2
    assert '--format vins needs --accel-noise-density' in capsys.readouterr().err
    assert cli.main(['calibrate', 'noise', str(log), '--format', 'vins', '-o', str(vins),
                     '--accel-noise-density', '0.002']) == 2
    assert 'give both' in capsys.readouterr().err


# --- the MPU-6050 log, gyro and accelerometer, from the log alone -------------

MPU_FORMATS = ('kalibr', 'openvins', 'vins', 'orbslam3', 'orbslam3-settings', 'gazebo')


@pytest.fixture(scope='module')
def mpu_files(tmp_path_factory):
    """Each format of the MPU-6050 log, written by a ``calibrate noise`` process, no flags."""
    if not os.path.isfile(MPU):
        pytest.skip('shared real data not present')
    folder = tmp_path_factory.mktemp('mpu')
    env = dict(os.environ, MPLBACKEND='Agg',
               PYTHONPATH=ROOT + os.pathsep + os.environ.get('PYTHONPATH', ''))
    files = {}
    for fmt in MPU_FORMATS:
        out = folder / f'{fmt}.yaml'
        done = subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', 'calibrate', 'noise',
                               MPU, '--format', fmt, '-o', str(out)], cwd=ROOT,
                              capture_output=True, text=True, env=env)
        assert done.returncode == 0, done.stderr
        assert 'Traceback' not in done.stderr
        # nothing left for the user to fill in but the camera (ORB-SLAM3's commented template)
        assert not [line for line in out.read_text().splitlines()
                    if 'FILL_IN' in line and not line.lstrip().startswith('#')], fmt
        files[fmt] = out.read_text()
    record = load_record(MPU)
    files['gyro'] = noise.export_noise(noise.calibrate_noise(record))
    files['accel'] = noise.export_noise(noise.calibrate_noise(record, sense=noise.ACCEL))
    return files


def test_mpu6050_kalibr_and_openvins_load_complete(mpu_files):
    gyro, accel = mpu_files['gyro'], mpu_files['accel']
    imu = KalibrImuParameters(mpu_files['kalibr'])
    assert imu.getRosTopic() == '/imu0' and imu.getUpdateRate() == RATE_HZ
    discrete, walk, density = imu.getAccelerometerStatistics()
    assert density == pytest.approx(accel.arw_rad_s_sqrt_hz, rel=1e-5)
    assert walk == pytest.approx(accel.rrw_rad_s_sqrt_s, rel=1e-5)
    assert discrete == pytest.approx(accel.arw_rad_s_sqrt_hz * np.sqrt(RATE_HZ), rel=1e-5)
    assert imu.getGyroStatistics()[2] == pytest.approx(gyro.arw_rad_s_sqrt_hz, rel=1e-5)
    got = openvins_imu(mpu_files['openvins'])
    assert got['rostopic'] == '/imu0'
    assert got['accelerometer_noise_density'] == pytest.approx(accel.arw_rad_s_sqrt_hz,
                                                               rel=1e-5)
    assert got['accelerometer_random_walk'] == pytest.approx(accel.rrw_rad_s_sqrt_s, rel=1e-5)
    assert got['gyroscope_random_walk'] == pytest.approx(gyro.rrw_rad_s_sqrt_s, rel=1e-5)
    # the user's figures in place of the log's, said beside each key, load the same way
    record = load_record(MPU)
    given = accel_figures(noise.calibrate_noise(record, sense=noise.ACCEL), given=(2e-3, 3e-3))
    text = export_noise.write_noise(noise.calibrate_noise(record), 'openvins', accel=given,
                                    topic='/imu0')
    assert "given by the user (--accel-random-walk), in place of the log's" in text
    got = openvins_imu(text)
    assert got['accelerometer_noise_density'] == 2e-3 and got['rostopic'] == '/imu0'
    # a K_a the record does not resolve goes out as its upper bound, and the file says so
    assert accel.rrw_is_bound
    assert 'accelerometer_random_walk: 0.000391268   # m/s^3/sqrt(Hz), K_a (upper bound)' in \
        mpu_files['kalibr']


def test_mpu6050_orbslam3_and_vins_load_complete(mpu_files):
    gyro, accel = mpu_files['gyro'], mpu_files['accel']
    got = orbslam3_v1(_uncomment_camera(mpu_files['orbslam3-settings']))
    assert got['IMU.NoiseAcc'] == pytest.approx(accel.arw_rad_s_sqrt_hz, rel=1e-5)
    assert got['IMU.AccWalk'] == pytest.approx(accel.rrw_rad_s_sqrt_s, rel=1e-5)
    assert got['IMU.NoiseGyro'] == pytest.approx(gyro.arw_rad_s_sqrt_hz, rel=1e-5)
    block = '%YAML:1.0\nFile.version: "1.0"\n' + mpu_files['orbslam3'] + CAMERA
    assert orbslam3_v1_imu(_storage(block))['IMU.AccWalk'] == pytest.approx(
        accel.rrw_rad_s_sqrt_s, rel=1e-5)
    legacy = '%YAML:1.0\n' + mpu_files['orbslam3'].replace(
        'IMU.Frequency: 100.0', 'IMU.Frequency: 100')
    assert orbslam3_legacy_imu(_storage(legacy))['IMU.NoiseAcc'] == pytest.approx(
        accel.arw_rad_s_sqrt_hz, rel=1e-5)
    config = '%YAML:1.0\nimu: 1\nimu_topic: "/imu0"\n' + mpu_files['vins'] + 'g_norm: 9.81\n'
    fs = _storage(config)
    for key in ('acc_n', 'acc_w', 'gyr_n', 'gyr_w'):
        assert fs.getNode(key).isReal(), key
    got = vins_fusion_imu(config)
    sqrt_f = np.sqrt(RATE_HZ)
    assert got['acc_n'] == pytest.approx(accel.arw_rad_s_sqrt_hz * sqrt_f, rel=1e-5)
    assert got['acc_w'] == pytest.approx(accel.rrw_rad_s_sqrt_s * sqrt_f, rel=1e-5)
    assert got['gyr_n'] == pytest.approx(gyro.arw_rad_s_sqrt_hz * sqrt_f, rel=1e-5)


def test_mpu6050_gazebo_accelerometer_follows_sdformat(mpu_files):
    text = mpu_files['gazebo']
    root = ElementTree.fromstring(text[text.index('<imu>'):])
    assert sdf_errors(root, SDF_IMU['imu']) == []
    record = load_record(MPU)
    cal = noise.calibrate_noise(record, sense=noise.ACCEL)
    for item in cal.axes:
        element = root.find(f'linear_acceleration/{item.axis}/noise')
        assert element.get('type') == 'gaussian_quantized'
        # per sample at the update rate, as the gyro's: N_a sqrt(f)
        assert float(element.find('stddev').text) == pytest.approx(
            item.fit.value('arw') * np.sqrt(RATE_HZ), rel=1e-5)
        assert float(element.find('precision').text) == pytest.approx(cal.lsb, rel=1e-5)
        assert float(element.find('dynamic_bias_stddev').text) > 0.0
