"""
``./dev.sh shell`` keeps the venv when ``~/.bashrc`` changes PATH (issue 25).

pyenv and conda put their own ``python`` first on PATH from ``~/.bashrc``.
The shell reads that file first and activates the venv after it (bash
``--rcfile``), so ``python`` is still the venv's, with ``mcap`` importable.
HOME is a temporary directory whose ``.bashrc`` puts a ``python`` that is not
the venv's first on PATH; the shell reads its commands from stdin.
"""

import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def dev_shell(home, commands):
    """Run ``./dev.sh shell`` with HOME=home, feeding ``commands`` on stdin."""
    env = {k: v for k, v in os.environ.items()
           if k not in ('VIRTUAL_ENV', 'ROS_DOMAIN_ID', 'PYTHONPATH')}
    env['HOME'] = str(home)
    return subprocess.run([os.path.join(ROOT, 'dev.sh'), 'shell'], input=commands, env=env,
                          cwd=str(home), capture_output=True, text=True, timeout=600)


def write_bashrc(home, text):
    """Give home a ``bin/python`` that is not the venv's, and ``.bashrc`` = text."""
    (home / 'bin').mkdir()
    fake = home / 'bin' / 'python'
    fake.write_text('#!/bin/sh\necho "the pyenv shim, not the venv" >&2\nexit 3\n')
    fake.chmod(0o755)
    (home / '.bashrc').write_text(text)


def test_the_venv_python_wins_over_a_bashrc_that_prepends_to_path(tmp_path):
    write_bashrc(tmp_path, 'export PATH="$HOME/bin:$PATH"\nexport FROM_BASHRC=yes\n')
    proc = dev_shell(tmp_path, 'python -c "import mcap, sys; print(sys.prefix)"\n'
                               'echo "rc=$FROM_BASHRC domain=$ROS_DOMAIN_ID '
                               'range=$ROS_AUTOMATIC_DISCOVERY_RANGE"\n'
                               'command -v gyro-emulator-node; command -v node || true\n')
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == os.path.join(ROOT, '.venv'), proc.stdout + proc.stderr
    assert lines[1].startswith('rc=yes domain=') and lines[1].endswith('range=LOCALHOST')
    assert 0 <= int(lines[1].split()[1].split('=')[1]) <= 101
    # The venv's ROS executables carry their long names; `node` is not the gyro node.
    assert lines[2] == os.path.join(ROOT, '.venv', 'bin', 'gyro-emulator-node')
    assert not any(line.startswith(os.path.join(ROOT, '.venv')) for line in lines[3:])
    assert 'the pyenv shim' not in proc.stderr


def test_the_shell_warns_when_bashrc_puts_a_ros_python_on_pythonpath(tmp_path):
    """A ROS setup.bash in ~/.bashrc puts Python 3.12 packages on PYTHONPATH."""
    write_bashrc(tmp_path, 'export PYTHONPATH=/opt/ros/jazzy/lib/python3.12/site-packages\n')
    proc = dev_shell(tmp_path, 'exit 0\n')
    assert proc.returncode == 0, proc.stderr
    assert "PYTHONPATH holds another Python's packages" in proc.stderr


def test_a_python312_rclpy_ahead_on_pythonpath_fails_in_the_venv(tmp_path):
    """
    What sourcing /opt/ros/jazzy/setup.bash (Python 3.12) does to the venv's 3.11.

    setup.bash prepends ``/opt/ros/jazzy/lib/python3.12/site-packages`` to
    PYTHONPATH. A stand-in of that directory holds rclpy with its extension
    tagged ``cpython-312``: the venv's interpreter imports that rclpy first and
    cannot load ``_rclpy_pybind11`` (3.11 loads only ``cpython-311``, ``abi3``
    and untagged ``.so`` files).
    """
    import rclpy  # the venv's, to copy its layout
    source = os.path.dirname(rclpy.__file__)
    site = tmp_path / 'opt' / 'ros' / 'jazzy' / 'lib' / 'python3.12' / 'site-packages'
    target = site / 'rclpy'
    for dirpath, _, files in os.walk(source):
        rel = os.path.relpath(dirpath, source)
        (target / rel).mkdir(parents=True, exist_ok=True)
        for name in files:
            link = name.replace('cpython-311', 'cpython-312')
            os.symlink(os.path.join(dirpath, name), target / rel / link)
    env = dict(os.environ, PYTHONPATH=str(site))
    proc = subprocess.run([sys.executable, '-c', 'import rclpy'], env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0
    assert '_rclpy_pybind11' in proc.stderr and "isn't present" in proc.stderr, proc.stderr
