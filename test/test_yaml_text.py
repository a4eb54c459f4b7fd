"""The calibration exports' YAML writer: PyYAML data, 6-digit figures, comments after keys."""

from gyro_emulator.yaml_text import dump, Figure, Flow, Quoted
import yaml


def test_figures_keep_six_digits_and_read_back_as_written():
    text = dump({'rate': Figure(100.0), 'n': Figure(2.3166512e-05), 'band': Flow(
        [Figure(0.00333333333), Figure(1000.0)]), 'one': 1.0, 'model': Quoted('kalibr')})
    assert text == ('rate: 100.0\nn: 2.31665e-05\nband: [0.00333333, 1000.0]\none: 1.0\n'
                    'model: "kalibr"\n')
    assert yaml.safe_load(text) == {'rate': 100.0, 'n': 2.31665e-05,
                                    'band': [0.00333333, 1000.0], 'one': 1.0, 'model': 'kalibr'}


def test_one_digit_figures_stay_floats():
    """``format(1e6, '.6g')`` is ``1e+06``: a string to YAML 1.1. Written ``1.0e+06``."""
    text = dump({'a': Figure(1e6), 'b': Figure(2e-5), 'c': Figure(-3e-12)})
    assert text == 'a: 1.0e+06\nb: 2.0e-05\nc: -3.0e-12\n'
    assert yaml.safe_load(text) == {'a': 1e6, 'b': 2e-5, 'c': -3e-12}


def test_comments_follow_their_keys_and_sequences_are_indented():
    text = dump({'imu0': {'T': [Flow([1.0, 0.0]), Flow([0.0, 1.0])], 'rate': Figure(200.0)}},
                {'rate': 'Hz'}, gap='  ')
    assert text == 'imu0:\n  T:\n    - [1.0, 0.0]\n    - [0.0, 1.0]\n  rate: 200.0  # Hz\n'
