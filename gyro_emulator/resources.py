"""
Files that ship with the package: the ``config/`` directory and YAML reading.

There is one way to find ``config/`` (:func:`config_dir`) and one YAML reader
(:func:`read_yaml`); presets, profiles, scenarios and node parameters use both.
"""

import os
import sys

#: A file every ``config/`` directory of this package holds.
_MARKER = 'sensor_paper.yaml'


def config_dir():
    """
    Return the directory holding the presets, profiles and node defaults.

    In order: ``config/`` of the source tree when running from a checkout;
    ``<prefix>/share/gyro_emulator/config`` of the first ``AMENT_PREFIX_PATH``
    prefix that has it (a colcon install, as ``ros2 run`` finds it); the
    pip-installed ``<sys.prefix>/share/gyro_emulator/config``.
    """
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    candidates = [os.path.join(here, 'config')]
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix:
            candidates.append(os.path.join(prefix, 'share', 'gyro_emulator', 'config'))
    candidates.append(os.path.join(sys.prefix, 'share', 'gyro_emulator', 'config'))
    for candidate in candidates:
        if os.path.isfile(os.path.join(candidate, _MARKER)):
            return candidate
    return candidates[-1]


def config_file(name):
    """Return the path of ``name`` inside :func:`config_dir`."""
    return os.path.join(config_dir(), name)


def read_yaml(path):
    """
    Return the document of the YAML file at ``path`` (safe loader).

    An unreadable file or malformed YAML raises ValueError naming the path
    and the parser's account of where it failed.
    """
    # `gyro-emulator --help` imports this module; yaml (20 ms) waits for a file.
    import yaml

    try:
        with open(path, encoding='utf-8') as handle:
            return yaml.safe_load(handle)
    except OSError as exc:
        raise ValueError(f'{path}: cannot read: {exc}') from None
    except yaml.YAMLError as exc:
        text = ' '.join(str(exc).split())      # the parser's account, on one line
        raise ValueError(f'{path}: malformed YAML: {text}') from None
