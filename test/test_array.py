"""Array specs (ros.gyro_array) and the gyro_array launch file, without ROS processes."""

import os

from gyro_emulator.ros import gyro_array as array
from gyro_emulator.sensor.config import load_sensor_config
import numpy as np
import pytest
from test_node_units import load_launch_file
import yaml


def write(tmp_path, doc):
    path = tmp_path / 'array.yaml'
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def test_the_shipped_spec_gives_three_parts_drawn_within_their_tolerances():
    instances = array.load_spec()
    assert [i.node_name for i in instances] == [
        f'/imu_array/gyro_{k}/gyro_emulator' for k in 'abc']
    consumer = load_sensor_config('consumer')
    a, b = (np.array(i.parameters['sensor.scale_factor_error']) for i in instances[:2])
    base = np.array(consumer.scale_factor_error)
    assert not np.array_equal(a, b)
    # 1-sigma 0.002: each of the 6 draws within 5 sigma of the preset.
    assert np.all(np.abs(np.concatenate([a, b]) - np.tile(base, 2)) < 0.01)
    mis = np.array(instances[0].parameters['sensor.misalignment']).reshape(3, 3)
    assert np.all(np.diag(mis) == 0.0)
    assert all(i.parameters['rate_hz'] == 400.0 for i in instances)
    assert instances[2].parameters['sensor_config'] == 'tactical'
    # A part keeps its errors from run to run (the draw is seeded by its name).
    assert array.load_spec()[0].parameters == instances[0].parameters


def test_each_part_publishes_in_its_own_frame(tmp_path):
    frames = [i.parameters['frame_id'] for i in array.load_spec()]
    assert frames == ['gyro_a_imu_link', 'gyro_b_imu_link', 'gyro_c_imu_link']
    instances = array.load_spec(write(tmp_path, {
        'parameters': {'frame_id': 'imu'},
        'instances': [{'name': 'left'}, {'name': 'right', 'parameters': {'frame_id': 'r'}}]}))
    assert [i.parameters['frame_id'] for i in instances] == ['left_imu', 'r']


def test_tolerance_draws_over_many_parts_have_the_stated_sigma(tmp_path):
    names = [f'g{k}' for k in range(300)]
    instances = array.load_spec(write(tmp_path, {
        'tolerances': {'turn_on_bias_rad_s': 0.001},
        'instances': [{'name': n} for n in names]}))
    draws = np.array([i.parameters['sensor.turn_on_bias_rad_s'] for i in instances]).ravel()
    # 900 normal draws: the sample sd within 10 % of 0.001 (about 4 standard errors).
    assert np.std(draws) == pytest.approx(0.001, rel=0.1)
    assert abs(np.mean(draws)) < 4 * 0.001 / np.sqrt(len(draws))


def test_instance_parameters_override_the_common_ones_and_the_draw(tmp_path):
    (inst,) = array.load_spec(write(tmp_path, {
        'namespace': 'robot', 'parameters': {'rate_hz': 100.0, 'sensor': {'latency_s': 0.002}},
        'tolerances': {'scale_factor_error': 0.01},
        'instances': [{'name': 'left', 'sensor_config': 'tactical', 'parameters': {
            'rate_hz': 50.0, 'seed': 3, 'sensor.scale_factor_error': [0.0, 0.0, 0.0]}}]}))
    assert inst.namespace == '/robot/left'
    assert inst.parameters['rate_hz'] == 50.0 and inst.parameters['seed'] == 3
    assert inst.parameters['sensor.latency_s'] == 0.002
    assert inst.parameters['sensor.scale_factor_error'] == [0.0, 0.0, 0.0]
    text = array.params_file_text(inst)
    assert yaml.safe_load(text)['/robot/left/gyro_emulator']['ros__parameters'][
        'sensor_config'] == 'tactical'
    command = array.node_command(inst, 'p.yaml', ['-p', 'use_sim_time:=true'])
    assert command[1:] == ['-m', 'gyro_emulator.ros.node', '--ros-args', '-r',
                           '__ns:=/robot/left', '--params-file', 'p.yaml', '-p',
                           'use_sim_time:=true']


@pytest.mark.parametrize('doc,match', [
    ({'instances': []}, 'instances = \\[\\] must be a non-empty list'),
    ({'instances': [{'name': '1x'}]}, "name = '1x' is not allowed: a ROS name"),
    ({'instances': [{'name': 'a'}, {'name': 'a'}]}, "name = 'a' is used twice"),
    ({'instances': [{'name': 'a', 'preset': 'x'}]}, 'unknown key\\(s\\) preset'),
    ({'tolerances': {'scale_factor_error': 0.5}, 'instances': [{'name': 'a'}]},
     'scale_factor_error = 0.5 is out of range: allowed \\[0, 0.1\\] ratio'),
    ({'tolerances': {'lsb_rad_s': 0.1}, 'instances': [{'name': 'a'}]},
     "unknown tolerance 'lsb_rad_s'"),
    ({'instance': []}, 'unknown key\\(s\\) instance'),
], ids=['empty', 'name', 'twice', 'key', 'range', 'tolerance', 'top'])
def test_spec_errors_name_the_key_and_the_allowed_values(tmp_path, doc, match):
    with pytest.raises(ValueError, match=match):
        array.load_spec(write(tmp_path, doc))


def test_the_array_entry_point_prints_its_plan_and_refuses_a_bad_spec(tmp_path, capsys):
    assert array.main(['--print']) == 0
    assert capsys.readouterr().out.count('ros__parameters') == 3
    assert array.main([write(tmp_path, {'instances': []})]) == 2
    assert 'array: error:' in capsys.readouterr().err


def test_the_array_launch_file_makes_one_node_per_instance(monkeypatch):
    made, module = load_launch_file(monkeypatch, 'gyro_array.launch.py')
    declared = {args[0]: kwargs for args, kwargs in made['DeclareLaunchArgument']}
    assert declared['spec']['default_value'].endswith(os.path.join('config',
                                                                   'gyro_array.yaml'))
    (args, kwargs), = made['OpaqueFunction']

    class Context:
        pass

    def value(name):
        class Sub:
            def perform(self, context):
                return {'spec': declared['spec']['default_value'],
                        'use_sim_time': 'true'}[name]
        return Sub()
    monkeypatch.setattr(module, 'LaunchConfiguration', value)
    nodes = kwargs['function'](Context())
    assert len(nodes) == 3
    node_kwargs = made['Node'][-1][1]
    assert node_kwargs['executable'] == 'node' and node_kwargs['name'] == 'gyro_emulator'
    assert node_kwargs['namespace'] == '/imu_array/gyro_c'
    assert node_kwargs['parameters'][0]['use_sim_time'] is True
