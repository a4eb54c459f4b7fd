"""
``gyro-emulator ros``: the stand-ins for ros2 run, launch, param and topic (issue 25).

Debian 12 plus PyPI has no ros2cli. Each verb is checked against a real node
process on a private localhost domain: ``ros run node`` starts it; ``topic
echo``, ``topic hz`` and ``topic list`` read it; ``param set`` injects a fault
that ``~/truth/fault`` then reports; ``ros launch`` starts the launch file's
node with its namespace and parameters file and stops it with one SIGINT.
"""

import os
import re
import signal
import subprocess
import sys

from conftest import ros_env
import pytest
from test_node import Probe
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLI = [sys.executable, '-m', 'gyro_emulator.cli', 'ros']


def ros_cli(env, *args, check=True):
    """Run ``gyro-emulator ros ARGS`` to its end; return the CompletedProcess."""
    proc = subprocess.run(CLI + list(args), env=env, capture_output=True, text=True,
                          timeout=600)
    if check:
        assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc


@pytest.mark.ros
def test_run_echo_hz_list_and_param_set_against_a_running_node(tmp_path):
    env = ros_env()
    log = tmp_path / 'node.log'
    with open(log, 'w') as handle:
        node = subprocess.Popen(CLI + ['run', 'node', '--ros-args', '-p', 'frame_id:=cli'],
                                env=env, stdout=handle, stderr=subprocess.STDOUT)
    try:
        echo = ros_cli(env, 'topic', 'echo', 'imu/data_raw', '--count', '2')
        docs = [d for d in echo.stdout.split('---\n') if d.strip()]
        assert len(docs) == 2
        assert all(yaml.safe_load(d)['header']['frame_id'] == 'cli' for d in docs)
        assert len(yaml.safe_load(docs[0])['angular_velocity_covariance']) == 9
        hz = ros_cli(env, 'topic', 'hz', 'imu/data_raw', '--count', '40')
        rates = re.findall(r'average rate: ([0-9.]+)', hz.stdout)
        assert rates and float(rates[-1]) > 0.0, hz.stdout
        assert re.search(r'window: \d+', hz.stdout)
        # `topic list` prints what discovery found in its --spin-time: asked again
        # until the node's topics are in (a poll, each try a new process).
        for _ in range(20):
            listing = ros_cli(env, 'topic', 'list').stdout.splitlines()
            if '/imu/data_raw [sensor_msgs/msg/Imu]' in listing:
                break
        assert '/imu/data_raw [sensor_msgs/msg/Imu]' in listing
        # An integer for a double parameter is sent as a double, as the node wants.
        assert 'Set parameter successful' in ros_cli(
            env, 'param', 'set', '/gyro_emulator', 'fault.start_s', '0').stdout
        assert ros_cli(env, 'param', 'get', '/gyro_emulator',
                       'fault.start_s').stdout.strip() == 'fault.start_s: 0.0'
        assert 'Set parameter successful' in ros_cli(
            env, 'param', 'set', '/gyro_emulator', 'fault.type', 'stuck').stdout
        fault = ros_cli(env, 'topic', 'echo', '/gyro_emulator/truth/fault', '--once')
        status = yaml.safe_load(fault.stdout.split('---\n')[0])['status'][0]
        assert status['message'] == 'stuck', fault.stdout
        refused = ros_cli(env, 'param', 'set', '/gyro_emulator', 'fault.type', 'melted',
                          check=False)
        assert refused.returncode == 1 and 'Setting parameter failed' in refused.stderr
        # An undeclared name: one line naming it and the close matches, no traceback.
        for action, name, match in ((['set', '/gyro_emulator', 'rate_hzz', '100'], 'rate_hzz',
                                     'rate_hz'),
                                    (['get', '/gyro_emulator', 'fault.typ'], 'fault.typ',
                                     'fault.type')):
            wrong = ros_cli(env, 'param', *action, check=False)
            lines = wrong.stderr.strip().splitlines()
            assert wrong.returncode == 2 and len(lines) == 1, wrong.stderr
            head, matches = lines[0].split('; close matches: ')
            assert head == (f"gyro-emulator ros: error: parameter '{name}' is not declared "
                            'by /gyro_emulator')
            assert match in matches.split(', ')
    finally:
        node.send_signal(signal.SIGINT)
        code = node.wait(120)
    text = log.read_text()
    assert code == 0 and 'Traceback' not in text, text


@pytest.mark.ros
def test_launch_starts_the_node_with_namespace_and_params_and_stops_it(tmp_path):
    env = ros_env()
    params = tmp_path / 'my_gyro.yaml'
    params.write_text(yaml.safe_dump({'/**': {'ros__parameters': {
        'frame_id': 'launched', 'rate_hz': 100.0}}}))
    log = tmp_path / 'launch.log'
    with open(log, 'w') as handle:
        launcher = subprocess.Popen(
            CLI + ['launch', 'gyro_emulator', 'gyro_emulator.launch.py',
                   f'params_file:={params}', 'namespace:=gyro'],
            env=env, stdout=handle, stderr=subprocess.STDOUT)
    probe = Probe(env)
    try:
        from sensor_msgs.msg import Imu
        got = probe.listen(Imu, '/gyro/imu/data_raw')
        probe.spin_until(lambda: len(got) >= 5, 600.0, 'Imu from the launched node')
        assert all(m.header.frame_id == 'launched' for m in got)
    finally:
        probe.close()
        launcher.send_signal(signal.SIGINT)
        code = launcher.wait(120)
    text = log.read_text()
    assert code == 0 and 'Traceback' not in text, text
    assert re.search(r'process \[\d+\] exited with 0', text), text


def launch_print(*args):
    """Return the commands ``ros launch --print`` shows for the shipped launch files."""
    proc = subprocess.run(CLI + ['launch', '--print', 'gyro_emulator'] + list(args),
                          env=ros_env(), capture_output=True, text=True, timeout=600)
    return proc


def test_launch_reads_the_array_file_into_one_node_per_instance():
    proc = launch_print('gyro_array.launch.py', 'use_sim_time:=true')
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 3
    for line, name in zip(lines, ('gyro_a', 'gyro_b', 'gyro_c')):
        assert ' ros run node --ros-args -r __node:=gyro_emulator ' in line
        assert f'-r __ns:=/imu_array/{name} --params-file ' in line


def test_launch_refuses_undeclared_arguments_and_unsupported_actions(tmp_path):
    proc = launch_print('gyro_emulator.launch.py', 'namespce:=gyro')
    assert proc.returncode == 2
    assert "'namespce' is not declared; declared: params_file, namespace" in proc.stderr
    other = tmp_path / 'other.launch.py'
    other.write_text('from launch.actions import IncludeLaunchDescription\n'
                     'def generate_launch_description():\n    return None\n')
    proc = subprocess.run(CLI + ['launch', str(other)], env=ros_env(), capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode != 0 and 'Traceback' not in proc.stderr
    assert 'launch.actions.IncludeLaunchDescription is not provided' in proc.stderr


#: A 9-level alias bomb in flow style (9**8 scalars once expanded), for a command line.
BOMB = '{' + ', '.join(['a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]'] + [
    f'a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * 9) + ']' for i in range(1, 9)]) + '}'


def test_param_values_are_read_bounded_and_never_end_in_a_traceback():
    """ros2 param set's reading of VALUE, behind the bounded loader; what rclpy cannot send."""
    from gyro_emulator.cli.ros_graph import parameter_value
    from rcl_interfaces.msg import ParameterType
    assert parameter_value('3').integer_value == 3
    assert parameter_value('2.5').double_value == 2.5
    assert list(parameter_value('[1, 2]').integer_array_value) == [1, 2]
    assert parameter_value('true').bool_value is True
    assert parameter_value('stuck').string_value == 'stuck'
    # rclpy's get_parameter_value puts a parsed mapping or date into string_value (TypeError)
    # and lets a scanner error through: each is sent as the text given
    for text in ('{a: 1}', '2024-01-01', 'a: b: c', '[1, x]'):
        value = parameter_value(text)
        assert value.type == ParameterType.PARAMETER_STRING and value.string_value == text
    with pytest.raises(ValueError, match=r"VALUE = '9{20}': an integer beyond the int64"):
        parameter_value('9' * 20)
    with pytest.raises(ValueError, match='aliases expand to more than'):
        parameter_value(BOMB)
    # refused before it looks for the node: one short line, no node needed
    proc = ros_cli(ros_env(), 'param', 'set', '/nobody', 'rate_hz', BOMB, check=False)
    assert proc.returncode == 2 and 'Traceback' not in proc.stderr
    assert proc.stderr.strip().splitlines() == [
        'gyro-emulator ros: error: VALUE: YAML aliases expand to more than 1000000 nodes: '
        'refused']


def test_a_launch_argument_is_read_bounded():
    proc = launch_print('gyro_emulator.launch.py', f'use_sim_time:={BOMB}')
    assert proc.returncode == 2 and 'Traceback' not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and len(lines[0]) < 200, lines
    assert 'parameter use_sim_time: YAML aliases expand to more than' in lines[0]
