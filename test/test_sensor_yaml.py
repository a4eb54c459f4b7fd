"""
One writer of the sensor YAML (issue 31 item 2): config_yaml is the inverse of config_from_mapping.

For every configuration the product writes (the sensor presets, the
calibrate noise and thermal presets, diagnose's extended model with and
without the record's noise) the text reads back as the same SensorConfig.
"""

from dataclasses import replace
from types import SimpleNamespace

from gyro_emulator.analysis.calibrate import export_noise, export_thermal
from gyro_emulator.analysis.calibrate.export_noise import TwinNoise
from gyro_emulator.sensor.config import (config_from_mapping, config_yaml, load_sensor_config,
                                         PRESET_NAMES, SensorConfig, YamlKey)
from gyro_emulator.sensor.extensions import (BiasHysteresis, BiasTime, ExtendedTerms,
                                             ScaleFactorTemperature)
from gyro_emulator.units import AXES
from gyro_emulator.yaml_text import Figure
import pytest
import yaml


def _read(text):
    return config_from_mapping(yaml.safe_load(text), source='test')


@pytest.mark.parametrize('name', PRESET_NAMES)
def test_every_sensor_preset_reads_back_as_itself(name):
    config = load_sensor_config(name)
    text = config_yaml(config, provenance='# a preset\n')
    assert text.startswith('# a preset\n')
    assert _read(text) == config


def test_extended_terms_and_noise_read_back_exactly():
    config = replace(
        SensorConfig(),
        electronics_noise_rad_s_sqrt_hz=(1 / 3 * 1e-4, 2e-4, 7.123456789e-5),
        bias_instability_rad_s=(1e-5 / 7, 0.0, 3e-6), turn_on_bias_rad_s=(-0.0634, 0.1, 1 / 9),
        lsb_rad_s=(9.999999999999999e-05, 1e-4, 0.0), bias_instability_band_s=(0.02 / 3, 1000.0),
        bias_instability_per_decade=2.0,
        misalignment=((0.0, 1e-3 / 3, 0.0), (0.0, 0.0, 2e-4), (-1e-4, 0.0, 0.0)),
        terms=replace(SensorConfig().terms, mechanical_noise=False, sense_dynamics=False),
        extended=ExtendedTerms(
            start_time_s=12.5,
            bias_hysteresis=BiasHysteresis(5.748379888436601, (0.0, 0.0, 0.0010319949043240508)),
            bias_time=BiasTime(600.0, (0.0, 1e-3 / 3, 0.0), (0.0, -2e-4, 0.0), 3700.0),
            scale_factor_temperature=ScaleFactorTemperature((2e-4, 0.0, 0.0), ref_temp_c=21.5)))
    assert _read(config_yaml(config)) == config


def test_datasheet_figures_read_back_exactly_in_their_units():
    # a figure in a datasheet unit reads back exactly at the digits it was given with
    figures = {'electronics_arw_deg_sqrt_h': [0.286956, 0.1, 0.3],
               'bias_instability_deg_h': 13.0555,
               'turn_on_bias_deg_s': [-3.94557, 3.40842, 1.65425], 'lsb_deg_s': 0.00572958,
               'misalignment_pct': [[0.0, 1.0, -0.5], [-0.8, 0.0, 0.6], [0.4, -1.2, 0.0]],
               'scale_factor_error_ppm': [300.0, -200.0, 100.0], 'range_deg_s': 250.0}
    config = config_from_mapping(figures)
    keys = [YamlKey(name, '.6g', scalar=not isinstance(value, list))
            for name, value in figures.items()]
    assert _read(config_yaml(config, keys)) == config


def test_the_writer_refuses_a_text_that_would_say_another_configuration():
    config = replace(SensorConfig(), electronics_noise_rad_s_sqrt_hz=(1 / 3 * 1e-4,) * 3)
    with pytest.raises(ValueError, match='does not read back'):
        config_yaml(config, [YamlKey('electronics_noise_rad_s_sqrt_hz', '.6g')])
    with pytest.raises(ValueError, match='does not read back'):
        config_yaml(config, [YamlKey('device', given='paper_sealed')])
    with pytest.raises(ValueError, match='one number cannot spell three'):
        config_yaml(replace(config, lsb_rad_s=(1e-4, 2e-4, 0.0)),
                    [YamlKey('lsb_rad_s', scalar=True)])


def _twin_noise(axes=AXES, lsb=True):
    per_axis = {a: {'electronics_arw_deg_sqrt_h': 0.2869561234 + i / 7,
                    'bias_instability_deg_h': 13.05551234, 'rate_random_walk_deg_h_sqrt_h': 0.0,
                    'turn_on_bias_deg_s': -3.945571234 * (i + 1)} for i, a in enumerate(axes)}
    shared = {'bias_instability_band_s': (0.01999999999998181, 1000.0),
              'bias_instability_per_decade': 2.0}
    if lsb:
        shared['lsb_deg_s'] = 0.005729577951308233
    on = {'electronics_noise', 'bias_instability', 'rate_random_walk', 'turn_on_bias'}
    return TwinNoise(per_axis, shared, frozenset(on | ({'quantization'} if lsb else set())), None)


@pytest.mark.parametrize('axes,lsb', [(AXES, True), (('x',), False)])
def test_the_calibrate_noise_preset_reads_back_as_its_configuration(axes, lsb):
    fields = _twin_noise(axes, lsb)
    config = export_noise.twin_config(fields)
    text = config_yaml(config, export_noise.preset_layout(fields))
    assert _read(text) == config
    assert 'electronics_arw_deg_sqrt_h: [0.286956, ' in text       # 6-digit figures
    assert ('lsb_deg_s: 0.00572958\n' in text) == lsb
    assert config.terms.quantization == lsb and not config.terms.mechanical_noise


def test_the_thermal_preset_reads_back_as_its_configuration():
    fit = SimpleNamespace(temp_ref_c=19.73634567, lsb_rad_s=1e-4,
                          arw_rad_s_sqrt_hz={a: 8.35e-5 + 1e-7 / 3 for a in AXES})
    values = {'x': (-0.0689, 0.00103923, 0.0), 'y': (0.0595, -0.000492, 3e-7 / 7)}
    config, device = export_thermal.preset_config(fit, values)
    text = config_yaml(config, export_thermal._preset_layout(device, fit.lsb_rad_s))
    assert _read(text) == config
    assert text.startswith('device:\n  preset: paper\n  calibration_temp_c: 19.7363\n')
    assert config.device[0].calibration_temp_c == 19.7363
    assert config.bias_temp_coeff_rad_s_k[2] == config.bias_temp_coeff_rad_s_k[0]   # copies x


def test_a_given_value_is_written_as_given():
    device = {'preset': 'paper_sealed', 'gas': {'pressure_pa': 100.0},
              'drive': {'dc_voltage_v': 10.0, 'ac_voltage_v': 1.0}}
    config = config_from_mapping({'device': device, 'lsb_deg_s': 0.00006})
    assert config.device == load_sensor_config('tactical').device
    text = config_yaml(config, [YamlKey('device', given=device),
                                YamlKey('lsb_deg_s', given=Figure(0.00006, '.6g'))])
    assert text == ('device:\n  preset: paper_sealed\n  gas:\n    pressure_pa: 100.0\n'
                    '  drive:\n    dc_voltage_v: 10.0\n    ac_voltage_v: 1.0\n'
                    'lsb_deg_s: 6.0e-05\n')
    # spelt from the configuration instead: the preset it differs least from, and the fields
    assert _read(config_yaml(config)) == config
